//! Application 1 — coupling-shaft health monitoring (thesis ch. 6, SPEC §7).
//!
//! `τ_sh = K·Δθ + B·Δω + τ_0` (Eq. 6.1), `Δθ = θ_dy − θ_en`, `Δω = ω_dy − ω_en`, with the torque
//! offset `τ_0` absorbing the encoders' unknown zero offset (SPEC §7). The three signals are
//! zero-phase low-pass filtered, decimated to the estimator's rate, and fed to a recursive
//! estimator (RLS, vector-forgetting RLS or DSFC; λ = 0.98 as in the thesis); the relative error
//! of each estimate from its healthy value (Eq. 6.3) raises an alarm when it stays beyond a
//! bound for a dwell — and names the parameter that moved (isolation).
//!
//! Here: the configuration, the estimator's choice and the results. By concern: `stage.rs`
//! (the stream stage), `glitch.rs` (the steps no shaft makes, taken out before the low-pass),
//! `dropout.rs` (samples that are not numbers, held and taken out likewise), `file.rs` (the file verb over it), `summary.rs` (the JSON); every public item is
//! re-exported here.

use crate::acquisition::{on_time_basis, uniform_step, StepCheck};
use crate::error::AppError;
use crate::excitation::{Steering, SupervisorConfig, SupervisorError};
use crate::stage::{Sink, Stage};
use physid_core::{Basis, ParamSet, Recording};
use physid_estim::{
    build_linear, CovSpec, EstimatorSpec, LinearEstimator, MethodName, RelativeErrorDetector,
    VfVariant,
};
use physid_models::shaft::{Shaft, NOMINAL};
use physid_signal::filter::{butter, Band, Sos};
use physid_signal::integrity::NOMINAL_SAMPLES;
use physid_signal::speed_angle::SpeedAngle;
use physid_signal::stream::{settling_length, ZeroPhaseStream};
use serde::Serialize;
use std::collections::VecDeque;

mod dropout;
mod file;
mod glitch;
mod stage;
mod summary;

pub use file::*;
pub use glitch::*;
pub use stage::*;
pub use summary::*;

/// The estimator.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MonitorMethod {
    /// Recursive least squares with exponential forgetting λ (`rlsf`, as in `physid estimate`;
    /// `rls` was its name here before the one vocabulary of docs/cli.md and is still read).
    #[serde(alias = "rls")]
    Rlsf,
    /// Vector forgetting: λ on K and B, 1 on the offset.
    Rlsvf,
    /// The square-root form (Alg. 5.5).
    Dsfc,
}

impl MonitorMethod {
    /// Parse `rlsf|rlsvf|dsfc` (and `rls`, the old name of `rlsf` here: see
    /// [`MonitorMethod::is_old_name`]).
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "rlsf" | "rls" => Some(Self::Rlsf),
            "rlsvf" => Some(Self::Rlsvf),
            "dsfc" => Some(Self::Dsfc),
            _ => None,
        }
    }

    /// `rls` meant RLS *with* forgetting in the shaft monitor, but RLS without it in
    /// `physid estimate`: it is still taken as `rlsf` for this release, with a warning.
    pub fn is_old_name(s: &str) -> bool {
        s == "rls"
    }

    /// The method in the one vocabulary of the estimators.
    pub fn method(self) -> MethodName {
        match self {
            Self::Rlsf => MethodName::Rlsf,
            Self::Rlsvf => MethodName::Rlsvf,
            Self::Dsfc => MethodName::Dsfc,
        }
    }

    /// The name (`rlsf`, `rlsvf`, `dsfc`).
    pub fn name(self) -> &'static str {
        self.method().as_str()
    }
}

impl std::str::FromStr for MonitorMethod {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::parse(s).ok_or_else(|| format!("'{s}': expected rlsf, rlsvf or dsfc"))
    }
}

/// How to monitor.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct MonitorConfig {
    /// Estimator.
    pub method: MonitorMethod,
    /// Forgetting factor.
    pub lambda: f64,
    /// `P0 = c·I`.
    pub p0: f64,
    /// Healthy K [N·m/rad] and B [N·m·s/rad]: the detector's reference.
    pub healthy: PerParam,
    /// Initial estimates of K, B, τ0 (the thesis's experiments start from 0; its fault
    /// simulations from the healthy values).
    pub theta0: ShaftParams,
    /// Relative-error bound (Eq. 6.3).
    pub bound: f64,
    /// Samples beyond the bound before an alarm.
    pub dwell: u64,
    /// Zero-phase low-pass cut-off [Hz] before estimation.
    pub cutoff_hz: f64,
    /// The estimator's sample rate [Hz] (the filtered signals are decimated to it).
    pub rate_hz: f64,
    /// Seconds of data before the detector starts (the estimator's start-up).
    pub settle_s: f64,
    /// Freeze K or B while the data no longer resolve them (the excitation supervisor, thesis
    /// §9.2: on-line identifiability over the last ≈ 0.1 s), release them when they do again.
    pub supervise: bool,
}

