//! What the live twin reports: a window's estimates and residuals, and its alarms.

use serde::Serialize;

/// What the twin reports each window.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TwinWindow {
    /// The window's end [s] (stream time).
    pub t_s: f64,
    /// The adapted parameters' values after the window, by path.
    pub params: Vec<(String, f64)>,
    /// Their window standard errors (NaN: frozen, or before the noise is known).
    pub std_err: Vec<f64>,
    /// Those frozen in this window.
    pub frozen: Vec<String>,
    /// Each channel's residual RMS over the window, in units of its noise (NaN before the noise
    /// is known): `(channel, value)`.
    pub residual: Vec<(String, f64)>,
    /// Each channel's mean over the window, measured [its unit] …
    pub measured: Vec<(String, f64)>,
    /// … and the twin's: measured against the twin, channel by channel.
    pub twin: Vec<(String, f64)>,
}

/// An alarm: a parameter left its calibrated value.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TwinAlarm {
    /// The parameter (its path).
    pub param: String,
    /// When raised [s].
    pub t_s: f64,
    /// When it left its band [s].
    pub t_start_s: f64,
    /// Its change from the calibrated value (−0.2: fell 20 %) as estimated when raised — on the
    /// residual's alarm the jump's linearised size from its first window (K −20 %: −18 % at a
    /// window's start, −29 % inside one); the `twin` windows track it on.
    pub change: f64,
}

/// The live twin's outputs.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub enum TwinOut {
    /// A window.
    Window(TwinWindow),
    /// An alarm.
    Alarm(TwinAlarm),
}
