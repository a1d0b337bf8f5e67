//! Tooth edges from a sensor's samples, as they come ([`EdgeDetector`]), and over a whole
//! record ([`edges`]).

use super::*;

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
