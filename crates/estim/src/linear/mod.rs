//! Recursive estimators for models linear in the parameters, `y(t) = φ(t)ᵀϑ + ε(t)` (Eq. 5.14).
//!
//! One engine serves all of them. For the covariance-form methods a step is
//!
//! ```text
//! e   = y − φᵀϑ                          a-priori prediction error
//! φ̃   = D_pre·φ                          (vector forgetting, symmetric variant only)
//! u   = P·φ̃,   d = r + φ̃ᵀu               gain numerator and denominator
//! ϑ  += D_pre·u/d · e                    (K = D_pre·u/d)
//! P   = D_post·(P − u·uᵀ/d)·D_post + Q
//! ```
//!
//! | method | `r` | `D_pre` | `D_post` | `Q` | thesis |
//! |---|---|---|---|---|---|
//! | RLS | 1 | I | I | 0 | Alg. 5.2 |
//! | RLSF, constant λ | λ | I | λ^(−1/2)·I | 0 | Alg. 5.3 |
//! | RLSF, time-varying λ(t) = λ0·λ(t−1) + 1 − λ0 | λ(t) | I | λ(t)^(−1/2)·I | 0 | Eq. 5.24 |
//! | vector forgetting, published | 1 | I | Λ⁻¹ | 0 | Alg. 5.4 (Vahidi et al. 2005) |
//! | vector forgetting, symmetric | 1 | Λ^(−1/2) | Λ^(−1/2) | 0 | SPEC §5.1 note |
//! | Kalman, random-walk parameters | R2 | I | I | R1 | Eq. 5.19 |
//!
//! `u·uᵀ/d` is `K·φᵀ·P` written symmetrically; every entry is formed from commutative products
//! (`(u_i·u_j)·(1/d)`, `s_i·s_j`), so P stays bit-for-bit symmetric. The update's loop over P
//! runs in four-lane vectors down each column (`kernels.rs`), about 3p² operations for a p² of
//! memory (BENCHMARKS.md has the roofline). For p ≤ 20 the step is compiled for the exact size
//! (one source, generic over nalgebra's `Dim`), which unrolls its loops. DSFC forms `f = Sᵀφ`
//! four columns at a time from p = 8 on.
//!
//! The symmetric vector-forgetting variant is Alg. 5.3 with the discount applied per parameter
//! before the gain (`M = Λ^(−1/2)PΛ^(−1/2)`); with `Λ = λI` it is exactly RLSF(λ). The published variant discounts by `Λ⁻¹·…·Λ⁻¹`, i.e. by λ² per step when
//! `Λ = λI`: it then equals RLSF(λ²) started from `P0·λ²`.
//!
//! DSFC (Alg. 5.5, Isermann's square-root filter in covariance form) keeps `S` with `P = S·Sᵀ`:
//! `f = Sᵀφ`, `a = 1/(fᵀf + λ)`, `γ = a·S·f`, `ϑ += γ·e`, `S = (S − g·γ·fᵀ)/√λ`,
//! `g = 1/(1 + √(λa))`. P is positive semi-definite by construction.
//!
//! ## Noise scale and standard errors
//! The RLS family's P is in units of the noise variance σ² (the implied `R2 = 1`): the
//! innovation variance it reports is `d/r` in those units, and σ² is estimated from the
//! standardised recursive residuals `w = e/√(d/r)` as `σ̂² = Σρ^k w² / (Σρ^k − p)`, ρ the
//! forgetting factor (1 for RLS: then `σ̂²` is the residual sum of squares of the regularised
//! least-squares problem over `n − p`). Standard errors are `√(σ̂²·P_ii)` — exact for λ = 1, the
//! conventional approximation under forgetting (it overstates the spread of an exponentially
//! weighted estimate by up to √(1+λ)). The Kalman filter's P is absolute (R1, R2 are given):
//! its standard errors are `√P_ii`.
//!
//! ## Files
//! Here: the estimator's state ([`LinearEstimator`]). `config.rs`: the configuration as plain
//! data; `estimator.rs`: construction, the step and accessors; `kernels.rs`: the step's loops
//! over P (or S), in four-lane vectors; `lanes.rs`: the lanes' two implementations and the
//! run-time choice of the step's AVX2 copy (a build below AVX2 only); `recursive.rs`: the
//! [`Recursive`](crate::recursive::Recursive) face.

use crate::cov::{Cov, CovForm};
use crate::error::{check_sample, check_view};
use crate::EstimError;
use nalgebra::{Const, DMatrix, DVector, Dim, Dyn};
use physid_core::{FreeSet, ParamSet};
use serde::{Deserialize, Serialize};

mod config;
mod estimator;
mod kernels;
mod lanes;
mod recursive;

pub use config::*;

/// The method with its per-step constants resolved: a covariance-form method (the table
/// above) or DSFC's square-root form — two steps, chosen once by the type.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
enum Kind {
    Cov(CovKind),
    Dsfc { lambda: f64 },
}

