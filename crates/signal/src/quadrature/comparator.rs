//! A comparator with hysteresis on one channel of a quadrature encoder (see the module
//! above): its level from the first samples, a dropout forgotten.

use crate::wheel::{HYSTERESIS, START_SAMPLES};

/// A comparator with hysteresis on one channel, started from its first samples.
#[derive(Debug, Clone)]
pub(super) struct Comparator {
    level: f64,
    band: f64,
    /// The state: high, low, or not known yet.
    pub(super) high: Option<bool>,
    prev: Option<(f64, f64)>,
    /// After a dropout: the next sample outside the band gives the state, no transition.
    resume: bool,
}

impl Comparator {
    /// From the 2nd and 98th percentiles of the first samples `v` (`range`: the smallest and
    /// largest of all the samples instead — an index is high a few samples a revolution).
    pub(super) fn start(v: &[f64], range: Option<(f64, f64)>) -> Result<Self, String> {
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
    pub(super) fn forget(&mut self) {
        self.prev = None;
        self.resume = true;
    }

    /// The sample `(t, v)`: `Some((time, new state))` at a transition.
    pub(super) fn step(&mut self, t: f64, v: f64) -> Option<(f64, bool)> {
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
