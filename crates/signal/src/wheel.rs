//! Trigger wheels: the crank angle from the raw signal of a sensor over an N−M toothed wheel
//! (N tooth pitches per revolution, M consecutive teeth left out to mark the reference) — an
//! inductive (variable-reluctance) pickup's analog voltage or a Hall sensor's digital one.
//! Generic: nothing engine-specific is assumed; the TDC's position relative to the wheel is a
//! parameter ([`Tdc`]).
//!
//! Three steps:
//! 1. [`EdgeDetector`] — tooth edges from the samples, as they come: a comparator with
//!    hysteresis whose level follows the signal's envelope tooth by tooth (an inductive
//!    pickup's amplitude grows with speed), or a level given. The edge time is interpolated
//!    linearly between the two samples either side of the level. A pulse narrower than
//!    [`GLITCH_WIDTH`] of the teeth before it is a glitch: rejected, counted, never a tooth.
//! 2. [`index_teeth`] — each edge's angle on the wheel: a tooth period against the median of
//!    its neighbours counts its pitches (1 for a tooth, M + 1 across the gap, more where edges
//!    are missing; a period much shorter than a pitch is an extra edge and dropped); the gap is
//!    the position, modulo N pitches, where most periods of M + 1 pitches end. Angle 0 is the
//!    first tooth edge after the first gap. Missing and extra edges, and a gap out of its
//!    place, are integrity findings at their sample.
//! 3. [`WheelAngles::angle_at`] — the angle at any time, interpolated between edges by a
//!    monotone piecewise-cubic Hermite curve (Fritsch–Carlson, as scipy's `PchipInterpolator`),
//!    so that a speed changing within a tooth (or across the gap) bends the curve.

use crate::integrity::{Finding, FindingKind};
use std::f64::consts::TAU;
use std::str::FromStr;
use thiserror::Error;

/// A toothed wheel: `teeth` pitches per revolution, `missing` of them left out (60−2, 36−1,
/// 60−3 …).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Wheel {
    /// Tooth pitches per revolution (N).
    pub teeth: u32,
    /// Consecutive teeth left out (M ≥ 1).
    pub missing: u32,
}

impl Wheel {
    /// The angle of one pitch `2π/N` [rad].
    pub fn pitch(&self) -> f64 {
        TAU / self.teeth as f64
    }

    /// The teeth on the wheel (N − M), edges per revolution.
    pub fn present(&self) -> u32 {
        self.teeth - self.missing
    }
}

impl std::fmt::Display for Wheel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}-{}", self.teeth, self.missing)
    }
}

impl FromStr for Wheel {
    type Err = String;

    /// `N-M` (or `N−M`): e.g. `60-2`, `36-1`, `60-3`.
    fn from_str(s: &str) -> Result<Self, String> {
        let bad =
            || format!("wheel '{s}': expected N-M (tooth pitches − missing teeth), e.g. 60-2");
        let (n, m) = s
            .split_once('-')
            .or_else(|| s.split_once('−'))
            .ok_or_else(bad)?;
        let teeth: u32 = n.trim().parse().map_err(|_| bad())?;
        let missing: u32 = m.trim().parse().map_err(|_| bad())?;
        if missing == 0 {
            return Err(format!(
                "wheel '{s}': no missing tooth, so no reference on the wheel — decode such an encoder's counts with --encoder CHANNEL=PPR and a TDC marker"
            ));
        }
        if teeth < missing + 4 {
            return Err(format!(
                "wheel '{s}': at least 4 teeth must remain between gaps (N − M ≥ 4)"
            ));
        }
        Ok(Self { teeth, missing })
    }
}

/// Which crossing of the level is the tooth's edge.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Edge {
    /// The signal rising through the level (a Hall sensor: a tooth's leading edge).
    #[default]
    Rising,
    /// The signal falling through it (an inductive pickup's steep flank after its peak).
    Falling,
}

impl FromStr for Edge {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "rising" => Ok(Self::Rising),
            "falling" => Ok(Self::Falling),
            _ => Err(format!("edge '{s}': expected rising or falling")),
        }
    }
}

