//! One co-simulation instance of the cell, whatever the FMI version: the variables' values,
//! the FMI state machine (instantiated → initialisation → step → terminated), and the
//! scenario's [`Run`] stepped to each communication point.
//!
//! **Outputs at a communication point** are the recording's sample at or just before it: the
//! run samples its channels on its own grid (`sample_rate`, 10 kHz by default), exactly as
//! `physid simulate --sample-rate` does, and a communication point `t` reads the sample
//! `⌊t·rate⌋` (a point within 10⁻⁶ of a sample counts as on it, so that `n·h` with round-off
//! meets sample `n`). With the communication step a multiple of the sample interval, the
//! outputs are the recording's samples bit for bit.
//!
//! **Inputs** are held over a step (zero-order hold). While `demand.from_scenario` is true the
//! scenario's profiles drive the cell; when false, `demand.speed` [rpm] or `demand.torque`
//! [N·m] (by `demand.torque_mode`) and `demand.throttle` [deg].
//!
//! **A tunable parameter set during the run** (the fault paths:
//! [`FAULT_PATHS`](physid_sim::scenario::FAULT_PATHS)) is a step fault at that time, as
//! `physid simulate --fault PATH=VALUE@T` gives.

use crate::log::{Logger, Status};
use crate::variables::{basis, table, Causality, Role, Type, Variability, Variable};
use crate::Cell;
use physid_sim::params::CellParams;
use physid_sim::run::{channels, Run, RunOptions};
use physid_sim::scenario::Fault;

/// The run's length when the importer gives no stop time [s]: a stream counts its samples
/// exactly up to 2⁵³, 9·10¹¹ s at 10 kHz.
const NO_STOP: f64 = 1e9;

/// Where an instance is in FMI's state machine.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Instantiated: parameters and start values may be set.
    Instantiated,
    /// Initialisation mode: the same, and the outputs may be read.
    Initialization,
    /// Step mode: the cell runs.
    Step,
    /// Terminated.
    Terminated,
    /// A call failed in a way that leaves the cell unusable (it diverged): only reset and
    /// free remain.
    Failed,
}

/// The samples drained from the run and not yet read: every channel's column (the
/// recording's order), the first one's index, and where each output is among the channels.
#[derive(Clone, Default)]
struct Samples {
    columns: Vec<Vec<f64>>,
    first: u64,
    of_output: Vec<usize>,
}

impl Samples {
    /// Empty columns for the channels on `basis`, and each output's among them.
    fn new(basis: physid_sim::run::OutputBasis, outputs: &[Variable]) -> Result<Self, Refusal> {
        let names: Vec<&str> = channels(basis).map(|c| c.0).collect();
        let of_output = outputs
            .iter()
            .map(|v| {
                names
                    .iter()
                    .position(|&n| n == v.name)
                    .ok_or_else(|| format!("the run records no channel '{}'", v.name))
            })
            .collect::<Result<_, _>>()?;
        Ok(Self {
            columns: vec![Vec::new(); names.len()],
            first: 0,
            of_output,
        })
    }

    /// The samples held.
    fn len(&self) -> u64 {
        self.columns.first().map_or(0, |c| c.len() as u64)
    }
}

/// One instance of the cell.
#[derive(Clone)]
pub struct Instance {
    cell: Cell,
    vars: Vec<Variable>,
    /// Every variable's value by value reference (a Boolean as 0 or 1).
    values: Vec<f64>,
    mode: Mode,
    start: f64,
    stop: Option<f64>,
    time: f64,
    run: Option<Run>,
    samples: Samples,
    /// Whether the scenario's profiles are the run's now.
    following: bool,
    /// The first output's value reference.
    first_output: usize,
    pub(crate) logger: Logger,
    /// Whether the importer wants the messages.
    pub(crate) logging: bool,
    /// Whether a step shorter than the sample interval has been warned of.
    warned_short_step: bool,
}

/// The most samples a step holds at once: a longer step is taken in pieces, the samples
/// before the one it ends on dropped as they come.
const HELD_SAMPLES: f64 = 65_536.0;

/// The highest `sample_rate` [Hz]: a thousand times the default, beyond any indicating
/// system's. One solver step's samples are held together (at 100 rpm, 1.7 ms of them: 17 000
/// samples at this rate); a rate of 1e12 Hz would ask for tens of GB in the importer's
/// process.
pub const MAX_SAMPLE_RATE: f64 = 1e7;

/// A refused or failed call: its message for the logger.
pub type Refusal = String;

