//! The fit's result: each parameter's estimate and interval, per TDC and fused
//! ([`CompressionFit`]).

use super::*;

/// One parameter's result.
#[derive(Debug, Clone, Serialize)]
pub struct ParamEstimate {
    /// Name (as [`PARAMS`]).
    pub name: String,
    /// Unit (`P`: the pressure channel's).
    pub unit: String,
    /// What it is.
    pub description: String,
    /// `fitted`, `held` (given with `--set`) or `unresolved` (the data do not resolve it: held
    /// at its starting value).
    pub status: &'static str,
    /// The value: fitted to all the events at once when fitted.
    pub value: f64,
    /// Its standard error (fitted only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub std_err: Option<f64>,
    /// 95 % interval (fitted only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ci95: Option<(f64, f64)>,
    /// The standard deviation of the per-event estimates over √(events): the spread's own
    /// standard error of the mean (fitted, two events or more).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub between_events_std_err: Option<f64>,
}

/// One event's fit.
#[derive(Debug, Clone, Serialize)]
pub struct EventFit {
    /// The cycle starting at this TDC.
    pub cycle: i64,
    /// Time at TDC [s].
    pub t_s: f64,
    /// Speed [rpm].
    pub rpm: f64,
    /// The fitted parameters' values (in [`CompressionFit::fitted`] order).
    pub values: Vec<f64>,
    /// Their standard errors.
    pub std_err: Vec<f64>,
    /// The recursive estimate after this event (Gauss–Newton over the events so far).
    pub recursive: Vec<f64>,
    /// Its standard errors.
    pub recursive_std_err: Vec<f64>,
    /// RMS of the fit's residual [the channel's unit].
    pub rms_residual: f64,
}

/// One TDC's pressure, measured and fitted.
#[derive(Debug, Clone, Serialize)]
pub struct Trace {
    /// The cycle starting at this TDC.
    pub cycle: i64,
    /// Angles [deg ATDC on the recording].
    pub atdc: Vec<f64>,
    /// The measured pressure.
    pub measured: Vec<f64>,
    /// The model with the estimate.
    pub fitted: Vec<f64>,
}

/// A pair of parameters that trade off in the fit of all of them.
#[derive(Debug, Clone, Serialize)]
pub struct Confounded {
    /// One …
    pub a: String,
    /// … and the other.
    pub b: String,
    /// Their estimates' correlation.
    pub correlation: f64,
}

/// The result of [`compression_fit`].
#[derive(Debug, Clone, Serialize)]
pub struct CompressionFit {
    /// The pressure channel …
    pub channel: String,
    /// … and its unit.
    pub unit: String,
    /// The window [deg ATDC].
    pub window_deg: (f64, f64),
    /// The starting values, every parameter in [`PARAMS`] order.
    pub start: Vec<f64>,
    /// The identifiability ranking of the parameters not held, at the fit of all of them.
    pub ranking: Vec<RankedParam>,
    /// The Wu criterion `J_K` per K, when it decided.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wu_j: Option<Vec<f64>>,
    /// Pairs whose estimates correlate beyond 0.95 in the fit of all the parameters not held
    /// (or `None` when their Fisher information is singular).
    pub confounded: Option<Vec<Confounded>>,
    /// Collinearity index of the fitted set (Brun et al.).
    pub collinearity: f64,
    /// The parameters fitted, in [`PARAMS`] order.
    pub fitted: Vec<String>,
    /// Every parameter's result, in [`PARAMS`] order.
    pub estimates: Vec<ParamEstimate>,
    /// Per event.
    pub events: Vec<EventFit>,
    /// Where the fitted trace peaks [deg ATDC, true]: before TDC by the loss angle.
    pub peak_deg: Option<f64>,
    /// RMS residual over all events [the channel's unit].
    pub rms_residual: f64,
    /// The last TDC fitted: measured and fitted pressure (the estimate).
    pub trace: Trace,
    /// Fitted parameters outside where they are physical ([`CompressionConfig::plausible`]),
    /// each with the reason: a fit that is not the engine's (the trace does not resolve them,
    /// or the cycles are not motored).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub implausible: Vec<String>,
    /// What was left out and why.
    pub notes: Vec<String>,
}

impl CompressionFit {
    /// A parameter's result by name.
    pub fn get(&self, name: &str) -> Option<&ParamEstimate> {
        self.estimates.iter().find(|e| e.name == name)
    }

    /// Every parameter's value, in [`PARAMS`] order.
    pub fn theta(&self) -> Vec<f64> {
        self.estimates.iter().map(|e| e.value).collect()
    }
}
