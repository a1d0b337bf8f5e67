//! Quadrature encoders: the shaft's angle, both ways, from the two channels A and B of an
//! incremental encoder (a quarter of a line apart) and its optional index Z (one pulse per
//! revolution) — digital or analog signals.
//!
//! * Each channel through a comparator with hysteresis: the level midway between the 2nd and
//!   98th percentiles of its first [`START_SAMPLES`](crate::wheel::START_SAMPLES) samples (Z:
//!   its smallest and largest sample over the whole signal, [`IndexRange`] — a first pass on a
//!   stream), ±20 % of their distance; each transition's time interpolated between the samples
//!   either side.
//! * ×4 decoding: every transition of A or B moves the count by one quarter line, forward when
//!   the Gray sequence (A, B) = 00 → 10 → 11 → 01 runs that way (A leads), back otherwise. Both
//!   channels changing between two samples is a transition the samples could not resolve: an
//!   integrity finding at its sample (the count may be off by two there).
//! * A sample where A or B is not finite (NaN, ±∞) is a dropout ([`Dropouts`], a finding at
//!   each run): skipped whole (Z with it), no transition interpolated across it. At the first
//!   sample after it the state of (A, B) gives the count the dropout hid modulo 4; the speed
//!   before it (the last four transitions, no faster than the time since the last) gives the
//!   rest — the count nearest the expected one, ties the way the shaft last turned. Exact while
//!   the shaft's mean speed over the dropout stays within the bounds the `pulse_loss` finding at
//!   that sample states (±2 counts of the expected); an index pulse later out of place
//!   (below) tells a count lost all the same. Z not finite alone: skipped, an index pulse it
//!   hides is not seen.
//! * Z: the count at each rising edge of the index while turning forward; the angle is 0 at the
//!   first, and every later one must come a whole revolution (4·lines counts) from it — else a
//!   finding at its sample with the counts found.
//! * The angle at any time by the same monotone cubic as [`crate::wheel`] (its extrema, where
//!   the shaft turns back, stay flat).

use crate::integrity::{Finding, FindingKind};
use crate::wheel::{pchip_at, Dropouts, Pchip, WheelError, HYSTERESIS, START_SAMPLES};
use std::f64::consts::TAU;

/// A comparator with hysteresis on one channel, started from its first samples.
#[derive(Debug, Clone)]
struct Comparator {
    level: f64,
    band: f64,
    high: Option<bool>,
    prev: Option<(f64, f64)>,
    /// After a dropout: the next sample outside the band gives the state, no transition.
    resume: bool,
}

impl Comparator {
    /// From the 2nd and 98th percentiles of the first samples `v` (`range`: the smallest and
    /// largest of all the samples instead — an index is high a few samples a revolution).
    fn start(v: &[f64], range: Option<(f64, f64)>) -> Result<Self, String> {
        let mut u: Vec<f64> = v
            .iter()
            .filter(|x| x.is_finite())
            .take(START_SAMPLES)
            .copied()
            .collect();
        if range.is_some_and(|(lo, hi)| !(lo.is_finite() && hi.is_finite())) {
            return Err("none of its samples is finite (NaN or ±inf)".into());
        }
        if u.is_empty() && range.is_none() {
            return Err("no finite sample".into());
        }
        let q = |u: &mut Vec<f64>, p: f64| {
            let k = ((u.len() - 1) as f64 * p).round() as usize;
            *u.select_nth_unstable_by(k, f64::total_cmp).1
        };
        let (lo, hi) = match range {
            Some(r) => r,
            None => (q(&mut u, 0.02), q(&mut u, 0.98)),
        };
        if hi <= lo {
            return Err(format!("flat over its first {} samples (at {lo})", u.len()));
        }
        Ok(Self {
            level: 0.5 * (lo + hi),
            band: HYSTERESIS * (hi - lo),
            high: None,
            prev: None,
            resume: false,
        })
    }

    /// A dropout: no crossing is interpolated across it; the state after it is taken from
    /// the next sample outside the band, without a transition.
    fn forget(&mut self) {
        self.prev = None;
        self.resume = true;
    }

