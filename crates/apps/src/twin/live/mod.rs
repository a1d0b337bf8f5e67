//! The twin beside the stream (issue 44; thesis §9.2): the calibrated cell stepped in lock-step
//! with the incoming samples — driven by their speed demand and throttle, started at their
//! crank angle — its outputs compared with the measured ones, its live parameters adapted, and
//! an alarm that names the physical parameter that moved.
//!
//! Beside the twin run copies of it, one per adapted parameter, each with that parameter
//! `1 + rel_step` times larger — from the start of an *epoch* (the twin's values since its last
//! update) on, so that a copy's difference from the twin is the outputs' sensitivity to that
//! parameter as the cell runs with it, not to a change made a moment ago. Each window of
//! [`TwinConfig::window_s`] (after [`TwinConfig::settle_s`] from the epoch's start: the switch
//! to new values has a transient of its own) adds its information `SᵀWS` and score `SᵀWr`
//! (`r = y − ŷ`, `W` each channel's 1/σ², relative units) to the epoch's with forgetting
//! [`TwinConfig::forgetting`]; the estimate is `u·(1 + (SᵀWS)⁻¹SᵀWr)`. A parameter whose
//! standard error exceeds [`TwinConfig::max_window_rel_se`] is frozen (no excitation: no
//! wind-up), the least resolved first. When an estimate has moved by more than
//! [`TwinConfig::rebase_change`] and 4 of its standard errors, a new epoch begins: the twin takes
//! the estimates and the copies start again from it — a Gauss–Newton iteration per epoch.
//!
//! An alarm names the physical parameter that moved, raised by whichever comes first:
//!
//! * **the residual**: a channel's residual beyond [`TwinConfig::isolate_above`] of its noise
//!   for [`TwinConfig::dwell`] windows in a row, and in the first of them a single parameter
//!   whose *jump* alone explains at least half of the window's residual (weighted sum of
//!   squares, `(gⱼ²/Fⱼⱼ)/rᵀWr`) by a change beyond [`TwinConfig::alarm_change`]. The jump's
//!   sensitivities are replayed: the twin is kept as it was at the start and each quarter of
//!   the last two windows, with the stream's inputs since and what was done to it at the
//!   windows' end (turned, given new values); in an excursion's first window a copy of each
//!   snapshot with one parameter `1 + rel_step` times larger is stepped through them again — a
//!   jump at that instant — and the instant and parameter that explain the residual of both
//!   windows best win (a jump placed too early is charged with the response it predicts where
//!   there was none). The twin then takes that jump, and only it. A
//!   sudden change drives a transient (the shaft's torsion rings after K falls) that the
//!   epoch's copies — a change made long ago — do not have. One such alarm per excursion
//!   of the residual, and only after [`TwinConfig::sigma_windows`] windows in a row within its
//!   band (a twin that has not matched the stream is not a residual *leaving* its band). This
//!   is the fast path: a jump is named after `dwell` windows.
//! * **the estimate**: a parameter's estimate more than [`TwinConfig::alarm_change`] (and
//!   [`TwinConfig::alarm_sigmas`] standard errors) from its calibrated value for
//!   [`TwinConfig::dwell`] windows in which it agrees with itself within half that band: a
//!   value the twin has settled at — a drift too slow to leave a residual. While a large
//!   residual is being explained the other parameters take a share of it for a window or two,
//!   each time another; they do not alarm.
//!
//! A parameter alarms again only after its estimate has come back within the band while the
//! residuals are within theirs.
//!
//! The noise of each channel is the twin's residual RMS over the windows after its warm-up
//! ([`TwinConfig::sigma_windows`]; the twin is taken as calibrated then).
//!
//! Only the cell's live parameters ([`LIVE_PARAMS`](physid_sim::run::LIVE_PARAMS): the
//! shaft's K and B, the reciprocating mass, the friction scale) can be adapted: the others fix
//! the engine's geometry and the machine when the cell is built, and stay at their calibrated
//! values.
//!
//! Here: the stage. `window.rs`: each window (the noise, the estimate, the alarms, the
//! epochs); `config.rs`: how it runs; `report.rs`: what it reports; `runs.rs`: the twin and
//! its copies, and the jump's replay.

