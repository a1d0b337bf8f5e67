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
/// (less than 4 samples per pulse: the steps' timing cannot tell). [`SpacingCheck`] on the
/// whole recording as one chunk.
pub fn uneven_spacing(t: &[f64], counts: &[f64], ppr: u32) -> Option<String> {
    if t.len() != counts.len() {
        return None;
    }
    let mut check = SpacingCheck::new(ppr);
    check.push(t, counts);
    check.finish()
}

/// [`uneven_spacing`] a chunk at a time. The sample period is the median time step of the
/// first [`NOMINAL_SAMPLES`](crate::integrity::NOMINAL_SAMPLES) samples (as `physid inspect`
/// takes it), so the answer is the same however the recording is cut. What it holds: those
/// steps, and the revolutions completed before they are all in (at most one a sample), until
/// then; one revolution's times per pulse after.
#[derive(Debug, Clone)]
pub struct SpacingCheck {
    ppr: usize,
    samples: usize,
    /// The last time seen, for the steps.
    t_prev: Option<f64>,
    /// The positive time steps of the first samples, until the sample period is taken.
    steps: Vec<f64>,
    /// The sample period: `None` until taken, `Some(None)` when there is none.
    ts: Option<Option<f64>>,
    /// The last count step's time and count.
    last: Option<(f64, f64)>,
    /// The revolution going: its times per pulse.
    window: Vec<f64>,
    /// Revolutions completed before the sample period was taken: (median, longest).
    early: Vec<(f64, f64)>,
    revolutions: usize,
    gapped: usize,
    worst: f64,
    /// A revolution's pulses are not resolved in time: no judgement.
    unresolved: bool,
}

impl SpacingCheck {
    /// The check of an encoder of `ppr` pulses per revolution.
    pub fn new(ppr: u32) -> Self {
        Self {
            ppr: ppr as usize,
            samples: 0,
            t_prev: None,
            steps: Vec::new(),
            ts: None,
            last: None,
            window: Vec::new(),
            early: Vec::new(),
            revolutions: 0,
            gapped: 0,
            worst: 0.0,
            unresolved: false,
        }
    }

    /// The next samples: times `t` [s] and counts (as long).
    pub fn push(&mut self, t: &[f64], counts: &[f64]) {
        let nominal = crate::integrity::NOMINAL_SAMPLES;
        for (&ti, &c) in t.iter().zip(counts) {
            if self.samples < nominal {
                if let Some(d) = self.t_prev.map(|p| ti - p).filter(|d| *d > 0.0) {
                    self.steps.push(d);
                }
                self.t_prev = Some(ti);
                if self.samples + 1 == nominal {
                    self.take_period();
                }
            }
            self.samples += 1;
            if !(ti.is_finite() && c.is_finite()) || self.ppr < 4 {
                continue;
            }
            match self.last {
                Some((t0, c0)) if c > c0 => {
                    let pulses = (c - c0).round().max(1.0) as usize;
                    for _ in 0..pulses.min(self.ppr) {
                        self.window.push((ti - t0) / pulses as f64);
                        if self.window.len() == self.ppr {
                            self.revolution();
                        }
                    }
                    self.last = Some((ti, c));
                }
                None => self.last = Some((ti, c)),
                _ => {}
            }
        }
    }

    /// The verdict at the end of the recording.
    pub fn finish(mut self) -> Option<String> {
        if self.ts.is_none() {
            self.take_period();
        }
        if self.ppr < 4 || self.samples < 3 || self.unresolved {
            return None;
        }
        let (gapped, revolutions, worst) = (self.gapped, self.revolutions, self.worst);
        (revolutions >= 3 && 2 * gapped > revolutions).then(|| {
            format!(
                "in {gapped} of {revolutions} revolutions one count step lasts {worst:.1}× the others or more: the counts are not equally spaced in angle (a trigger wheel with missing teeth?), so no crank angle can be taken from them"
            )
        })
    }

    /// The sample period from the steps so far; the revolutions waiting for it judged.
    fn take_period(&mut self) {
        let steps = std::mem::take(&mut self.steps);
        let ts = if steps.is_empty() {
            None
        } else {
            let mut d = steps;
            let mid = d.len() / 2;
            d.select_nth_unstable_by(mid, f64::total_cmp);
            Some(d[mid])
        };
        self.ts = Some(ts);
        for (median, longest) in std::mem::take(&mut self.early) {
            self.judge(median, longest);
        }
    }

    /// A revolution's `ppr` times per pulse are in: its median and longest.
    fn revolution(&mut self) {
        self.window.sort_unstable_by(f64::total_cmp);
        let (median, longest) = (self.window[self.ppr / 2], self.window[self.ppr - 1]);
        self.window.clear();
        match self.ts {
            Some(_) => self.judge(median, longest),
            None => self.early.push((median, longest)),
        }
    }

    /// One revolution, the longest time per pulse against the median, each given the benefit
    /// of one sample period.
    fn judge(&mut self, median: f64, longest: f64) {
        let Some(Some(ts)) = self.ts else {
            // No sample period: nothing can be judged.
            self.unresolved = true;
            return;
        };
        if self.unresolved {
            return;
        }
        if median < 4.0 * ts {
            self.unresolved = true;
            return;
        }
        let ratio = (longest - ts) / (median + ts);
        self.revolutions += 1;
        if ratio >= GAP_RATIO {
            self.gapped += 1;
            self.worst = self.worst.max(ratio);
        }
    }
}

/// The engine angle at an encoder's count steps, a chunk at a time: `θ = q·(c − c₀)` (Eq. 4.2,
/// [`Encoder::angle`]), `c₀` the first sample's count, at the first sample and at every sample
/// whose count is above the one before — the points between which the angle is interpolated.
#[derive(Debug, Clone)]
pub struct CountSteps {
    q: f64,
    /// The first sample's count.
    c0: Option<f64>,
    /// The count of the sample before.
    prev: Option<f64>,
}

impl CountSteps {
    /// The steps of `encoder`'s counts.
    pub fn new(encoder: Encoder) -> Self {
        Self {
            q: encoder.quantum(),
            c0: None,
            prev: None,
        }
    }

    /// The next samples' times `t` [s] and counts: the steps among them to `t_out` and
    /// `theta_out` [rad] (cleared first).
    pub fn push(
        &mut self,
        t: &[f64],
        counts: &[f64],
        t_out: &mut Vec<f64>,
        theta_out: &mut Vec<f64>,
    ) {
        t_out.clear();
        theta_out.clear();
        for (&ti, &c) in t.iter().zip(counts) {
            let step = match self.prev {
                None => true,
                Some(p) => c > p,
            };
            let c0 = *self.c0.get_or_insert(c);
            if step {
                t_out.push(ti);
                theta_out.push(self.q * (c - c0));
            }
            self.prev = Some(c);
        }
    }
}