    /// The sample `(t, v)`: `Some((time, new state))` at a transition.
    fn step(&mut self, t: f64, v: f64) -> Option<(f64, bool)> {
        let prev = self.prev.replace((t, v));
        let state = if v > self.level + self.band {
            Some(true)
        } else if v < self.level - self.band {
            Some(false)
        } else {
            None
        };
        if std::mem::take(&mut self.resume) {
            self.high = state.or(self.high);
            return None;
        }
        match (self.high, state) {
            (None, s) => {
                self.high = s;
                None
            }
            (Some(h), Some(s)) if s != h => {
                self.high = Some(s);
                // The crossing of the level, between this sample and the one before.
                let (tp, vp) = prev.unwrap_or((t, v));
                let f = if v != vp {
                    ((self.level - vp) / (v - vp)).clamp(0.0, 1.0)
                } else {
                    1.0
                };
                Some((tp + f * (t - tp), s))
            }
            _ => None,
        }
    }
}

/// The decoded encoder.
#[derive(Debug, Clone, PartialEq)]
pub struct QuadratureAngles {
    /// Lines per revolution.
    pub lines: u32,
    /// Transition times [s].
    pub t: Vec<f64>,
    /// The angle at each transition [rad]: 0 at the first index pulse turning forward (or at
    /// the first transition without Z).
    pub angle: Vec<f64>,
    /// The times of the index pulses turning forward [s].
    pub index_t: Vec<f64>,
    /// Transitions going backward (the shaft turning back).
    pub backward: usize,
    /// Unresolved transitions and index pulses out of place, at their sample.
    pub findings: Vec<Finding>,
}

impl QuadratureAngles {
    /// The angle at the times `at` [s] (increasing); NaN before the first transition and after
    /// the last.
    pub fn angle_at(&self, at: &[f64]) -> Vec<f64> {
        pchip_at(&self.t, &self.angle, at)
    }
}

/// The smallest and largest finite sample of an index channel, a chunk at a time: its
/// comparator's level ([`QuadratureDecoder`]'s first pass, and a pulse encoder's index).
#[derive(Debug, Clone, Copy)]
pub struct IndexRange {
    /// Smallest and largest so far.
    pub range: (f64, f64),
}

impl Default for IndexRange {
    fn default() -> Self {
        Self {
            range: (f64::INFINITY, f64::NEG_INFINITY),
        }
    }
}

impl IndexRange {
    /// The next samples.
    pub fn push(&mut self, z: &[f64]) {
        self.range = z
            .iter()
            .filter(|x| x.is_finite())
            .fold(self.range, |(a, b), &x| (a.min(x), b.max(x)));
    }
}

/// A transition of A or B as [`QuadratureDecoder`] gives it: its time [s] and the edge crossed
/// (between counts `c − 1` and `c`, called `c`, whichever the way).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transition {
    /// Time [s].
    pub t: f64,
    /// The edge crossed, in quarter lines.
    pub edge: i64,
}

/// An index pulse turning forward: its time [s] and sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IndexPulse {
    /// Time [s].
    pub t: f64,
    /// Sample.
    pub index: usize,
}

/// The ×4 decoding of A/B (and Z) as samples come (see the module docs): the comparators
/// started from the first [`START_SAMPLES`] samples (held until then) — Z's from its smallest
/// and largest sample over the whole signal, found by a first pass ([`IndexRange`]) — then the
/// transitions and index pulses in order ([`pop`](Self::pop)). Holds the first samples, the
/// transitions and pulses not yet taken, and the findings.
#[derive(Debug, Clone)]
pub struct QuadratureDecoder {
    names: [String; 3],
    z_range: Option<(f64, f64)>,
    /// The first samples, held until the comparators start: sample, `[t, A, B, Z]` (a
    /// dropout's run held as its first sample); those with A and B finite.
    start: Vec<(usize, [f64; 4])>,
    start_finite: usize,
    comparators: Option<[Comparator; 2]>,
    cz: Option<Comparator>,
    sa: Option<bool>,
    sb: Option<bool>,
    count: i64,
    last_dir: i64,
    /// Transitions so far, the last one's time, steps back.
    transitions: usize,
    last_t: Option<f64>,
    backward: usize,
    /// The last transitions' times (a ring): the speed before a dropout.
    recent: [f64; 5],
    /// The samples not finite on A, B and Z; the dropout of A/B under way: its first sample
    /// and the time of the finite sample before it.
    dropouts: [Dropouts; 3],
    gap: Option<(usize, Option<f64>)>,
    /// The time of the last sample with A and B finite the comparators took, and of the last
    /// sample (time must increase through dropouts too); samples seen.
    prev_t: Option<f64>,
    t_seen: Option<f64>,
    seen: usize,
    out: std::collections::VecDeque<Transition>,
    pulses: std::collections::VecDeque<IndexPulse>,
    findings: Vec<Finding>,
    error: Option<WheelError>,
}

