//! How the live twin runs: its configuration and defaults.

use crate::error::AppError;
use physid_sim::params::CellParams;
use physid_sim::run::LIVE_PARAMS;
use serde::{Deserialize, Serialize};

/// The channels a live twin compares by default (those the stream has): the speeds, the shaft
/// torque and the manifold pressure — the cylinder pressure's steep flanks make a time-basis
/// comparison a comparison of the crank angle's alignment.
pub const LIVE_CHANNELS: &[&str] = &["omega_en", "omega_dy", "torque_shaft", "p_int"];

/// A channel's noise is taken as at least this fraction of its own spread over the noise
/// windows (the twin's model error: a noiseless channel is not trusted to the last digit).
pub const MODEL_FLOOR: f64 = 1e-2;

/// How the live twin runs.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct TwinConfig {
    /// The calibrated cell, as `(path, value)` settings over the built-in cell.
    pub set: Vec<(String, f64)>,
    /// The parameters adapted (of [`LIVE_PARAMS`]).
    pub adapt: Vec<String>,
    /// The channels compared (default [`LIVE_CHANNELS`], those the stream has).
    pub channels: Vec<String>,
    /// The firing TDC's angle on the stream's `theta_en` [rad] (the twin starts there).
    pub theta_tdc: f64,
    /// Time from the stream's start before the twin is compared [s] (its own transients).
    pub warmup_s: f64,
    /// One adaptation per this much time [s].
    pub window_s: f64,
    /// Windows after the warm-up whose residual gives each channel's noise.
    pub sigma_windows: usize,
    /// The copies' relative parameter step.
    pub rel_step: f64,
    /// A channel's residual band, in its noise's units: beyond it, only the parameter that
    /// alone explains most of the residual moves, and the residual's alarm watches.
    pub isolate_above: f64,
    /// The twin and its copies are turned to the stream's crank angle when they are further
    /// apart than this at a window's end [rad].
    pub phase_tolerance: f64,
    /// After the twin takes new values, this long before it is compared again [s] (the
    /// switch's transient).
    pub settle_s: f64,
    /// Forgetting per window of the epoch's information.
    pub forgetting: f64,
    /// The twin takes the estimate when a parameter has moved beyond this fraction (and 4 of
    /// its standard errors).
    pub rebase_change: f64,
    /// A parameter is frozen for a window whose relative standard error exceeds this.
    pub max_window_rel_se: f64,
    /// An alarm needs a change from the calibrated value beyond this fraction …
    pub alarm_change: f64,
    /// … and beyond this many window standard errors …
    pub alarm_sigmas: f64,
    /// … for this many windows in a row (also the residual's: this many beyond its band).
    pub dwell: usize,
}

impl TwinConfig {
    /// The twin of the cell `set`, adapting `adapt`, with the defaults: a 1 s warm-up, windows
    /// of 0.05 s, the noise from the 4 after the warm-up, copies 1e-3 apart, 0.05 s of settling
    /// after each update, forgetting 0.7 per window, an update when an estimate moved 1 %,
    /// frozen above 5 %; a residual band of 5σ; alarms beyond 10 % (the shaft monitor's bound)
    /// and 4σ settled for 2 windows, or on a residual beyond its band for 2 windows.
    pub fn new(set: Vec<(String, f64)>, adapt: Vec<String>) -> Self {
        Self {
            set,
            adapt,
            channels: LIVE_CHANNELS.iter().map(|s| s.to_string()).collect(),
            theta_tdc: 0.0,
            warmup_s: 1.0,
            window_s: 0.05,
            sigma_windows: 4,
            rel_step: 1e-3,
            phase_tolerance: 1e-3,
            isolate_above: 5.0,
            settle_s: 0.05,
            forgetting: 0.7,
            rebase_change: 0.01,
            max_window_rel_se: 0.05,
            alarm_change: 0.1,
            alarm_sigmas: 4.0,
            dwell: 2,
        }
    }

    /// The calibrated cell.
    pub(super) fn cell(&self) -> Result<CellParams, AppError> {
        let mut c = CellParams::default();
        for (k, v) in &self.set {
            c.set(k, *v)?;
        }
        Ok(c)
    }

    /// Check the settings.
    pub fn validate(&self) -> Result<(), AppError> {
        self.cell()?;
        for p in &self.adapt {
            if !LIVE_PARAMS.contains(&p.as_str()) || p == "engine.t_oil" {
                return Err(AppError::Invalid(format!(
                    "twin: '{p}' cannot be adapted on the stream; the twin adapts shaft.k, shaft.b, engine.m_rec, engine.friction_scale (the others fix the cell when it is built)"
                )));
            }
        }
        for (what, v) in [
            ("window", self.window_s),
            ("warm-up", self.warmup_s),
            ("step", self.rel_step),
            ("frozen above", self.max_window_rel_se),
            ("alarm change", self.alarm_change),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(AppError::Invalid(format!(
                    "twin: {what} {}: expected > 0",
                    physid_core::Num(v)
                )));
            }
        }
        Ok(())
    }
}