/// How the edges are found.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct EdgeOptions {
    /// Rising or falling crossings.
    pub edge: Edge,
    /// A fixed level and hysteresis (half-band) in the signal's unit; `None`: automatic.
    pub threshold: Option<(f64, f64)>,
}

/// The samples whose 2nd and 98th percentiles give the automatic level's start (midway) and
/// hysteresis (±[`HYSTERESIS`] of their distance); from the first tooth on, each tooth's own
/// peak and trough.
pub const START_SAMPLES: usize = 4096;

/// The hysteresis either side of the automatic level, as a fraction of the last teeth's
/// peak-to-trough swing.
pub const HYSTERESIS: f64 = 0.2;

/// A pulse narrower than this fraction of the median width of the last teeth's pulses is a
/// glitch, not a tooth.
pub const GLITCH_WIDTH: f64 = 0.3;

/// Without an edge for this many tooth periods (the last), the automatic level starts again
/// from the signal's swing since: longer than any gap of a wheel with N − M ≥ 4 teeth
/// between gaps and M ≤ 6.
pub const SILENCE: f64 = 8.0;

/// Errors of the decoding.
#[derive(Debug, Clone, Error, PartialEq)]
pub enum WheelError {
    /// A sample that is not a number (the decoder never guesses over it).
    #[error("sample {index} is {value}: the wheel's signal must be finite (cut the recording or repair the sample)")]
    NonFinite {
        /// Sample index.
        index: usize,
        /// The value.
        value: f64,
    },
    /// Time not increasing.
    #[error("the time does not increase at sample {index} ({prev} → {next} s)")]
    Time {
        /// Sample index.
        index: usize,
        /// Time before.
        prev: f64,
        /// Time at the index.
        next: f64,
    },
    /// The data cannot be decoded as the wheel given, explained.
    #[error("{0}")]
    Invalid(String),
}

/// One tooth edge.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Crossing {
    /// Interpolated time [s].
    t: f64,
    /// The first sample past the level.
    index: usize,
}

/// The comparator's state.
#[derive(Debug, Clone, Copy, PartialEq)]
enum State {
    /// Waiting for the signal to go below the low threshold (armed then).
    Unarmed,
    /// Below the low threshold: the next upward crossing of the level is a candidate edge.
    Armed,
    /// Crossed the level upward at this edge: waiting for the high threshold (a tooth) or the
    /// low one again (noise).
    Candidate(Crossing),
    /// Above the high threshold since this edge: waiting for the downward crossing of the level,
    /// which ends the pulse.
    High(Crossing),
}

/// The tooth edges of a wheel's signal, found sample by sample as chunks come (one code path
/// for a whole recording and a stream). Memory grows with the edges only (N − M per
/// revolution), not with the samples.
#[derive(Debug, Clone)]
pub struct EdgeDetector {
    sign: f64,
    fixed: Option<(f64, f64)>,
    /// The level and hysteresis in use (on the signal times `sign`).
    level: f64,
    band: f64,
    /// The first samples, held until the automatic level can start from them.
    start: Vec<(f64, f64)>,
    state: State,
    prev: Option<(f64, f64)>,
    /// The current pulse's peak and the trough before it.
    peak: f64,
    trough: f64,
    /// The swing since the last edge (the level starts again from it after a silence), the
    /// last edge's time and the last tooth period [s].
    quiet: (f64, f64),
    last_edge: Option<f64>,
    period: f64,
    /// The widths of the last teeth's pulses [s].
    widths: [f64; 5],
    n_widths: usize,
    seen: usize,
    edges_t: Vec<f64>,
    edges_index: Vec<usize>,
    glitches: Vec<usize>,
    error: Option<WheelError>,
}