impl QuadratureDecoder {
    /// A decoder for channels `names` (A, B, Z; Z's `z_range` from a first pass, `None`
    /// without Z).
    pub fn new(names: [&str; 3], z_range: Option<(f64, f64)>) -> Self {
        Self {
            names: names.map(str::to_string),
            z_range,
            start: Vec::new(),
            start_finite: 0,
            comparators: None,
            cz: None,
            sa: None,
            sb: None,
            count: 0,
            last_dir: 1,
            transitions: 0,
            last_t: None,
            backward: 0,
            recent: [f64::NAN; 5],
            dropouts: Default::default(),
            gap: None,
            prev_t: None,
            t_seen: None,
            seen: 0,
            out: std::collections::VecDeque::new(),
            pulses: std::collections::VecDeque::new(),
            findings: Vec::new(),
            error: None,
        }
    }

    /// The next samples: times `t` [s], A, B and Z (empty without Z). A sample not finite is
    /// a dropout (see the module docs).
    pub fn push(&mut self, t: &[f64], a: &[f64], b: &[f64], z: &[f64]) {
        for i in 0..t.len() {
            if self.error.is_some() {
                return;
            }
            let index = self.seen;
            self.seen += 1;
            if !t[i].is_finite() || self.t_seen.is_some_and(|p| t[i] <= p) {
                self.error = Some(WheelError::Time {
                    index,
                    prev: self.t_seen.unwrap_or(f64::NAN),
                    next: t[i],
                });
                return;
            }
            self.t_seen = Some(t[i]);
            let sample = [t[i], a[i], b[i], z.get(i).copied().unwrap_or(0.0)];
            for (k, &x) in sample[1..].iter().enumerate() {
                if !x.is_finite() {
                    self.dropouts[k].add(index, t[i], x);
                }
            }
            if self.comparators.is_none() {
                let finite = a[i].is_finite() && b[i].is_finite();
                // A dropout's run is held as one mark: what is held grows with the finite
                // samples only.
                let marked = self
                    .start
                    .last()
                    .is_some_and(|(_, s)| !(s[1].is_finite() && s[2].is_finite()));
                if finite || !marked {
                    self.start.push((index, sample));
                }
                self.start_finite += usize::from(finite);
                if self.start_finite == START_SAMPLES {
                    self.begin();
                }
                continue;
            }
            self.step(sample, index);
        }
    }

    /// The comparators from the first samples, then those samples through them.
    fn begin(&mut self) {
        let start = std::mem::take(&mut self.start);
        if self.start_finite == 0 {
            self.error = Some(WheelError::Invalid(format!(
                "'{}', '{}': none of their {} samples is finite in both (NaN or ±inf): no transition",
                self.names[0], self.names[1], self.seen
            )));
            return;
        }
        // The channel `k` (A, B, Z) of the samples held: after the time.
        let column = |k: usize| start.iter().map(|s| s.1[k + 1]).collect::<Vec<f64>>();
        let names = &self.names;
        let comparator = |k: usize, range| {
            Comparator::start(&column(k), range)
                .map_err(|e| WheelError::Invalid(format!("'{}': {e}", names[k])))
        };
        let started = comparator(0, None).and_then(|a| Ok([a, comparator(1, None)?]));
        let z = match self.z_range {
            Some(r) => comparator(2, Some(r)).map(Some),
            None => Ok(None),
        };
        match (started, z) {
            (Ok(c), Ok(z)) => {
                self.comparators = Some(c);
                self.cz = z;
            }
            (Err(e), _) | (_, Err(e)) => {
                self.error = Some(e);
                return;
            }
        }
        for (i, s) in start {
            self.step(s, i);
        }
    }

    fn step(&mut self, [t, a, b, z]: [f64; 4], i: usize) {
        let Some([ca, cb]) = self.comparators.as_mut() else {
            return;
        };
        if !(a.is_finite() && b.is_finite()) {
            // A dropout of A or B: the whole sample skipped.
            ca.forget();
            cb.forget();
            if let Some(c) = self.cz.as_mut() {
                c.forget();
            }
            self.gap.get_or_insert((i, self.prev_t));
            return;
        }
        let ea = ca.step(t, a);
        let eb = cb.step(t, b);
        let high = (ca.high, cb.high);
        if let Some((from, before)) = self.gap.take() {
            self.across(from, before, high, t, i);
        }
        self.step_ab(ea, eb, high, t, i);
        if let Some(c) = self.cz.as_mut() {
            if !z.is_finite() {
                c.forget();
            } else if let Some((te, true)) = c.step(t, z) {
                if self.last_dir > 0 {
                    self.pulses.push_back(IndexPulse { t: te, index: i });
                }
            }
        }
        self.prev_t = Some(t);
    }

