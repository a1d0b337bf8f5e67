//! One interface for every recursive estimator of this crate — the linear family (RLS, RLSF,
//! vector forgetting, Kalman, DSFC), the non-linear filters (EKF, UKF, SR-UKF) and a linear
//! estimator fed with a model's exact gradient ([`LinearInParams`]) — so that the file verbs,
//! the pipeline and the live stages drive any of them the same way, and checkpoint them.
//!
//! A [`Snapshot`] is the estimator's whole mutable state as plain data (serde): restoring it
//! into an estimator built from the same configuration continues the run exactly as if it had
//! never stopped (asserted bit for bit in the tests).

use crate::cov::Cov;
use crate::resolution::{resolution, Resolution};
use crate::{EstimError, EstimatorConfig, LinearEstimator, Step};
use nalgebra::DMatrix;
use physid_core::{FreeSet, GradientEngine, ParamModel, ParamSet};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// What every recursive estimator offers.
pub trait Recursive {
    /// Method name (`rls`, `rlsf`, `rlsvf`, `kf`, `dsfc`, `ekf`, `ukf`, `srukf`).
    fn method_name(&self) -> &'static str;
    /// One sample: `inputs` are the regressor φ over the full parameter set (linear methods) or
    /// the model's inputs (model-based ones), `y` the measured output. A refused sample leaves
    /// the state untouched. Allocation-free.
    fn update(&mut self, inputs: &[f64], y: f64) -> Result<Step, EstimError>;
    /// Names of all the parameters, free and fixed, in order.
    fn param_names(&self) -> &[String];
    /// Names of the estimated (free) parameters, in order.
    fn free_names(&self) -> Vec<&str>;
    /// The free parameters' estimates, physical units.
    fn estimate(&self) -> Vec<f64>;
    /// The full parameter vector (fixed ones at their nominal values), physical units.
    fn estimate_full(&self) -> Vec<f64>;
    /// The covariance over the free parameters, in the estimator's coordinates (scaled ones for
    /// a filter in scaled coordinates; σ² units for the RLS family).
    fn covariance(&self) -> DMatrix<f64>;
    /// The starting covariance P0, in the same coordinates.
    fn initial_covariance(&self) -> DMatrix<f64>;
    /// Standard errors of the free estimates, physical units; `None` while they cannot be
    /// estimated yet (the RLS family needs more samples than parameters).
    fn std_errors(&self) -> Option<Vec<f64>>;
    /// Samples accepted.
    fn samples(&self) -> u64;
    /// Covariance repairs so far (the unscented filters; `None` for methods that have none).
    fn repairs(&self) -> Option<u64> {
        None
    }
    /// Times a bound was enforced (model-based methods; `None` for the others).
    fn projections(&self) -> Option<u64> {
        None
    }
    /// Which estimates the data resolved so far ([`resolution`]).
    fn resolution(&self) -> Resolution {
        resolution(&self.covariance(), &self.initial_covariance())
    }
    /// The whole mutable state, for a checkpoint.
    fn snapshot(&self) -> Snapshot;
    /// Continue from a checkpoint taken of an estimator built with the same configuration;
    /// refused (state untouched) if it does not fit.
    fn restore(&mut self, snapshot: &Snapshot) -> Result<(), EstimError>;
}

/// An estimator's whole mutable state (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Snapshot {
    /// The method's name, checked on restore.
    pub method: String,
    /// Indices of the free parameters in the full set.
    pub free: Vec<usize>,
    /// The full parameter vector at the checkpoint: the fixed parameters are held at these
    /// values (a parameter frozen by the excitation supervisor at its estimate then).
    pub params: Vec<f64>,
    /// The state vector (estimator coordinates).
    pub state: Vec<f64>,
    /// The covariance as held.
    pub cov: Cov,
    /// Samples accepted.
    pub samples: u64,
    /// What the method remembers beyond state and covariance.
    pub memory: Memory,
}

fn one() -> f64 {
    1.0
}

fn is_one(v: &f64) -> bool {
    *v == 1.0
}

/// Method-specific memory of a [`Snapshot`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Memory {
    /// The linear family.
    Linear {
        /// λ(t) of time-varying forgetting (1 otherwise).
        lambda_t: f64,
        /// Numerator of the noise-variance estimate.
        noise_num: f64,
        /// Its denominator (effective sample count).
        noise_den: f64,
        /// The power of two the residuals are divided by (`noise_num` is in its units; 1,
        /// and not written, for data of ordinary size).
        #[serde(default = "one", skip_serializing_if = "is_one")]
        noise_scale: f64,
        /// Times the wind-up guard acted.
        guard_activations: u64,
        /// Per parameter of the full set, its variance when last frozen (`None`: never).
        frozen_variance: Vec<Option<f64>>,
        /// The last accepted step.
        last: Option<Step>,
    },
    /// The model-based filters.
    Model {
        /// Covariance repairs.
        repairs: u64,
        /// Bound projections.
        projections: u64,
    },
    /// An estimator steered from outside this crate (the excitation supervisor of
    /// `physid-apps`): the estimator's own memory, and the steering's state as its owner
    /// serialises it (MessagePack).
    Steered {
        /// The steered estimator's memory.
        estimator: Box<Memory>,
        /// The steering's state.
        steering: Vec<u8>,
    },
}

