//! Running a scenario: the cell stepped one crank increment at a time with the scenario's
//! demand, throttle and faults, and the acquisition as it goes — each output grid point carried
//! from the two steps around it, then measured by its sensor (SPEC §2.7) — into a
//! [`Recording`] with the DESIGN.md channel names. Only the output is kept: a run's memory is
//! its recording's.
//!
//! Sensors act on the output samples: `y = gain·lag(x) + offset + noise`, quantised; the
//! encoders count `floor(θ/q)` pulses (a lost-pulse fault drops pulses at random, for good);
//! the TDC marker is 1 on the first sample of each engine revolution (θ_en passing a multiple
//! of 2π from firing TDC). The true torque components and the cylinder temperature come along
//! as `true_*` channels, the parameters and faults in the metadata: the ground truth that
//! identification results are checked against.

use crate::cell::{Inputs, Sample, TestCell};
use crate::control::Demand;
use crate::numeric::SinCosTrack;
use crate::params::CellParams;
use crate::scenario::{Fault, Profile, Scenario};
use physid_core::{Num, Recording};
use std::f64::consts::PI;

pub use crate::error::SimError;

/// The output basis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum OutputBasis {
    /// Uniform time steps at this rate [Hz].
    Time(f64),
    /// One sample per this many crank degrees from the first firing TDC.
    Crank(f64),
}

/// How to run.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// Base parameters. The scenario's own `set` is applied over them: to override one of a
    /// scenario's settings, put it in the scenario's `set` (as `physid simulate --set` does).
    pub params: CellParams,
    /// Recorded duration [s] (the scenario's if `None`).
    pub duration: Option<f64>,
    /// Extra faults (`--fault`).
    pub faults: Vec<Fault>,
    /// Output basis.
    pub basis: OutputBasis,
    /// The samples are taken as the run goes ([`Run::drain`]) rather than kept for
    /// [`Run::finish`]: no limit from the memory the whole recording would take.
    pub stream: bool,
}

impl Default for RunOptions {
    fn default() -> Self {
        Self {
            params: CellParams::default(),
            duration: None,
            faults: Vec::new(),
            basis: OutputBasis::Time(10_000.0),
            stream: false,
        }
    }
}

mod acquisition;
mod channels;
mod dense;
mod sensors;
mod truth;

pub use truth::parameter_truth;

use acquisition::Acquisition;
use channels::{raw_row, OUTPUT};
use sensors::{Prepared, SensorState};

/// The recording's channels on `basis`, in their order: `(name, unit)` (DESIGN.md's table).
pub fn channels(basis: OutputBasis) -> impl Iterator<Item = (&'static str, &'static str)> {
    OUTPUT
        .iter()
        .filter(move |c| c.2.on(basis))
        .map(|c| (c.0, c.1))
}

/// Run a scenario to its end: a [`Run`] stepped through the whole duration.
/// `progress` is told the fraction done, about every 1 %.
pub fn simulate(
    scenario: &Scenario,
    opts: &RunOptions,
    mut progress: impl FnMut(f64),
) -> Result<Recording, SimError> {
    let mut run = Run::new(scenario, opts)?;
    let duration = run.duration();
    let mut t = 0.0;
    while !run.is_done() {
        // At least one step each time: a duration too short for its hundredth to move the
        // time (1e-300 s) would otherwise never end.
        t = (t + duration / 100.0).max(run.time());
        run.step_until(t)?;
        progress((run.time() / duration).clamp(0.0, 1.0));
    }
    progress(1.0);
    run.finish()
}

/// A scenario being run, one solver step at a time: the cell with the scenario's demand,
/// throttle and faults, and the acquisition as it goes. [`step_until`](Self::step_until)
/// advances it to a recording time; between calls its inputs can change
/// ([`set_speed`](Self::set_speed), [`set_throttle`](Self::set_throttle),
/// [`add_fault`](Self::add_fault)) — what a paced live cell needs; [`finish`](Self::finish)
/// gives the recording. A clone is the run as it is, to go on from later (an FMU's saved
/// state).
#[derive(Clone)]
pub struct Run {
    scenario: Scenario,
    base: CellParams,
    faults: Vec<Fault>,
    duration: f64,
    torque_mode: bool,
    cell: TestCell,
    acquisition: Acquisition,
    /// The drive's own speed sensor, read at every step (from the time of the one before).
    speed_sensor: SensorState,
    measured_at: f64,
    /// The machine frame's angle, for the phase currents and voltages.
    frame: SinCosTrack,
    done: bool,
    /// The recording's size in memory (every channel as float64) [bytes].
    bytes: f64,
    /// The dynamometer's torque averaged over the last whole engine cycle (720° of crank
    /// angle) [N·m] — the pulsation averaged out exactly — and the running cycle's integral
    /// [N·m·s], duration [s] and index (crank angle ÷ 4π, floored).
    mean_torque_dy: f64,
    torque_sum: f64,
    torque_span: f64,
    torque_cycle: f64,
    /// Whether a cycle boundary has passed (from then on the mean is over whole cycles).
    torque_whole: bool,
}

