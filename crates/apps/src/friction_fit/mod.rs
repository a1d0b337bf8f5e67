//! Application 2 — adaptive characterisation of engine friction (thesis §7.3, SPEC §8).
//!
//! 1. **Cycle means** from a motored recording on a crank-angle basis (a time-basis recording is
//!    first resampled to one sample per crank degree from its engine encoder and TDC marker):
//!    speed N, manifold pressure p_int, ambient pressure p_atm, oil temperature T_oil and the
//!    motoring torque — `−torque_engine` (the engine's load cell) or `+torque_shaft` (the
//!    in-line transducer) — averaged over each 720° cycle. The crank-angle mean of a torque is
//!    the cycle's work over 4π, so the gas torque contributes exactly its pumping work: the
//!    motoring torque is the *total* friction the regression form models, pumping (c17 … c20)
//!    included, as the thesis's characterisation has it. A cycle whose speed changes by more than
//!    [`FrictionFitConfig::max_speed_change`] between its first and last sample is skipped (its
//!    mean carries the inertia torque J·α), and so is one whose mean manifold pressure moved by
//!    more than [`FrictionFitConfig::max_pressure_change`] from a neighbouring cycle's (the
//!    manifold filling or emptying after a throttle step is not quasi-steady).
//! 2. **Identifiability** of c1 … c20 on those cycles (Alg. 5.1 with the thesis's scaling
//!    `∂τ/∂c_i · c_i0/τ0`, Eq. 7.10): the estimable subset, ranked (Table 7.3).
//! 3. **DSFC** (Alg. 5.5) over the estimable subset from the nominal coefficients, the rest
//!    fixed (§7.3). It estimates relative deviations `x` with `c = c0·(1 + x)`, `x0 = 0`,
//!    `S0 = s0·I` (the thesis's `√100·I`): one covariance scale for coefficients that span
//!    1e-10 … 1e5. Forgetting λ (default 1: the engine's friction is characterised, not tracked).
//! 4. **Prediction error over time**: the one-step-ahead prediction `ψᵀ c(t−1)` — each cycle is
//!    predicted before the estimator sees it — against the measured cycle mean, and against
//!    the simulated truth when the recording carries it.
//!
//! Here: the configuration. `cycles.rs`: step 1; `stage.rs`: steps 2–4 as a stream stage;
//! `file.rs`: the file verb over it; `result.rs`: the result, the presets, the JSON.

use crate::acquisition::{from_first_marker, to_crank_angle, AcquisitionOptions, TDC_MARKER};
use crate::error::AppError;
use crate::stage::{Dropout, DropoutLog, Sink, Stage};
use physid_core::{Basis, FreeSet, ParamSet, Recording};
use physid_estim::metrics::nmse;
use physid_estim::{build_linear, CovSpec, EstimatorSpec, LinearEstimator, MethodName};
use physid_ident::{analyse, Cutoff, Data, IdentConfig, RankedParam, Selection};
use physid_models::friction::{
    Design, FrictionRegression, OperatingPoint, Settings, REGRESSION_PARAMS,
};
use physid_signal::cycles::{CycleStream, CycleSummary};
use serde::Serialize;
use std::collections::BTreeMap;

mod cycles;
mod file;
mod result;
mod stage;

pub use cycles::*;
pub use file::*;
pub use result::*;
pub use stage::*;

/// Where the motoring torque comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TorqueSource {
    /// `−torque_engine`: the engine torque load cell (negative when motored).
    Engine,
    /// `+torque_shaft`: the in-line shaft torque transducer (dynamometer into the engine).
    Shaft,
}

impl TorqueSource {
    /// Parse `engine|shaft`.
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "engine" => Some(Self::Engine),
            "shaft" => Some(Self::Shaft),
            _ => None,
        }
    }

    fn channel(self) -> (&'static str, f64) {
        match self {
            Self::Engine => ("torque_engine", -1.0),
            Self::Shaft => ("torque_shaft", 1.0),
        }
    }
}

/// How to fit.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct FrictionFitConfig {
    /// The engine's design (mm) for the regressors.
    pub design: Design<f64>,
    /// Its discrete settings (oil, valvetrain, counts, model variant).
    pub settings: Settings,
    /// Motoring-torque channel.
    pub source: TorqueSource,
    /// How many of the ranked coefficients to estimate.
    #[serde(with = "physid_ident::SelectionData")]
    pub selection: Selection,
    /// The coefficients to estimate, when chosen beforehand (a designed test's, `physid
    /// design --app friction`): these instead of the ranked estimable subset, which is still
    /// reported.
    #[serde(default)]
    pub estimate: Option<Vec<String>>,
    /// `S0 = s0·I` in relative coordinates (thesis: √100 = 10).
    pub s0: f64,
    /// DSFC forgetting factor λ ∈ (0, 1].
    pub lambda: f64,
    /// Skip cycles whose relative speed change first → last sample exceeds this.
    pub max_speed_change: f64,
    /// Skip cycles whose mean manifold pressure differs from the previous or the next cycle's
    /// by more than this (relative): the manifold filling or emptying after a throttle step is not the
    /// quasi-steady state the mean-value model describes.
    pub max_pressure_change: f64,
    /// Start-up transient excluded from the "after the transient" error [s from the first
    /// cycle used].
    pub transient_s: f64,
    /// Ambient pressure [kPa] when the recording has no `p_atm` channel.
    pub p_atm_kpa: Option<f64>,
}

impl FrictionFitConfig {
    /// The thesis's settings (§7.3) for an engine: motoring torque from the load cell, the
    /// repeat cut-off, `S0 = 10·I`, λ = 1, cycles steady within 1 % in speed and manifold
    /// pressure, 5 s start-up transient.
    pub fn new(design: Design<f64>, settings: Settings) -> Self {
        Self {
            design,
            settings,
            source: TorqueSource::Engine,
            selection: Selection::Rule(Cutoff::Repeat),
            estimate: None,
            s0: 10.0,
            lambda: 1.0,
            max_speed_change: 0.01,
            max_pressure_change: 0.01,
            transient_s: 5.0,
            p_atm_kpa: None,
        }
    }
}
