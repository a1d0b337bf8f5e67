//! Sensitivity rows of a [`ParamModel`] over data, exact through the seam, and their scaling
//! (thesis Eq. 5.11).
//!
//! Row i of the sensitivity matrix is `J_i· = ∂h(u_i, ϑ)/∂ϑ` at the nominal `ϑ0` over the
//! analysed parameters. Scalings:
//!
//! | mode | `Z_ij` | note |
//! |---|---|---|
//! | `thesis` | `J_ij·ϑ0_j / y_i` | Eq. 5.11; `y_i` guarded away from 0 (below) |
//!
//! (A parameter whose nominal value is 0 has no relative sensitivity; its column uses 1 in
//! place of `ϑ0_j`.)
//! | `sigma` | `J_ij·ϑ0_j / σ_y` | one scale for every row: no division by `y ≈ 0` |
//! | `none` | `J_ij` | |
//!
//! `y` is the measured output when given, the model's output at `ϑ0` otherwise. The guard:
//! where `|y_i| < g·rms(y)` (g = 10⁻³ by default) the row is divided by `±g·rms(y)` instead —
//! the cyclic torque crosses zero twice a revolution, and one such row would otherwise dominate
//! the whole ranking; how many rows hit the guard is reported.

use crate::rows::{for_each_row, Data, Rows};
use crate::IdentError;
use physid_core::{GradientEngine, ParamModel};
use serde::{Deserialize, Serialize};

/// How sensitivities are scaled (see the module table).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Scaling {
    /// `ϑ0_j / y_i` (Eq. 5.11), guarded.
    #[default]
    Thesis,
    /// `ϑ0_j / σ_y`.
    Sigma,
    /// Unscaled.
    None,
}

impl Scaling {
    /// The mode's name.
    pub fn name(self) -> &'static str {
        match self {
            Scaling::Thesis => "thesis",
            Scaling::Sigma => "sigma",
            Scaling::None => "none",
        }
    }

    /// Parse a name.
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "thesis" => Some(Scaling::Thesis),
            "sigma" => Some(Scaling::Sigma),
            "none" => Some(Scaling::None),
            _ => None,
        }
    }
}

impl std::fmt::Display for Scaling {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Scaling {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::parse(s).ok_or_else(|| format!("'{s}': expected thesis, sigma or none"))
    }
}

/// Turns a gradient row into a scaled row (shared by the batch and on-line analyses).
#[derive(Debug, Clone)]
pub struct RowScaler {
    scaling: Scaling,
    /// `ϑ0_j` of the analysed parameters (1 for `none`).
    column: Vec<f64>,
    /// Thesis: the guard floor `g·rms(y)`; sigma: `σ_y`.
    level: f64,
}

impl RowScaler {
    /// A scaler for `scaling` with the analysed parameters' nominal values `theta0_free` and
    /// the output level: `g·rms(y)` (thesis) or `σ_y` (sigma); ignored for `none`.
    pub fn new(scaling: Scaling, theta0_free: &[f64], level: f64) -> Result<Self, IdentError> {
        if scaling != Scaling::None && !level.is_finite() {
            return Err(IdentError::Invalid(format!(
                "the output's level overflowed ({level}): the data or the model's output is too large for 64-bit floating point (its squares pass 1.8e308); rescale the data (e.g. to SI units or by a power of ten)"
            )));
        }
        if scaling != Scaling::None && level <= 0.0 {
            return Err(IdentError::Invalid(format!(
                "{} scaling needs an output level > 0 (the output is {level}): is it identically zero? Use --scaling none",
                scaling.name()
            )));
        }
        // A zero nominal value has no relative sensitivity: its column is scaled by 1
        // (absolute) instead of vanishing — `Analysis::unit_scaled` names such parameters.
        let column = match scaling {
            Scaling::None => vec![1.0; theta0_free.len()],
            _ => theta0_free
                .iter()
                .map(|&t| if t == 0.0 { 1.0 } else { t })
                .collect(),
        };
        Ok(Self {
            scaling,
            column,
            level,
        })
    }