impl EdgeDetector {
    /// A detector with these options.
    pub fn new(opts: &EdgeOptions) -> Self {
        let sign = match opts.edge {
            Edge::Rising => 1.0,
            Edge::Falling => -1.0,
        };
        let (level, band) = opts
            .threshold
            .map_or((f64::NAN, 0.0), |(l, b)| (sign * l, b.abs()));
        Self {
            sign,
            fixed: opts.threshold,
            level,
            band,
            start: Vec::new(),
            state: State::Unarmed,
            prev: None,
            peak: f64::NEG_INFINITY,
            trough: f64::INFINITY,
            quiet: (f64::INFINITY, f64::NEG_INFINITY),
            last_edge: None,
            period: f64::INFINITY,
            widths: [0.0; 5],
            n_widths: 0,
            seen: 0,
            edges_t: Vec::new(),
            edges_index: Vec::new(),
            glitches: Vec::new(),
            error: None,
        }
    }

    /// Take the next samples: times `t` [s] and the signal `v` (same length).
    pub fn push(&mut self, t: &[f64], v: &[f64]) {
        for (&ti, &vi) in t.iter().zip(v) {
            if self.error.is_some() {
                return;
            }
            let index = self.seen;
            self.seen += 1;
            if !vi.is_finite() {
                self.error = Some(WheelError::NonFinite { index, value: vi });
                return;
            }
            if !ti.is_finite() || self.prev.is_some_and(|(tp, _)| ti <= tp) {
                let prev = self.prev.map_or(f64::NAN, |p| p.0);
                self.error = Some(WheelError::Time {
                    index,
                    prev,
                    next: ti,
                });
                return;
            }
            let u = self.sign * vi;
            if self.level.is_nan() {
                self.start.push((ti, u));
                self.prev = Some((ti, u));
                if self.start.len() == START_SAMPLES {
                    self.begin();
                }
                continue;
            }
            self.step(ti, u, index);
        }
    }

    /// The automatic level's start from the first samples, then those samples through the
    /// comparator.
    fn begin(&mut self) {
        let mut u: Vec<f64> = self.start.iter().map(|s| s.1).collect();
        let q = |u: &mut Vec<f64>, p: f64| {
            let k = ((u.len() - 1) as f64 * p).round() as usize;
            *u.select_nth_unstable_by(k, f64::total_cmp).1
        };
        let (lo, hi) = (q(&mut u, 0.02), q(&mut u, 0.98));
        self.level = 0.5 * (lo + hi);
        self.band = HYSTERESIS * (hi - lo);
        let start = std::mem::take(&mut self.start);
        self.prev = None;
        for (i, (t, u)) in start.into_iter().enumerate() {
            self.step(t, u, i);
        }
    }

    fn step(&mut self, t: f64, u: f64, index: usize) {
        let (level, band) = (self.level, self.band);
        let crossing = |prev: Option<(f64, f64)>| {
            let (tp, up) = prev.unwrap_or((t, u));
            let f = if u != up {
                (level - up) / (u - up)
            } else {
                1.0
            };
            Crossing {
                t: tp + f.clamp(0.0, 1.0) * (t - tp),
                index,
            }
        };
        let prev = self.prev;
        self.prev = Some((t, u));
        self.quiet = (self.quiet.0.min(u), self.quiet.1.max(u));
        // Silent for longer than SILENCE tooth periods (the amplitude fell, as when the engine
        // slows sharply): the level starts again from the swing seen since the last edge.
        if self.fixed.is_none()
            && self
                .last_edge
                .is_some_and(|e| t - e > SILENCE * self.period)
            && self.quiet.1 > self.quiet.0
        {
            self.level = 0.5 * (self.quiet.0 + self.quiet.1);
            self.band = HYSTERESIS * (self.quiet.1 - self.quiet.0);
            self.last_edge = Some(t);
            self.quiet = (u, u);
            self.state = State::Unarmed;
            return;
        }
        self.state = match self.state {
            State::Unarmed => {
                if u < level - band {
                    self.trough = u;
                    State::Armed
                } else {
                    State::Unarmed
                }
            }
            State::Armed => {
                self.trough = self.trough.min(u);
                if u >= level && prev.is_some_and(|p| p.1 < level) {
                    self.peak = u;
                    if u > level + band {
                        State::High(crossing(prev))
                    } else {
                        State::Candidate(crossing(prev))
                    }
                } else {
                    State::Armed
                }
            }
            State::Candidate(c) => {
                self.peak = self.peak.max(u);
                if u > level + band {
                    State::High(c)
                } else if u < level - band {
                    State::Armed
                } else {
                    State::Candidate(c)
                }
            }
            State::High(c) => {
                self.peak = self.peak.max(u);
                if u < level {
                    let end = crossing(prev);
                    self.pulse(c, end.t - c.t);
                    self.trough = u;
                    if u < level - band {
                        State::Armed
                    } else {
                        State::Unarmed
                    }
                } else {
                    State::High(c)
                }
            }
        };
    }

