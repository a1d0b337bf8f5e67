//! The ×4 decoding of a quadrature encoder's A/B (and Z) as samples come, dropouts included
//! (see the module above).

use super::comparator::Comparator;
use crate::integrity::{Finding, FindingKind};
use crate::wheel::{Dropouts, WheelError, START_SAMPLES};

/// The most counts a dropout is taken to hide, whatever the speed before expects.
const MOST_HIDDEN: f64 = 1e12;

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
/// and largest sample over the whole signal, found by a first pass ([`IndexRange`](super::IndexRange)) — then the
/// transitions and index pulses in order ([`pop`](Self::pop)). Holds the first samples, the
/// transitions and pulses not yet taken, and the findings.
#[derive(Debug, Clone)]
pub struct QuadratureDecoder {
    names: [String; 3],
    z_range: Option<(f64, f64)>,
    /// Counts a revolution (4 × lines).
    revolution: i64,
    /// The count at the first index pulse turning forward; the transitions after a dropout
    /// whose count the speed gave, held until the next index pulse checks it ([`Held`]).
    z_count: Option<i64>,
    held: Option<Held>,
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

/// The transitions held after a dropout whose count the speed before gave, until the next
/// index pulse turning forward checks it: the dropout's first sample, and where in the
/// transitions not yet taken the held ones start.
#[derive(Debug, Clone, Copy)]
struct Held {
    from: usize,
    at: usize,
}

impl QuadratureDecoder {
    /// A decoder for channels `names` (A, B, Z; Z's `z_range` from a first pass, `None`
    /// without Z) of an encoder of `lines` lines.
    pub fn new(names: [&str; 3], z_range: Option<(f64, f64)>, lines: u32) -> Self {
        Self {
            names: names.map(str::to_string),
            z_range,
            revolution: 4 * i64::from(lines.max(1)),
            z_count: None,
            held: None,
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
                    self.index_pulse(i);
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
                self.count = self.count.saturating_add(2 * self.last_dir);
                if let (Some((ta, _)), Some((tb, _))) = (ea, eb) {
                    let edge = if self.last_dir > 0 {
                        self.count
                    } else {
                        self.count.saturating_add(1)
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
                self.count = self.count.saturating_add(dir);
                if dir < 0 {
                    self.backward += 1;
                }
                self.last_dir = dir;
                let edge = if forward {
                    self.count
                } else {
                    self.count.saturating_add(1)
                };
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
        // Within what a count holds (a dropout of 1e12 counts is days at any speed).
        let expected = rate.map_or(0.0, |r| (r * (t - before)).min(MOST_HIDDEN));
        let target = self.last_dir as f64 * expected;
        // The count ≡ `moved` (mod 4) nearest the expected one, ties the way it last turned.
        let low = moved + 4 * ((target - moved as f64) / 4.0).floor() as i64;
        let (dl, dh) = (target - low as f64, (low + 4) as f64 - target);
        let count = if dl < dh || (dl == dh && self.last_dir < 0) {
            low
        } else {
            low + 4
        };
        self.count = self.count.saturating_add(count);
        if count != 0 {
            self.last_dir = count.signum();
        }
        if count < 0 {
            self.backward = self.backward.saturating_add(count.unsigned_abs() as usize);
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
                "'{}', '{}': the dropout from sample {from} to {} hides its transitions: taken as {count} count(s) — the states either side give the count modulo 4, {rest}{}",
                self.names[0],
                self.names[1],
                i - 1,
                if self.z_count.is_some() { "; the next index pulse checks it" } else { "" }
            ),
        });
        if self.z_count.is_some() && self.held.is_none() {
            self.held = Some(Held {
                from,
                at: self.out.len(),
            });
        }
    }

    /// An index pulse turning forward at sample `i`: the first is the count's reference; a
    /// later one checks the count a dropout's transitions were taken at ([`Held`]) — a whole
    /// number of lines off a whole revolution (within a count), those lines were lost or
    /// gained across the dropout: the count corrected from there, the held transitions with
    /// it, and a finding. Anything else is left as it is (an index pulse out of place tells
    /// it, [`super::IndexZero`]).
    fn index_pulse(&mut self, i: usize) {
        let Some(reference) = self.z_count else {
            self.z_count = Some(self.count);
            return;
        };
        let Some(held) = self.held.take() else {
            return;
        };
        let rev = self.revolution;
        let d = self.count.saturating_sub(reference);
        let off = d - rev * (d as f64 / rev as f64).round() as i64;
        let lost = 4 * (off as f64 / 4.0).round() as i64;
        if lost == 0 || (off - lost).abs() > 1 {
            return;
        }
        let (n, way) = if lost > 0 {
            (lost, "many")
        } else {
            (-lost, "few")
        };
        for tr in self.out.iter_mut().skip(held.at) {
            tr.edge = tr.edge.saturating_sub(lost);
        }
        self.count = self.count.saturating_sub(lost);
        self.findings.push(Finding {
            kind: FindingKind::PulseLoss,
            index: i,
            detail: format!(
                "'{}', '{}': the index pulse at sample {i} comes {off} count(s) off a whole revolution: the count taken across the dropout from sample {} was {n} too {way} ({} line(s)), corrected from there",
                self.names[0],
                self.names[1],
                held.from,
                n / 4
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
        // Held no longer than two revolutions without an index pulse turning forward.
        if let Some(h) = self.held {
            if (self.out.len() - h.at) as i64 > 2 * self.revolution {
                self.unchecked("within two revolutions after it");
            }
        }
    }

    /// The transitions held after a dropout go on unchecked (no index pulse turning forward
    /// came `when`): a note.
    fn unchecked(&mut self, when: &str) {
        if let Some(h) = self.held.take() {
            self.findings.push(Finding {
                kind: FindingKind::Note,
                index: h.from,
                detail: format!(
                    "'{}', '{}': the count taken across the dropout from sample {} is not checked: no index pulse turning forward {when}",
                    self.names[0], self.names[1], h.from
                ),
            });
        }
    }

    /// The next transition found: none of those held after a dropout until the next index
    /// pulse has checked its count.
    pub fn pop(&mut self) -> Option<Transition> {
        if let Some(h) = self.held.as_mut() {
            if h.at == 0 {
                return None;
            }
            h.at -= 1;
        }
        self.out.pop_front()
    }

    /// The next index pulse found (turning forward).
    pub fn pop_pulse(&mut self) -> Option<IndexPulse> {
        self.pulses.pop_front()
    }

    /// No more samples: the comparators started if fewer than [`START_SAMPLES`] came, the
    /// error that stopped the decoding, or fewer than two transitions.
    pub fn finish(&mut self) -> Result<(), WheelError> {
        // No index pulse left to check a dropout's count: the transitions held go on.
        self.unchecked("before the signal ends");
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
