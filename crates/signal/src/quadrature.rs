//! Quadrature encoders: the shaft's angle, both ways, from the two channels A and B of an
//! incremental encoder (a quarter of a line apart) and its optional index Z (one pulse per
//! revolution) — digital or analog signals.
//!
//! * Each channel through a comparator with hysteresis: the level midway between the 2nd and
//!   98th percentiles of its first [`START_SAMPLES`](crate::wheel::START_SAMPLES) samples (Z:
//!   its smallest and largest sample), ±20 % of their distance; each transition's time
//!   interpolated between the samples either side.
//! * ×4 decoding: every transition of A or B moves the count by one quarter line, forward when
//!   the Gray sequence (A, B) = 00 → 10 → 11 → 01 runs that way (A leads), back otherwise. Both
//!   channels changing between two samples is a transition the samples could not resolve: an
//!   integrity finding at its sample (the count may be off by two there).
//! * Z: the count at each rising edge of the index while turning forward; the angle is 0 at the
//!   first, and every later one must come a whole revolution (4·lines counts) from it — else a
//!   finding at its sample with the counts found.
//! * The angle at any time by the same monotone cubic as [`crate::wheel`] (its extrema, where
//!   the shaft turns back, stay flat).

use crate::integrity::{Finding, FindingKind};
use crate::wheel::{pchip_at, WheelError, HYSTERESIS, START_SAMPLES};
use std::f64::consts::TAU;

/// A comparator with hysteresis on one channel, started from its first samples.
#[derive(Debug, Clone)]
struct Comparator {
    level: f64,
    band: f64,
    high: Option<bool>,
    prev: Option<(f64, f64)>,
}

impl Comparator {
    /// From the 2nd and 98th percentiles of the first samples (`pulse`: the smallest and
    /// largest of all — an index is high a few samples a revolution).
    fn start(v: &[f64], pulse: bool) -> Result<Self, String> {
        let mut u: Vec<f64> = v.iter().take(START_SAMPLES).copied().collect();
        if u.is_empty() {
            return Err("no samples".into());
        }
        let q = |u: &mut Vec<f64>, p: f64| {
            let k = ((u.len() - 1) as f64 * p).round() as usize;
            *u.select_nth_unstable_by(k, f64::total_cmp).1
        };
        let (lo, hi) = if pulse {
            v.iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                    (a.min(x), b.max(x))
                })
        } else {
            (q(&mut u, 0.02), q(&mut u, 0.98))
        };
        if hi <= lo {
            return Err(format!("flat over its first {} samples (at {lo})", u.len()));
        }
        Ok(Self {
            level: 0.5 * (lo + hi),
            band: HYSTERESIS * (hi - lo),
            high: None,
            prev: None,
        })
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

