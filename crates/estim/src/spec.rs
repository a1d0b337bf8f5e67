//! One estimator described as plain data, and the one factory that builds it.
//!
//! The command line (`physid estimate`), pipeline files (`physid run`), the Python package and
//! the applications all say which estimator they want the same way: an [`EstimatorSpec`] — a
//! [`MethodName`] from the one vocabulary and the tuning the methods take (each method reads
//! what applies to it: λ for RLSF/RLSVF/DSFC, R1/R2 for the Kalman filters, the sigma points
//! for the unscented ones). [`build_linear`] makes the regression estimator `y = φᵀϑ`
//! (Eq. 5.14) of the linear methods; [`build`] makes an estimator over a model: the EKF, UKF
//! or SR-UKF (Alg. 5.6, 5.7) for the model-based methods, a linear method fed with the model's
//! exact gradient ([`LinearInParams`]) for the others.
//!
//! [`Method`] and [`NlMethod`] stay the resolved configurations the estimators keep inside
//! (what a checkpoint records); nothing outside this crate names them.

use crate::linear::{CovSpec, EstimatorConfig, LinearEstimator, Method, VfVariant, WindupGuard};
use crate::nonlinear::{NlConfig, NlMethod, NonlinearEstimator, SigmaPoints};
use crate::recursive::{LinearInParams, MethodName, Recursive};
use crate::EstimError;
use physid_core::{FreeSet, ParamModel, ParamSet};
use serde::{Deserialize, Serialize};

/// An estimator by name with its tuning (see the module docs). [`EstimatorSpec::new`] gives
/// each field the value the estimators' own configurations default to.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EstimatorSpec {
    /// Which estimator.
    pub method: MethodName,
    /// The forgetting factor λ ∈ (0, 1]: RLSF's (Alg. 5.3), DSFC's (Alg. 5.5), and each λ_i of
    /// RLSVF (Alg. 5.4) unless `lambdas`; with `lambda0`, RLSF's λ(0).
    pub lambda: f64,
    /// RLSF with time-varying forgetting `λ(t) = λ0·λ(t−1) + (1 − λ0)` (Eq. 5.24).
    pub lambda0: Option<f64>,
    /// RLSVF: λ_i per free parameter.
    pub lambdas: Option<Vec<f64>>,
    /// RLSVF: the published or the symmetric form.
    pub vf_variant: VfVariant,
    /// The initial covariance P(0) over the free parameters (in scaled coordinates when
    /// `scaled`; DSFC and SR-UKF start from its Cholesky factor).
    pub p0: CovSpec,
    /// The parameters' random walk R1 (KF, EKF, UKF, SR-UKF).
    pub r1: CovSpec,
    /// The measurement-noise variance R2 (KF, EKF, UKF, SR-UKF).
    pub r2: f64,
    /// The unscented transform's spread (UKF, SR-UKF).
    pub sigma_points: SigmaPoints,
    /// Estimate `x` with `ϑ = ϑ0·(1 + x)` (model-based methods; needs non-zero nominals).
    pub scaled: bool,
    /// Bounds `(name, low, high)` enforced by projection (model-based methods).
    pub bounds: Vec<(String, f64, f64)>,
    /// The covariance wind-up guard (linear methods).
    pub guard: Option<WindupGuard>,
}

impl EstimatorSpec {
    /// `method` with the estimators' defaults: λ = 1, P(0) = 1000·I for a linear method and
    /// 100·I for a model-based one (thesis ch. 8), R1 = 0, R2 = 1, the thesis's sigma points,
    /// physical coordinates, no bounds, no guard.
    pub fn new(method: MethodName) -> Self {
        Self {
            method,
            lambda: 1.0,
            lambda0: None,
            lambdas: None,
            vf_variant: VfVariant::default(),
            p0: CovSpec::Scaled(if method.is_model_based() {
                100.0
            } else {
                1000.0
            }),
            r1: CovSpec::Scaled(0.0),
            r2: 1.0,
            sigma_points: SigmaPoints::default(),
            scaled: false,
            bounds: Vec::new(),
            guard: None,
        }
    }

