//! Incremental encoders (thesis Eq. 4.2–4.4, SPEC §2.7): angle, speed and acceleration from
//! cumulative pulse counts sampled on a time basis, with a TDC marker.
//!
//! Two estimators of speed and acceleration:
//!
//! * the thesis's pulse-count differences, `ω_k = 2π·(c_k − c_{k−1})/(ppr·dt)` (Eq. 4.3) and
//!   `α_k = 2π·(c_k − 2c_{k−1} + c_{k−2})/(ppr·dt²)` (Eq. 4.4). Counting quantises the angle to
//!   `q = 2π/ppr`; with the quantisation errors of successive samples independent and uniform,
//!   the speed noise is `q/(dt·√6)` rms — at 1 kHz and 360 pulses/rev, 7.1 rad/s;
//! * a local least-squares polynomial fit of the angle over `2h + 1` samples (Savitzky–Golay):
//!   the slope of the fitted line gives ω, the curvature of the fitted parabola α. The speed
//!   noise falls to about `q/(dt·√(12·Σk²))`, `Σk² = h(h+1)(2h+1)/3` — at h = 10 and 360
//!   pulses/rev, 0.18 rad/s predicted, 0.22 rad/s measured on a simulated encoder (neighbouring
//!   quantisation errors are not quite independent), 31× lower than Eq. 4.3 — at the price of
//!   smoothing over `(2h+1)·dt`. Both are checked on a simulated encoder (`tests/encoder.rs`).

use std::f64::consts::TAU;

/// An incremental encoder with `ppr` pulses per revolution.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Encoder {
    /// Pulses per revolution (360 on the thesis's engine, 1024 on its dynamometer).
    pub ppr: u32,
}

impl Encoder {
    /// Angle per pulse `q = 2π/ppr` [rad].
    pub fn quantum(&self) -> f64 {
        TAU / self.ppr as f64
    }

    /// Continuous angle `θ_con = q·(c − c_0)` [rad] from cumulative counts, zero at `counts[zero]`
    /// (e.g. the first TDC marker).
    pub fn angle(&self, counts: &[f64], zero: usize) -> Vec<f64> {
        let q = self.quantum();
        let c0 = counts.get(zero).copied().unwrap_or(0.0);
        counts.iter().map(|c| q * (c - c0)).collect()
    }

    /// Speed from count differences (Eq. 4.3) [rad/s]; the first sample repeats the second.
    pub fn speed_counts(&self, counts: &[f64], dt: f64) -> Vec<f64> {
        let k = self.quantum() / dt;
        let mut w: Vec<f64> = std::iter::once(0.0)
            .chain(counts.windows(2).map(|c| k * (c[1] - c[0])))
            .collect();
        if w.len() > 1 {
            w[0] = w[1];
        }
        w.truncate(counts.len());
        w
    }

    /// Acceleration from second differences of counts (Eq. 4.4) [rad/s²]; the first two
    /// samples repeat the third.
    pub fn accel_counts(&self, counts: &[f64], dt: f64) -> Vec<f64> {
        let k = self.quantum() / (dt * dt);
        let mut a = vec![0.0; counts.len()];
        for i in 2..counts.len() {
            a[i] = k * (counts[i] - 2.0 * counts[i - 1] + counts[i - 2]);
        }
        if counts.len() > 2 {
            a[0] = a[2];
            a[1] = a[2];
        }
        a
    }

    /// Speed from a local straight-line fit of the angle over `2h + 1` samples (shrunk
    /// symmetrically at the ends) [rad/s].
    pub fn speed_fit(&self, counts: &[f64], dt: f64, h: usize) -> Vec<f64> {
        let q = self.quantum();
        let n = counts.len();
        (0..n)
            .map(|i| {
                let hi = h.min(i).min(n - 1 - i);
                if hi == 0 {
                    // An end sample: one-sided difference.
                    return match (i, n) {
                        (_, 0 | 1) => 0.0,
                        (0, _) => q * (counts[1] - counts[0]) / dt,
                        _ => q * (counts[i] - counts[i - 1]) / dt,
                    };
                }
                let hf = hi as f64;
                let s2 = hf * (hf + 1.0) * (2.0 * hf + 1.0) / 3.0;
                let mut s = 0.0;
                for k in 1..=hi {
                    s += k as f64 * (counts[i + k] - counts[i - k]);
                }
                q * s / (s2 * dt)
            })
            .collect()
    }