use crate::error::AppError;
use nalgebra::{DMatrix, DVector};
use physid_core::Recording;
use physid_sim::params::CellParams;
use physid_sim::run::{OutputBasis, Run, RunOptions};
use physid_sim::scenario::{Profile, Scenario};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

mod config;
mod report;
mod runs;
mod window;

pub use config::*;
pub use report::*;
use runs::*;

/// One adapted parameter's alarm state.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
struct Watch {
    /// Windows in a row out of the band, and when the first began.
    out: usize,
    since: f64,
    /// The last changes out of the band (at most the dwell's).
    recent: Vec<f64>,
    raised: bool,
}

/// The residual's watch: windows in a row with a channel's residual beyond
/// [`TwinConfig::isolate_above`] of its noise, when the first ended, the parameter whose jump
/// alone explains most of it (its index and relative change); whether this excursion has
/// raised its alarm; and the windows in a row the residual was within its band before it (the
/// excursion can alarm after at least [`TwinConfig::sigma_windows`] of them: a twin that has
/// not matched the stream for as long as its noise took to learn has no residual *leaving* its
/// band — its mismatch is named by the estimate's alarm).
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
struct Excursion {
    out: usize,
    since: f64,
    pick: Option<(usize, f64)>,
    raised: bool,
    matched: usize,
}

/// The live twin as a stream stage (see the module docs).
#[derive(Serialize, Deserialize)]
pub struct TwinStage {
    cfg: TwinConfig,
    rate_hz: f64,
    /// The adapted parameters' values now and as calibrated.
    values: Vec<f64>,
    calibrated: Vec<f64>,
    /// The stream's start [s] (NaN before its first sample).
    t0: f64,
    /// The channels compared (those of the configuration the stream has).
    channels: Vec<String>,
    /// The measured samples not yet compared, per channel.
    measured: Vec<Vec<f64>>,
    /// The stream's engine angle over the same samples (less the firing TDC's) [rad].
    theta: Vec<f64>,
    /// Samples compared so far (the next window starts there).
    compared: usize,
    /// Per channel over the noise windows: the residual's sum of squares, the measured sum and
    /// sum of squares, the count; then σ.
    sigma_acc: Vec<[f64; 4]>,
    sigma: Vec<f64>,
    noise_windows: usize,
    watch: Vec<Watch>,
    /// The sample the present epoch (the twin's values since the last update) began at, and
    /// its information and score `Σ λ^i·SᵀWS`, `Σ λ^i·SᵀWr` (row-major).
    epoch_start: usize,
    info: Vec<f64>,
    score: Vec<f64>,
    #[serde(skip)]
    runs: Option<Runs>,
    /// The residual's watch (the fast alarm).
    #[serde(default)]
    excursion: Excursion,
}

impl TwinStage {
    /// The twin of `cfg` on a stream at `rate_hz` [Hz].
    pub fn new(cfg: TwinConfig, rate_hz: f64) -> Result<Self, AppError> {
        cfg.validate()?;
        if !(rate_hz.is_finite() && rate_hz > 0.0) {
            return Err(AppError::Invalid(format!(
                "twin: a stream at {} Hz: expected a time basis at a rate > 0",
                physid_core::Num(rate_hz)
            )));
        }
        let cell = cfg.cell()?;
        let values: Vec<f64> = cfg
            .adapt
            .iter()
            .map(|p| cell.get(p).unwrap_or(f64::NAN))
            .collect();
        Ok(Self {
            rate_hz,
            calibrated: values.clone(),
            watch: vec![Watch::default(); values.len()],
            values,
            t0: f64::NAN,
            channels: Vec::new(),
            measured: Vec::new(),
            theta: Vec::new(),
            compared: 0,
            sigma_acc: Vec::new(),
            sigma: Vec::new(),
            noise_windows: 0,
            epoch_start: 0,
            info: Vec::new(),
            score: Vec::new(),
            runs: None,
            excursion: Excursion::default(),
            cfg,
        })
    }

    /// The adapted parameters' values now, by path.
    pub fn values(&self) -> Vec<(String, f64)> {
        self.cfg
            .adapt
            .iter()
            .cloned()
            .zip(self.values.iter().copied())
            .collect()
    }

    /// Samples per window.
    fn window_samples(&self) -> usize {
        ((self.cfg.window_s * self.rate_hz).round() as usize).max(10)
    }

