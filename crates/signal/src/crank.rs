//! Crank-angle data (thesis §4, SPEC §2.7): resampling between a time basis and one sample per
//! crank degree, cycle indexing from the first TDC marker (data before it is discarded, as in
//! the thesis), per-cycle statistics and the indicated mean effective pressure.
//!
//! A four-stroke cycle is 720° (4π rad); cycle 0 starts at the first TDC marker.

use std::f64::consts::PI;
use thiserror::Error;

/// Errors of the crank-angle processing.
#[derive(Debug, Error, PartialEq)]
pub enum CrankError {
    /// The abscissa does not increase.
    #[error("{what} does not increase at sample {index} ({prev} → {next}): resampling needs a strictly increasing abscissa")]
    NotIncreasing {
        /// Which abscissa.
        what: &'static str,
        /// Sample index.
        index: usize,
        /// Value before.
        prev: f64,
        /// Value at the index.
        next: f64,
    },
    /// A bad parameter or empty input, explained.
    #[error("{0}")]
    Invalid(String),
}

/// Check that `x` is finite and strictly increasing.
pub fn check_increasing(x: &[f64], what: &'static str) -> Result<(), CrankError> {
    if let Some(i) = x.iter().position(|v| !v.is_finite()) {
        return Err(CrankError::Invalid(format!(
            "{what} is {} at sample {i}",
            x[i]
        )));
    }
    match x.windows(2).position(|w| w[1] <= w[0]) {
        Some(i) => Err(CrankError::NotIncreasing {
            what,
            index: i + 1,
            prev: x[i],
            next: x[i + 1],
        }),
        None => Ok(()),
    }
}

/// Linear interpolation of `y(x)` at the points `at` (both `x` and `at` increasing; points
/// outside `x` take the end values). O(n + m).
pub fn interp(x: &[f64], y: &[f64], at: &[f64]) -> Vec<f64> {
    let mut out = Vec::with_capacity(at.len());
    let mut j = 0;
    let n = x.len();
    for &a in at {
        if n == 0 {
            out.push(f64::NAN);
            continue;
        }
        if a <= x[0] {
            out.push(y[0]);
            continue;
        }
        if a >= x[n - 1] {
            out.push(y[n - 1]);
            continue;
        }
        while x[j + 1] < a {
            j += 1;
        }
        let f = (a - x[j]) / (x[j + 1] - x[j]);
        out.push(y[j] + f * (y[j + 1] - y[j]));
    }
    out
}

/// A crank-angle grid: one sample every `step` from the first TDC marker.
#[derive(Debug, Clone, PartialEq)]
pub struct CrankGrid {
    /// Continuous crank angle at the grid points [rad], 0 at the first TDC marker.
    pub theta: Vec<f64>,
    /// Time at the grid points [s] (interpolated).
    pub t: Vec<f64>,
    /// Cycle index (cycle 0 starts at the first TDC marker).
    pub cycle: Vec<f64>,
    /// Crank angle within the cycle [deg], 0 … 720.
    pub crank_deg: Vec<f64>,
}

/// Build the grid from a time basis: `t` [s] and the continuous angle `theta` [rad] (strictly
/// increasing — a rotating engine), `theta_tdc` the angle at the first TDC marker, one sample
/// every `step_deg` degrees from it to the end of the data.
pub fn crank_grid(
    t: &[f64],
    theta: &[f64],
    theta_tdc: f64,
    step_deg: f64,
) -> Result<CrankGrid, CrankError> {
    if !(step_deg.is_finite() && step_deg > 0.0) {
        return Err(CrankError::Invalid(format!(
            "crank-angle step {step_deg}°: expected > 0",
            step_deg = physid_core::Num(step_deg)
        )));
    }
    if t.len() != theta.len() || t.len() < 2 {
        return Err(CrankError::Invalid(format!(
            "time ({}) and angle ({}) need the same length, at least 2",
            t.len(),
            theta.len()
        )));
    }
    check_increasing(theta, "the crank angle")?;
    let step = step_deg.to_radians();
    let last = theta[theta.len() - 1];
    let n = ((last - theta_tdc) / step).floor().max(-1.0) as i64 + 1;
    let first = theta_tdc.max(theta[0]);
    let k0 = ((first - theta_tdc) / step).ceil() as i64;
    let grid: Vec<f64> = (k0..n).map(|k| theta_tdc + k as f64 * step).collect();
    let tt = interp(theta, t, &grid);
    let (cycle, crank_deg) = grid.iter().map(|g| cycle_position(g - theta_tdc)).unzip();
    Ok(CrankGrid {
        theta: grid.iter().map(|g| g - theta_tdc).collect(),
        t: tt,
        cycle,
        crank_deg,
    })
}