/// The cell's parameters a run can change as it goes ([`Run::set_live_parameter`]): the
/// shaft's stiffness and damping, the reciprocating mass, the friction's scale and the oil
/// temperature (the others fix the engine's geometry and the machine when the cell is built).
pub const LIVE_PARAMS: &[&str] = &[
    "shaft.k",
    "shaft.b",
    "engine.m_rec",
    "engine.friction_scale",
    "engine.t_oil",
];

/// The most samples a streaming run takes: its output grid counts them exactly below 2^53.
const MAX_STREAM_SAMPLES: f64 = 9_007_199_254_740_992.0;

impl Run {
    /// Check the scenario, options and parameters, refuse a recording that cannot fit in
    /// memory, and start the cell at BDC before firing TDC (so that the first cycle begins
    /// with compression), `settle` seconds before the recording starts.
    pub fn new(scenario: &Scenario, opts: &RunOptions) -> Result<Self, SimError> {
        scenario.validate()?;
        let mut base = opts.params.clone();
        for (k, v) in &scenario.set {
            base.set(k, *v)?;
        }
        base.validate()?;
        let mut faults: Vec<Fault> = scenario
            .faults
            .iter()
            .map(|f| Fault::parse(f))
            .collect::<Result<_, _>>()?;
        faults.extend(opts.faults.iter().cloned());
        let duration = opts.duration.unwrap_or(scenario.duration);
        if !(duration.is_finite() && duration > 0.0) {
            return Err(SimError::Invalid(format!(
                "duration {}: expected > 0 s",
                physid_core::Num(duration)
            )));
        }
        let torque_mode = scenario.torque_mode || base.dyno.torque_mode != 0.0;
        // The recording's size, known in advance: refused when it cannot fit (a typo such as
        // `duration = 1e6` would otherwise grow until the allocator aborts).
        let per_second = match opts.basis {
            OutputBasis::Time(rate) => rate,
            OutputBasis::Crank(step) => {
                // The fastest demanded speed over the run (1000 rpm when the demand is a torque).
                let rpm = if torque_mode {
                    1000.0
                } else {
                    (0..=1000)
                        .map(|k| scenario.speed.value(duration * f64::from(k) / 1000.0))
                        .fold(0.0, f64::max)
                };
                rpm / 60.0 * 360.0 / step
            }
        };
        let what = format!("a recording of {} s", Num(duration));
        let samples = duration * per_second;
        let bytes = samples * OUTPUT.len() as f64 * 8.0;
        if !opts.stream {
            physid_core::memory::check_fits(bytes, &what)
                .map_err(|e| SimError::Invalid(format!("{e}: record less (duration)")))?;
        } else if samples >= MAX_STREAM_SAMPLES {
            // A stream holds nothing, but counts its samples exactly.
            return Err(SimError::Invalid(format!(
                "{what} at {} samples/s is {samples:e} samples, more than a stream counts exactly (2^53): record less (duration)",
                Num(per_second)
            )));
        }
        let w0 = if torque_mode {
            scenario.torque_start_rpm() * PI / 30.0
        } else {
            scenario.speed.value(0.0) * PI / 30.0
        };
        let cell = TestCell::new(base.clone(), w0.max(1.0), -PI)?;
        let acquisition = Acquisition::new(&base, &faults, opts.basis, duration, w0, opts.stream)?;
        Ok(Self {
            speed_sensor: SensorState::new(base.sensors.seed as u64, 0),
            measured_at: cell.time(),
            frame: SinCosTrack::default(),
            scenario: scenario.clone(),
            base,
            faults,
            duration,
            torque_mode,
            cell,
            acquisition,
            done: false,
            bytes,
            mean_torque_dy: 0.0,
            torque_sum: 0.0,
            torque_span: 0.0,
            torque_cycle: f64::NAN,
            torque_whole: false,
        })
    }

    /// The recording's time now [s] (negative while the cell settles).
    pub fn time(&self) -> f64 {
        self.cell.time() - self.scenario.settle
    }

    /// The recorded duration [s].
    pub fn duration(&self) -> f64 {
        self.duration
    }

    /// The whole recording's size as float64 values [bytes], known in advance (a file of it
    /// takes at least this much, uncompressed).
    pub fn size_bytes(&self) -> f64 {
        self.bytes
    }

