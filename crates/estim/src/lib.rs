//! # physid-estim — recursive estimators (thesis §5.3)
//!
//! Every estimator here has one shape: it is built from plain data ([`EstimatorConfig`], serde),
//! a [`ParamSet`](physid_core::ParamSet) and a [`FreeSet`](physid_core::FreeSet) view (the
//! parameters it estimates; the others stay at their nominal values), and it is fed one sample at
//! a time by [`LinearEstimator::update`], which returns a [`Step`] or an [`EstimError`] — never a
//! NaN, never a corrupted state, never a heap allocation.
//!
//! * [`linear`] — models linear in the parameters, `y = φᵀϑ + ε` (Eq. 5.14): RLS (Alg. 5.2),
//!   RLS with constant or time-varying forgetting (Alg. 5.3, Eq. 5.24), RLS with vector
//!   forgetting (Alg. 5.4), the Kalman filter for random-walk parameters (Eq. 5.19) and the DSFC
//!   square-root filter (Alg. 5.5).
//! * [`nonlinear`] — models non-linear in the parameters (Eq. 5.29–5.32), any
//!   [`ParamModel`](physid_core::ParamModel): EKF (Alg. 5.6) with exact Jacobians, UKF (Alg. 5.7)
//!   with covariance repair, scaled coordinates and bounds.
//! * [`recursive`] — the one interface all of them implement ([`Recursive`]: update,
//!   estimate, covariance, standard errors, checkpoints), and [`LinearInParams`], a linear
//!   estimator fed with a model's exact gradient.
//! * [`spec`] — an estimator by name with its tuning ([`EstimatorSpec`]), and the one factory
//!   ([`build`], [`build_linear`]) the command line, pipelines, applications and Python use.
//! * [`cov`] — the covariance with its form (P or its Cholesky factor S) in the type, and the
//!   factorisations and the jitter repair the estimators share.
//! * [`tracks`] — an estimator over whole arrays, recording its estimate, standard errors and
//!   prediction errors after every row (the Python package's `run`).
//! * [`metrics`] — NMSE (Eq. 6.4), NRMSE, fit %.
//! * [`workload`] — the standard benchmark workloads (criterion and `physid bench`).
//! * [`detect`] — the relative-error change detector (Eq. 6.3) with a dwell, and the CUSUM test
//!   of the recursive residuals (Brown, Durbin & Evans 1975).
//!
//! This crate knows nothing of engines.

pub mod cov;
pub mod detect;
pub mod error;
pub mod linear;
pub mod metrics;
pub mod nonlinear;
pub mod recursive;
pub mod resolution;
pub mod spec;
pub mod tracks;
pub mod workload;

pub use cov::{Cov, CovForm};
pub use detect::{Alarm, Cusum, CusumLevel, RelativeErrorDetector};
pub use error::EstimError;
pub use linear::{
    CovSpec, EstimatorConfig, GuardAction, LinearEstimator, Method, Step, VfVariant, WindupGuard,
};
pub use nonlinear::{
    CovFactor, Ekf, Frame, FullCov, ModelFilter, NlConfig, NlMethod, NonlinearEstimator,
    SigmaPoints, SigmaWeights, SqrtCov, Ukf,
};
pub use recursive::{
    feed, FeedError, FeedSummary, LinearInParams, Memory, MethodName, OnBad, ParamResolution,
    Recursive, RunSummary, Snapshot, Timing,
};
pub use spec::{build, build_linear, EstimatorSpec};