    /// The twin's run from the stream's first sample: settled for 1 s (and as much more as
    /// brings its crank angle to the stream's) at the first sample's inputs, its sensors quiet.
    fn start_runs(&self, theta: f64, rpm: f64, throttle: f64) -> Result<Runs, AppError> {
        let mut cell = self.cfg.cell()?;
        for (p, _, _) in CellParams::TABLE {
            if p.ends_with(".noise") || p.ends_with(".quantum") {
                cell.set(p, 0.0)?;
            }
        }
        for (p, v) in self.cfg.adapt.iter().zip(&self.values) {
            cell.set(p, *v)?;
        }
        let opts = RunOptions {
            params: cell,
            basis: OutputBasis::Time(self.rate_hz),
            stream: true,
            ..RunOptions::default()
        };
        let build = |settle: f64| -> Result<Run, AppError> {
            let scenario = Scenario {
                name: "twin".into(),
                description: String::new(),
                duration: 1e9,
                settle,
                speed: Profile::constant(rpm, 1e9),
                throttle: Profile::constant(throttle, 1e9),
                torque_mode: false,
                speed_range: None,
                set: Default::default(),
                faults: Vec::new(),
            };
            let mut run = Run::new(&scenario, &opts)?;
            let mut keep: Vec<&str> = self.channels.iter().map(String::as_str).collect();
            keep.push("theta_en");
            run.keep_channels(&keep)?;
            Ok(run)
        };
        // The crank angle the twin reaches at the stream's start, brought to the stream's
        // (modulo a cycle) by settling longer: three passes correct the settling's transient.
        let w = (rpm * PI / 30.0).max(1.0);
        let target = theta - self.cfg.theta_tdc;
        let mut settle = 1.0;
        for _ in 0..3 {
            let mut probe = build(settle)?;
            // A few samples on: the first grid point is placed once the steps around it are.
            probe.step_until(0.002)?;
            let rec = probe.drain()?;
            let at = rec.values("theta_en")?.first().copied().unwrap_or(0.0);
            let gap = (target - at).rem_euclid(4.0 * PI);
            let gap = if gap > 2.0 * PI { gap - 4.0 * PI } else { gap };
            if gap.abs() < 1e-6 {
                break;
            }
            settle = if settle + gap / w < 1.0 {
                settle + (gap + 4.0 * PI) / w
            } else {
                settle + gap / w
            };
        }
        let twin = build(settle)?;
        let snaps = vec![Snap {
            stepped: 0,
            placed: 0,
            values: self.values.clone(),
            run: twin.clone(),
        }];
        let p = self.cfg.adapt.len();
        let mut runs = Runs {
            runs: vec![twin; 1 + p],
            out: vec![vec![Vec::new(); self.channels.len()]; 1 + p],
            theta: Vec::new(),
            stepped: 0,
            placed: 0,
            snaps,
            boundaries: Vec::new(),
            inputs: Vec::new(),
            inputs_from: 0,
            window_start: 0,
            prev: None,
        };
        fork(&mut runs, &self.cfg.adapt, &self.values, self.cfg.rel_step)?;
        Ok(runs)
    }
}

/// The stream's value of `name` (every sample finite, else the sample named).
fn column<'a>(chunk: &'a Recording, name: &str) -> Result<&'a [f64], AppError> {
    let v = chunk.values(name)?;
    if let Some(k) = v.iter().position(|x| !x.is_finite()) {
        return Err(AppError::Invalid(format!(
            "twin: channel '{name}', sample {k} of the chunk: {} — the twin is driven and compared sample by sample",
            v[k]
        )));
    }
    Ok(v)
}

impl crate::stage::Stage for TwinStage {
    type Out = TwinOut;

