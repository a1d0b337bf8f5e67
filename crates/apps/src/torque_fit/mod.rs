//! Application 3 — cyclic engine torque for end-of-line cold testing (thesis ch. 8, SPEC §9).
//!
//! The model is Eq. 8.2 ([`CyclicTorque`]): indicated, reciprocating and friction torque of a
//! motored engine from θ, ω, α, p_cyl, p_crank and T_oil, one sample per crank degree, with 15
//! parameters (M_rec, b, L, r, δ, c1 … c10).
//!
//! 1. **Identifiability** on the recording at the nominal values (Alg. 5.1, thesis scaling):
//!    which parameters the test supports (Table 8.1). Parameters known by design can be held
//!    out (`fixed`; δ by default — its nominal value is 0, so it has no relative sensitivity).
//!    Eq. 8.2 is invariant under `r → λr, L → λL, b → b/√λ, M_rec → M_rec/λ²`: at most three of
//!    those four are identifiable together, and the analysis finds which.
//! 2. **Estimation** of the estimable subset by EKF, UKF or SR-UKF (Alg. 5.6–5.7) in scaled
//!    coordinates `ϑ = ϑ0·(1 + x)`, the rest fixed at their nominal values. `R2` defaults to the
//!    residual variance of the batch fit of that subset (what the data says the model's error
//!    is), so that the reported ±3σ mean something; a random walk `R1` on chosen parameters
//!    lets the filter track a change (a reciprocating-mass fault).
//! 3. **Prediction quality** before (nominal) and after (final estimates): NMSE as the thesis
//!    defines it (Eq. 6.4 — ill-defined for a torque whose mean is near zero, SPEC §5.3), and
//!    NRMSE.
//!
//! Here: the nominal values and the configuration. `data.rs`: the model's rows and their
//! identifiability; `degrees.rs`: the 1° samples made in passes; `stage.rs`: the filter and the
//! live stage; `file.rs`: the file verb; `result.rs`: the result and its JSON.

use crate::acquisition::{
    first_guess, to_crank_angle, told_or_first, AcquisitionOptions, FirstMarker, MarkerPhase,
    PhaseFrom, TDC_MARKER,
};
pub use crate::cell::cyclic_torque_nominal;
use crate::error::AppError;
use crate::recording_rows::{Column, RecordingRows};
use crate::stage::{Dropout, DropoutLog, Sink, Stage};
use physid_core::{Basis, ParamModel, ParamSet, Recording, Recordings, Reopen};
use physid_estim::metrics::Prediction;
use physid_estim::{CovSpec, EstimatorSpec, MethodName, NonlinearEstimator};
use physid_ident::{
    analyse, fit_subset, Analysis, Cutoff, Data, DataRows, IdentConfig, IdentError, RankedParam,
    Rows, Selection,
};
use physid_io::{ChunkReader, ReadOptions, CHUNK_ROWS};
use physid_models::cyclic_torque::{CyclicTorque, PARAMS};
use physid_signal::cycles::{CycleStream, CycleSummary};
use serde::Serialize;
use std::cell::{Cell, RefCell};
use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::path::Path;

mod data;
mod degrees;
mod file;
mod result;
mod stage;

pub use data::*;
pub use degrees::*;
pub use file::*;
pub use result::*;
pub use stage::*;

/// The relative cut-off of the cyclic-torque ranking: residuals below 1e-6 of the first are
/// at the level of the measured oil temperature's noise (0.1 K on 363 K, squared), which is all
/// that separates the temperature terms of the friction cubic at a constant oil temperature.
pub const TORQUE_CUTOFF: f64 = 1e-6;

/// The finest resolution of a torque measurement, relative to its RMS: the batch fit's
/// residual variance, R2's default, is at least `(R2_FLOOR·RMS)²` (a 24-bit converter's step is
/// 6e-8 of its range). On data the model fits exactly the residual is 0, and a filter told the
/// torque is exact loses its covariance's positive definiteness within samples.
pub const R2_FLOOR: f64 = 1e-7;

/// How to fit.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct TorqueFitConfig {
    /// Initial (nominal) values ϑ0 of the 15 parameters.
    pub nominal: [f64; 15],
    /// Parameters known by design, held out of the analysis and the filter.
    pub fixed: Vec<String>,
    /// How many ranked parameters to estimate.
    #[serde(with = "physid_ident::SelectionData")]
    pub selection: Selection,
    /// The parameters to estimate, when chosen beforehand (a designed test's, `physid torque
    /// fit --estimate`): the selection is then not used and the others are held at their
    /// nominal values; the ranking is still reported.
    #[serde(default)]
    pub estimate: Option<Vec<String>>,
    /// EKF, UKF or SR-UKF (with the thesis's sigma points).
    pub method: MethodName,
    /// `P0 = p0·I` over the scaled coordinates x (relative deviations).
    pub p0: f64,
    /// Measurement-noise variance R2 [N²·m²]; `None` = the batch fit's residual variance (at
    /// least `(R2_FLOOR·RMS of the measured torque)²`).
    pub r2: Option<f64>,
    /// Random-walk variance per sample (scaled coordinates) of chosen parameters, to track a
    /// change; the others are constant.
    pub track: Vec<(String, f64)>,
}

impl TorqueFitConfig {
    /// Defaults: UKF with the thesis's sigma points, δ fixed, the relative cut-off
    /// [`TORQUE_CUTOFF`], `P0 = 0.01·I` (a prior standard deviation of 10 % of each nominal
    /// value: the UKF's sigma points then stay within ±20 % — wider ones can reach a crank
    /// radius longer than the rod, where the slider-crank has no solution), R2 from the batch
    /// fit, no tracking.
    pub fn new(nominal: [f64; 15]) -> Self {
        Self {
            nominal,
            fixed: vec!["delta".into()],
            selection: Selection::Rule(Cutoff::Relative(TORQUE_CUTOFF)),
            estimate: None,
            method: MethodName::Ukf,
            p0: 0.01,
            r2: None,
            track: Vec::new(),
        }
    }

    /// The parameters chosen beforehand ([`estimate`](Self::estimate)) as indices into
    /// [`PARAMS`]: known names, each once, none held by `fixed`, each with a non-zero nominal
    /// value (the filter works in deviations relative to it). `None` when not chosen.
    pub fn chosen(&self) -> Result<Option<Vec<usize>>, AppError> {
        let Some(names) = &self.estimate else {
            return Ok(None);
        };
        if names.is_empty() {
            return Err(AppError::Invalid("no parameter chosen to estimate".into()));
        }
        let mut idx = Vec::with_capacity(names.len());
        for name in names {
            let j = PARAMS.iter().position(|p| p == name).ok_or_else(|| {
                AppError::Invalid(format!(
                    "parameter '{name}': expected one of {}",
                    PARAMS.join(", ")
                ))
            })?;
            if idx.contains(&j) {
                return Err(AppError::Invalid(format!(
                    "parameter '{name}' is chosen twice"
                )));
            }
            if self.nominal[j] == 0.0 {
                return Err(AppError::Invalid(format!(
                    "'{name}' has nominal value 0: scaled coordinates ϑ = ϑ0·(1 + x) cannot move it — give it a non-zero nominal value or leave it out"
                )));
            }
            if self.fixed.contains(name) {
                return Err(AppError::Invalid(format!(
                    "parameter '{name}' is both fixed and chosen to estimate"
                )));
            }
            idx.push(j);
        }
        Ok(Some(idx))
    }
}