/// Cycle index and angle in the cycle [deg] of an angle from the first TDC marker [rad]
/// (`θ_cyc = θ_con mod 720°`, Eq. 4.2).
pub fn cycle_position(theta_from_tdc: f64) -> (f64, f64) {
    let c = (theta_from_tdc / (4.0 * PI)).floor();
    let deg = (theta_from_tdc - c * 4.0 * PI).to_degrees();
    // Rounding can put 719.9999999 at 720: keep it in [0, 720).
    if deg >= 720.0 - 1e-9 {
        (c + 1.0, 0.0)
    } else {
        (c, deg.max(0.0))
    }
}

/// Statistics of a channel over one cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CycleStats {
    /// Cycle index.
    pub cycle: i64,
    /// Samples in the cycle.
    pub samples: usize,
    /// Mean.
    pub mean: f64,
    /// Minimum.
    pub min: f64,
    /// Maximum.
    pub max: f64,
}

/// Per-cycle mean, min and max of `x`, grouped by the `cycle` channel (consecutive runs of
/// one cycle index; negative indices — before the first TDC — are skipped).
pub fn cycle_stats(cycle: &[f64], x: &[f64]) -> Vec<CycleStats> {
    let mut out: Vec<CycleStats> = Vec::new();
    for (&c, &v) in cycle.iter().zip(x) {
        if c < 0.0 || !c.is_finite() {
            continue;
        }
        let ci = c as i64;
        match out.last_mut() {
            Some(s) if s.cycle == ci => {
                s.samples += 1;
                s.mean += (v - s.mean) / s.samples as f64;
                s.min = s.min.min(v);
                s.max = s.max.max(v);
            }
            _ => out.push(CycleStats {
                cycle: ci,
                samples: 1,
                mean: v,
                min: v,
                max: v,
            }),
        }
    }
    out
}

/// Indicated mean effective pressure of each complete cycle: `∮p dV / V_d` [Pa], with the
/// loop closed from the cycle's last sample back to its first (trapezoidal rule). A cycle is
/// complete when it has `per_cycle` samples.
pub fn imep(cycle: &[f64], p: &[f64], v: &[f64], vd: f64, per_cycle: usize) -> Vec<(i64, f64)> {
    let n = cycle.len().min(p.len()).min(v.len());
    let mut out = Vec::new();
    for (c, run) in cycle_runs(&cycle[..n]) {
        if c >= 0.0 && run.len() == per_cycle {
            let (start, end) = (run.start, run.end);
            let mut w = 0.0;
            for i in start..end {
                let j = if i + 1 < end { i + 1 } else { start };
                w += 0.5 * (p[i] + p[j]) * (v[j] - v[i]);
            }
            out.push((c as i64, w / vd));
        }
    }
    out
}

/// The runs of one value of a crank-angle recording's `cycle` channel, in order: each cycle's
/// index and its samples (complete when their number is the samples per cycle).
pub fn cycle_runs(cycle: &[f64]) -> impl Iterator<Item = (f64, std::ops::Range<usize>)> + '_ {
    let mut start = 0;
    std::iter::from_fn(move || {
        let c = *cycle.get(start)?;
        let mut end = start + 1;
        while end < cycle.len() && cycle[end] == c {
            end += 1;
        }
        let run = start..end;
        start = end;
        Some((c, run))
    })
}