/// A covariance-form method (the rows of the module table).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
enum CovKind {
    Rls,
    Rlsf { lambda: f64, inv_lambda: f64 },
    RlsfTv { lambda0: f64 },
    Vf { symmetric: bool, min_lambda: f64 },
    Kalman { r1: DMatrix<f64>, r2: f64 },
}

/// What one covariance-form step needs of its method, resolved before the step borrows the
/// estimator's state: `r`, `1/r` (the innovation variance in σ² units), λ(t) to commit on
/// success, the noise-scale decay ρ, and the table's switches.
#[derive(Debug, Clone, Copy)]
struct CovStep {
    r: f64,
    r_inv: f64,
    lambda_now: f64,
    rho: f64,
    /// `D_pre ≠ I` (vector forgetting, symmetric variant).
    symmetric_vf: bool,
    /// P is divided by λ(t) (time-varying forgetting).
    time_varying: bool,
    /// P is absolute and R1 is added (Kalman).
    kalman: bool,
}

impl CovKind {
    /// The step's constants, λ(t−1) = `lambda_t`.
    fn step(&self, lambda_t: f64) -> CovStep {
        let (r, r_inv, lambda_now, rho) = match self {
            CovKind::Rls => (1.0, 1.0, 1.0, 1.0),
            CovKind::Rlsf { lambda, inv_lambda } => (*lambda, *inv_lambda, *lambda, *lambda),
            CovKind::RlsfTv { lambda0 } => {
                let l = lambda0 * lambda_t + (1.0 - lambda0);
                (l, l.recip(), l, l)
            }
            CovKind::Vf { min_lambda, .. } => (1.0, 1.0, 1.0, *min_lambda),
            CovKind::Kalman { r2, .. } => (*r2, 1.0, 1.0, 1.0),
        };
        CovStep {
            r,
            r_inv,
            lambda_now,
            rho,
            symmetric_vf: matches!(
                self,
                CovKind::Vf {
                    symmetric: true,
                    ..
                }
            ),
            time_varying: matches!(self, CovKind::RlsfTv { .. }),
            kalman: matches!(self, CovKind::Kalman { .. }),
        }
    }
}

/// A recursive estimator for a model linear in the parameters: RLS, RLSF (constant or
/// time-varying λ), vector forgetting, Kalman or DSFC, over a free subset of a parameter set.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct LinearEstimator {
    /// The configuration as built, over `universe` (for [`set_free`](Self::set_free)).
    config: EstimatorConfig,
    /// The free set the estimator was built with: what `set_free` may choose from.
    universe: FreeSet,
    /// Per parameter (full set): its variance when `set_free` last froze it (NaN: never).
    frozen_variance: Vec<f64>,
    kind: Kind,
    params: ParamSet,
    free: FreeSet,
    /// Free-parameter estimates.
    theta: DVector<f64>,
    /// P, or S for DSFC.
    cov: Cov,
    /// Scratch of the same size as `cov`; swapped in on a successful step.
    work: DMatrix<f64>,
    /// P0 (or S0 for DSFC), for covariance resetting.
    cov0: Cov,
    /// Pφ̃, or f = Sᵀφ for DSFC.
    u: DVector<f64>,
    /// DSFC: γ. Covariance form: the gain K.
    k: DVector<f64>,
    /// φ of the free parameters.
    phi: Vec<f64>,
    /// D_pre (vector forgetting, symmetric).
    pre: Vec<f64>,
    /// D_post diagonal.
    post: Vec<f64>,
    /// Current forgetting factor λ(t) of the time-varying method (1 otherwise).
    lambda_t: f64,
    noise_num: f64,
    noise_den: f64,
    /// The power of two the residuals are divided by before they are squared into
    /// `noise_num` (1 unless the first residual's size is outside [`NOISE_RANGE`]): σ̂ of data
    /// scaled by 1e-300 or 1e150 neither underflows to 0 nor overflows.
    #[serde(default = "one")]
    noise_scale: f64,
    samples: u64,
    guard_activations: u64,
    last: Option<Step>,
}

fn one() -> f64 {
    1.0
}

/// Residuals whose size is within this range are squared as they are; outside it (data
/// scaled by 1e-300, or 1e150, whose squares underflow to 0 or overflow), they are first
/// divided by a power of two near the first one's size — exact, so the standard errors are
/// right to the last digit at any scale a double holds (issue 41, item 5).
pub const NOISE_RANGE: std::ops::RangeInclusive<f64> = 1e-100..=1e100;

fn check_lambda(name: &str, l: f64) -> Result<f64, EstimError> {
    if l.is_finite() && l > 0.0 && l <= 1.0 {
        Ok(l)
    } else {
        Err(EstimError::InvalidConfig(format!(
            "{name} = {} is outside (0, 1]",
            physid_core::Num(l)
        )))
    }
}

/// Why a step was refused — small and `Copy`, so the success path carries no `String`; it
/// becomes an [`EstimError::LostPositiveDefiniteness`] only when it happens.
#[derive(Debug, Clone, Copy)]
struct Breakdown {
    what: &'static str,
    value: f64,
}

fn breakdown(what: &'static str, value: f64) -> Breakdown {
    Breakdown { what, value }
}
