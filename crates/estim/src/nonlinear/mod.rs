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
//! Files: `frame.rs`, what every filter shares ([`Frame`]) and its one face ([`ModelFilter`],
//! which makes it a [`Recursive`] estimator); `ekf.rs`, [`Ekf`]; `ukf.rs`, [`Ukf`] over a
//! [`CovFactor`] (`factor.rs`: [`FullCov`], [`SqrtCov`]); `config.rs`, the configuration; here,
//! [`NonlinearEstimator`], the filter chosen at run time.

use crate::cov::{chol_rank_one, factor_with_jitter, Cov, CovForm};
use crate::error::check_view;
use crate::linear::kalman_noise;
use crate::recursive::{Memory, Recursive, Snapshot};
use crate::{CovSpec, EstimError, EstimatorConfig, LinearEstimator, Method, Step};
use nalgebra::{DMatrix, DVector};
use physid_core::{FreeSet, GradientEngine, ParamModel, ParamSet};
use serde::{Deserialize, Serialize};

mod config;
mod ekf;
mod factor;
mod frame;
mod ukf;

pub use config::*;
pub use ekf::Ekf;
pub use factor::{CovFactor, FullCov, SqrtCov};
pub use frame::{Frame, ModelFilter};
pub use ukf::Ukf;

/// The EKF, the UKF or the SR-UKF over the free parameters of a [`ParamModel`], as
/// [`NlConfig::method`] chooses at run time. Serialised whole (its model too, when the model
/// serialises): a copy restored from it continues bit for bit.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(tag = "filter", rename_all = "snake_case")]
pub enum NonlinearEstimator<M: ParamModel> {
    /// Alg. 5.6.
    Ekf(Box<Ekf<M>>),
    /// Alg. 5.7.
    Ukf(Box<Ukf<M, FullCov>>),
    /// The square-root form of Alg. 5.7.
    Srukf(Box<Ukf<M, SqrtCov>>),
}

/// `body` with `f` bound to the filter inside `est`, whichever it is.
macro_rules! each {
    ($est:expr, $f:ident => $body:expr) => {
        match $est {
            NonlinearEstimator::Ekf($f) => $body,
            NonlinearEstimator::Ukf($f) => $body,
            NonlinearEstimator::Srukf($f) => $body,
        }
    };
}

impl<M: ParamModel> NonlinearEstimator<M> {
    /// Build the filter `config.method` names, of the `free` parameters of `model`, starting
    /// from `params`' nominal values (which hold the fixed ones).
    pub fn new(
        model: M,
        params: &ParamSet,
        free: &FreeSet,
        config: &NlConfig,
    ) -> Result<Self, EstimError> {
        Ok(match config.method {
            NlMethod::Ekf => Self::Ekf(Box::new(Ekf::new(model, params, free, config)?)),
            NlMethod::Ukf(sp) => Self::Ukf(Box::new(Ukf::new(model, params, free, config, sp)?)),
            NlMethod::Srukf(sp) => {
                Self::Srukf(Box::new(Ukf::new(model, params, free, config, sp)?))
            }
        })
    }

    /// Process one sample ([`ModelFilter::step`]).
    pub fn update(&mut self, inputs: &[f64], y: f64) -> Result<Step, EstimError> {
        self.step(inputs, y)
    }

    /// Names of the free parameters.
    pub fn free_names(&self) -> Vec<&str> {
        Recursive::free_names(self)
    }

    /// The free parameters' estimates, physical units.
    pub fn estimate(&self) -> Vec<f64> {
        Recursive::estimate(self)
    }

    /// The full parameter vector (fixed ones at nominal), physical units.
    pub fn estimate_full(&self) -> Vec<f64> {
        Recursive::estimate_full(self)
    }

    /// Covariance of the state (scaled coordinates when `scaled`).
    pub fn covariance(&self) -> DMatrix<f64> {
        self.held().covariance()
    }

    /// Standard errors of the free parameters in physical units: `√P_ii` (times `|ϑ0_i|` in
    /// scaled coordinates). R1 and R2 are taken as given (absolute).
    pub fn std_errors(&self) -> Vec<f64> {
        let mut out = vec![0.0; self.state().len()];
        self.std_errors_into(&mut out);
        out
    }

    /// [`estimate`](Self::estimate) into `out` (one value per free parameter), without
    /// allocating — for a caller that records it after every update.
    pub fn estimate_into(&self, out: &mut [f64]) {
        ModelFilter::estimate_into(self, out)
    }

    /// [`std_errors`](Self::std_errors) into `out` (one value per free parameter), without
    /// allocating.
    pub fn std_errors_into(&self, out: &mut [f64]) {
        ModelFilter::std_errors_into(self, out)
    }

    /// Samples accepted.
    pub fn samples(&self) -> u64 {
        Recursive::samples(self)
    }

    /// The method.
    pub fn method(&self) -> NlMethod {
        ModelFilter::method(self)
    }

    /// The model.
    pub fn model(&self) -> &M {
        ModelFilter::model(self)
    }

    /// How many covariance repairs the filter needed (see the module docs).
    pub fn repairs(&self) -> u64 {
        ModelFilter::repairs(self)
    }

    /// How many times a bound was enforced.
    pub fn projections(&self) -> u64 {
        ModelFilter::projections(self)
    }
}

impl<M: ParamModel> ModelFilter for NonlinearEstimator<M> {
    type Model = M;
    fn method(&self) -> NlMethod {
        each!(self, f => f.method())
    }
    fn frame(&self) -> &Frame<M> {
        each!(self, f => f.frame())
    }
    fn frame_mut(&mut self) -> &mut Frame<M> {
        each!(self, f => f.frame_mut())
    }
    fn state(&self) -> &[f64] {
        each!(self, f => f.state())
    }
    fn held(&self) -> &Cov {
        each!(self, f => f.held())
    }
    fn step(&mut self, inputs: &[f64], y: f64) -> Result<Step, EstimError> {
        each!(self, f => f.step(inputs, y))
    }
    fn restore_state(&mut self, s: &Snapshot) -> Result<(), EstimError> {
        each!(self, f => f.restore_state(s))
    }
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
        let NonlinearEstimator::Ukf(u) = &mut est else {
            panic!("UKF")
        };
        *u.p.held_mut() = Cov::full(DMatrix::from_row_slice(2, 2, &[1.0, 1.0, 1.0, 1.0]));
        est.update(&[1.0, 0.5], 2.0).unwrap();
        assert_eq!(est.repairs(), 1);
        assert!(est.estimate().iter().all(|v| v.is_finite()));
    }

    /// The square-root downdate `S Sᵀ − U Uᵀ` that is exactly singular fails as a rank-one
    /// downdate and is repaired by re-factoring with jitter.
    #[test]
    fn failed_square_root_downdate_is_repaired() {
        let mut p = SqrtCov::new(DMatrix::identity(2, 2), DMatrix::zeros(2, 2)).unwrap();
        let pxy = DVector::from_vec(vec![1.0, 0.0]);
        let (mut work, mut v) = (DMatrix::zeros(2, 2), DVector::zeros(2));
        // S Sᵀ − U Uᵀ with U = Pxy·√(1/S_y²), S_y² = 1: I − e1 e1ᵀ, singular.
        let repairs = p.update(&pxy, 1.0, &mut work, &mut v, 0).unwrap();
        assert_eq!(repairs, 1);
        let p = p.held().covariance();
        assert!(p[(0, 0)] > 0.0 && p[(0, 0)] < 1e-9 && (p[(1, 1)] - 1.0).abs() < 1e-9);
    }
}
