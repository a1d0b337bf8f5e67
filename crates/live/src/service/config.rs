//! What the live service is told: its sources' stages and their settings, the panel's feed.

use super::*;

/// How the live loop runs.
#[derive(Debug, Clone)]
pub struct LiveConfig {
    /// The shaft monitor's settings.
    pub monitor: MonitorConfig,
    /// At most one estimate event per this much recording time [s] (the last estimate is always
    /// sent at the end).
    pub estimate_every_s: f64,
    /// How fast against the wall clock.
    pub pace: Pace,
    /// The angle of a firing TDC [rad] on `theta_en` (cycles start there and every 4π; the
    /// virtual cell's is 0).
    pub theta_tdc: f64,
    /// The panel's extras: time traces at this rate [Hz] and the cycles' curves at this
    /// crank-angle step [deg]; `None` headless.
    pub panel: Option<PanelFeed>,
    /// Where `record` controls write their logs.
    pub log_dir: PathBuf,
    /// The friction characterisation on the stream (a motored engine), when asked for.
    pub friction: Option<FrictionLive>,
    /// The cyclic-torque estimation on the stream, when asked for.
    pub torque: Option<TorqueLive>,
    /// The combustion analysis on the stream, when asked for.
    pub combustion: Option<CombustionLive>,
    /// The self-calibrated twin beside the stream, when asked for (`theta_tdc` is the run's).
    pub twin: Option<TwinConfig>,
    /// Set (by a SIGINT or SIGTERM handler) to end the run after the current chunk, as a
    /// `stop` control does: the stages finish and a log being written is closed.
    pub stop: Option<Arc<AtomicBool>>,
}

/// The combustion analysis's settings live (`physid cycles`' per cycle, on the stream).
#[derive(Debug, Clone)]
pub struct CombustionLive {
    /// The cylinder-pressure channel.
    pub channel: String,
    /// The geometry, pegging, heat release and knock.
    pub settings: PerCycleSettings,
    /// The crank-angle grid the pressure is taken onto [deg].
    pub step_deg: f64,
}

/// The cyclic-torque estimation's settings live.
#[derive(Debug, Clone)]
pub struct TorqueLive {
    /// The fit's settings (nominal values, fixed parameters, filter, tracking).
    pub fit: TorqueFitConfig,
    /// Choose the estimable parameters after this many cycles (at least 1); a replay that ends
    /// sooner chooses on all of it at its end, as `physid torque fit` does.
    pub select_after_cycles: usize,
}

/// The friction characterisation's settings live.
#[derive(Debug, Clone)]
pub struct FrictionLive {
    /// The fit's settings (model, torque source, estimator).
    pub fit: FrictionFitConfig,
    /// Choose the estimable coefficients after this many steady cycles (at least 20); a replay
    /// that ends sooner chooses on all of them at its end, as `physid friction fit` does.
    pub select_after: usize,
}

/// What the panel gets beyond the headless events.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PanelFeed {
    /// Time traces: bin means at this rate [Hz].
    pub trace_hz: f64,
    /// Recording time per trace event [s].
    pub trace_every_s: f64,
    /// Crank-angle step of the cycles' curves [deg].
    pub curve_step_deg: f64,
}

impl Default for PanelFeed {
    /// 200 Hz traces sent every 0.05 s; curves every 2°.
    fn default() -> Self {
        Self {
            trace_hz: 200.0,
            trace_every_s: 0.05,
            curve_step_deg: 2.0,
        }
    }
}

impl Default for LiveConfig {
    /// The monitor's defaults, 10 estimate events per second, as fast as it can, TDC at 0,
    /// headless, logs in `physid-logs`.
    fn default() -> Self {
        Self {
            monitor: MonitorConfig::default(),
            estimate_every_s: 0.1,
            pace: Pace::Max,
            theta_tdc: 0.0,
            panel: None,
            log_dir: PathBuf::from("physid-logs"),
            friction: None,
            torque: None,
            combustion: None,
            twin: None,
            stop: None,
        }
    }
}

/// The channels whose cycle statistics are reported (those the source has).
pub const CYCLE_CHANNELS: [&str; 5] = [
    "omega_en",
    "torque_engine",
    "torque_shaft",
    "p_cyl",
    "p_int",
];

/// The most bytes of a client's message an `error` event quotes.
pub const MAX_QUOTED: usize = 300;
