//! Estimators for models non-linear in the parameters (thesis §5.3.2, Eq. 5.29–5.32):
//! random-walk parameters `ϑ(t) = ϑ(t−1) + w`, `w ~ N(0, R1)`, observed through
//! `y = h(φ(t), ϑ(t)) + ε`, `ε ~ N(0, R2)`, for any [`ParamModel`].
//!
//! * **EKF** (Alg. 5.6) — the Kalman filter of Eq. 5.19 ([`LinearEstimator`]) fed with the
//!   exact Jacobian `J = ∇_ϑ h(φ, ϑ̂)` (forward-mode dual numbers, [`GradientEngine`]) as its
//!   regressor and `y − h(φ, ϑ̂)` as its innovation: `K = PJᵀ/(R2 + JPJᵀ)`, `ϑ += K·e`,
//!   `P = P − KJP + R1`. On a linear model it *is* the Kalman filter.
//! * **UKF** (Alg. 5.7, Julier; Wan & van der Merwe) — `2l+1` sigma points from the prior
//!   covariance `P + R1`:
//!   `ζ = α²(l + κ) − l`, `W0m = ζ/(l+ζ)`, `W0c = W0m + 1 − α² + β`, `Wi = 1/(2(l+ζ))`
//!   (SPEC fix: the text prints `ζ/(2l+ζ)`); thesis defaults α = 1, β = 2, κ = 3 − l.
//!
//! Both keep P as the *prior* of the next sample, as Eq. 5.19 does (`P = P − KJP + R1`): `P0` is
//! the prior of the first sample. So on a linear model EKF, UKF and the Kalman filter agree.
//!
//! * **SR-UKF** (van der Merwe & Wan 2001) — the UKF carrying `S`, the lower Cholesky factor of
//!   the prior P: sigma points `x ± √(l+ζ)·S`, the update `S Sᵀ − U Uᵀ` with `U = Pxy/√S_y`
//!   as a rank-one Cholesky downdate, and R1 added as rank-one updates by its square-root
//!   columns. P stays positive semi-definite by construction; a downdate that fails numerically
//!   is repaired by re-factoring `SSᵀ − UUᵀ` with the jitter rule (1) and counted.
//!
//! **Repairs.** With the thesis defaults `W0 < 0` for l > 3, so the unscented covariance can
//! lose definiteness. The filter does not fail; it repairs by a fixed rule and counts:
//! (1) if the prior P has no Cholesky factor, it is symmetrised and `ε·I` is added with
//! `ε = 1e-12·(trace/l)`, ×10 per try, up to 12 tries; (2) if the predicted output variance
//! `S = Σ Wc_i (Y_i − ŷ)² + R2` is not positive, it is recomputed without the negative centre
//! weight. Anything beyond that refuses the sample (state untouched) with an error.
//!
//! **Scaled coordinates.** With [`NlConfig::scaled`], the filter estimates `x` with
//! `ϑ = ϑ0·(1 + x)`, so one covariance scale fits parameters of very different magnitudes
//! (thesis Table 8.2 mixes 1e-9 and 88 mm); estimates and standard errors are reported in
//! physical units. **Bounds** (e.g. a mass stays positive) are enforced by projection after each
//! update and counted.
//!
//! Here: the estimator's state ([`NonlinearEstimator`]). `config.rs`: the configuration;
//! `estimator.rs`: construction and the step; `recursive.rs`: the `Recursive` face.

use crate::cov::{chol_rank_one, factor_with_jitter, Cov, CovForm};
use crate::error::check_view;
use crate::linear::kalman_noise;
use crate::recursive::{Memory, Recursive, Snapshot};
use crate::{CovSpec, EstimError, EstimatorConfig, LinearEstimator, Method, Step};
use nalgebra::{DMatrix, DVector};
use physid_core::{FreeSet, GradientEngine, ParamModel, ParamSet};
use serde::{Deserialize, Serialize};

mod config;
mod estimator;
mod recursive;

pub use config::*;

/// The UKF's state and preallocated work space.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Ukf {
    x: DVector<f64>,
    /// The prior covariance: P (UKF), or its factor S (SR-UKF).
    p: Cov,
    r1: DMatrix<f64>,
    r2: f64,
    /// (l+ζ)·P (P the prior), then its Cholesky factor in place.
    chol: DMatrix<f64>,
    w: SigmaWeights,
    /// Outputs of the 2l+1 sigma points.
    ys: Vec<f64>,
    /// Cross-covariance / gain.
    pxy: DVector<f64>,
    /// Candidate state.
    x_new: DVector<f64>,
    /// Square-root columns of R1 (SR-UKF): R1 = Σ c cᵀ.
    r1_cols: Vec<DVector<f64>>,
    /// Work matrix and vector of the rank-one updates.
    work: DMatrix<f64>,
    v: DVector<f64>,
    /// Deviations of the 2l outer sigma points from the mean, after projection onto bounds.
    dev: DMatrix<f64>,
}

