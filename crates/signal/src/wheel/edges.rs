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
    /// The first samples, held until the automatic level can start from them: time, value (NaN
    /// marks a dropout), sample; the finite ones among them.
    start: Vec<(f64, f64, usize)>,
    start_finite: usize,
    state: State,
    /// The last sample, `None` after a dropout (no edge is interpolated across one).
    prev: Option<(f64, f64)>,
    /// The last sample's time, a dropout's included (time must increase through them).
    last_t: Option<f64>,
    dropouts: Dropouts,
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
            start_finite: 0,
            state: State::Unarmed,
            prev: None,
            last_t: None,
            dropouts: Dropouts::default(),
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

    /// Take the next samples: times `t` [s] and the signal `v` (same length). A sample not
    /// finite is a dropout ([`Dropouts`]): skipped, and no edge is found across it.
    pub fn push(&mut self, t: &[f64], v: &[f64]) {
        for (&ti, &vi) in t.iter().zip(v) {
            if self.error.is_some() {
                return;
            }
            let index = self.seen;
            self.seen += 1;
            if !ti.is_finite() || self.last_t.is_some_and(|tp| ti <= tp) {
                self.error = Some(WheelError::Time {
                    index,
                    prev: self.last_t.unwrap_or(f64::NAN),
                    next: ti,
                });
                return;
            }
            self.last_t = Some(ti);
            let dropout = !vi.is_finite();
            if dropout {
                self.dropouts.add(index, ti, vi);
            }
            let u = if dropout { f64::NAN } else { self.sign * vi };
            if self.level.is_nan() {
                // A dropout's run is held as one mark: what is held grows with the finite
                // samples only.
                if !(dropout && self.start.last().is_some_and(|s| s.1.is_nan())) {
                    self.start.push((ti, u, index));
                }
                self.start_finite += usize::from(!dropout);
                if self.start_finite == START_SAMPLES {
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
        let mut u: Vec<f64> = self
            .start
            .iter()
            .map(|s| s.1)
            .filter(|u| u.is_finite())
            .collect();
        if u.is_empty() {
            // Nothing but dropouts so far: no level yet.
            return;
        }
        let q = |u: &mut Vec<f64>, p: f64| {
            let k = ((u.len() - 1) as f64 * p).round() as usize;
            *u.select_nth_unstable_by(k, f64::total_cmp).1
        };
        let (lo, hi) = (q(&mut u, 0.02), q(&mut u, 0.98));
        self.level = 0.5 * (lo + hi);
        self.band = HYSTERESIS * (hi - lo);
        let start = std::mem::take(&mut self.start);
        self.prev = None;
        for (t, u, i) in start {
            self.step(t, u, i);
        }
    }

    /// The comparator's next sample `u` (the signal times `sign`; NaN: a dropout).
    fn step(&mut self, t: f64, u: f64, index: usize) {
        if u.is_nan() {
            self.prev = None;
            return;
        }
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
            return Err(WheelError::Invalid(if self.dropouts.samples == self.seen {
                format!(
                    "none of its {} samples is finite (NaN or ±inf): no tooth passes",
                    self.seen
                )
            } else if self.band <= 0.0 {
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
            dropouts: self.dropouts,
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
    /// The samples not finite, skipped.
    pub dropouts: Dropouts,
    /// Samples seen.
    pub samples: usize,
}

/// The samples of a sensor's signal that are not finite (NaN, ±inf — a dropout), which the
/// edge detector skips: no edge is interpolated across them, so an edge they hide is lost and
/// the indexing counts it as a missing tooth ([`ToothIndex::dropouts`] tells them as findings).
/// Holds the first [`DROPOUT_RUNS_KEPT`] runs and counts the rest.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Dropouts {
    /// Samples not finite, in all.
    pub samples: usize,
    /// Runs of consecutive ones, in all.
    pub runs: usize,
    /// The first runs.
    pub first: Vec<DropoutRun>,
    /// The last one's sample.
    last: Option<usize>,
}

/// A run of consecutive samples not finite (equal to another with the same value, NaN too).
#[derive(Debug, Clone, Copy)]
pub struct DropoutRun {
    /// Its first sample.
    pub index: usize,
    /// Its first sample's time [s].
    pub t: f64,
    /// Samples in it.
    pub samples: usize,
    /// Its first sample's value.
    pub value: f64,
}

impl PartialEq for DropoutRun {
    fn eq(&self, o: &Self) -> bool {
        (self.index, self.samples, self.value.to_bits()) == (o.index, o.samples, o.value.to_bits())
            && self.t == o.t
    }
}

/// The dropout runs [`Dropouts`] holds one by one.
pub const DROPOUT_RUNS_KEPT: usize = 20;

impl Dropouts {
    /// Sample `index` at `t` [s] is `value`, not finite.
    pub(crate) fn add(&mut self, index: usize, t: f64, value: f64) {
        self.samples += 1;
        let joined = self.last.is_some_and(|l| l + 1 == index);
        self.last = Some(index);
        if joined {
            // The run goes on: its length, if it is one of those kept.
            if let Some(r) = self
                .first
                .last_mut()
                .filter(|r| r.index + r.samples == index)
            {
                r.samples += 1;
            }
            return;
        }
        self.runs += 1;
        if self.first.len() < DROPOUT_RUNS_KEPT {
            self.first.push(DropoutRun {
                index,
                t,
                samples: 1,
                value,
            });
        }
    }

    /// The runs on `channel` as findings: a `non_finite` at each run kept, saying what was
    /// done with them (`skipped`, e.g. "skipped, no edge is found across them"), and a note
    /// counting the rest.
    pub fn findings(&self, channel: &str, skipped: &str) -> Vec<Finding> {
        let mut out: Vec<Finding> = self
            .first
            .iter()
            .map(|r| Finding {
                kind: FindingKind::NonFinite,
                index: r.index,
                detail: format!(
                    "'{channel}': {} sample(s) from sample {} (t = {} s) are {}: {skipped}",
                    r.samples, r.index, r.t, r.value
                ),
            })
            .collect();
        if let Some(last) = self.first.last().filter(|_| self.runs > self.first.len()) {
            out.push(Finding {
                kind: FindingKind::Note,
                index: last.index,
                detail: format!(
                    "'{channel}': {} more run(s) of samples not finite after sample {} ({} sample(s) in all), skipped as these",
                    self.runs - self.first.len(),
                    last.index,
                    self.samples
                ),
            });
        }
        out
    }
}

/// Edges of a whole signal: [`EdgeDetector`] over it in one chunk.
pub fn edges(t: &[f64], v: &[f64], opts: &EdgeOptions) -> Result<Edges, WheelError> {
    let mut d = EdgeDetector::new(opts);
    d.push(t, v);
    d.finish()
}
