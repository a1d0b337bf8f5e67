//! An estimator's configuration as plain data: the method and its tuning ([`Method`]), the
//! initial covariance ([`CovSpec`]), the wind-up guard, and what a step returns ([`Step`]).

use super::*;

/// Which recursive estimator, and its tuning.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Method {
    /// Recursive least squares (Alg. 5.2).
    Rls,
    /// RLS with a constant forgetting factor λ ∈ (0, 1] (Alg. 5.3).
    Rlsf {
        /// Forgetting factor.
        lambda: f64,
    },
    /// RLS with time-varying forgetting `λ(t) = λ0·λ(t−1) + (1 − λ0)` (Eq. 5.24), tending to 1.
    RlsfTv {
        /// The rate λ0 ∈ (0, 1] at which λ(t) approaches 1.
        lambda0: f64,
        /// λ(0) ∈ (0, 1].
        lambda_init: f64,
    },
    /// RLS with one forgetting factor per free parameter (Alg. 5.4).
    Rlsvf {
        /// λ_i ∈ (0, 1] for each free parameter, in the parameter set's order.
        lambdas: Vec<f64>,
        /// Published (thesis) or symmetric form.
        #[serde(default)]
        variant: VfVariant,
    },
    /// Kalman filter for random-walk parameters (Eq. 5.19).
    Kalman {
        /// Parameter random-walk covariance R1 (positive semi-definite).
        r1: CovSpec,
        /// Measurement noise variance R2 > 0.
        r2: f64,
    },
    /// DSFC square-root filter with forgetting λ ∈ (0, 1] (Alg. 5.5).
    Dsfc {
        /// Forgetting factor.
        lambda: f64,
    },
}

impl Method {
    /// Short name used on the command line and in benchmark output.
    pub fn name(&self) -> &'static str {
        match self {
            Method::Rls => "rls",
            Method::Rlsf { .. } | Method::RlsfTv { .. } => "rlsf",
            Method::Rlsvf { .. } => "rlsvf",
            Method::Kalman { .. } => "kf",
            Method::Dsfc { .. } => "dsfc",
        }
    }
}

/// The two forms of vector forgetting (SPEC §5.1 note).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum VfVariant {
    /// `P = Λ⁻¹(P − KφᵀP)Λ⁻¹` as published (Vahidi, Stefanopoulou & Peng 2005; thesis Alg. 5.4):
    /// with `Λ = λI` it discounts by λ² per step.
    #[default]
    Published,
    /// `M = Λ^(−1/2)PΛ^(−1/2)` before the gain: with `Λ = λI` exactly Alg. 5.3.
    Symmetric,
}

impl std::str::FromStr for VfVariant {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "published" => Ok(Self::Published),
            "symmetric" => Ok(Self::Symmetric),
            _ => Err(format!("'{s}': expected published or symmetric")),
        }
    }
}

/// A covariance matrix given as `c·I`, a diagonal, or in full (rows).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CovSpec {
    /// `c·I`.
    Scaled(f64),
    /// `diag(v)`.
    Diagonal(Vec<f64>),
    /// Full symmetric matrix, row by row.
    Full(Vec<Vec<f64>>),
}

impl CovSpec {
    /// The matrix of size `n`, checked finite and symmetric.
    pub fn to_matrix(&self, n: usize, what: &'static str) -> Result<DMatrix<f64>, EstimError> {
        let m = match self {
            CovSpec::Scaled(c) => DMatrix::from_diagonal_element(n, n, *c),
            CovSpec::Diagonal(v) => {
                if v.len() != n {
                    return Err(EstimError::DimensionMismatch {
                        what,
                        expected: n,
                        got: v.len(),
                    });
                }
                DMatrix::from_diagonal(&DVector::from_column_slice(v))
            }
            CovSpec::Full(rows) => {
                if rows.len() != n {
                    return Err(EstimError::DimensionMismatch {
                        what,
                        expected: n,
                        got: rows.len(),
                    });
                }
                for r in rows {
                    if r.len() != n {
                        return Err(EstimError::DimensionMismatch {
                            what,
                            expected: n,
                            got: r.len(),
                        });
                    }
                }
                DMatrix::from_fn(n, n, |i, j| rows[i][j])
            }
        };
        if m.iter().any(|v| !v.is_finite()) {
            return Err(EstimError::InvalidConfig(format!(
                "{what} has a non-finite entry"
            )));
        }
        for i in 0..n {
            for j in 0..i {
                let (a, b) = (m[(i, j)], m[(j, i)]);
                if (a - b).abs() > 1e-12 * (a.abs() + b.abs()) {
                    return Err(EstimError::InvalidConfig(format!(
                        "{what} is not symmetric: entry ({i},{j}) = {a} but ({j},{i}) = {b}"
                    )));
                }
            }
        }
        // Exactly symmetric from here on ((a + b)/2 is the same for both halves).
        Ok((&m + m.transpose()) * 0.5)
    }
}