    /// A pulse ended: a tooth (its edge kept, the level follows its swing) or a glitch.
    fn pulse(&mut self, c: Crossing, width: f64) {
        let n = self.n_widths.min(self.widths.len());
        if n >= 3 {
            let mut w = self.widths;
            let w = &mut w[..n];
            w.sort_unstable_by(f64::total_cmp);
            if width < GLITCH_WIDTH * w[n / 2] {
                self.glitches.push(c.index);
                return;
            }
        }
        self.widths[self.n_widths % self.widths.len()] = width;
        self.n_widths += 1;
        if let Some(e) = self.last_edge {
            self.period = c.t - e;
        }
        self.last_edge = Some(c.t);
        self.quiet = (f64::INFINITY, f64::NEG_INFINITY);
        self.edges_t.push(c.t);
        self.edges_index.push(c.index);
        if self.fixed.is_none() && self.peak > self.trough {
            // Half the way to this tooth's own swing: smooth through noise, quick enough for an
            // amplitude that grows with speed.
            let (level, band) = (
                0.5 * (self.peak + self.trough),
                HYSTERESIS * (self.peak - self.trough),
            );
            self.level = 0.5 * (self.level + level);
            self.band = 0.5 * (self.band + band);
        }
    }

    /// The edges found (a recording shorter than [`START_SAMPLES`] is taken whole).
    pub fn finish(mut self) -> Result<Edges, WheelError> {
        if self.level.is_nan() && !self.start.is_empty() {
            self.begin();
        }
        if let Some(e) = self.error {
            return Err(e);
        }
        if self.edges_t.is_empty() {
            return Err(WheelError::Invalid(if self.band <= 0.0 {
                format!(
                    "the signal is flat over its first {} samples: no tooth passes",
                    self.seen.min(START_SAMPLES)
                )
            } else {
                format!(
                    "no tooth edge in {} samples: the signal never crosses {} with ±{} hysteresis",
                    self.seen,
                    self.sign * self.level,
                    self.band
                )
            }));
        }
        Ok(Edges {
            t: self.edges_t,
            index: self.edges_index,
            glitches: self.glitches,
            samples: self.seen,
        })
    }
}

/// Tooth edges: times [s] and the sample at or just after each.
#[derive(Debug, Clone, PartialEq)]
pub struct Edges {
    /// Edge times [s].
    pub t: Vec<f64>,
    /// The sample index of each edge (the first sample past the level).
    pub index: Vec<usize>,
    /// The glitch pulses rejected: their samples.
    pub glitches: Vec<usize>,
    /// Samples seen.
    pub samples: usize,
}

/// Edges of a whole signal: [`EdgeDetector`] over it in one chunk.
pub fn edges(t: &[f64], v: &[f64], opts: &EdgeOptions) -> Result<Edges, WheelError> {
    let mut d = EdgeDetector::new(opts);
    d.push(t, v);
    d.finish()
}

/// What a signal's edges say about the wheel it came from ([`recognise`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Recognised {
    /// The wheel: teeth between gaps + the gap's pitches − 1 = N, M from the gap's length.
    pub wheel: Wheel,
    /// The gaps seen.
    pub gaps: usize,
    /// Edges found.
    pub edges: usize,
}