impl Default for MonitorConfig {
    /// λ = 0.98, ϑ0 = 0, P0 = 1000·I (thesis ch. 6), healthy = Table 6.1's yellow spider,
    /// ±10 %, 0.1 s dwell, 500 Hz low-pass, 2 kHz estimator rate, 1 s settling.
    fn default() -> Self {
        Self {
            method: MonitorMethod::Rlsf,
            lambda: 0.98,
            p0: 1000.0,
            healthy: PerParam {
                k: NOMINAL[0],
                b: NOMINAL[1],
            },
            theta0: ShaftParams {
                k: 0.0,
                b: 0.0,
                tau0: 0.0,
            },
            bound: 0.1,
            dwell: 200,
            cutoff_hz: 500.0,
            rate_hz: 2000.0,
            settle_s: 1.0,
            supervise: false,
        }
    }
}

/// The coupling shaft's parameters by name (JSON: `K`, `B`, `tau0`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct ShaftParams {
    /// Stiffness K [N·m/rad].
    #[serde(rename = "K")]
    pub k: f64,
    /// Damping B [N·m·s/rad].
    #[serde(rename = "B")]
    pub b: f64,
    /// Encoder-offset torque τ0 [N·m].
    pub tau0: f64,
}

/// A figure per monitored parameter (JSON: `K`, `B`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct PerParam {
    /// For K.
    #[serde(rename = "K", deserialize_with = "physid_core::nan_null::f64")]
    pub k: f64,
    /// For B.
    #[serde(rename = "B", deserialize_with = "physid_core::nan_null::f64")]
    pub b: f64,
}

/// A raised alarm, in time.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ShaftAlarm {
    /// `K` or `B`.
    pub param: String,
    /// When the relative error first left the bound [s].
    pub t_start_s: f64,
    /// When the dwell completed [s].
    pub t_raised_s: f64,
    /// The relative error then (Eq. 6.3: `(ϑ_healthy − ϑ̂)/ϑ_healthy`, positive when the
    /// estimate fell).
    pub relative_error: f64,
    /// The estimate's change from its healthy value then, `(ϑ̂ − ϑ_healthy)/ϑ_healthy =
    /// −relative_error` (K fell 12 % → −0.12): how a person reads it.
    pub change: f64,
}

/// The monitor's result.
#[derive(Debug, Clone, Serialize)]
pub struct ShaftMonitor {
    /// The method.
    pub method: &'static str,
    /// The recording's sample rate [Hz].
    pub input_rate_hz: f64,
    /// The zero-phase low-pass cut-off applied before estimation [Hz] (`None`: the cut-off was
    /// at or above the Nyquist frequency, and the signals went in unfiltered).
    pub lowpass_hz: Option<f64>,
    /// One input sample in `every` goes to the estimator.
    pub every: usize,
    /// Estimator sample times [s].
    pub t: Vec<f64>,
    /// K estimates.
    pub k: Vec<f64>,
    /// B estimates.
    pub b: Vec<f64>,
    /// Offset estimates [N·m].
    pub tau0: Vec<f64>,
    /// Standard errors of K and B at each sample.
    pub std_err: Vec<[f64; 2]>,
    /// Final K, B, τ0.
    pub final_estimate: ShaftParams,
    /// Final standard errors of K, B, τ0 (NaN before they can be estimated, and for those
    /// the data did not resolve).
    pub final_std_err: ShaftParams,
    /// The parameters the data did not resolve (their variance did not halve from P0): their
    /// final values are the estimator's start, not the shaft's.
    pub unresolved: Vec<&'static str>,
    /// What in the recording makes the estimates suspect: a speed that is not its angle's
    /// derivative ([`physid_signal::speed_angle`]: a units row that lies).
    pub warnings: Vec<String>,
    /// Alarms.
    pub alarms: Vec<ShaftAlarm>,
    /// True K and B over time, when the recording carries them (simulated data).
    pub truth: Option<(Vec<f64>, Vec<f64>)>,
    /// NMSE of the K and B tracks against the truth after settling (thesis Fig. 6.9).
    pub nmse: Option<PerParam>,
    /// First time after which the estimates stay within ±5 % of the truth [s], per parameter.
    pub within_5pct_s: Option<[Option<f64>; 2]>,
    /// With the excitation supervisor: how long K and B were frozen [s] (estimator samples
    /// frozen × the estimator's step).
    pub frozen_s: Option<PerParam>,
    /// With the excitation supervisor: K, B and τ0 frozen or not at each estimator sample.
    pub frozen: Vec<[bool; 3]>,
}

/// How long the excitation supervisor must hold a parameter frozen (or free) before the stage
/// reports the change [s]: longer than an engine cycle above 500 rpm, whose quiet part (no
/// compression near bottom dead centre) the estimator's own short memory (λ = 0.98 at 2 kHz:
/// 25 ms) cannot resolve K and B in — the estimator freezes them there (no wind-up), but that is
/// not a loss of excitation worth telling.
pub const FREEZE_HOLD_S: f64 = 0.25;

/// Samples per chunk when a file is streamed through the stage.
const FILE_CHUNK: usize = 4096;