impl Instance {
    /// An instance of `cell` driven from Rust (no importer, no logger): the same state machine
    /// and values as through the C functions.
    pub fn of(cell: Cell) -> Self {
        Self::new(cell, Logger::None, false)
    }

    /// A new instance of `cell`, its variables at their start values.
    pub(crate) fn new(cell: Cell, logger: Logger, logging: bool) -> Self {
        let vars = table(&cell);
        let values = vars.iter().map(|v| v.start.unwrap_or(0.0)).collect();
        let first_output = vars
            .iter()
            .position(|v| v.causality == Causality::Output)
            .unwrap_or(vars.len());
        Self {
            cell,
            vars,
            values,
            mode: Mode::Instantiated,
            start: 0.0,
            stop: None,
            time: 0.0,
            run: None,
            samples: Samples::default(),
            following: true,
            first_output,
            logger,
            logging,
            warned_short_step: false,
        }
    }

    /// An instance of the cell an FMU carries in `resources`, checked against the token
    /// (GUID) of its description.
    pub(crate) fn from_resources(
        resources: &std::path::Path,
        token: Option<&str>,
        logger: Logger,
        logging: bool,
    ) -> Result<Self, Refusal> {
        let (cell, guid) = Cell::from_resources(resources)?;
        match token {
            Some(t) if t == guid => {}
            Some(t) => {
                return Err(format!(
                    "the description's GUID {t} is not this FMU's {guid} (resources from another export?)"
                ))
            }
            None => return Err("no GUID / instantiation token given".into()),
        }
        Ok(Self::new(cell, logger, logging))
    }