    /// Record only the channels `names` (the time always): what a caller that reads a few
    /// channels needs, without the cost of carrying and measuring the rest. The kept channels
    /// are bit for bit those of a full run. Before the first step only; an unknown name is
    /// refused with the channels there are.
    pub fn keep_channels(&mut self, names: &[&str]) -> Result<(), SimError> {
        self.acquisition.keep(names)
    }

    /// Whether the run has reached its end (one step past the duration).
    pub fn is_done(&self) -> bool {
        self.done
    }

    /// The speed demand [rpm] (a torque demand [N·m] in torque mode) from now on, against the
    /// recording's time.
    pub fn set_speed(&mut self, profile: Profile) {
        self.scenario.speed = profile;
    }

    /// The throttle opening [deg] from now on, against the recording's time.
    pub fn set_throttle(&mut self, profile: Profile) {
        self.scenario.throttle = profile;
    }

    /// The speed demand [rpm] (torque demand [N·m] in torque mode) held at `value` from now on,
    /// and the throttle at `throttle_deg`: what an importer's inputs set at every step, without
    /// allocating.
    pub fn hold_inputs(&mut self, value: f64, throttle_deg: f64) {
        self.scenario.speed.hold(value);
        self.scenario.throttle.hold(throttle_deg);
    }

    /// Another scenario's inputs from now on: its demand and throttle profiles starting now,
    /// and its demand mode (speed or torque). The cell's parameters and the faults stay.
    pub fn set_scenario(&mut self, s: &Scenario) {
        let now = self.time().max(0.0);
        self.scenario.speed = s.speed.shifted(now);
        self.scenario.throttle = s.throttle.shifted(now);
        self.torque_mode = s.torque_mode || self.base.dyno.torque_mode != 0.0;
    }

    /// Switch the dynamometer between speed and torque demand, continuing from where it is:
    /// speed demand at its present speed [rpm], or torque demand at its mean torque over the
    /// last whole engine cycle [N·m] (at a fixed throttle the engine then finds its own speed).
    pub fn set_torque_mode(&mut self, torque: bool) {
        if torque == self.torque_mode {
            return;
        }
        let hold = if torque {
            self.mean_torque_dy
        } else {
            self.cell.omega_dy() * 30.0 / PI
        };
        self.torque_mode = torque;
        self.scenario.speed = Profile::constant(hold, f64::MAX);
    }

    /// Whether the dynamometer follows a torque demand (else a speed demand).
    pub fn torque_mode(&self) -> bool {
        self.torque_mode
    }

    /// Set one of the cell's live parameters ([`LIVE_PARAMS`]) to `value` from now on, as
    /// its base value (a fault on it still applies over it): what a twin adapting its cell
    /// does at every update, without a fault's record.
    pub fn set_live_parameter(&mut self, path: &str, value: f64) -> Result<(), SimError> {
        if !LIVE_PARAMS.contains(&path) {
            return Err(SimError::Invalid(format!(
                "'{path}' cannot change during a run; those that can: {}",
                LIVE_PARAMS.join(", ")
            )));
        }
        self.base.set_checked(path, value)?;
        self.cell.params.set(path, value)?;
        self.cell.refresh_live_parameters();
        Ok(())
    }

    /// Turn the driveline by `delta` [rad] (engine and dynamometer together, from now on): a
    /// twin's crank angle kept on a measured one ([`TestCell::turn`]).
    pub fn turn(&mut self, delta: f64) {
        self.cell.turn(delta);
    }

    /// A fault from its time on (relative to the recording's start, as every fault).
    pub fn add_fault(&mut self, fault: Fault) {
        self.acquisition.add_fault(fault.clone());
        self.faults.push(fault);
    }

    /// Step the cell until the recording's time passes `t` [s] (or the run ends: one step past
    /// the duration, so that the output grid reaches it).
    pub fn step_until(&mut self, t: f64) -> Result<(), SimError> {
        while !self.done && self.time() <= t {
            self.step()?;
        }
        Ok(())
    }