impl Memory {
    /// What kind of estimator it is the memory of, for an error.
    pub fn of(&self) -> &'static str {
        match self {
            Memory::Linear { .. } => "a linear estimator",
            Memory::Model { .. } => "a model-based filter",
            Memory::Steered { .. } => "a supervised estimator",
        }
    }
}

impl Snapshot {
    /// Refuse a snapshot of another method or size.
    pub(crate) fn check(
        &self,
        method: &str,
        free: &[usize],
        n_params: usize,
        cov: &Cov,
    ) -> Result<(), EstimError> {
        let wrong = |what: String| Err(EstimError::InvalidConfig(format!("checkpoint: {what}")));
        if self.method != method {
            return wrong(format!(
                "taken of a {} estimator, restored into a {method} one",
                self.method
            ));
        }
        if self.free != free {
            return wrong(format!(
                "free parameters {:?}, the estimator's are {free:?}",
                self.free
            ));
        }
        if self.params.len() != n_params {
            return wrong(format!(
                "{} parameters, the estimator has {n_params}",
                self.params.len()
            ));
        }
        if self.state.len() != free.len()
            || self.cov.dim() != free.len()
            || self.cov.form() != cov.form()
        {
            return wrong(format!(
                "state of {} and a {:?} covariance of size {}, expected {} and {:?}",
                self.state.len(),
                self.cov.form(),
                self.cov.dim(),
                free.len(),
                cov.form()
            ));
        }
        if let Some(v) = self
            .state
            .iter()
            .chain(self.cov.held().iter())
            .chain(&self.params)
            .find(|v| !v.is_finite())
        {
            return wrong(format!("a non-finite value ({v})"));
        }
        Ok(())
    }
}

/// A linear estimator ([`LinearEstimator`]) over a model linear in its parameters, fed with the
/// model's exact gradient as its regressor: `h(φ, ϑ) = ∇_ϑ h · ϑ`, so `φ_reg = ∇_ϑ h(φ, ϑ0)`
/// (Eq. 5.14). Linearity is checked on every sample (`h(φ, ϑ0) = φ_regᵀϑ0` to 1e-9 relative);
/// a model that is not linear is refused with the advice to use a filter.
#[derive(Debug, Clone)]
pub struct LinearInParams<M: ParamModel> {
    model: M,
    est: LinearEstimator,
    engine: GradientEngine,
    nominal: Vec<f64>,
    all: Vec<usize>,
    phi: Vec<f64>,
}

impl<M: ParamModel> LinearInParams<M> {
    /// The `free` parameters of `model` (nominal values in `params`, which must be the model's
    /// parameters) by the linear method of `config`.
    pub fn new(
        model: M,
        params: &ParamSet,
        free: &FreeSet,
        config: &EstimatorConfig,
    ) -> Result<Self, EstimError> {
        crate::error::check_model_params(params, &model)?;
        let n = params.len();
        Ok(Self {
            est: LinearEstimator::new(config, params, free)?,
            engine: GradientEngine::new(n),
            nominal: params.nominal().to_vec(),
            all: (0..n).collect(),
            phi: vec![0.0; n],
            model,
        })
    }
}

impl<M: ParamModel> Recursive for LinearInParams<M> {
    fn method_name(&self) -> &'static str {
        self.est.method_name()
    }
    fn param_names(&self) -> &[String] {
        self.est.params().names()
    }
    fn update(&mut self, inputs: &[f64], y: f64) -> Result<Step, EstimError> {
        crate::error::check_model_sample(&self.model, self.est.samples(), inputs, y)?;
        let h = self.engine.value_and_gradient(
            &self.model,
            inputs,
            &self.nominal,
            &self.all,
            &mut self.phi,
        );
        let lin: f64 = self.phi.iter().zip(&self.nominal).map(|(g, v)| g * v).sum();
        if (h - lin).abs() > 1e-9 * (h.abs() + lin.abs()).max(1e-300) {
            return Err(EstimError::InvalidConfig(format!(
                "the model is not linear in its parameters (h = {h}, φᵀϑ = {lin}); use ekf, ukf or srukf"
            )));
        }
        self.est.update(&self.phi, y)
    }
    fn free_names(&self) -> Vec<&str> {
        self.est.free_names()
    }
    fn estimate(&self) -> Vec<f64> {
        self.est.estimate().to_vec()
    }
    fn estimate_full(&self) -> Vec<f64> {
        self.est.estimate_full()
    }
    fn covariance(&self) -> DMatrix<f64> {
        self.est.covariance()
    }
    fn initial_covariance(&self) -> DMatrix<f64> {
        Recursive::initial_covariance(&self.est)
    }
    fn std_errors(&self) -> Option<Vec<f64>> {
        self.est.std_errors().ok()
    }
    fn samples(&self) -> u64 {
        self.est.samples()
    }
    fn snapshot(&self) -> Snapshot {
        Recursive::snapshot(&self.est)
    }
    fn restore(&mut self, snapshot: &Snapshot) -> Result<(), EstimError> {
        Recursive::restore(&mut self.est, snapshot)
    }
}