/// How state coordinates map to physical parameter values, and the bounds on them.
struct Coords<'a> {
    free: &'a [usize],
    scale: &'a [f64],
    scaled: bool,
    bounds: &'a [Option<(f64, f64)>],
}

impl Coords<'_> {
    /// Physical value of free parameter `k` at state coordinate `x`.
    #[inline]
    fn physical(&self, k: usize, x: f64) -> f64 {
        if self.scaled {
            self.scale[k] * (1.0 + x)
        } else {
            x
        }
    }

    /// Write the physical values of state `x` into their places of the full vector `theta`.
    fn load(&self, theta: &mut [f64], x: &[f64]) {
        for (k, (&i, &xk)) in self.free.iter().zip(x).enumerate() {
            theta[i] = self.physical(k, xk);
        }
    }

    /// State coordinate `x` of parameter `k` projected onto its bounds (unchanged without one).
    #[inline]
    fn project(&self, k: usize, x: f64) -> f64 {
        match self.bounds[k] {
            Some((lo, hi)) => {
                let phys = self.physical(k, x);
                let clamped = phys.clamp(lo, hi);
                if clamped == phys {
                    x
                } else if self.scaled {
                    clamped / self.scale[k] - 1.0
                } else {
                    clamped
                }
            }
            None => x,
        }
    }
}

#[derive(Debug, Clone, Serialize, Deserialize)]
enum Engine {
    Ekf(Box<LinearEstimator>),
    Ukf(Box<Ukf>),
}

/// EKF or UKF over the free parameters of a [`ParamModel`]. Serialised whole (its model
/// too, when the model serialises): a copy restored from it continues bit for bit.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct NonlinearEstimator<M: ParamModel> {
    model: M,
    method: NlMethod,
    params: ParamSet,
    free: FreeSet,
    engine: Engine,
    gradient: GradientEngine,
    /// Full physical parameter vector at the current estimate.
    theta: Vec<f64>,
    /// Jacobian over the free parameters (state coordinates).
    jac: Vec<f64>,
    /// ϑ0 of the free parameters (the scale of scaled coordinates).
    scale: Vec<f64>,
    scaled: bool,
    bounds: Vec<Option<(f64, f64)>>,
    repairs: u64,
    projections: u64,
    samples: u64,
    /// P0 in state coordinates (for [`Recursive::initial_covariance`]).
    p0: DMatrix<f64>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use physid_core::Scalar;

    #[derive(Debug, Clone)]
    struct Lin2 {
        p: Vec<String>,
        u: Vec<String>,
    }

    impl ParamModel for Lin2 {
        fn param_names(&self) -> &[String] {
            &self.p
        }
        fn input_names(&self) -> &[String] {
            &self.u
        }
        fn eval<T: Scalar>(&self, u: &[f64], p: &[T]) -> T {
            p[0] * u[0] + p[1] * u[1]
        }
    }

    fn ukf(method: NlMethod) -> NonlinearEstimator<Lin2> {
        let m = Lin2 {
            p: vec!["a".into(), "b".into()],
            u: vec!["x".into(), "y".into()],
        };
        let params = ParamSet::zeros(["a", "b"]).unwrap();
        NonlinearEstimator::new(m, &params, &params.all_free(), &NlConfig::new(method)).unwrap()
    }

    /// Repair (1): a prior with no Cholesky factor (here singular, P = v vᵀ) is jittered until
    /// it has one; the step succeeds and the repair is counted.
    #[test]
    fn singular_prior_is_repaired_and_counted() {
        let mut est = ukf(NlMethod::Ukf(SigmaPoints::default()));
        if let Engine::Ukf(u) = &mut est.engine {
            u.p = Cov::full(DMatrix::from_row_slice(2, 2, &[1.0, 1.0, 1.0, 1.0]));
        }
        est.update(&[1.0, 0.5], 2.0).unwrap();
        assert_eq!(est.repairs(), 1);
        assert!(est.estimate().iter().all(|v| v.is_finite()));
    }

    /// The square-root downdate `S Sᵀ − U Uᵀ` that is exactly singular fails as a rank-one
    /// downdate and is repaired by re-factoring with jitter.
    #[test]
    fn failed_square_root_downdate_is_repaired() {
        let mut est = ukf(NlMethod::Srukf(SigmaPoints::default()));
        let Engine::Ukf(u) = &mut est.engine else {
            panic!("SR-UKF engine")
        };
        u.p = Cov::sqrt(DMatrix::identity(2, 2));
        u.pxy = DVector::from_vec(vec![1.0, 0.0]);
        // S Sᵀ − U Uᵀ with U = Pxy·√(1/S_y²), S_y² = 1: I − e1 e1ᵀ, singular.
        let repairs = NonlinearEstimator::<Lin2>::sqrt_update(u, 1.0, 0).unwrap();
        assert_eq!(repairs, 1);
        let p = u.p.covariance();
        assert!(p[(0, 0)] > 0.0 && p[(0, 0)] < 1e-9 && (p[(1, 1)] - 1.0).abs() < 1e-9);
    }
}