    /// The transitions of A and B at sample `i` at `t` (`ea`, `eb`: their comparators'
    /// crossings; `high`: their states now).
    fn step_ab(
        &mut self,
        ea: Option<(f64, bool)>,
        eb: Option<(f64, bool)>,
        (high_a, high_b): (Option<bool>, Option<bool>),
        t: f64,
        i: usize,
    ) {
        if self.sa.is_none() {
            self.sa = high_a;
        }
        if self.sb.is_none() {
            self.sb = high_b;
        }
        match (ea, eb) {
            (Some(_), Some(_)) => {
                self.findings.push(Finding {
                    kind: FindingKind::PulseLoss,
                    index: i,
                    detail: format!(
                        "'{}' and '{}' both changed at sample {i}: a transition the samples cannot resolve, taken as two steps the way the shaft last turned (sample faster)",
                        self.names[0], self.names[1]
                    ),
                });
                // Taken as two steps on in the direction of the last one.
                self.count += 2 * self.last_dir;
                if let (Some((ta, _)), Some((tb, _))) = (ea, eb) {
                    let edge = if self.last_dir > 0 {
                        self.count
                    } else {
                        self.count + 1
                    };
                    self.transition(0.5 * (ta + tb), edge);
                }
                self.sa = high_a;
                self.sb = high_b;
            }
            (Some((te, s)), None) | (None, Some((te, s))) => {
                // Strictly after the transition before (a level hit exactly by two samples).
                let te = match self.last_t {
                    Some(last) if te <= last => last + 1e-6 * (t - self.prev_t.unwrap_or(t)),
                    _ => te,
                };
                let (Some(pa), Some(pb)) = (self.sa, self.sb) else {
                    self.sa = high_a;
                    self.sb = high_b;
                    return;
                };
                // Forward (A leads): A rises when B is low, falls when B is high; B rises when
                // A is high, falls when A is low.
                let forward = if ea.is_some() { s != pb } else { s == pa };
                let dir = if forward { 1 } else { -1 };
                self.count += dir;
                if dir < 0 {
                    self.backward += 1;
                }
                self.last_dir = dir;
                let edge = if forward { self.count } else { self.count + 1 };
                self.transition(te, edge);
                if ea.is_some() {
                    self.sa = Some(s);
                } else {
                    self.sb = Some(s);
                }
            }
            (None, None) => {}
        }
    }

    /// The first sample `i` at `t` after a dropout of A/B from sample `from` (the finite sample
    /// before it at `before`; `high`: the states of A and B now): the count it hid, from the
    /// states either side (modulo 4) and the speed before (see the module docs); a
    /// `pulse_loss` finding where it may have hidden a transition.
    fn across(
        &mut self,
        from: usize,
        before: Option<f64>,
        high: (Option<bool>, Option<bool>),
        t: f64,
        i: usize,
    ) {
        let (Some(pa), Some(pb), (Some(na), Some(nb)), Some(before)) =
            (self.sa, self.sb, high, before)
        else {
            return;
        };
        // The Gray sequence forward: 00 → 10 → 11 → 01.
        let place = |a: bool, b: bool| match (a, b) {
            (false, false) => 0_i64,
            (true, false) => 1,
            (true, true) => 2,
            (false, true) => 3,
        };
        let moved = (place(na, nb) - place(pa, pb)).rem_euclid(4);
        let rate = self.rate(before);
        let expected = rate.map_or(0.0, |r| r * (t - before));
        let target = self.last_dir as f64 * expected;
        // The count ≡ `moved` (mod 4) nearest the expected one, ties the way it last turned.
        let low = moved + 4 * ((target - moved as f64) / 4.0).floor() as i64;
        let (dl, dh) = (target - low as f64, (low + 4) as f64 - target);
        let count = if dl < dh || (dl == dh && self.last_dir < 0) {
            low
        } else {
            low + 4
        };
        self.count += count;
        if count != 0 {
            self.last_dir = count.signum();
        }
        if count < 0 {
            self.backward += count.unsigned_abs() as usize;
        }
        self.sa = Some(na);
        self.sb = Some(nb);
        if count == 0 && expected < 0.5 {
            return;
        }
        let rest = match rate {
            Some(_) if expected > 0.0 => {
                // Right while the count the speed gives is within 2 of the one taken.
                let m = count.abs() as f64;
                let (lo, hi) = (((m - 2.0) / expected).max(0.0), (m + 2.0) / expected);
                let digits = usize::from(hi - lo < 0.1);
                format!(
                    "the speed before{} {expected:.1}; exact while the mean speed across it stays within {:.digits$}–{:.digits$} % of the speed before",
                    if self.last_dir < 0 { " (turning back)" } else { "" },
                    100.0 * lo,
                    100.0 * hi,
                )
            }
            _ => "no speed known before it: the least turn that gives them".to_string(),
        };
        self.findings.push(Finding {
            kind: FindingKind::PulseLoss,
            index: i,
            detail: format!(
                "'{}', '{}': the dropout from sample {from} to {} hides its transitions: taken as {count} count(s) — the states either side give the count modulo 4, {rest}",
                self.names[0],
                self.names[1],
                i - 1
            ),
        });
    }

