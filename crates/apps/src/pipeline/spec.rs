//! A pipeline file's sections — the model, the data, the identifiability cutoff, the
//! estimator, the objective — as they are read, with their defaults.

use physid_estim::{metrics, MethodName};
use physid_ident::{Cutoff, Scaling, Selection};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// The model section.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelSpec {
    /// A built-in model's name.
    pub builtin: Option<String>,
    /// Or a formula in the expression language.
    pub expr: Option<String>,
    /// Nominal parameter values (all of them for a formula; overrides for a built-in).
    #[serde(default)]
    pub params: BTreeMap<String, f64>,
    /// The measured output channel.
    pub output: String,
    /// Model input → `CHANNEL` or `CHANNEL:UNIT` (converted to that unit, e.g. `T_oil:degC`),
    /// where they differ.
    #[serde(default)]
    pub inputs: BTreeMap<String, String>,
    /// Parameters known by design, never estimated.
    #[serde(default)]
    pub fixed: Vec<String>,
    /// A formula's parameters' units, for the report (a built-in model's are known).
    #[serde(default)]
    pub units: BTreeMap<String, String>,
    /// A formula's parameters' one-line meanings, for the report.
    #[serde(default)]
    pub descriptions: BTreeMap<String, String>,
}

/// The data section: a file, or a scenario of the virtual test cell.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DataSpec {
    /// A recording (CSV, Parquet, MDF4); a relative path is relative to the pipeline file.
    pub file: Option<PathBuf>,
    /// Or a named scenario, or a scenario TOML file (relative to the pipeline file).
    pub scenario: Option<String>,
    /// Simulated duration [s] (default: the scenario's).
    pub duration: Option<f64>,
    /// `crank` (one sample per crank degree) or `time`.
    pub basis: Option<DataBasis>,
    /// Sample rate of a time basis [Hz].
    pub rate_hz: Option<f64>,
    /// Cell parameters for the simulation.
    #[serde(default)]
    pub set: BTreeMap<String, f64>,
    /// Faults for the simulation (`PATH=VALUE@T[+RAMP]`).
    #[serde(default)]
    pub faults: Vec<String>,
}

/// The basis a simulated recording is sampled on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DataBasis {
    /// One sample per crank degree.
    Crank,
    /// `rate_hz` samples per second.
    Time,
}

/// The simulated recording's sample rate on a time basis when `rate_hz` is not given [Hz].
pub(super) const DEFAULT_RATE_HZ: f64 = 10_000.0;

/// The identifiability section.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IdentSpec {
    /// `repeat`, `wu`, `rel:FRACTION` or an absolute residual.
    #[serde(default = "default_cutoff")]
    pub cutoff: Selection,
    /// `thesis`, `sigma` or `none`.
    #[serde(default)]
    pub scaling: Scaling,
}

fn default_cutoff() -> Selection {
    Selection::Rule(Cutoff::Repeat)
}

impl Default for IdentSpec {
    fn default() -> Self {
        Self {
            cutoff: default_cutoff(),
            scaling: Scaling::default(),
        }
    }
}

/// The estimator section.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EstimatorSection {
    /// `ekf`, `ukf`, `srukf` (any model) or `rls`, `rlsf`, `rlsvf`, `kf`, `dsfc` (linear in the
    /// parameters).
    #[serde(default = "default_method")]
    pub method: MethodName,
    /// `P0 = p0·I` (scaled coordinates for the non-linear filters; physical for the linear).
    pub p0: Option<f64>,
    /// Measurement-noise variance R2 of the Kalman filters, kf, ekf, ukf, srukf (default: the
    /// batch fit's residual variance).
    pub r2: Option<f64>,
    /// Forgetting factor of RLSF, RLSVF (the same for every parameter) and DSFC.
    pub lambda: Option<f64>,
}

fn default_method() -> MethodName {
    MethodName::Ukf
}

impl Default for EstimatorSection {
    fn default() -> Self {
        Self {
            method: default_method(),
            p0: None,
            r2: None,
            lambda: None,
        }
    }
}

/// The objective section.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectiveSpec {
    /// The prediction must be within this many per cent.
    #[serde(default = "five")]
    pub prediction_within_pct: f64,
    /// `nrmse` or `max_relative`.
    #[serde(default)]
    pub metric: Metric,
    /// Start-up transient left out [s].
    #[serde(default)]
    pub after_s: f64,
}

fn five() -> f64 {
    5.0
}
/// How the objective measures the one-step-ahead prediction (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Metric {
    /// `100·rms(y − ŷ)/rms(y)` ([`metrics::nrmse`] in per cent).
    #[default]
    Nrmse,
    /// `max 100·|y − ŷ|/|y|`.
    MaxRelative,
}

impl Metric {
    /// The name as the file spells it.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Nrmse => "nrmse",
            Self::MaxRelative => "max_relative",
        }
    }

    /// The metric of `y` predicted by `yhat`, in per cent ([`metrics`]); NaN where it is
    /// undefined (no samples, an all-zero signal).
    pub fn percent(self, y: &[f64], yhat: &[f64]) -> f64 {
        metrics::Prediction::of(y, yhat).map_or(f64::NAN, |m| self.of(&m))
    }

    /// The metric of predictions accumulated a sample at a time, in per cent; NaN where it is
    /// undefined.
    pub fn of(self, m: &metrics::Prediction) -> f64 {
        match self {
            Self::Nrmse => m.nrmse().map_or(f64::NAN, |v| 100.0 * v),
            Self::MaxRelative => m.max_relative_percent().unwrap_or(f64::NAN),
        }
    }
}

impl Default for ObjectiveSpec {
    fn default() -> Self {
        Self {
            prediction_within_pct: 5.0,
            metric: Metric::default(),
            after_s: 0.0,
        }
    }
}

impl std::fmt::Display for Metric {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}
