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
use std::collections::VecDeque;
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
    /// Edges found, those handed on included.
    found: usize,
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
            found: 0,
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
        self.found += 1;
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

    /// Hand on the edges found so far, `(time [s], sample)` in order, and forget them: what it
    /// holds is then a few numbers, whatever the recording's length.
    pub fn drain(&mut self, mut f: impl FnMut(f64, usize)) {
        for (t, i) in self.edges_t.drain(..).zip(self.edges_index.drain(..)) {
            f(t, i);
        }
    }

    /// The edges found (a recording shorter than [`START_SAMPLES`] is taken whole), those
    /// [`drain`](Self::drain) handed on left out.
    pub fn finish(mut self) -> Result<Edges, WheelError> {
        if self.level.is_nan() && !self.start.is_empty() {
            self.begin();
        }
        if let Some(e) = self.error {
            return Err(e);
        }
        if self.found == 0 {
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
    let mut rel = Relative::default();
    let mut r = Vec::with_capacity(t.len().saturating_sub(1));
    for &x in t {
        rel.push(x);
        while let Some((_, x)) = rel.next(false) {
            r.push(x);
        }
    }
    while let Some((_, x)) = rel.next(true) {
        r.push(x);
    }
    r
}

/// [`relative_periods`] as the edge times come: period `k` (from edge `k` to `k + 1`) is
/// known once three more periods have come, or the edges have ended. Holds seven periods.
#[derive(Debug, Clone, Default)]
struct Relative {
    /// The periods from `from` on [s].
    p: VecDeque<f64>,
    from: usize,
    /// Periods so far, the next to give, the last edge's time.
    periods: usize,
    next: usize,
    last: Option<f64>,
}

impl Relative {
    fn push(&mut self, t: f64) {
        if let Some(last) = self.last {
            self.p.push_back(t - last);
            self.periods += 1;
        }
        self.last = Some(t);
    }

    /// The next period's index and ratio, once known (`end`: no more edges will come).
    fn next(&mut self, end: bool) -> Option<(usize, f64)> {
        let (k, n) = (self.next, self.periods);
        if k >= n || (!end && k + 3 >= n) {
            return None;
        }
        let p = |i: usize| self.p[i - self.from];
        let mut buf = [0.0; 6];
        let mut m = 0;
        for i in (k.saturating_sub(3)..k).chain((k + 1).min(n)..(k + 4).min(n)) {
            buf[m] = p(i);
            m += 1;
        }
        let r = if m == 0 {
            1.0
        } else {
            p(k) / median(&mut buf[..m])
        };
        self.next += 1;
        while self.from + 3 < self.next {
            self.p.pop_front();
            self.from += 1;
        }
        Some((k, r))
    }
}

/// The distance of `x` from the nearest whole number of at least 1.
fn off_whole(x: f64) -> f64 {
    (x - x.round().max(1.0)).abs()
}

/// A tooth period between two kept edges, as [`Teeth`] gives it.
#[derive(Debug, Clone, Copy)]
struct Period {
    /// Its number (from 0) and the edges at its ends: times [s], samples.
    k: usize,
    t: (f64, f64),
    index: (usize, usize),
    /// Its length against its neighbours', and the pitches counted across it.
    r: f64,
    pitches: i64,
    /// Its pitch count is unsure: not near a whole number, or longer than a revolution (a
    /// dropout). The count across it may slip; it is set again at the next gap.
    unsure: bool,
}

/// What [`Teeth`] gives as the edges come.
#[derive(Debug, Clone, Copy)]
enum Tooth {
    /// An extra edge dropped, at its sample.
    Extra(usize),
    /// A period between kept edges.
    Period(Period),
}

/// The first step of the indexing, as the edges come: drop extra edges — where a period is
/// shorter than [`EXTRA_EDGE`] pitches, whichever of its two ends leaves the period across it
/// nearer a whole number of pitches — then count the pitches across each period between the
/// edges kept. Holds a few edges.
#[derive(Debug, Clone)]
struct Teeth {
    teeth: i64,
    /// The ratios of the edges' periods; the edges from `raw_from` on (times, samples).
    raw_rel: Relative,
    raw: VecDeque<(f64, usize)>,
    raw_from: usize,
    /// The kept edges not yet final: the last two.
    top: Option<(f64, usize)>,
    second: Option<(f64, usize)>,
    /// The ratios of the kept edges' periods; the kept edges from `kept_from` on.
    kept_rel: Relative,
    kept: VecDeque<(f64, usize)>,
    kept_from: usize,
    /// Edges seen, and kept.
    edges: usize,
    n_kept: usize,
}

impl Teeth {
    fn new(wheel: Wheel) -> Self {
        Self {
            teeth: i64::from(wheel.teeth),
            raw_rel: Relative::default(),
            raw: VecDeque::new(),
            raw_from: 0,
            top: None,
            second: None,
            kept_rel: Relative::default(),
            kept: VecDeque::new(),
            kept_from: 0,
            edges: 0,
            n_kept: 0,
        }
    }

    /// The next edge: time [s] and sample.
    fn push(&mut self, t: f64, index: usize, out: &mut impl FnMut(Tooth)) {
        self.edges += 1;
        self.raw.push_back((t, index));
        self.raw_rel.push(t);
        if self.top.is_none() {
            self.top = Some((t, index));
        }
        while let Some((k, r)) = self.raw_rel.next(false) {
            self.extra(k + 1, r, out);
        }
    }

    /// No more edges.
    fn finish(&mut self, out: &mut impl FnMut(Tooth)) {
        while let Some((k, r)) = self.raw_rel.next(true) {
            self.extra(k + 1, r, out);
        }
        for e in [self.second.take(), self.top.take()].into_iter().flatten() {
            self.keep(e, out);
        }
        self.second = None;
        while let Some((k, r)) = self.kept_rel.next(true) {
            self.period(k, r, out);
        }
    }

    /// The edge `j`, the ratio of the period before it `r`: kept, or it or the edge before
    /// dropped.
    fn extra(&mut self, j: usize, r: f64, out: &mut impl FnMut(Tooth)) {
        let raw = |i: usize| self.raw[i - self.raw_from];
        let (tj, ij) = raw(j);
        let q = (tj - raw(j - 1).0) / r;
        let next = (j + 1 < self.edges).then(|| raw(j + 1).0);
        let Some(last) = self.top else { return };
        if (tj - last.0) / q >= EXTRA_EDGE {
            if let Some(below) = self.top.replace((tj, ij)) {
                if let Some(final_) = self.second.replace(below) {
                    self.keep(final_, out);
                }
            }
        } else {
            // Drop the edge before (its predecessor → j), or j (the edge before → j + 1).
            let drop_last = self
                .second
                .map_or(f64::INFINITY, |s| off_whole((tj - s.0) / q));
            let drop_j = next.map_or(0.0, |next| off_whole((next - last.0) / q));
            if drop_last < drop_j {
                out(Tooth::Extra(last.1));
                self.top = Some((tj, ij));
            } else {
                out(Tooth::Extra(ij));
            }
        }
        while self.raw_from < j {
            self.raw.pop_front();
            self.raw_from += 1;
        }
    }

    /// A kept edge, final.
    fn keep(&mut self, e: (f64, usize), out: &mut impl FnMut(Tooth)) {
        self.n_kept += 1;
        self.kept.push_back(e);
        self.kept_rel.push(e.0);
        while let Some((k, r)) = self.kept_rel.next(false) {
            self.period(k, r, out);
        }
    }

    fn period(&mut self, k: usize, r: f64, out: &mut impl FnMut(Tooth)) {
        let (a, b) = (
            self.kept[k - self.kept_from],
            self.kept[k + 1 - self.kept_from],
        );
        let pitches = r.round().max(1.0) as i64;
        out(Tooth::Period(Period {
            k,
            t: (a.0, b.0),
            index: (a.1, b.1),
            r,
            pitches,
            unsure: off_whole(r) > PITCH_TOLERANCE || pitches > self.teeth,
        }));
        while self.kept_from < k + 1 {
            self.kept.pop_front();
            self.kept_from += 1;
        }
    }
}

/// Fewer edges than two revolutions: the error.
fn too_few(edges: usize, wheel: Wheel, channel: &str) -> Result<(), WheelError> {
    if edges < 2 * wheel.present() as usize + 2 {
        return Err(WheelError::Invalid(format!(
            "'{channel}': {edges} tooth edges, fewer than two revolutions of a {wheel} wheel ({} edges each)",
            wheel.present()
        )));
    }
    Ok(())
}

/// The first pass of the indexing ([`index_teeth`]): where the gap is, modulo N pitches — where
/// most periods of M + 1 pitches end, over the periods before the first unsure one when they
/// span two revolutions, else over all. Holds N votes twice, and the places of the longest
/// periods (for the error that says what the periods show, about one a revolution).
#[derive(Debug, Clone)]
pub struct GapSurvey {
    teeth: Teeth,
    tally: Tally,
}

/// [`GapSurvey`]'s count of the periods.
#[derive(Debug, Clone)]
struct Tally {
    wheel: Wheel,
    channel: String,
    /// The pitch count so far, and the votes over all periods and before the first unsure.
    count: i64,
    votes: Vec<usize>,
    votes_sure: Vec<usize>,
    periods: usize,
    sure: Option<usize>,
    /// The longest periods' pitches and places.
    longest: i64,
    longest_at: Vec<usize>,
}

/// Where a wheel's gap is: what [`GapSurvey`] found, for [`ToothIndex`].
#[derive(Debug, Clone, PartialEq)]
pub struct Gap {
    /// The wheel.
    pub wheel: Wheel,
    /// The pitch count, modulo N, where the gap ends.
    pub residue: i64,
    /// The error to give if no period turns out to be the gap (what the periods show).
    mismatch: String,
}

impl GapSurvey {
    /// A survey of the edges of a `wheel` on the channel `channel` (named in the errors).
    pub fn new(wheel: Wheel, channel: &str) -> Self {
        let n = wheel.teeth as usize;
        Self {
            teeth: Teeth::new(wheel),
            tally: Tally {
                wheel,
                channel: channel.to_string(),
                count: 0,
                votes: vec![0; n],
                votes_sure: vec![0; n],
                periods: 0,
                sure: None,
                longest: 1,
                longest_at: Vec::new(),
            },
        }
    }

    /// The next edge: time [s] and sample.
    pub fn push(&mut self, t: f64, index: usize) {
        let tally = &mut self.tally;
        self.teeth.push(t, index, &mut |tooth| tally.take(tooth));
    }

    /// Where the gap is, or why it cannot be told (too few edges; no gap where the wheel has
    /// it).
    pub fn finish(mut self) -> Result<Gap, WheelError> {
        let tally = &mut self.tally;
        self.teeth.finish(&mut |tooth| tally.take(tooth));
        let (wheel, channel) = (tally.wheel, tally.channel.as_str());
        too_few(self.teeth.edges, wheel, channel)?;
        too_few(self.teeth.n_kept, wheel, channel)?;
        let sure = tally.sure.unwrap_or(tally.periods);
        let (voters, votes) = if sure >= 2 * wheel.present() as usize {
            (sure, &tally.votes_sure)
        } else {
            (tally.periods, &tally.votes)
        };
        let span = voters / wheel.present() as usize;
        let (residue, &best) = votes
            .iter()
            .enumerate()
            .max_by_key(|v| *v.1)
            .unwrap_or((0, &0));
        let mismatch = tally.mismatch(span);
        if 2 * best < span.max(1) {
            return Err(WheelError::Invalid(mismatch));
        }
        Ok(Gap {
            wheel,
            residue: residue as i64,
            mismatch,
        })
    }
}

impl Tally {
    fn take(&mut self, tooth: Tooth) {
        let Tooth::Period(p) = tooth else { return };
        let (n, m) = (i64::from(self.wheel.teeth), i64::from(self.wheel.missing));
        self.periods += 1;
        if p.unsure && self.sure.is_none() {
            self.sure = Some(p.k);
        }
        self.count += p.pitches;
        if p.pitches == m + 1 {
            let at = self.count.rem_euclid(n) as usize;
            self.votes[at] += 1;
            if self.sure.is_none() {
                self.votes_sure[at] += 1;
            }
        }
        if p.pitches > self.longest {
            self.longest = p.pitches;
            self.longest_at.clear();
        }
        if p.pitches > 1 && p.pitches == self.longest {
            self.longest_at.push(p.k);
        }
    }

    /// Why the periods do not show the wheel's gap: what they show instead.
    fn mismatch(&self, span: usize) -> String {
        let (wheel, channel, longest) = (self.wheel, &self.channel, self.longest);
        let expected = format!(
            "a {wheel} wheel has a gap of {} pitches every {} teeth",
            wheel.missing + 1,
            wheel.present()
        );
        // The longest periods that recur, and the teeth between them.
        if longest <= 1 {
            return format!(
                "'{channel}': no gap — every tooth period is within {PITCH_TOLERANCE} of its neighbours over {} edges, but {expected}",
                self.periods + 1
            );
        }
        let at = &self.longest_at;
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
}

/// The second pass of the indexing ([`index_teeth`]), as the edges come: each kept edge's
/// angle on the wheel, the gap placed by the [`Gap`] the first pass found. Inside a period,
/// every pitch position that is not one of the M missing teeth should have had an edge; a
/// period of M + 1 pitches ending out of the gap's place is the gap itself — when M ≥ 2 (so it
/// is no single missing edge) or after an unsure period — and the count is set again from it.
/// Angle 0 is the first gap's edge: the edges before it are held until it comes (less than a
/// revolution). Holds the findings.
#[derive(Debug, Clone)]
pub struct ToothIndex {
    teeth: Teeth,
    counting: Counting,
}

/// [`ToothIndex`]'s count of the pitches.
#[derive(Debug, Clone)]
struct Counting {
    gap: Gap,
    channel: String,
    count: i64,
    resync: bool,
    /// The count at the first gap's edge, once it has come, and the edges before it: time [s],
    /// count, sample, and whether the period ending there was sure.
    zero: Option<i64>,
    held: VecDeque<(f64, i64, usize, bool)>,
    /// The angles ready: time [s], angle [rad], sample.
    ready: VecDeque<(f64, f64, usize)>,
    /// The last edge given: time, angle.
    last: Option<(f64, f64)>,
    gaps: usize,
    rpm: (f64, f64),
    glitches: Option<(usize, usize)>,
    extras: Vec<Finding>,
    findings: Vec<Finding>,
}

/// What the indexing found besides the angles ([`ToothIndex::finish`]).
#[derive(Debug, Clone, PartialEq)]
pub struct ToothReport {
    /// The wheel.
    pub wheel: Wheel,
    /// Edges kept (the extra ones dropped).
    pub edges: usize,
    /// Whole revolutions between the first and last gap.
    pub revolutions: usize,
    /// The slowest and fastest speed over a tooth period [rpm].
    pub rpm: (f64, f64),
    /// Glitch pulses the edge detector rejected.
    pub glitches: usize,
    /// Missing and extra edges, gaps out of place (findings, by sample), glitches rejected
    /// (a note).
    pub findings: Vec<Finding>,
}

impl ToothIndex {
    /// The indexing of the edges on `channel` with the gap found by a first pass over them.
    pub fn new(gap: &Gap, channel: &str) -> Self {
        Self {
            teeth: Teeth::new(gap.wheel),
            counting: Counting {
                gap: gap.clone(),
                channel: channel.to_string(),
                count: 0,
                resync: false,
                zero: None,
                held: VecDeque::new(),
                ready: VecDeque::new(),
                last: None,
                gaps: 0,
                rpm: (f64::INFINITY, 0.0),
                glitches: None,
                extras: Vec::new(),
                findings: Vec::new(),
            },
        }
    }

    /// The next edge: time [s] and sample.
    pub fn push(&mut self, t: f64, index: usize) {
        let counting = &mut self.counting;
        self.teeth.push(t, index, &mut |tooth| counting.take(tooth));
    }

    /// Glitch pulses rejected by the edge detector: how many, the first's sample (a note).
    pub fn glitches(&mut self, count: usize, first: usize) {
        if count > 0 {
            self.counting.glitches = Some((count, first));
        }
    }

    /// The next edge whose angle is known: time [s], angle [rad], sample.
    pub fn pop(&mut self) -> Option<(f64, f64, usize)> {
        self.counting.ready.pop_front()
    }

    /// No more edges: what was found (the findings sorted by sample), or the error when no
    /// period was the gap. The last angles are then ready ([`pop`](Self::pop)).
    pub fn finish(&mut self) -> Result<ToothReport, WheelError> {
        let counting = &mut self.counting;
        self.teeth.finish(&mut |tooth| counting.take(tooth));
        counting.report(self.teeth.n_kept)
    }
}

impl Counting {
    fn take(&mut self, tooth: Tooth) {
        let p = match tooth {
            Tooth::Extra(i) => {
                let channel = &self.channel;
                self.extras.push(Finding {
                    kind: FindingKind::ExtraPulses,
                    index: i,
                    detail: format!(
                        "'{channel}': an extra edge at sample {i} (less than {EXTRA_EDGE} of a tooth pitch after the one before), dropped"
                    ),
                });
                return;
            }
            Tooth::Period(p) => p,
        };
        if p.k == 0 {
            self.edge(p.t.0, 0, p.index.0, true, false);
        }
        let (n, m) = (
            i64::from(self.gap.wheel.teeth),
            i64::from(self.gap.wheel.missing),
        );
        let residue = self.gap.residue;
        let channel = &self.channel;
        let start = self.count;
        self.count += p.pitches;
        let c = self.count;
        let off = (c - residue).rem_euclid(n);
        let mut gap = false;
        if p.unsure {
            let detail = if p.pitches > n {
                format!(
                    "'{channel}': no tooth edge for {:.4} s before sample {} (about {} pitches at the speed around): the angle across is uncertain and is counted again from the next gap",
                    p.t.1 - p.t.0,
                    p.index.1,
                    p.pitches
                )
            } else {
                format!(
                    "'{channel}': the tooth period ending at sample {} is {:.2} pitches, not a whole number (taken as {})",
                    p.index.1, p.r, p.pitches
                )
            };
            self.findings.push(Finding {
                kind: FindingKind::OutOfSync,
                index: p.index.1,
                detail,
            });
            self.resync = true;
        } else if p.pitches == m + 1 && (m >= 2 || self.resync) && off != 0 {
            self.resync = false;
            let correction = if off > n / 2 { n - off } else { -off };
            self.findings.push(Finding {
                kind: FindingKind::OutOfSync,
                index: p.index.1,
                detail: format!(
                    "'{channel}': the gap ends at sample {} {} pitch(es) from where the teeth before place it: the angle is counted again from it",
                    p.index.1,
                    -correction
                ),
            });
            self.count += correction;
            gap = true;
        } else {
            let lost = (start + 1..c)
                .filter(|q| (q - residue).rem_euclid(n) < n - m)
                .count();
            if lost > 0 {
                self.findings.push(Finding {
                    kind: FindingKind::PulseLoss,
                    index: p.index.1,
                    detail: format!(
                        "'{channel}': {lost} tooth edge(s) missing before sample {} (the angle counts the pitches across)",
                        p.index.1
                    ),
                });
            }
            if off == 0 {
                gap = true;
                self.resync = false;
            }
        }
        self.edge(p.t.1, self.count, p.index.1, !p.unsure, gap);
    }

    /// A kept edge's count (`sure`: the period ending there; `gap`: it ends the gap).
    fn edge(&mut self, t: f64, count: i64, index: usize, sure: bool, gap: bool) {
        self.held.push_back((t, count, index, sure));
        if gap {
            self.gaps += 1;
            self.zero.get_or_insert(count);
        }
        let Some(zero) = self.zero else { return };
        let pitch = self.gap.wheel.pitch();
        while let Some((t, c, index, sure)) = self.held.pop_front() {
            let angle = (c - zero) as f64 * pitch;
            if let (Some((tp, ap)), true) = (self.last, sure) {
                let rpm = (angle - ap) / (t - tp) * 30.0 / std::f64::consts::PI;
                self.rpm = (self.rpm.0.min(rpm), self.rpm.1.max(rpm));
            }
            self.last = Some((t, angle));
            self.ready.push_back((t, angle, index));
        }
    }

    /// What was found, once the edges have ended.
    fn report(&mut self, edges: usize) -> Result<ToothReport, WheelError> {
        if self.zero.is_none() {
            return Err(WheelError::Invalid(self.gap.mismatch.clone()));
        }
        let channel = &self.channel;
        let mut findings: Vec<Finding> = self
            .glitches
            .map(|(count, first)| Finding {
                kind: FindingKind::Note,
                index: first,
                detail: format!(
                    "'{channel}': {count} glitch pulse(s) narrower than {:.0} % of a tooth rejected (the first at sample {first})",
                    GLITCH_WIDTH * 100.0,
                ),
            })
            .into_iter()
            .collect();
        findings.append(&mut self.extras);
        findings.append(&mut self.findings);
        findings.sort_by_key(|f| f.index);
        Ok(ToothReport {
            wheel: self.gap.wheel,
            edges,
            revolutions: self.gaps.saturating_sub(1),
            rpm: self.rpm,
            glitches: self.glitches.map_or(0, |g| g.0),
            findings,
        })
    }
}

/// The angle of every edge on the wheel `wheel` (see the module docs), from edges found on
/// the channel `channel` (named in the findings and errors): [`GapSurvey`] over them, then
/// [`ToothIndex`] — the two passes a stream makes, over the edges held.
pub fn index_teeth(edges: &Edges, wheel: Wheel, channel: &str) -> Result<WheelAngles, WheelError> {
    if edges.index.len() != edges.t.len() {
        return Err(WheelError::Invalid(format!(
            "'{channel}': {} edge times but {} samples",
            edges.t.len(),
            edges.index.len()
        )));
    }
    let pairs = || edges.t.iter().copied().zip(edges.index.iter().copied());
    let mut survey = GapSurvey::new(wheel, channel);
    for (t, i) in pairs() {
        survey.push(t, i);
    }
    let gap = survey.finish()?;
    let mut index = ToothIndex::new(&gap, channel);
    index.glitches(
        edges.glitches.len(),
        edges.glitches.first().copied().unwrap_or(0),
    );
    let (mut t, mut angle, mut at) = (Vec::new(), Vec::new(), Vec::new());
    let mut take = |index: &mut ToothIndex| {
        while let Some((x, a, i)) = index.pop() {
            t.push(x);
            angle.push(a);
            at.push(i);
        }
    };
    for (x, i) in pairs() {
        index.push(x, i);
        take(&mut index);
    }
    let report = index.finish()?;
    take(&mut index);
    Ok(WheelAngles {
        wheel,
        t,
        angle,
        index: at,
        revolutions: report.revolutions,
        rpm: report.rpm,
        findings: report.findings,
    })
}

impl WheelAngles {
    /// The wheel's angle at the times `at` [s] (increasing), by the monotone cubic through the
    /// edges; NaN before the first edge and after the last.
    pub fn angle_at(&self, at: &[f64]) -> Vec<f64> {
        pchip_at(&self.t, &self.angle, at)
    }
}

/// The monotone piecewise-cubic Hermite interpolant through `(x, y)` (`x` increasing, at least
/// 2 points) at the points `at` (increasing); NaN outside `[x₀, xₙ]`: [`Pchip`] over the
/// points all given.
pub fn pchip_at(x: &[f64], y: &[f64], at: &[f64]) -> Vec<f64> {
    let mut p = Pchip::default();
    for (&x, &y) in x.iter().zip(y) {
        p.push(x, y);
    }
    p.end();
    at.iter().map(|&a| p.at(a).unwrap_or(f64::NAN)).collect()
}

/// The monotone piecewise-cubic Hermite interpolant (Fritsch–Carlson, with scipy
/// `PchipInterpolator`'s weighted harmonic mean of the slopes inside and its shape-preserving
/// three-point formula at the ends) as its points come: a value between two points is known
/// once the point after them has come (or the points have ended). Holds four points.
#[derive(Debug, Clone, Default)]
pub struct Pchip {
    /// The points from `from` on.
    x: VecDeque<f64>,
    y: VecDeque<f64>,
    from: usize,
    /// The first point's `x`; points so far; no more will come.
    first: f64,
    n: usize,
    ended: bool,
    /// The interval of the last value: from point `k` to `k + 1`.
    k: usize,
}

impl Pchip {
    /// The next point (`x` above the last).
    pub fn push(&mut self, x: f64, y: f64) {
        if self.n == 0 {
            self.first = x;
        }
        self.x.push_back(x);
        self.y.push_back(y);
        self.n += 1;
    }

    /// No more points.
    pub fn end(&mut self) {
        self.ended = true;
    }

    /// The last point's `x`.
    pub fn last_x(&self) -> Option<f64> {
        self.x.back().copied()
    }

    /// The value at `a` (the queries increasing): NaN outside the points' span; `None` while
    /// points after `a` are still to come.
    pub fn at(&mut self, a: f64) -> Option<f64> {
        let n = self.n;
        if n == 0 {
            return (self.ended || a.is_nan()).then_some(f64::NAN);
        }
        if a.is_nan() || a < self.first {
            return Some(f64::NAN);
        }
        let x = |i: usize| self.x[i - self.from];
        if a > x(n - 1) {
            return self.ended.then_some(f64::NAN);
        }
        if self.ended && n < 2 {
            return Some(f64::NAN);
        }
        let mut k = self.k;
        while k + 2 < n && a > x(k + 1) {
            k += 1;
        }
        if !self.ended && k + 2 >= n {
            return None;
        }
        self.k = k;
        while self.from + 1 < k {
            self.x.pop_front();
            self.y.pop_front();
            self.from += 1;
        }
        let (xk, xk1) = (self.x[k - self.from], self.x[k + 1 - self.from]);
        let (yk, yk1) = (self.y[k - self.from], self.y[k + 1 - self.from]);
        let h = xk1 - xk;
        let s = (a - xk) / h;
        let (h00, h10, h01, h11) = (
            (1.0 + 2.0 * s) * (1.0 - s) * (1.0 - s),
            s * (1.0 - s) * (1.0 - s),
            s * s * (3.0 - 2.0 * s),
            s * s * (s - 1.0),
        );
        Some(h00 * yk + h10 * h * self.slope(k) + h01 * yk1 + h11 * h * self.slope(k + 1))
    }

    /// The slope at point `i` (its neighbours here).
    fn slope(&self, i: usize) -> f64 {
        let h = |j: usize| self.x[j + 1 - self.from] - self.x[j - self.from];
        let delta = |j: usize| (self.y[j + 1 - self.from] - self.y[j - self.from]) / h(j);
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
        let n = self.n;
        if self.ended && n == 2 {
            return delta(0);
        }
        if i == 0 {
            return end(h(0), h(1), delta(0), delta(1));
        }
        if self.ended && i == n - 1 {
            return end(h(n - 2), h(n - 3), delta(n - 2), delta(n - 3));
        }
        let (a, b) = (delta(i - 1), delta(i));
        if a * b <= 0.0 {
            0.0
        } else {
            let w1 = 2.0 * h(i) + h(i - 1);
            let w2 = h(i) + 2.0 * h(i - 1);
            (w1 + w2) / (w1 / a + w2 / b)
        }
    }
}