    /// The speed before a dropout whose finite sample before is at `before` [s], in
    /// transitions a second: over the last (up to) four transitions, no faster than one since
    /// the last (a shaft at rest); `None` before two transitions.
    fn rate(&self, before: f64) -> Option<f64> {
        let n = self.transitions.min(self.recent.len());
        if n < 2 {
            return None;
        }
        let at = |k: usize| self.recent[(self.transitions - k) % self.recent.len()];
        let (newest, oldest) = (at(1), at(n));
        let period = (newest - oldest) / (n - 1) as f64;
        Some(1.0 / period.max(before - newest))
    }

    fn transition(&mut self, t: f64, edge: i64) {
        self.recent[self.transitions % self.recent.len()] = t;
        self.transitions += 1;
        self.last_t = Some(t);
        self.out.push_back(Transition { t, edge });
    }

    /// The next transition found.
    pub fn pop(&mut self) -> Option<Transition> {
        self.out.pop_front()
    }

    /// The next index pulse found (turning forward).
    pub fn pop_pulse(&mut self) -> Option<IndexPulse> {
        self.pulses.pop_front()
    }

    /// No more samples: the comparators started if fewer than [`START_SAMPLES`] came, the
    /// error that stopped the decoding, or fewer than two transitions.
    pub fn finish(&mut self) -> Result<(), WheelError> {
        if self.comparators.is_none() && self.error.is_none() {
            if self.start.is_empty() {
                let e = format!("'{}': no samples", self.names[0]);
                self.error = Some(WheelError::Invalid(e));
            } else {
                self.begin();
            }
        }
        if let Some(e) = self.error.clone() {
            return Err(e);
        }
        for (k, d) in self.dropouts.iter().enumerate() {
            let skipped = match k {
                2 => "skipped: an index pulse they hide is not seen".to_string(),
                _ => format!(
                    "skipped with '{}' at the same samples: no transition is found across them",
                    self.names[1 - k]
                ),
            };
            let found = d.findings(&self.names[k], &skipped);
            self.findings.extend(found);
        }
        self.dropouts = Default::default();
        if self.transitions < 2 {
            return Err(WheelError::Invalid(format!(
                "'{}', '{}': {} transitions — the shaft does not turn, or the channels do not cross their levels",
                self.names[0], self.names[1], self.transitions
            )));
        }
        Ok(())
    }

    /// Steps back (the shaft turning back), and the findings so far (unresolved transitions).
    pub fn backward(&self) -> usize {
        self.backward
    }

    /// The unresolved transitions found, at their samples.
    pub fn take_findings(&mut self) -> Vec<Finding> {
        std::mem::take(&mut self.findings)
    }
}

/// The angle 0 of a decoded encoder and the index pulses out of place, as transitions and
/// pulses come: the angle at the first index pulse turning forward (by the monotone cubic
/// through the transitions, [`Pchip`]), or without one the first transition's; every later
/// pulse a whole revolution on within 1.5 counts, else a finding. Holds the pulses not yet
/// placed.
#[derive(Debug, Clone)]
pub struct IndexZero {
    q: f64,
    lines: u32,
    name: String,
    pchip: Pchip,
    pending: std::collections::VecDeque<IndexPulse>,
    first_angle: Option<f64>,
    zero: Option<f64>,
    pulses: usize,
    findings: Vec<Finding>,
}