/// Whether `edges` look like a toothed wheel's — a regular pulse train with a longer gap at a
/// fixed count of teeth — and which N−M: each gap is a period of about M+1 pitches (1.6 … 6,
/// relative to the median of its neighbours), N−M teeth lie between consecutive gaps. Needs
/// 50 edges, 3 gaps, four in five of the counts between them and of their lengths the same,
/// and nine periods in ten regular (a tooth or a gap).
pub fn recognise(edges: &Edges) -> Option<Recognised> {
    let t = &edges.t;
    if t.len() < 50 {
        return None;
    }
    let r = relative_periods(t);
    let gaps: Vec<usize> = (0..r.len())
        .filter(|&k| (1.6..6.0).contains(&r[k]))
        .collect();
    let regular = r.iter().filter(|x| (0.7..1.4).contains(*x)).count();
    if gaps.len() < 3 || (regular + gaps.len()) * 10 < r.len() * 9 {
        return None;
    }
    // The most common spacing and gap length, and how many agree with them.
    let mode = |v: &[usize]| {
        let mut best = (0, 0);
        for &x in v {
            let c = v.iter().filter(|&&y| y == x).count();
            if c > best.1 {
                best = (x, c);
            }
        }
        best
    };
    let spacing: Vec<usize> = gaps.windows(2).map(|w| w[1] - w[0]).collect();
    let lengths: Vec<usize> = gaps.iter().map(|&k| r[k].round() as usize).collect();
    let (present, agree) = mode(&spacing);
    let (gap, agree_gap) = mode(&lengths);
    let m = gap.checked_sub(1)?;
    if agree * 5 < spacing.len() * 4 || agree_gap * 5 < lengths.len() * 4 || m == 0 || present < 2 {
        return None;
    }
    Some(Recognised {
        wheel: Wheel {
            teeth: u32::try_from(present + m).ok()?,
            missing: u32::try_from(m).ok()?,
        },
        gaps: gaps.len(),
        edges: t.len(),
    })
}

/// A period's pitch count is rounded from its ratio to the neighbours' median; further than
/// this from a whole number, it is reported as irregular.
const PITCH_TOLERANCE: f64 = 0.3;

/// A period shorter than this fraction of a pitch ends on an extra edge.
const EXTRA_EDGE: f64 = 0.6;