    /// The mode.
    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// The instance's time [s].
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Log `message` as an error (always: an importer that refused the messages still gets
    /// the one that says why a call failed) and give it back.
    pub(crate) fn refuse(&self, message: String) -> Refusal {
        self.logger.log(Status::Error, &message);
        message
    }

    /// Mark the instance unusable (a panic inside a call).
    pub(crate) fn fail(&mut self) {
        self.mode = Mode::Failed;
    }

    /// Restore a saved state, keeping this instance's logger.
    pub(crate) fn restore(&mut self, saved: &Instance) {
        let (logger, logging) = (self.logger.clone(), self.logging);
        *self = saved.clone();
        self.logger = logger;
        self.logging = logging;
    }

    /// Refuse unless in one of `modes`.
    fn expect(&self, what: &str, modes: &[Mode]) -> Result<(), Refusal> {
        if modes.contains(&self.mode) {
            return Ok(());
        }
        Err(match self.mode {
            Mode::Failed => format!("{what}: the instance failed earlier; reset or free it"),
            m => format!("{what}: not allowed in {m:?} mode (only in {modes:?})"),
        })
    }

    /// The experiment: its start time [s] (the recording's time, from 0; the cell settles
    /// before it) and its stop time, if known.
    pub fn setup(&mut self, start: f64, stop: Option<f64>) -> Result<(), Refusal> {
        self.expect("setting up the experiment", &[Mode::Instantiated])?;
        if !(start.is_finite() && start >= 0.0) {
            return Err(format!(
                "start time {} s: expected ≥ 0 (the recording's time; the cell settles for {} s before 0)",
                physid_core::Num(start),
                self.cell.scenario.settle
            ));
        }
        if let Some(stop) = stop {
            if !(stop.is_finite() && stop > start) {
                return Err(format!(
                    "stop time {stop} s: expected after the start time {start} s",
                    stop = physid_core::Num(stop),
                    start = physid_core::Num(start)
                ));
            }
        }
        self.start = start;
        self.stop = stop;
        self.time = start;
        Ok(())
    }

    /// Enter initialisation mode.
    pub fn enter_initialization(&mut self) -> Result<(), Refusal> {
        self.expect("entering initialisation", &[Mode::Instantiated])?;
        self.mode = Mode::Initialization;
        Ok(())
    }

    /// Leave initialisation: the cell built with the parameters as set, run to the start time.
    pub fn exit_initialization(&mut self) -> Result<(), Refusal> {
        self.expect("leaving initialisation", &[Mode::Initialization])?;
        self.ensure_run()?;
        self.mode = Mode::Step;
        Ok(())
    }

    /// The cell's parameters from the variables.
    fn params(&self) -> CellParams {
        let mut p = CellParams::default();
        for v in &self.vars {
            if let Role::Cell(k) = v.role {
                // Every value was checked when it was set.
                let _ = p.set(CellParams::TABLE[k].0, self.values[v.vr as usize]);
            }
        }
        p
    }

    fn value_of(&self, role: Role) -> f64 {
        self.vars
            .iter()
            .find(|v| v.role == role)
            .map_or(0.0, |v| self.values[v.vr as usize])
    }

    /// The run, built when first needed from the parameters as they are, at the start time.
    fn ensure_run(&mut self) -> Result<(), Refusal> {
        if self.run.is_some() {
            return Ok(());
        }
        let mut scenario = self.cell.scenario.clone();
        // The settings are the parameters' values now (their start values unless set).
        scenario.set.clear();
        let opts = RunOptions {
            params: self.params(),
            duration: Some(self.stop.unwrap_or(NO_STOP)),
            faults: Vec::new(),
            basis: basis(self.value_of(Role::SampleRate)),
            stream: true,
        };
        let run = Run::new(&scenario, &opts).map_err(|e| format!("the cell: {e}"))?;
        self.samples = Samples::new(opts.basis, &self.vars[self.first_output..])?;
        self.run = Some(run);
        self.following = true;
        self.apply_inputs();
        let start = self.start;
        if let Err(e) = self.advance(start) {
            self.run = None;
            return Err(e);
        }
        Ok(())
    }

    /// The inputs in force for the next step: the scenario's profiles, or the `demand.*`
    /// values held.
    fn apply_inputs(&mut self) {
        let from_scenario = self.value_of(Role::FromScenario) != 0.0;
        let torque = self.value_of(Role::TorqueMode) != 0.0;
        let (speed, torque_demand, throttle) = (
            self.value_of(Role::Speed),
            self.value_of(Role::Torque),
            self.value_of(Role::Throttle),
        );
        let Some(run) = self.run.as_mut() else {
            return;
        };
        if from_scenario {
            if !self.following {
                let s = &self.cell.scenario;
                run.set_torque_mode(s.torque_mode);
                run.set_speed(s.speed.clone());
                run.set_throttle(s.throttle.clone());
                self.following = true;
            }
            return;
        }
        self.following = false;
        run.set_torque_mode(torque);
        run.hold_inputs(if torque { torque_demand } else { speed }, throttle);
    }

    /// Run to the sample at or just before `t` and put it in the outputs (a sample already
    /// read holds: a step shorter than the sample interval).
    fn advance(&mut self, t: f64) -> Result<(), Refusal> {
        let rate = self.value_of(Role::SampleRate);
        let k = (t * rate + 1e-6).floor().max(0.0) as u64;
        let Some(run) = self.run.as_mut() else {
            return Err("the cell is not built yet".into());
        };
        let samples = &mut self.samples;
        if k < samples.first {
            return Ok(());
        }
        // A long step is taken in pieces of [`HELD_SAMPLES`], the samples before the one it
        // ends on dropped as they come: an hour's step at 10 kHz would otherwise hold 10 GB.
        let piece = HELD_SAMPLES / rate;
        while samples.first + samples.len() <= k {
            if run.is_done() {
                return Err(format!(
                    "time {t} s is past the run's end ({} s)",
                    run.duration()
                ));
            }
            // Towards `t` a piece at a time; past it, one more solver step each round, until
            // sample k is out.
            let now = run.time();
            let aim = if now < t { (now + piece).min(t) } else { now };
            run.step_until(aim).map_err(|e| format!("the cell: {e}"))?;
            run.drain_into(&mut samples.columns);
            let held = samples.len();
            if held > 0 && samples.first + held <= k {
                for column in &mut samples.columns {
                    column.clear();
                }
                samples.first += held;
            }
        }
        let at = (k - samples.first) as usize;
        let outputs = &mut self.values[self.first_output..];
        for (value, &c) in outputs.iter_mut().zip(&samples.of_output) {
            *value = samples.columns[c][at];
        }
        for column in &mut samples.columns {
            column.drain(..=at);
        }
        samples.first = k + 1;
        Ok(())
    }

    /// One communication step from `t` over `h` [s].
    pub fn do_step(&mut self, t: f64, h: f64) -> Result<(), Refusal> {
        self.expect("a step", &[Mode::Step])?;
        if !(h.is_finite() && h > 0.0) {
            return Err(format!(
                "step size {h} s: expected > 0",
                h = physid_core::Num(h)
            ));
        }
        if !t.is_finite() || (t - self.time).abs() > 1e-9 * self.time.abs().max(1.0) {
            return Err(format!(
                "a step from {t} s, but the instance is at {} s (restore a saved state to go back)",
                self.time
            ));
        }
        let rate = self.value_of(Role::SampleRate);
        if h * rate < 1.0 - 1e-6 && !self.warned_short_step {
            self.warned_short_step = true;
            if self.logging {
                self.logger.log(
                    Status::Warning,
                    &format!(
                        "a step of {h} s, shorter than the sample interval 1/{rate} s: the outputs hold the last sample (raise sample_rate for finer outputs)"
                    ),
                );
            }
        }
        let target = t + h;
        if let Some(stop) = self.stop {
            if target > stop + 1e-9 * stop.abs().max(1.0) {
                return Err(format!("a step to {target} s, past the stop time {stop} s"));
            }
        }
        self.apply_inputs();
        if let Err(e) = self.advance(target) {
            self.mode = Mode::Failed;
            return Err(e);
        }
        self.time = target;
        Ok(())
    }

    /// Terminate.
    pub fn terminate(&mut self) -> Result<(), Refusal> {
        self.expect("terminating", &[Mode::Step, Mode::Initialization])?;
        self.mode = Mode::Terminated;
        Ok(())
    }

    /// Back to just instantiated, every variable at its start value.
    pub fn reset(&mut self) {
        let (logger, logging) = (self.logger.clone(), self.logging);
        *self = Self::new(self.cell.clone(), logger, logging);
    }

    fn variable(&self, vr: u32, ty: Type) -> Result<&Variable, Refusal> {
        let v = self
            .vars
            .get(vr as usize)
            .ok_or_else(|| format!("no variable has value reference {vr}"))?;
        if v.ty != ty {
            return Err(format!(
                "'{}' (value reference {vr}) is a {:?}, not a {ty:?}",
                v.name, v.ty
            ));
        }
        Ok(v)
    }

    /// Read a variable of type `ty`.
    pub fn get(&mut self, vr: u32, ty: Type) -> Result<f64, Refusal> {
        let v = self.variable(vr, ty)?;
        match (v.role, v.causality) {
            (Role::Time, _) => Ok(self.time),
            (_, Causality::Output) => {
                if self.mode == Mode::Instantiated {
                    return Err(format!(
                        "'{}': the outputs are there from initialisation mode on",
                        v.name
                    ));
                }
                self.ensure_run()?;
                Ok(self.values[vr as usize])
            }
            _ => Ok(self.values[vr as usize]),
        }
    }

    /// Set a variable of type `ty`, checked: known, settable now, finite, and (a cell
    /// parameter) within the cell's ranges.
    pub fn set(&mut self, vr: u32, ty: Type, value: f64) -> Result<(), Refusal> {
        self.expect(
            "setting a variable",
            &[Mode::Instantiated, Mode::Initialization, Mode::Step],
        )?;
        let v = self.variable(vr, ty)?;
        let (causality, variability, role) = (v.causality, v.variability, v.role);
        if !value.is_finite() {
            return Err(format!("'{}' = {value}: expected a finite number", v.name));
        }
        match causality {
            Causality::Output | Causality::Independent => {
                return Err(format!(
                    "'{}' is computed by the cell: it cannot be set",
                    v.name
                ))
            }
            Causality::Input => {}
            Causality::Parameter => {
                let running = self.mode == Mode::Step;
                if running && variability == Variability::Fixed {
                    return Err(format!(
                        "'{}' is fixed once initialised (during the run only the tunable ones: {})",
                        v.name,
                        physid_sim::scenario::FAULT_PATHS.join(", ")
                    ));
                }
                match role {
                    Role::Cell(k) => {
                        let path = CellParams::TABLE[k].0;
                        let mut p = self.params();
                        p.set(path, value).map_err(|e| e.to_string())?;
                        p.validate().map_err(|e| e.to_string())?;
                        if running {
                            if let Some(run) = self.run.as_mut() {
                                run.add_fault(Fault {
                                    path: path.to_string(),
                                    value,
                                    at: run.time().max(0.0),
                                    ramp: 0.0,
                                });
                            }
                        } else {
                            // Built again from the new values when next needed.
                            self.run = None;
                        }
                    }
                    Role::SampleRate if !(value > 0.0 && value <= MAX_SAMPLE_RATE) => {
                        return Err(format!(
                            "sample_rate {value} Hz: expected > 0 and at most {MAX_SAMPLE_RATE} Hz",
                            value = physid_core::Num(value)
                        ))
                    }
                    Role::SampleRate => self.run = None,
                    _ => {}
                }
            }
        }
        self.values[vr as usize] = value;
        Ok(())
    }
}