impl IndexZero {
    /// For an encoder of `lines` lines whose index channel is `name`.
    pub fn new(lines: u32, name: &str) -> Self {
        Self {
            q: TAU / (4.0 * lines as f64),
            lines,
            name: name.to_string(),
            pchip: Pchip::default(),
            pending: std::collections::VecDeque::new(),
            first_angle: None,
            zero: None,
            pulses: 0,
            findings: Vec::new(),
        }
    }

    /// The next transition.
    pub fn transition(&mut self, tr: Transition) {
        let angle = tr.edge as f64 * self.q;
        self.first_angle.get_or_insert(angle);
        self.pchip.push(tr.t, angle);
        self.place();
    }

    /// The next index pulse.
    pub fn pulse(&mut self, p: IndexPulse) {
        self.pulses += 1;
        self.pending.push_back(p);
        self.place();
    }

    /// The pulses whose angle is known.
    fn place(&mut self) {
        while let Some(p) = self.pending.front().copied() {
            let Some(at) = self.pchip.at(p.t) else {
                return;
            };
            self.pending.pop_front();
            match self.zero {
                None => {
                    self.zero = Some(if at.is_finite() {
                        at
                    } else {
                        self.first_angle.unwrap_or(0.0)
                    });
                }
                Some(zero) => {
                    let revs = (at - zero) / TAU;
                    let off = (revs - revs.round()) * 4.0 * self.lines as f64;
                    if off.abs() > 1.5 {
                        self.findings.push(Finding {
                            kind: FindingKind::OutOfSync,
                            index: p.index,
                            detail: format!(
                                "'{}': index pulse at sample {} {:.1} counts after the first, not a whole number of revolutions of {}",
                                self.name,
                                p.index,
                                revs * 4.0 * self.lines as f64,
                                4 * self.lines
                            ),
                        });
                    }
                }
            }
        }
    }

    /// No more transitions or pulses: the angle 0 [rad on the counts' scale], the pulses turning
    /// forward, and the pulses out of place.
    pub fn finish(mut self) -> (f64, usize, Vec<Finding>) {
        self.pchip.end();
        self.place();
        let zero = self.zero.or(self.first_angle).unwrap_or(0.0);
        (zero, self.pulses, self.findings)
    }
}

/// Decode A/B (and Z) sampled at the times `t` [s]; `lines` per revolution; `names` the
/// channels (for the findings and errors): [`QuadratureDecoder`] and [`IndexZero`] over the
/// whole signal.
pub fn decode(
    t: &[f64],
    a: &[f64],
    b: &[f64],
    z: Option<&[f64]>,
    lines: u32,
    names: [&str; 3],
) -> Result<QuadratureAngles, WheelError> {
    if lines == 0 {
        return Err(WheelError::Invalid(
            "an encoder needs 1 line or more".into(),
        ));
    }
    for (name, x) in [(names[0], a), (names[1], b)]
        .into_iter()
        .chain(z.map(|z| (names[2], z)))
    {
        if x.len() != t.len() {
            return Err(WheelError::Invalid(format!(
                "'{name}' has {} samples, the time {}",
                x.len(),
                t.len()
            )));
        }
    }
    let z_range = z.map(|z| {
        let mut r = IndexRange::default();
        r.push(z);
        r.range
    });
    let mut d = QuadratureDecoder::new(names, z_range);
    d.push(t, a, b, z.unwrap_or(&[]));
    d.finish()?;
    let mut zero = IndexZero::new(lines, names[2]);
    let (mut tt, mut edges, mut index_t) = (Vec::new(), Vec::new(), Vec::new());
    // Transitions and pulses in time order (a pulse placed once the transitions after it came).
    while let Some(tr) = d.pop() {
        tt.push(tr.t);
        edges.push(tr.edge);
        zero.transition(tr);
    }
    while let Some(p) = d.pop_pulse() {
        index_t.push(p.t);
        zero.pulse(p);
    }
    let (zero, _, mut out_of_place) = zero.finish();
    let q = TAU / (4.0 * lines as f64);
    let angle: Vec<f64> = edges.iter().map(|&c| c as f64 * q - zero).collect();
    let mut findings = d.take_findings();
    findings.append(&mut out_of_place);
    findings.sort_by_key(|f| f.index);
    Ok(QuadratureAngles {
        lines,
        angle,
        t: tt,
        index_t,
        backward: d.backward(),
        findings,
    })
}