    fn push(
        &mut self,
        chunk: &Recording,
        out: &mut dyn physid_core::Sink<TwinOut>,
    ) -> Result<(), AppError> {
        if chunk.is_empty() {
            return Ok(());
        }
        let t = column(chunk, "t")?;
        let demand = chunk.values_in("speed_demand", "rad/s")?;
        let throttle = column(chunk, "throttle")?;
        if self.runs.is_none() {
            // The first chunk (or the first after a restore): the channels, the twin's start.
            self.channels = self
                .cfg
                .channels
                .iter()
                .filter(|c| chunk.channel(c).is_ok())
                .cloned()
                .collect();
            if self.channels.is_empty() {
                return Err(AppError::Invalid(format!(
                    "twin: the stream has none of the channels compared ({})",
                    self.cfg.channels.join(", ")
                )));
            }
            // A dynamometer on a torque demand records the torque [N·m] in `speed_demand`: far
            // from the dynamometer's speed, where a speed demand is near it. The twin follows a
            // speed demand only (an open-loop twin's speed would drift from the stream's).
            if let Ok(w) = chunk.values_in("omega_dy", "rad/s") {
                let (d, w) = (demand[0], w[0]);
                if !super::replay::near_the_speed(d, w) {
                    return Err(AppError::Invalid(format!(
                        "twin: the stream's speed_demand ({d:.3}) is far from the dynamometer's speed ({w:.3} rad/s) at its first sample — a dynamometer on a torque demand, whose torque the cell records there? The live twin follows a speed demand only (physid twin calibrate and check replay torque-demand recordings)"
                    )));
                }
            }
            let theta = column(chunk, "theta_en")?;
            self.t0 = t[0];
            self.compared = 0;
            self.epoch_start = 0;
            self.info.clear();
            self.score.clear();
            self.excursion = Excursion::default();
            self.measured = vec![Vec::new(); self.channels.len()];
            self.theta.clear();
            self.runs = Some(self.start_runs(theta[0], demand[0] * 30.0 / PI, throttle[0])?);
        }
        let cols: Vec<&[f64]> = self
            .channels
            .iter()
            .map(|c| column(chunk, c))
            .collect::<Result<_, _>>()?;
        for (m, c) in self.measured.iter_mut().zip(&cols) {
            m.extend_from_slice(c);
        }
        let tdc = self.cfg.theta_tdc;
        self.theta
            .extend(column(chunk, "theta_en")?.iter().map(|x| x - tdc));
        // The twin and its copies stepped sample by sample; at each window's end (once the
        // twin has placed its last sample) the window, and the copies start again from there.
        let n = self.window_samples();
        for k in 0..t.len() {
            let tau = t[k] - self.t0;
            let rpm = demand[k] * 30.0 / PI;
            if !rpm.is_finite() {
                return Err(AppError::Invalid(format!(
                    "twin: channel 'speed_demand', sample {k} of the chunk: not a number"
                )));
            }
            let runs = self
                .runs
                .as_mut()
                .ok_or_else(|| AppError::Invalid("twin: no run".into()))?;
            for run in &mut runs.runs {
                run.hold_inputs(rpm, throttle[k]);
                run.step_until(tau)?;
            }
            runs.stepped += 1;
            runs.inputs.push((tau, rpm, throttle[k]));
            // The twin at each quarter of the window (the window's start is taken after it).
            let into = runs.stepped - runs.window_start;
            if into % (n / 4).max(1) == 0 && into < n {
                runs.snaps.push(Snap {
                    stepped: runs.stepped,
                    placed: runs.placed,
                    values: self.values.clone(),
                    run: runs.runs[0].clone(),
                });
            }
            let window_end = (self.compared + n) as f64 / self.rate_hz;
            if tau >= window_end || k + 1 == t.len() {
                for (i, (run, o)) in runs.runs.iter_mut().zip(&mut runs.out).enumerate() {
                    let rec = run.drain()?;
                    for (buf, c) in o.iter_mut().zip(&self.channels) {
                        buf.extend_from_slice(rec.values(c)?);
                    }
                    if i == 0 {
                        runs.theta.extend_from_slice(rec.values("theta_en")?);
                        runs.placed += rec.len();
                    }
                }
                let have = runs
                    .out
                    .iter()
                    .map(|o| o.first().map_or(0, Vec::len))
                    .min()
                    .unwrap_or(0);
                // (The chunk's measured samples are all in the buffer already.)
                if have.min(self.measured[0].len()) >= n {
                    let t_end = self.t0 + (self.compared + n - 1) as f64 / self.rate_hz;
                    self.window(n, t_end, out)?;
                }
            }
        }
        Ok(())
    }

    fn finish(&mut self, _out: &mut dyn physid_core::Sink<TwinOut>) -> Result<(), AppError> {
        Ok(())
    }
}