/// The wheel's angle at its edges, and what the decoding found.
#[derive(Debug, Clone, PartialEq)]
pub struct WheelAngles {
    /// The wheel.
    pub wheel: Wheel,
    /// Edge times [s] (the extra edges dropped).
    pub t: Vec<f64>,
    /// The wheel's angle at each edge [rad]: 0 at the first edge after the first gap (the
    /// reference tooth), a pitch per tooth, M + 1 pitches across the gap.
    pub angle: Vec<f64>,
    /// The sample index of each edge.
    pub index: Vec<usize>,
    /// Whole revolutions between the first and last gap.
    pub revolutions: usize,
    /// The slowest and fastest speed over a tooth period [rpm].
    pub rpm: (f64, f64),
    /// Missing and extra edges, gaps out of place (findings, by sample), glitches rejected
    /// (a note).
    pub findings: Vec<Finding>,
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_unstable_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Each period's length against the median of up to three periods either side of it.
fn relative_periods(t: &[f64]) -> Vec<f64> {
    let p: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    let mut buf = Vec::with_capacity(6);
    (0..p.len())
        .map(|k| {
            buf.clear();
            buf.extend(p[k.saturating_sub(3)..k].iter());
            buf.extend(p[(k + 1).min(p.len())..(k + 4).min(p.len())].iter());
            if buf.is_empty() {
                return 1.0;
            }
            p[k] / median(&mut buf)
        })
        .collect()
}

/// The distance of `x` from the nearest whole number of at least 1.
fn off_whole(x: f64) -> f64 {
    (x - x.round().max(1.0)).abs()
}

/// Drop extra edges: where a period is shorter than [`EXTRA_EDGE`] pitches, drop whichever of
/// its two ends leaves the period across it nearer a whole number of pitches. Returns the kept
/// edges' positions in `t` and the dropped ones.
fn drop_extra(t: &[f64]) -> (Vec<usize>, Vec<usize>) {
    let r = relative_periods(t);
    // The local pitch [s] at each period (its length over its ratio).
    let pitch: Vec<f64> = t
        .windows(2)
        .zip(&r)
        .map(|(w, r)| (w[1] - w[0]) / r)
        .collect();
    let mut keep: Vec<usize> = vec![0];
    let mut dropped = Vec::new();
    for j in 1..t.len() {
        let last = keep[keep.len() - 1];
        let q = pitch[j - 1];
        if (t[j] - t[last]) / q >= EXTRA_EDGE {
            keep.push(j);
            continue;
        }
        // Drop the edge before (its predecessor → j), or j (the edge before → j + 1).
        let drop_last = match keep.len() {
            1 => f64::INFINITY,
            k => off_whole((t[j] - t[keep[k - 2]]) / q),
        };
        let drop_j = t
            .get(j + 1)
            .map_or(0.0, |&next| off_whole((next - t[last]) / q));
        if drop_last < drop_j {
            dropped.push(last);
            keep.pop();
            keep.push(j);
        } else {
            dropped.push(j);
        }
    }
    (keep, dropped)
}

/// The angle of every edge on the wheel `wheel` (see the module docs), from edges found on
/// the channel `channel` (named in the findings and errors).
pub fn index_teeth(edges: &Edges, wheel: Wheel, channel: &str) -> Result<WheelAngles, WheelError> {
    let n = wheel.teeth as i64;
    let m = wheel.missing as i64;
    let mut findings = Vec::new();
    if !edges.glitches.is_empty() {
        findings.push(Finding {
            kind: FindingKind::Note,
            index: edges.glitches[0],
            detail: format!(
                "'{channel}': {} glitch pulse(s) narrower than {:.0} % of a tooth rejected (the first at sample {})",
                edges.glitches.len(),
                GLITCH_WIDTH * 100.0,
                edges.glitches[0]
            ),
        });
    }
    if edges.t.len() < 2 * wheel.present() as usize + 2 || edges.index.len() != edges.t.len() {
        return Err(WheelError::Invalid(format!(
            "'{channel}': {} tooth edges, fewer than two revolutions of a {wheel} wheel ({} edges each)",
            edges.t.len(),
            wheel.present()
        )));
    }
    let (keep, dropped) = drop_extra(&edges.t);
    for &d in &dropped {
        findings.push(Finding {
            kind: FindingKind::ExtraPulses,
            index: edges.index[d],
            detail: format!(
                "'{channel}': an extra edge at sample {} (less than {EXTRA_EDGE} of a tooth pitch after the one before), dropped",
                edges.index[d]
            ),
        });
    }
    let t: Vec<f64> = keep.iter().map(|&k| edges.t[k]).collect();
    let index: Vec<usize> = keep.iter().map(|&k| edges.index[k]).collect();
    if t.len() < 2 * wheel.present() as usize + 2 {
        return Err(WheelError::Invalid(format!(
            "'{channel}': {} tooth edges, fewer than two revolutions of a {wheel} wheel ({} edges each)",
            t.len(),
            wheel.present()
        )));
    }
    let r = relative_periods(&t);
    // Pitches per period and the pitch count at each edge.
    let pitches: Vec<i64> = r.iter().map(|x| x.round().max(1.0) as i64).collect();
    // A period whose pitch count is unsure: not near a whole number, or longer than a
    // revolution (a dropout). The count across it may slip; it is set again at the next gap.
    let unsure: Vec<bool> = r
        .iter()
        .zip(&pitches)
        .map(|(x, &u)| off_whole(*x) > PITCH_TOLERANCE || u > n)
        .collect();
    for (k, x) in r.iter().enumerate() {
        if unsure[k] {
            let detail = if pitches[k] > n {
                format!(
                    "'{channel}': no tooth edge for {:.4} s before sample {} (about {} pitches at the speed around): the angle across is uncertain and is counted again from the next gap",
                    t[k + 1] - t[k],
                    index[k + 1],
                    pitches[k]
                )
            } else {
                format!(
                    "'{channel}': the tooth period ending at sample {} is {x:.2} pitches, not a whole number (taken as {})",
                    index[k + 1],
                    pitches[k]
                )
            };
            findings.push(Finding {
                kind: FindingKind::OutOfSync,
                index: index[k + 1],
                detail,
            });
        }
    }
    // The gap: where, modulo N, most periods of M + 1 pitches end — over the periods before
    // the first unsure one when they span two revolutions, else over all.
    let sure = unsure.iter().position(|&u| u).unwrap_or(pitches.len());
    let voters = if sure >= 2 * wheel.present() as usize {
        sure
    } else {
        pitches.len()
    };
    let mut votes = vec![0usize; n as usize];
    let mut c = 0i64;
    for &u in &pitches[..voters] {
        c += u;
        if u == m + 1 {
            votes[c.rem_euclid(n) as usize] += 1;
        }
    }
    let span = voters / wheel.present() as usize;
    let (residue, &best) = votes
        .iter()
        .enumerate()
        .max_by_key(|v| *v.1)
        .unwrap_or((0, &0));
    if 2 * best < span.max(1) {
        return Err(WheelError::Invalid(mismatch(
            &pitches, wheel, channel, span,
        )));
    }
    let residue = residue as i64;
    // The pitch count at each edge. Inside a period, every pitch position that is not one of
    // the M missing teeth should have had an edge; a period of M + 1 pitches ending out of the
    // gap's place is the gap itself — when M ≥ 2 (so it is no single missing edge) or after an
    // unsure period — and the count is set again from it.
    let mut count = vec![0i64; t.len()];
    let mut gaps = Vec::new();
    let mut c = 0i64;
    let mut resync = false;
    for k in 0..pitches.len() {
        let start = c;
        c += pitches[k];
        let off = (c - residue).rem_euclid(n);
        if unsure[k] {
            resync = true;
            count[k + 1] = c;
            continue;
        }
        if pitches[k] == m + 1 && (m >= 2 || resync) && off != 0 {
            resync = false;
            let correction = if off > n / 2 { n - off } else { -off };
            findings.push(Finding {
                kind: FindingKind::OutOfSync,
                index: index[k + 1],
                detail: format!(
                    "'{channel}': the gap ends at sample {} {} pitch(es) from where the teeth before place it: the angle is counted again from it",
                    index[k + 1],
                    -correction
                ),
            });
            c += correction;
            gaps.push(k + 1);
        } else {
            let lost = (start + 1..c)
                .filter(|p| (p - residue).rem_euclid(n) < n - m)
                .count();
            if lost > 0 {
                findings.push(Finding {
                    kind: FindingKind::PulseLoss,
                    index: index[k + 1],
                    detail: format!(
                        "'{channel}': {lost} tooth edge(s) missing before sample {} (the angle counts the pitches across)",
                        index[k + 1]
                    ),
                });
            }
            if off == 0 {
                gaps.push(k + 1);
                resync = false;
            }
        }
        count[k + 1] = c;
    }
    let zero = count[*gaps
        .first()
        .ok_or_else(|| WheelError::Invalid(mismatch(&pitches, wheel, channel, span)))?];
    let pitch = wheel.pitch();
    let angle: Vec<f64> = count.iter().map(|&c| (c - zero) as f64 * pitch).collect();
    let revolutions = gaps.len().saturating_sub(1);
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for k in (0..pitches.len()).filter(|&k| !unsure[k]) {
        let rpm = (angle[k + 1] - angle[k]) / (t[k + 1] - t[k]) * 30.0 / std::f64::consts::PI;
        lo = lo.min(rpm);
        hi = hi.max(rpm);
    }
    findings.sort_by_key(|f| f.index);
    Ok(WheelAngles {
        wheel,
        t,
        angle,
        index,
        revolutions,
        rpm: (lo, hi),
        findings,
    })
}

/// Why the periods do not show the wheel's gap: what they show instead.
fn mismatch(pitches: &[i64], wheel: Wheel, channel: &str, span: usize) -> String {
    let expected = format!(
        "a {wheel} wheel has a gap of {} pitches every {} teeth",
        wheel.missing + 1,
        wheel.present()
    );
    // The longest periods that recur, and the teeth between them.
    let longest = pitches.iter().copied().max().unwrap_or(1);
    if longest <= 1 {
        return format!(
            "'{channel}': no gap — every tooth period is within {PITCH_TOLERANCE} of its neighbours over {} edges, but {expected}",
            pitches.len() + 1
        );
    }
    let at: Vec<usize> = (0..pitches.len())
        .filter(|&k| pitches[k] == longest)
        .collect();
    let mut between: Vec<f64> = at.windows(2).map(|w| (w[1] - w[0]) as f64).collect();
    let teeth = if between.is_empty() {
        None
    } else {
        Some(median(&mut between))
    };
    match teeth {
        Some(teeth) if at.len() * 2 >= span => format!(
            "'{channel}': {teeth:.0} teeth between gaps of {longest} pitches, expected {} ({expected}) — is it a {}-{} wheel?",
            wheel.present(),
            teeth as i64 + longest - 1,
            longest - 1
        ),
        _ => format!(
            "'{channel}': no regular gap of {} pitches; the longest periods, of {longest} pitches, come {} times over {span} revolutions — {expected}",
            wheel.missing + 1,
            at.len()
        ),
    }
}

impl WheelAngles {
    /// The wheel's angle at the times `at` [s] (increasing), by the monotone cubic through the
    /// edges; NaN before the first edge and after the last.
    pub fn angle_at(&self, at: &[f64]) -> Vec<f64> {
        pchip_at(&self.t, &self.angle, at)
    }
}

/// The monotone piecewise-cubic Hermite interpolant through `(x, y)` (`x` increasing, at least
/// 2 points) at the points `at` (increasing); NaN outside `[x₀, xₙ]`.
pub fn pchip_at(x: &[f64], y: &[f64], at: &[f64]) -> Vec<f64> {
    let d = pchip_slopes(x, y);
    let mut out = Vec::with_capacity(at.len());
    let mut k = 0;
    for &a in at {
        if x.len() < 2 || !(a >= x[0] && a <= x[x.len() - 1]) {
            out.push(f64::NAN);
            continue;
        }
        while k + 2 < x.len() && a > x[k + 1] {
            k += 1;
        }
        let h = x[k + 1] - x[k];
        let s = (a - x[k]) / h;
        let (h00, h10, h01, h11) = (
            (1.0 + 2.0 * s) * (1.0 - s) * (1.0 - s),
            s * (1.0 - s) * (1.0 - s),
            s * s * (3.0 - 2.0 * s),
            s * s * (s - 1.0),
        );
        out.push(h00 * y[k] + h10 * h * d[k] + h01 * y[k + 1] + h11 * h * d[k + 1]);
    }
    out
}

/// The slopes of the monotone piecewise-cubic Hermite interpolant (Fritsch–Carlson, with
/// scipy `PchipInterpolator`'s weighted harmonic mean inside and its shape-preserving
/// three-point formula at the ends).
pub fn pchip_slopes(x: &[f64], y: &[f64]) -> Vec<f64> {
    let n = x.len();
    if n < 2 {
        return vec![0.0; n];
    }
    let h: Vec<f64> = x.windows(2).map(|w| w[1] - w[0]).collect();
    let delta: Vec<f64> = (0..n - 1).map(|k| (y[k + 1] - y[k]) / h[k]).collect();
    if n == 2 {
        return vec![delta[0]; 2];
    }
    let mut d = vec![0.0; n];
    for k in 1..n - 1 {
        let (a, b) = (delta[k - 1], delta[k]);
        if a * b <= 0.0 {
            d[k] = 0.0;
        } else {
            let w1 = 2.0 * h[k] + h[k - 1];
            let w2 = h[k] + 2.0 * h[k - 1];
            d[k] = (w1 + w2) / (w1 / a + w2 / b);
        }
    }
    let end = |h0: f64, h1: f64, m0: f64, m1: f64| {
        let d = ((2.0 * h0 + h1) * m0 - h0 * m1) / (h0 + h1);
        if d.signum() != m0.signum() {
            0.0
        } else if m0.signum() != m1.signum() && d.abs() > 3.0 * m0.abs() {
            3.0 * m0
        } else {
            d
        }
    };
    d[0] = end(h[0], h[1], delta[0], delta[1]);
    d[n - 1] = end(h[n - 2], h[n - 3], delta[n - 2], delta[n - 3]);
    d
}