    /// Acceleration from a local parabola fitted to the angle over `2h + 1` samples (h ≥ 1;
    /// shrunk symmetrically at the ends, the first and last sample repeat their neighbour)
    /// [rad/s²].
    pub fn accel_fit(&self, counts: &[f64], dt: f64, h: usize) -> Vec<f64> {
        let q = self.quantum();
        let n = counts.len();
        let h = h.max(1);
        let mut a: Vec<f64> = (0..n)
            .map(|i| {
                let hi = h.min(i).min(n.saturating_sub(1 + i));
                if hi == 0 {
                    return f64::NAN;
                }
                let hf = hi as f64;
                let m = hf * (hf + 1.0) / 3.0; // mean of k²
                let n_pts = 2.0 * hf + 1.0;
                let s4 =
                    hf * (hf + 1.0) * (2.0 * hf + 1.0) * (3.0 * hf * hf + 3.0 * hf - 1.0) / 15.0;
                let norm = s4 - n_pts * m * m; // Σ (k² − m)²
                let mut s = (0.0 - m) * counts[i];
                for k in 1..=hi {
                    let w = (k * k) as f64 - m;
                    s += w * (counts[i + k] + counts[i - k]);
                }
                2.0 * q * s / (norm * dt * dt)
            })
            .collect();
        if n > 2 {
            a[0] = a[1];
            a[n - 1] = a[n - 2];
        }
        a
    }
}

/// Cumulative counts of an ideal encoder following the angle trace `theta` [rad]:
/// `floor(θ/q)` — for simulating encoders and testing the decoders.
pub fn counts_from_angle(theta: &[f64], ppr: u32) -> Vec<f64> {
    let q = TAU / ppr as f64;
    theta.iter().map(|t| (t / q).floor()).collect()
}

/// Index of the first rising edge of a marker channel (0 → non-zero), or of its first
/// sample if that is already high.
pub fn first_marker(marker: &[f64]) -> Option<usize> {
    if marker.first().is_some_and(|&m| m != 0.0) {
        return Some(0);
    }
    marker
        .windows(2)
        .position(|w| w[0] == 0.0 && w[1] != 0.0)
        .map(|i| i + 1)
}

/// Indices of every rising edge of a marker channel.
pub fn marker_edges(marker: &[f64]) -> Vec<usize> {
    let mut v: Vec<usize> = marker
        .windows(2)
        .enumerate()
        .filter(|(_, w)| w[0] == 0.0 && w[1] != 0.0)
        .map(|(i, _)| i + 1)
        .collect();
    if marker.first().is_some_and(|&m| m != 0.0) {
        v.insert(0, 0);
    }
    v
}

/// A revolution's longest time per pulse against its median beyond which pulses are not
/// equally spaced in angle: a toothed wheel's gap of M missing teeth lasts M + 1 pulse
/// periods (4× for a 60−3 wheel), while an engine's speed changes within a revolution by a few
/// per cent.
pub const GAP_RATIO: f64 = 1.8;

/// Whether an encoder's count steps are equally spaced in angle, as `Encoder::angle` takes
/// them: over each full revolution (`ppr` pulses) of the count `counts` against the time `t`,
/// the longest time per pulse against the median. The counts of a trigger wheel with missing
/// teeth (a 60−3 wheel's 57 real teeth) have one step per revolution [`GAP_RATIO`] times
/// longer or more — a crank angle taken from them is wrong by up to the gap (12.6° for
/// 60−3). `Some(description)` when most revolutions (at least 3) show such a gap, beyond the
/// sample period's uncertainty on either; `None` too when the pulses are not resolved in time
/// (less than 4 samples per pulse: the steps' timing cannot tell).
pub fn uneven_spacing(t: &[f64], counts: &[f64], ppr: u32) -> Option<String> {
    let ppr = ppr as usize;
    if ppr < 4 || t.len() != counts.len() || t.len() < 3 {
        return None;
    }
    let ts = crate::integrity::median_step(t)?;
    // Time per pulse of each count step.
    let mut per_pulse: Vec<f64> = Vec::new();
    let mut last: Option<(f64, f64)> = None;
    for (&ti, &c) in t.iter().zip(counts) {
        if !(ti.is_finite() && c.is_finite()) {
            continue;
        }
        match last {
            Some((t0, c0)) if c > c0 => {
                let pulses = (c - c0).round().max(1.0) as usize;
                for _ in 0..pulses.min(ppr) {
                    per_pulse.push((ti - t0) / pulses as f64);
                }
                last = Some((ti, c));
            }
            None => last = Some((ti, c)),
            _ => {}
        }
    }
    let (mut revolutions, mut gapped, mut worst) = (0usize, 0usize, 0.0f64);
    let mut window = Vec::with_capacity(ppr);
    for rev in per_pulse.chunks_exact(ppr) {
        window.clear();
        window.extend_from_slice(rev);
        window.sort_unstable_by(f64::total_cmp);
        let median = window[ppr / 2];
        if median < 4.0 * ts {
            return None;
        }
        // The longest against the median, each given the benefit of one sample period.
        let ratio = (window[ppr - 1] - ts) / (median + ts);
        revolutions += 1;
        if ratio >= GAP_RATIO {
            gapped += 1;
            worst = worst.max(ratio);
        }
    }
    (revolutions >= 3 && 2 * gapped > revolutions).then(|| {
        format!(
            "in {gapped} of {revolutions} revolutions one count step lasts {worst:.1}× the others or more: the counts are not equally spaced in angle (a trigger wheel with missing teeth?), so no crank angle can be taken from them"
        )
    })
}