/// What the wind-up guard does when trace(P) exceeds its bound.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum GuardAction {
    /// Scale P down so that trace(P) equals the bound (direction information kept).
    #[default]
    Scale,
    /// Reset P to P0 (covariance resetting).
    Reset,
}

impl std::str::FromStr for GuardAction {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "scale" => Ok(Self::Scale),
            "reset" => Ok(Self::Reset),
            _ => Err(format!("'{s}': expected scale or reset")),
        }
    }
}

/// Protection against covariance wind-up when excitation is poor: under forgetting, the
/// directions the regressor does not excite grow by 1/λ per step without bound.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WindupGuard {
    /// Bound on trace(P) (in P's units).
    pub max_trace: f64,
    /// What to do beyond it.
    #[serde(default)]
    pub action: GuardAction,
}

fn default_p0() -> CovSpec {
    CovSpec::Scaled(1000.0)
}

/// Everything needed to build an estimator, as plain data (TOML, JSON, CLI flags and tests all
/// build it the same way).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EstimatorConfig {
    /// Method and its tuning.
    pub method: Method,
    /// Initial covariance `P(0)` over the free parameters (default `1000·I`, SPEC §5.1; for DSFC
    /// `S(0)` is its Cholesky factor, `√c·I` for `c·I`).
    #[serde(default = "default_p0")]
    pub p0: CovSpec,
    /// Optional wind-up guard.
    #[serde(default)]
    pub guard: Option<WindupGuard>,
}

impl EstimatorConfig {
    /// A configuration with `P0 = 1000·I` and no guard.
    pub fn new(method: Method) -> Self {
        Self {
            method,
            p0: default_p0(),
            guard: None,
        }
    }
}

/// What one update produced.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Step {
    /// A-priori prediction error `e = y − φᵀϑ(t−1)`.
    pub prediction_error: f64,
    /// Innovation variance `Var(e)`: in units of the noise variance σ² for the RLS family and
    /// DSFC (multiply by [`LinearEstimator::noise_variance`]), absolute for the Kalman filter.
    pub innovation_variance: f64,
}

impl Step {
    /// Standardised recursive residual `w = e/√innovation_variance` (computed on demand: the
    /// square root is kept off the update's critical path).
    pub fn standardized_residual(&self) -> f64 {
        self.prediction_error / self.innovation_variance.sqrt()
    }
}

/// The Kalman filter's noise, checked: R1 (of size `n`) positive semi-definite, R2 a positive
/// variance (Eq. 5.19). Shared by the linear Kalman filter, the EKF and the UKFs.
pub(crate) fn kalman_noise(
    r1: &CovSpec,
    r2: f64,
    n: usize,
) -> Result<(DMatrix<f64>, f64), EstimError> {
    if !(r2.is_finite() && r2 > 0.0) {
        return Err(EstimError::InvalidConfig(format!(
            "R2 = {} must be a positive variance",
            physid_core::Num(r2)
        )));
    }
    let r1 = r1.to_matrix(n, "R1")?;
    let eig = r1.clone().symmetric_eigenvalues();
    let scale = r1.amax().max(f64::MIN_POSITIVE);
    if eig.iter().any(|&v| v < -1e-12 * scale) {
        return Err(EstimError::InvalidConfig(
            "R1 is not positive semi-definite".into(),
        ));
    }
    Ok((r1, r2))
}
