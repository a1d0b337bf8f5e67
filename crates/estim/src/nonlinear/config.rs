//! A non-linear estimator's configuration as plain data ([`NlConfig`]), its method
//! ([`NlMethod`]) and the unscented transform's spread and weights ([`SigmaPoints`],
//! [`SigmaWeights`]).

use super::*;

/// Sigma-point settings of the UKF.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SigmaPoints {
    /// Spread α (thesis: 1).
    pub alpha: f64,
    /// Prior-knowledge β (thesis: 2, Gaussian).
    pub beta: f64,
    /// κ; `None` = the thesis's 3 − l.
    pub kappa: Option<f64>,
}

impl Default for SigmaPoints {
    fn default() -> Self {
        Self {
            alpha: 1.0,
            beta: 2.0,
            kappa: None,
        }
    }
}

/// The unscented transform's weights for `l` free parameters (Alg. 5.7, SPEC fix):
/// `ζ = α²(l + κ) − l`, `W0m = ζ/(l+ζ)`, `W0c = W0m + 1 − α² + β`, `Wi = 1/(2(l+ζ))`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SigmaWeights {
    /// Mean weight of the centre point, `W0m`.
    pub wm0: f64,
    /// Covariance weight of the centre point, `W0c`.
    pub wc0: f64,
    /// Weight of each of the 2l outer points, `Wi` (mean and covariance).
    pub wi: f64,
}

impl SigmaWeights {
    /// The weights of `points` for `l` parameters; refused unless α > 0 and `l + ζ > 0`.
    pub fn new(points: &SigmaPoints, l: usize) -> Result<Self, EstimError> {
        let lf = l as f64;
        let kappa = points.kappa.unwrap_or(3.0 - lf);
        let zeta = points.alpha * points.alpha * (lf + kappa) - lf;
        if !(points.alpha > 0.0 && lf + zeta > 0.0 && zeta.is_finite() && points.beta.is_finite()) {
            return Err(EstimError::InvalidConfig(format!(
                "sigma points need α > 0 and l + ζ > 0 (α = {}, κ = {kappa}, l = {l})",
                points.alpha
            )));
        }
        let wm0 = zeta / (lf + zeta);
        Ok(Self {
            wm0,
            wc0: wm0 + 1.0 - points.alpha * points.alpha + points.beta,
            wi: 1.0 / (2.0 * (lf + zeta)),
        })
    }

    /// `l + ζ`, the square of the sigma points' spread factor.
    pub fn spread2(&self) -> f64 {
        1.0 / (2.0 * self.wi)
    }
}

/// Which non-linear estimator.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum NlMethod {
    /// Extended Kalman filter (Alg. 5.6).
    Ekf,
    /// Unscented Kalman filter (Alg. 5.7).
    Ukf(SigmaPoints),
    /// Square-root UKF (van der Merwe & Wan 2001): the same filter carrying the Cholesky factor
    /// of P, updated by rank-one updates and downdates — the robust option.
    Srukf(SigmaPoints),
}

impl NlMethod {
    /// Short name (`ekf`, `ukf`).
    pub fn name(&self) -> &'static str {
        match self {
            NlMethod::Ekf => "ekf",
            NlMethod::Ukf(_) => "ukf",
            NlMethod::Srukf(_) => "srukf",
        }
    }
}

pub(super) fn default_p0() -> CovSpec {
    CovSpec::Scaled(100.0)
}
pub(super) fn default_r1() -> CovSpec {
    CovSpec::Scaled(0.0)
}
pub(super) fn default_r2() -> f64 {
    1.0
}

/// Configuration of a non-linear estimator, as plain data.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NlConfig {
    /// EKF or UKF.
    pub method: NlMethod,
    /// Initial covariance over the free parameters (in scaled coordinates when `scaled`);
    /// default `100·I` (thesis ch. 8).
    #[serde(default = "default_p0")]
    pub p0: CovSpec,
    /// Random-walk covariance R1 (default 0).
    #[serde(default = "default_r1")]
    pub r1: CovSpec,
    /// Measurement-noise variance R2 (default 1).
    #[serde(default = "default_r2")]
    pub r2: f64,
    /// Estimate `x` with `ϑ = ϑ0·(1 + x)` (needs non-zero nominal values).
    #[serde(default)]
    pub scaled: bool,
    /// Bounds `(name, low, high)` enforced by projection.
    #[serde(default)]
    pub bounds: Vec<(String, f64, f64)>,
}

impl NlConfig {
    /// Defaults: P0 = 100·I, R1 = 0, R2 = 1, physical coordinates, no bounds.
    pub fn new(method: NlMethod) -> Self {
        Self {
            method,
            p0: default_p0(),
            r1: default_r1(),
            r2: default_r2(),
            scaled: false,
            bounds: Vec::new(),
        }
    }
}