    /// One solver step with the inputs in force, its truth handed to the acquisition.
    fn step(&mut self) -> Result<(), SimError> {
        let settle = self.scenario.settle;
        let t_rel = self.cell.time() - settle;
        let cell = &mut self.cell;
        Fault::apply_all(&self.faults, &self.base, &mut cell.params, t_rel.max(0.0));
        cell.refresh_live_parameters();
        let v = self.scenario.speed.value(t_rel.max(0.0));
        let inputs = Inputs {
            demand: if self.torque_mode {
                Demand::Torque(v)
            } else {
                Demand::Speed(v * PI / 30.0)
            },
            throttle_deg: self.scenario.throttle.value(t_rel.max(0.0)),
        };
        let ss = Prepared::from(cell.params.dyno.speed_sensor);
        let w_meas =
            self.speed_sensor
                .measure_one(&ss, cell.omega_dy(), cell.time() - self.measured_at);
        self.measured_at = cell.time();
        let t_before = cell.time();
        let mut s = cell.step_with(&inputs, w_meas);
        check(&s, self.base.engine.active != 0.0).map_err(|e| match e {
            SimError::Diverged { what, .. } => SimError::Diverged { t: t_rel, what },
            e => e,
        })?;
        if self.torque_mode {
            if let Some([lo, hi]) = self.scenario.speed_range {
                let rpm = s.omega_en * 30.0 / PI;
                if !(lo..=hi).contains(&rpm) {
                    return Err(SimError::Invalid(format!(
                        "the engine left the scenario's speed range {lo}–{hi} rpm at t = {:.2} s ({rpm:.0} rpm): its torque demand does not keep it there",
                        s.t - settle
                    )));
                }
            }
        }
        let dt = cell.time() - t_before;
        self.average_torque(s.torque_dy, dt, s.theta_en);
        let cell = &mut self.cell;
        // From the step that spans t = 0 on, so that the output grid starts at 0.
        if cell.time() - settle > 0.0 {
            s.t = t_rel;
            self.acquisition
                .accept(&raw_row(&s, &cell.params, self.frame.at(s.theta_syn)))?;
        }
        // One sample past the end, so that the output grid reaches it.
        if t_rel > self.duration {
            self.done = true;
        }
        Ok(())
    }

    /// The dynamometer's mean torque over the last whole engine cycle: the torque integrated
    /// step by step (rectangle rule at the step's end) over a cycle of 720° of crank angle,
    /// divided by the cycle's duration. Until the first cycle is whole, the mean so far.
    fn average_torque(&mut self, torque: f64, dt: f64, theta_en: f64) {
        let cycle = (theta_en / (4.0 * PI)).floor();
        if cycle != self.torque_cycle {
            if !self.torque_cycle.is_nan() {
                self.mean_torque_dy = self.torque_sum / self.torque_span;
                self.torque_whole = true;
            }
            self.torque_cycle = cycle;
            self.torque_sum = 0.0;
            self.torque_span = 0.0;
        }
        self.torque_sum += torque * dt;
        self.torque_span += dt;
        if !self.torque_whole {
            self.mean_torque_dy = self.torque_sum / self.torque_span;
        }
    }

    /// The samples acquired since the last call (all channels, the recording's names and
    /// units): a streaming run's output, chunk by chunk — every output sample up to the last
    /// solver step. The chunks put end to end are the recording `simulate` gives, bit for bit.
    pub fn drain(&mut self) -> Result<Recording, SimError> {
        self.acquisition.drain()
    }

    /// The samples acquired since the last call appended to `columns`, one per channel in
    /// [`channels`]' order: what [`drain`](Self::drain) gives, without the recording around
    /// it (an FMU's steps take them so, allocating nothing once the columns have grown).
    pub fn drain_into(&mut self, columns: &mut [Vec<f64>]) {
        self.acquisition.drain_into(columns);
    }

    /// The run in `rec`'s metadata, as [`finish`](Self::finish) puts it: the scenario, the
    /// faults so far and the parameters (for a streaming run's first chunk, before its file is
    /// written).
    pub fn describe(&self, rec: &mut Recording) {
        self.acquisition.describe(rec, &self.scenario);
    }

    /// The recording so far (the whole run once [`is_done`](Self::is_done)), with the
    /// scenario, the faults and the parameters in the metadata.
    pub fn finish(self) -> Result<Recording, SimError> {
        self.acquisition.finish(&self.scenario)
    }
}

/// Catch a state that left the physical domain.
fn check(s: &Sample, engine_active: bool) -> Result<(), SimError> {
    let bad = |what: String| Err(SimError::Diverged { t: s.t, what });
    for (k, name) in ["intake", "cylinder", "exhaust"]
        .iter()
        .enumerate()
        .filter(|_| engine_active)
    {
        if !(s.gas.p[k].is_finite() && s.gas.p[k] > 0.0) {
            return bad(format!("{name} pressure {}", s.gas.p[k]));
        }
        if !(s.temperatures[k].is_finite() && s.temperatures[k] > 0.0) {
            return bad(format!("{name} temperature {}", s.temperatures[k]));
        }
    }
    if !s.omega_en.is_finite() || !s.omega_dy.is_finite() || !s.torque_dy.is_finite() {
        return bad("speeds or machine torque not finite".into());
    }
    Ok(())
}