/// Decode A/B (and Z) sampled at the times `t` [s]; `lines` per revolution; `names` the
/// channels (for the findings and errors).
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
        if let Some(i) = x.iter().position(|v| !v.is_finite()) {
            return Err(WheelError::Invalid(format!(
                "'{name}': sample {i} is {}: the encoder's signal must be finite",
                x[i]
            )));
        }
    }
    if let Some(i) = t
        .windows(2)
        .position(|w| w[1].partial_cmp(&w[0]) != Some(std::cmp::Ordering::Greater))
    {
        return Err(WheelError::Time {
            index: i + 1,
            prev: t[i],
            next: t[i + 1],
        });
    }
    let comparator = |x: &[f64], name: &str, pulse: bool| {
        Comparator::start(x, pulse).map_err(|e| WheelError::Invalid(format!("'{name}': {e}")))
    };
    let (mut ca, mut cb) = (
        comparator(a, names[0], false)?,
        comparator(b, names[1], false)?,
    );
    let mut cz = match z {
        Some(z) => Some(comparator(z, names[2], true)?),
        None => None,
    };
    let q = TAU / (4.0 * lines as f64);
    let (mut sa, mut sb) = (None::<bool>, None::<bool>);
    let mut count: i64 = 0;
    let (mut tt, mut edges) = (Vec::new(), Vec::new());
    let mut index: Vec<(f64, i64, usize)> = Vec::new();
    let mut findings = Vec::new();
    let mut backward = 0;
    let mut last_dir = 1i64;
    for i in 0..t.len() {
        let ea = ca.step(t[i], a[i]);
        let eb = cb.step(t[i], b[i]);
        if sa.is_none() {
            sa = ca.high;
        }
        if sb.is_none() {
            sb = cb.high;
        }
        match (ea, eb) {
            (Some(_), Some(_)) => {
                findings.push(Finding {
                    kind: FindingKind::PulseLoss,
                    index: i,
                    detail: format!(
                                        "'{}' and '{}' both changed at sample {i}: a transition the samples cannot resolve, taken as two steps the way the shaft last turned (sample faster)",
                        names[0], names[1]
                    ),
                });
                // Taken as two steps on in the direction of the last one.
                count += 2 * last_dir;
                if let (Some((ta, _)), Some((tb, _))) = (ea, eb) {
                    tt.push(0.5 * (ta + tb));
                    edges.push(if last_dir > 0 { count } else { count + 1 });
                }
                sa = ca.high;
                sb = cb.high;
            }
            (Some((te, s)), None) | (None, Some((te, s))) => {
                // Strictly after the transition before (a level hit exactly by two samples).
                let te = match tt.last() {
                    Some(&last) if te <= last => last + 1e-6 * (t[i] - t[i.saturating_sub(1)]),
                    _ => te,
                };
                let (Some(pa), Some(pb)) = (sa, sb) else {
                    sa = ca.high;
                    sb = cb.high;
                    continue;
                };
                // Forward (A leads): A rises when B is low, falls when B is high; B rises when
                // A is high, falls when A is low.
                let forward = if ea.is_some() { s != pb } else { s == pa };
                let dir = if forward { 1 } else { -1 };
                count += dir;
                if dir < 0 {
                    backward += 1;
                }
                last_dir = dir;
                tt.push(te);
                // The edge crossed: between counts c − 1 and c, called c, whichever the way.
                edges.push(if forward { count } else { count + 1 });
                if ea.is_some() {
                    sa = Some(s);
                } else {
                    sb = Some(s);
                }
            }
            (None, None) => {}
        }
        if let (Some(c), Some(z)) = (cz.as_mut(), z) {
            if let Some((te, true)) = c.step(t[i], z[i]) {
                if last_dir > 0 {
                    index.push((te, count, i));
                }
            }
        }
    }
    if tt.len() < 2 {
        return Err(WheelError::Invalid(format!(
            "'{}', '{}': {} transitions — the shaft does not turn, or the channels do not cross their levels",
            names[0],
            names[1],
            tt.len()
        )));
    }
    // The angle at the transitions, then 0 at the first index pulse's time.
    let mut angle: Vec<f64> = edges.iter().map(|&c| c as f64 * q).collect();
    let index_t: Vec<f64> = index.iter().map(|x| x.0).collect();
    let at_index = pchip_at(&tt, &angle, &index_t);
    let zero = at_index
        .first()
        .copied()
        .filter(|z| z.is_finite())
        .unwrap_or(angle[0]);
    for x in angle.iter_mut() {
        *x -= zero;
    }
    // Every later index a whole revolution on (within 1.5 counts: the index edge may fall on
    // either side of an A/B transition).
    for (k, &(_, _, i)) in index.iter().enumerate().skip(1) {
        let revs = (at_index[k] - zero) / TAU;
        let off = (revs - revs.round()) * 4.0 * lines as f64;
        if off.abs() > 1.5 {
            findings.push(Finding {
                kind: FindingKind::OutOfSync,
                index: i,
                detail: format!(
                    "'{}': index pulse at sample {i} {:.1} counts after the first, not a whole number of revolutions of {}",
                    names[2],
                    revs * 4.0 * lines as f64,
                    4 * lines
                ),
            });
        }
    }
    findings.sort_by_key(|f| f.index);
    Ok(QuadratureAngles {
        lines,
        angle,
        t: tt,
        index_t,
        backward,
        findings,
    })
}