    /// The linear method's configuration for `free` free parameters; an error for a
    /// model-based method.
    pub fn linear_config(&self, free: usize) -> Result<EstimatorConfig, EstimError> {
        let lambda = self.lambda;
        let method = match self.method {
            MethodName::Rls => Method::Rls,
            MethodName::Rlsf => match self.lambda0 {
                Some(lambda0) => Method::RlsfTv {
                    lambda0,
                    lambda_init: lambda,
                },
                None => Method::Rlsf { lambda },
            },
            MethodName::Rlsvf => Method::Rlsvf {
                lambdas: self.lambdas.clone().unwrap_or_else(|| vec![lambda; free]),
                variant: self.vf_variant,
            },
            MethodName::Kf => Method::Kalman {
                r1: self.r1.clone(),
                r2: self.r2,
            },
            MethodName::Dsfc => Method::Dsfc { lambda },
            m @ (MethodName::Ekf | MethodName::Ukf | MethodName::Srukf) => {
                return Err(EstimError::InvalidConfig(format!(
                    "{m} is a filter over a model, not a regression y = φᵀϑ: give it a model"
                )))
            }
        };
        Ok(EstimatorConfig {
            method,
            p0: self.p0.clone(),
            guard: self.guard,
        })
    }

    /// The model-based method's configuration; an error for a linear method.
    pub fn nl_config(&self) -> Result<NlConfig, EstimError> {
        let sp = self.sigma_points;
        let method = match self.method {
            MethodName::Ekf => NlMethod::Ekf,
            MethodName::Ukf => NlMethod::Ukf(sp),
            MethodName::Srukf => NlMethod::Srukf(sp),
            m => {
                return Err(EstimError::InvalidConfig(format!(
                    "{m} is a linear method; the filters over a model are ekf, ukf and srukf"
                )))
            }
        };
        Ok(NlConfig {
            method,
            p0: self.p0.clone(),
            r1: self.r1.clone(),
            r2: self.r2,
            scaled: self.scaled,
            bounds: self.bounds.clone(),
        })
    }
}

/// The regression estimator `y = φᵀϑ` (Eq. 5.14) of `spec`'s linear method over the `free`
/// parameters of `params` (the others held at their values).
pub fn build_linear(
    spec: &EstimatorSpec,
    params: &ParamSet,
    free: &FreeSet,
) -> Result<LinearEstimator, EstimError> {
    LinearEstimator::new(&spec.linear_config(free.free().len())?, params, free)
}

/// `spec`'s estimator of the `free` parameters of `model` (nominal values in `params`): the
/// EKF, UKF or SR-UKF over the model, or a linear method fed with the model's exact gradient
/// (the model must then be linear in the free parameters, which the estimator checks per
/// sample).
pub fn build<M: ParamModel + 'static>(
    spec: &EstimatorSpec,
    model: M,
    params: &ParamSet,
    free: &FreeSet,
) -> Result<Box<dyn Recursive>, EstimError> {
    Ok(if spec.method.is_model_based() {
        Box::new(NonlinearEstimator::new(
            model,
            params,
            free,
            &spec.nl_config()?,
        )?)
    } else {
        Box::new(LinearInParams::new(
            model,
            params,
            free,
            &spec.linear_config(free.free().len())?,
        )?)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_method_has_one_configuration_and_the_other_family_is_refused() {
        for m in MethodName::ALL {
            let spec = EstimatorSpec::new(m);
            assert_eq!(spec.linear_config(2).is_ok(), !m.is_model_based(), "{m}");
            assert_eq!(spec.nl_config().is_ok(), m.is_model_based(), "{m}");
        }
        let mut spec = EstimatorSpec::new(MethodName::Rlsvf);
        spec.lambda = 0.99;
        assert_eq!(
            spec.linear_config(3).unwrap().method,
            Method::Rlsvf {
                lambdas: vec![0.99; 3],
                variant: VfVariant::Published
            }
        );
        spec.method = MethodName::Rlsf;
        spec.lambda0 = Some(0.9);
        assert_eq!(
            spec.linear_config(3).unwrap().method,
            Method::RlsfTv {
                lambda0: 0.9,
                lambda_init: 0.99
            }
        );
    }

    #[test]
    fn a_built_estimator_answers_to_its_name() {
        let params = ParamSet::new(["a", "b"], vec![0.0, 0.0]).unwrap();
        let free = params.all_free();
        for m in MethodName::ALL.into_iter().filter(|m| !m.is_model_based()) {
            let est = build_linear(&EstimatorSpec::new(m), &params, &free).unwrap();
            assert_eq!(est.method_name(), m.as_str());
        }
    }
}