/// What a run over recorded data does with a sample the estimator refuses as not finite.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OnBad {
    /// Stop and report the sample (the default: nothing is absorbed silently).
    #[default]
    Error,
    /// Skip it and count it.
    Skip,
}

impl std::str::FromStr for OnBad {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "error" => Ok(Self::Error),
            "skip" => Ok(Self::Skip),
            _ => Err(format!("'{s}': expected error or skip")),
        }
    }
}

/// What [`feed`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeedSummary {
    /// Samples accepted.
    pub accepted: usize,
    /// Non-finite samples skipped ([`OnBad::Skip`]).
    pub skipped: usize,
    /// Time spent in the estimator's updates [s].
    pub seconds: f64,
}

impl std::ops::AddAssign for FeedSummary {
    /// The summary of two runs of [`feed`] one after the other (a stream fed chunk by chunk).
    fn add_assign(&mut self, other: Self) {
        self.accepted += other.accepted;
        self.skipped += other.skipped;
        self.seconds += other.seconds;
    }
}

/// A sample [`feed`] stopped at.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("sample {sample}: {error}")]
pub struct FeedError {
    /// Its index in the columns.
    pub sample: usize,
    /// What the estimator said.
    pub error: EstimError,
}

/// Feed sample `i` of `columns` (the estimator's inputs, in its order) and `y[i]` for every
/// `i`, calling `accepted(i, step, estimator)` after each accepted sample. Non-finite samples
/// stop the run or are skipped, as `on_bad` says; any other refusal stops it. Allocation-free
/// per sample (one input buffer for the run).
pub fn feed(
    est: &mut dyn Recursive,
    columns: &[&[f64]],
    y: &[f64],
    on_bad: OnBad,
    mut accepted: impl FnMut(usize, Step, &dyn Recursive),
) -> Result<FeedSummary, FeedError> {
    let mut inputs = vec![0.0; columns.len()];
    let mut summary = FeedSummary {
        accepted: 0,
        skipped: 0,
        seconds: 0.0,
    };
    for (i, &yi) in y.iter().enumerate() {
        for (u, c) in inputs.iter_mut().zip(columns) {
            *u = c[i];
        }
        let t0 = std::time::Instant::now();
        let r = est.update(&inputs, yi);
        summary.seconds += t0.elapsed().as_secs_f64();
        match r {
            Ok(step) => {
                summary.accepted += 1;
                accepted(i, step, est);
            }
            Err(EstimError::NonFinite { .. }) if on_bad == OnBad::Skip => summary.skipped += 1,
            Err(error) => return Err(FeedError { sample: i, error }),
        }
    }
    Ok(summary)
}

/// The estimators by name, as the command line, pipeline files and the Python package spell
/// them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MethodName {
    /// Recursive least squares (Alg. 5.2).
    Rls,
    /// RLS with forgetting, constant or time-varying (Alg. 5.3, Eq. 5.24).
    Rlsf,
    /// RLS with vector forgetting (Alg. 5.4).
    Rlsvf,
    /// Kalman filter for random-walk parameters (Eq. 5.19).
    Kf,
    /// DSFC square-root filter (Alg. 5.5).
    Dsfc,
    /// Extended Kalman filter over a model (Alg. 5.6).
    Ekf,
    /// Unscented Kalman filter over a model (Alg. 5.7).
    Ukf,
    /// Square-root UKF over a model.
    Srukf,
}

impl MethodName {
    /// Every method, in the order the documentation lists them.
    pub const ALL: [MethodName; 8] = [
        Self::Rls,
        Self::Rlsf,
        Self::Rlsvf,
        Self::Kf,
        Self::Dsfc,
        Self::Ekf,
        Self::Ukf,
        Self::Srukf,
    ];