    /// `out = scaled(grad)` for output `y`; returns whether the thesis guard was applied.
    pub fn scale(&self, grad: &[f64], y: f64, out: &mut [f64]) -> bool {
        let (inv, guarded) = match self.scaling {
            Scaling::None => (1.0, false),
            Scaling::Sigma => (1.0 / self.level, false),
            Scaling::Thesis => {
                if y.abs() < self.level {
                    (1.0 / self.level.copysign(y), true)
                } else {
                    (1.0 / y, false)
                }
            }
        };
        for ((o, g), c) in out.iter_mut().zip(grad).zip(&self.column) {
            *o = g * c * inv;
        }
        guarded
    }
}

/// The sensitivity matrix itself (n × p, row-major rows in a nalgebra matrix), for small data
/// and for tests; the analyses stream rows instead. Returns `(Z, J, guarded rows)`.
pub fn sensitivity_matrix<M: ParamModel>(
    model: &M,
    data: &Data,
    theta0: &[f64],
    free: &[usize],
    scaling: Scaling,
    guard: f64,
) -> Result<(nalgebra::DMatrix<f64>, nalgebra::DMatrix<f64>, usize), IdentError> {
    let n = data.rows(model)?;
    let levels = output_levels(model, data, theta0)?;
    let theta_free: Vec<f64> = free.iter().map(|&j| theta0[j]).collect();
    let scaler = RowScaler::new(scaling, &theta_free, levels.level(scaling, guard))?;
    let mut engine = GradientEngine::new(theta0.len());
    let (mut u, mut g, mut z) = (
        vec![0.0; model.input_names().len()],
        vec![0.0; free.len()],
        vec![0.0; free.len()],
    );
    let mut zm = nalgebra::DMatrix::zeros(n, free.len());
    let mut jm = zm.clone();
    let mut guarded = 0;
    for i in 0..n {
        data.row(model, i, &mut u)?;
        let h = engine.value_and_gradient(model, &u, theta0, free, &mut g);
        let y = data.y_at(i)?.unwrap_or(h);
        guarded += usize::from(scaler.scale(&g, y, &mut z));
        for j in 0..free.len() {
            zm[(i, j)] = z[j];
            jm[(i, j)] = g[j];
        }
    }
    Ok((zm, jm, guarded))
}

/// Output statistics for the scalings: rms and standard deviation of `y` (measured, or the
/// model at `ϑ0`), over how many rows.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
pub struct OutputLevels {
    /// √mean(y²).
    pub rms: f64,
    /// Standard deviation of y.
    pub std: f64,
    /// Rows.
    pub rows: usize,
}

impl OutputLevels {
    /// The level a [`RowScaler`] needs for `scaling` with guard `g`.
    pub fn level(&self, scaling: Scaling, guard: f64) -> f64 {
        match scaling {
            Scaling::Thesis => guard * self.rms,
            Scaling::Sigma => self.std,
            Scaling::None => 1.0,
        }
    }
}

/// First pass over the rows: the output's rms and standard deviation (Welford), checking every
/// value.
pub fn output_levels<M: ParamModel, R: Rows + ?Sized>(
    model: &M,
    rows: &R,
    theta0: &[f64],
) -> Result<OutputLevels, IdentError> {
    let (mut mean, mut m2, mut sq) = (0.0, 0.0, 0.0);
    // An output whose size is outside 1e±100 is summed divided by a power of two near its first
    // value that is not 0 (exact), so its square neither underflows (data scaled by 1e-300 are
    // not "identically zero") nor overflows (issue 41, item 5).
    let mut scale = 1.0f64;
    let n = for_each_row(model, rows, |i, u, y| {
        let y = match y {
            Some(y) => y,
            None => {
                let h = model.eval::<f64>(u, theta0);
                if !h.is_finite() {
                    return Err(IdentError::BadValue {
                        row: i,
                        column: "model output at ϑ0".into(),
                        value: h,
                    });
                }
                h
            }
        };
        if sq == 0.0 && y != 0.0 && !(1e-100..=1e100).contains(&y.abs()) {
            scale = 2f64.powi(y.abs().log2().floor() as i32);
        }
        let y = y / scale;
        let k = (i + 1) as f64;
        let d = y - mean;
        mean += d / k;
        m2 += d * (y - mean);
        sq += (y * y - sq) / k;
        Ok(())
    })?;
    Ok(OutputLevels {
        rms: scale * sq.sqrt(),
        std: scale * (m2 / n as f64).sqrt(),
        rows: n,
    })
}
