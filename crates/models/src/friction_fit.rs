//! Fitting the cyclic-torque model's friction cubic (Eq. 8.1, Fig. 8.1) to the mean-value
//! friction model: least squares of `c1 … c10` over an (N, T_oil) grid — how the thesis generated
//! the friction term of its cyclic-torque model.
//!
//! The target is the *mechanical* fmep (without pumping): in the cyclic-torque model the
//! pumping work is in the indicated torque through the measured cylinder pressure (SPEC §2.3).

use crate::cyclic_torque::cubic_regressors;
use crate::friction::{fmep, Design, OperatingPoint, Settings};
use nalgebra::{DMatrix, DVector};

/// Result of the fit.
#[derive(Debug, Clone)]
pub struct CubicFit {
    /// c1 … c10 (fmep in kPa, N in rpm, T in °C).
    pub coefficients: [f64; 10],
    /// Root-mean-square error over the grid [kPa].
    pub rms_kpa: f64,
    /// Largest error relative to the model's fmep at that point.
    pub max_relative: f64,
    /// Grid points used.
    pub points: usize,
}

/// Errors of the fit.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitError {
    /// Fewer distinct speeds or temperatures than a cubic needs, or too few points.
    #[error("the grid needs at least 4 speeds and 4 temperatures (got {speeds} and {temps})")]
    GridTooSmall {
        /// Distinct speeds.
        speeds: usize,
        /// Distinct temperatures.
        temps: usize,
    },
    /// The least-squares problem could not be solved.
    #[error("least-squares solve failed: {0}")]
    Solve(String),
}

/// Least squares of `target(N, T)` on the cubic over the grid; columns scaled to unit maximum
/// and solved by SVD (N³ reaches 10¹¹ while the constant column is 1).
pub fn fit_cubic(
    n_grid: &[f64],
    t_grid: &[f64],
    target: impl Fn(f64, f64) -> f64,
) -> Result<CubicFit, FitError> {
    if n_grid.len() < 4 || t_grid.len() < 4 {
        return Err(FitError::GridTooSmall {
            speeds: n_grid.len(),
            temps: t_grid.len(),
        });
    }
    let rows = n_grid.len() * t_grid.len();
    let mut a = DMatrix::zeros(rows, 10);
    let mut y = DVector::zeros(rows);
    for (i, (&n, &t)) in n_grid
        .iter()
        .flat_map(|n| t_grid.iter().map(move |t| (n, t)))
        .enumerate()
    {
        for (j, v) in cubic_regressors(n, t).iter().enumerate() {
            a[(i, j)] = *v;
        }
        y[i] = target(n, t);
    }
    let scale: Vec<f64> = (0..10)
        .map(|j| a.column(j).amax().max(f64::MIN_POSITIVE))
        .collect();
    let mut scaled = a.clone();
    for (j, s) in scale.iter().enumerate() {
        scaled.column_mut(j).scale_mut(1.0 / s);
    }
    let x = scaled
        .svd(true, true)
        .solve(&y, 1e-14)
        .map_err(|e| FitError::Solve(e.to_string()))?;
    let mut c = [0.0; 10];
    for j in 0..10 {
        c[j] = x[j] / scale[j];
    }
    let fitted = &a * DVector::from_column_slice(&c);
    let mut sse = 0.0;
    let mut max_rel: f64 = 0.0;
    for i in 0..rows {
        let e = fitted[i] - y[i];
        sse += e * e;
        max_rel = max_rel.max((e / y[i]).abs());
    }
    Ok(CubicFit {
        coefficients: c,
        rms_kpa: (sse / rows as f64).sqrt(),
        max_relative: max_rel,
        points: rows,
    })
}

/// Fit the cubic to the mean-value model's mechanical fmep at intake pressure `p_int_kpa`.
pub fn fit_friction_cubic(
    design: &Design<f64>,
    settings: &Settings,
    p_int_kpa: f64,
    p_atm_kpa: f64,
    n_grid: &[f64],
    t_grid: &[f64],
) -> Result<CubicFit, FitError> {
    fit_cubic(n_grid, t_grid, |n, t| {
        let op = OperatingPoint {
            n_rpm: n,
            p_int_kpa,
            p_atm_kpa,
            t_oil_c: t,
        };
        fmep(design, settings, &op).mechanical()
    })
}