    /// The name.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Rls => "rls",
            Self::Rlsf => "rlsf",
            Self::Rlsvf => "rlsvf",
            Self::Kf => "kf",
            Self::Dsfc => "dsfc",
            Self::Ekf => "ekf",
            Self::Ukf => "ukf",
            Self::Srukf => "srukf",
        }
    }

    /// A filter over a model (EKF, UKF, SR-UKF) rather than a regression `y = φᵀϑ`.
    pub fn is_model_based(self) -> bool {
        matches!(self, Self::Ekf | Self::Ukf | Self::Srukf)
    }

    /// `ekf`, `ukf` or `srukf`: the methods a non-linear model (the cyclic torque's Eq. 8.2)
    /// takes, as a flag or an argument names them.
    pub fn parse_model_based(s: &str) -> Result<Self, String> {
        match s.parse::<Self>() {
            Ok(m) if m.is_model_based() => Ok(m),
            _ => Err(format!("'{s}': expected ekf, ukf or srukf")),
        }
    }
}

impl std::fmt::Display for MethodName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl std::str::FromStr for MethodName {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|m| m.as_str() == s)
            .ok_or_else(|| {
                let all: Vec<&str> = Self::ALL.iter().map(|m| m.as_str()).collect();
                format!("unknown method '{s}'; the methods are: {}", all.join(", "))
            })
    }
}

/// A run's result as `physid estimate --json` prints it (and the Python package returns it):
/// the final estimates, their standard errors where the data resolve them, the one-step
/// prediction metrics and the timing.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunSummary {
    /// The method.
    pub method: &'static str,
    /// Samples accepted.
    pub samples: usize,
    /// Non-finite samples skipped.
    pub skipped: usize,
    /// Every parameter's final value (fixed ones at their nominal values).
    pub params: BTreeMap<String, f64>,
    /// The free parameters' standard errors; null where the data do not resolve the parameter
    /// or the estimator cannot give one yet.
    pub std_err: BTreeMap<String, Option<f64>>,
    /// The free parameters the data do not resolve ([`crate::resolution`]).
    pub unresolved: Vec<String>,
    /// Per free parameter, the resolution tests.
    pub resolution: BTreeMap<String, ParamResolution>,
    /// NMSE (Eq. 6.4) of the one-step predictions.
    pub nmse: Option<f64>,
    /// NRMSE of the same.
    pub nrmse: Option<f64>,
    /// Fit [%] of the same.
    pub fit_percent: Option<f64>,
    /// Time spent in the updates.
    pub timing: Timing,
    /// Covariance repairs (the unscented filters).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub repairs: Option<u64>,
    /// Bound projections (model-based filters).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub projections: Option<u64>,
}

/// One parameter's resolution ([`Resolution`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ParamResolution {
    /// Both tests passed.
    pub resolved: bool,
    /// `P_jj / P0_jj`.
    pub variance_ratio: f64,
    /// `1/VIF_j`.
    pub independence: f64,
}

/// Time spent in the updates of a run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Timing {
    /// Seconds.
    pub seconds: f64,
    /// Updates per second.
    pub updates_per_s: f64,
}

impl RunSummary {
    /// The summary of `est` after [`feed`] (`fed`), the metrics of its one-step predictions
    /// (`prediction`).
    pub fn new(
        est: &dyn Recursive,
        fed: &FeedSummary,
        prediction: &crate::metrics::Prediction,
    ) -> Self {
        let names: Vec<String> = est.free_names().iter().map(|s| s.to_string()).collect();
        let res = est.resolution();
        let se = est.std_errors();
        Self {
            method: est.method_name(),
            samples: fed.accepted,
            skipped: fed.skipped,
            params: est
                .param_names()
                .iter()
                .cloned()
                .zip(est.estimate_full())
                .collect(),
            std_err: names
                .iter()
                .enumerate()
                .map(|(j, n)| {
                    let s = se.as_ref().map(|s| s[j]).filter(|_| res.resolved[j]);
                    (n.clone(), s)
                })
                .collect(),
            unresolved: res.unresolved().iter().map(|&j| names[j].clone()).collect(),
            resolution: names
                .iter()
                .enumerate()
                .map(|(j, n)| {
                    (
                        n.clone(),
                        ParamResolution {
                            resolved: res.resolved[j],
                            variance_ratio: res.variance_ratio[j],
                            independence: res.independence[j],
                        },
                    )
                })
                .collect(),
            nmse: prediction.nmse(),
            nrmse: prediction.nrmse(),
            fit_percent: prediction.fit_percent(),
            timing: Timing {
                seconds: fed.seconds,
                updates_per_s: fed.accepted as f64 / fed.seconds.max(1e-12),
            },
            repairs: est.repairs(),
            projections: est.projections(),
        }
    }
}
