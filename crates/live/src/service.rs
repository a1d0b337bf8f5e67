//! The live loop: chunks from a [`Source`] through the applications' stages (the same stages
//! the file verbs run), events out — what `physid live --headless --json` prints and what the
//! panel shows.

use crate::control::{Control, ControlRequest};
use crate::event::{quote, App, Event, Input, LatencyMs};
use crate::record::Recorder;
use crate::source::{Pace, Pacer, Source};
use crate::trace::TraceStage;
use physid_apps::acquisition::AcquisitionOptions;
use physid_apps::error::AppError;
use physid_apps::friction_fit::{FrictionFitConfig, FrictionOutput, FrictionStage};
use physid_apps::shaft_monitor::{MonitorConfig, ShaftInputs, ShaftParams, ShaftStage};
use physid_apps::torque_fit::{TorqueFitConfig, TorqueOutput, TorqueStage};
use physid_core::{Basis, Recording, RecordingError};
use physid_io::IoError;
use physid_models::friction::REGRESSION_PARAMS;
use physid_signal::crank::CrankError;
use physid_signal::cycles::{CycleStream, CycleSummary};
use physid_signal::integrity::{Finding as IntegrityFinding, IntegrityStream};
use physid_sim::run::SimError;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::sync::Arc;
use std::time::{Duration, Instant};
use thiserror::Error;
/// Errors of the live service.
#[derive(Debug, Error)]
pub enum LiveError {
    /// An application's stage.
    #[error(transparent)]
    App(#[from] AppError),
    /// The virtual test cell.
    #[error(transparent)]
    Sim(#[from] SimError),
    /// Reading a recording.
    #[error(transparent)]
    Io(#[from] IoError),
    /// A chunk without a channel a stage needs.
    #[error(transparent)]
    Recording(#[from] RecordingError),
    /// The cycle statistics.
    #[error(transparent)]
    Cycles(#[from] CrankError),
    /// Writing the events.
    #[error("writing the events: {0}")]
    Output(String),
    /// One frame from outside that is not valid: refused, the stream goes on.
    #[error("frame on line {line}: {what}")]
    BadFrame {
        /// Its line in the input.
        line: usize,
        /// What was wrong.
        what: String,
    },
    /// Anything else, explained.
    #[error("{0}")]
    Invalid(String),
}

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
    /// Set (by a SIGINT or SIGTERM handler) to end the run after the current chunk, as a
    /// `stop` control does: the stages finish and a log being written is closed.
    pub stop: Option<Arc<AtomicBool>>,
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

/// What a run did.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// Samples taken from the source.
    pub samples: usize,
    /// Frames refused.
    pub dropped: usize,
    /// The shaft's final K, B, τ0 and their standard errors (`None` when the shaft monitor
    /// stopped: a source without its channels, or an estimator error).
    pub shaft: Option<(ShaftParams, ShaftParams)>,
    /// Complete cycles reported.
    pub cycles: usize,
    /// Events sent.
    pub events: usize,
}

/// Run `source` to its end through the stages — the shaft monitor, the cycle statistics (when
/// the source has `theta_en` and a channel of [`CYCLE_CHANNELS`]) and, for the panel, the
/// time traces — applying the control messages that arrive on `controls` between chunks (each
/// answered on its reply channel and by an event), handing each event to `emit` (whose error,
/// e.g. a closed output, stops the run). An application stage that fails — a source without
/// the channels it needs, an estimator that loses positive definiteness — stops with a `finding`
/// saying why, and the run and the other stages go on; the source's own error (a file that
/// cannot be read, a cell that diverges) stops the run with the error (the events so far have
/// been sent).
pub fn run_live(
    source: &mut dyn Source,
    cfg: &LiveConfig,
    controls: Option<&Receiver<ControlRequest>>,
    emit: impl FnMut(&Event) -> Result<(), String>,
) -> Result<Summary, LiveError> {
    let mut live = Stages::new(cfg.clone(), source.rate_hz(), emit)?;
    loop {
        if live.stopping() {
            break;
        }
        let chunk = match source.next_chunk() {
            Ok(Some(c)) => c,
            Ok(None) => break,
            Err(LiveError::BadFrame { line, what }) => {
                live.refuse(Input::Frames, line, what)?;
                continue;
            }
            Err(e) => return Err(e),
        };
        // Control messages that have arrived, applied between chunks; while paused, wait for
        // them (the pacer does not count the pause).
        if let Some(rx) = controls {
            live.controls(rx, source)?;
        }
        if let Some(message) = source.notice() {
            let t_s = live.st.last_t;
            live.send(&Event::finding(t_s, message))?;
        }
        live.chunk(&chunk)?;
    }
    live.finish()
}

/// The applications' stages on one cell's stream, chunk by chunk, each event handed to `emit`:
/// what [`run_live`] runs over a source and a fleet worker over a cell's NATS stream. The
/// state of the shaft monitor, the cycle statistics and the integrity checks is plain data:
/// [`checkpoint`](Self::checkpoint) writes it, [`restore`](Self::restore) takes the run up
/// where it was (the friction and torque stages, the panel's traces and a log being written are
/// not checkpointed: a checkpoint refuses while they run).
pub struct Stages<E> {
    cfg: LiveConfig,
    rate_hz: f64,
    st: State,
    traces: Option<TraceStage>,
    /// The friction characterisation (stopped, with a finding, at its first error).
    friction: Option<FrictionStage>,
    friction_out: Vec<FrictionOutput>,
    /// The cyclic-torque estimation (stopped, with a finding, at its first error).
    torque: Option<TorqueStage>,
    torque_out: Vec<TorqueOutput>,
    findings: Vec<IntegrityFinding>,
    recorder: Recorder,
    pacer: Pacer,
    emit: E,
    paused: bool,
    /// A `stop` control for a source that cannot end itself (a replay, frames): the loop ends
    /// before the next chunk.
    stop_requested: bool,
    latency: LatencyHistogram,
    samples: Vec<physid_apps::shaft_monitor::ShaftSample>,
    alarms: Vec<physid_apps::shaft_monitor::ShaftAlarm>,
    done_cycles: Vec<CycleSummary>,
}

/// The checkpointed part of [`Stages`].
#[derive(Debug, Clone, Serialize, Deserialize)]
struct State {
    /// The rate the stages were built for [Hz] (a restore at another is refused).
    rate_hz: f64,
    /// The shaft monitor (stopped, with a finding, at its first error).
    shaft: Option<ShaftStage>,
    /// The cycle statistics and the channels they cover, as indices into [`CYCLE_CHANNELS`]
    /// (set up on the first chunk).
    cycles: Option<(CycleStream, Vec<usize>)>,
    /// The cycle statistics stopped at a sample they cannot take (a value not finite): with a
    /// finding; the run and the other stages go on, a `restart` brings them back.
    #[serde(default)]
    cycles_stopped: bool,
    /// K, B, τ0 frozen by the shaft's excitation supervisor, as last told.
    shaft_frozen: Option<[bool; 3]>,
    /// The integrity checks on the stream (set up on the first chunk).
    integrity: Option<IntegrityStream>,
    /// The time of the stream's first sample [s].
    t_first: f64,
    events: usize,
    taken: usize,
    dropped: usize,
    cycles_sent: usize,
    control_line: usize,
    last_t: f64,
    last_sent: Option<f64>,
    /// The latest estimate not sent (thinned out): sent at the end.
    pending: Option<physid_apps::shaft_monitor::ShaftSample>,
}

/// The version of a [`Stages`] checkpoint's layout (a checkpoint of another is refused).
pub const CHECKPOINT_VERSION: u32 = 1;

impl<E: FnMut(&Event) -> Result<(), String>> Stages<E> {
    /// The stages of `cfg` for a stream at `rate_hz` [Hz].
    pub fn new(cfg: LiveConfig, rate_hz: f64, emit: E) -> Result<Self, LiveError> {
        let st = State {
            rate_hz,
            shaft: Some(ShaftStage::new(&cfg.monitor, rate_hz)?),
            cycles: None,
            cycles_stopped: false,
            shaft_frozen: None,
            integrity: None,
            t_first: f64::NAN,
            events: 0,
            taken: 0,
            dropped: 0,
            cycles_sent: 0,
            control_line: 0,
            last_t: f64::NAN,
            last_sent: None,
            pending: None,
        };
        Self::with_state(cfg, st, emit)
    }

    fn with_state(cfg: LiveConfig, st: State, emit: E) -> Result<Self, LiveError> {
        let friction = Self::friction_stage(&cfg)?;
        let torque = Self::torque_stage(&cfg)?;
        Ok(Self {
            rate_hz: st.rate_hz,
            st,
            traces: None,
            friction,
            friction_out: Vec::new(),
            torque,
            torque_out: Vec::new(),
            findings: Vec::new(),
            recorder: Recorder::new(&cfg.log_dir),
            pacer: Pacer::new(cfg.pace),
            cfg,
            emit,
            paused: false,
            stop_requested: false,
            latency: LatencyHistogram::default(),
            samples: Vec::new(),
            alarms: Vec::new(),
            done_cycles: Vec::new(),
        })
    }

    /// The friction characterisation `cfg` asks for, new.
    fn friction_stage(cfg: &LiveConfig) -> Result<Option<FrictionStage>, LiveError> {
        let Some(f) = &cfg.friction else {
            return Ok(None);
        };
        let mut stage = FrictionStage::new(f.fit.clone(), Some(f.select_after))?;
        stage.set_theta_tdc(cfg.theta_tdc)?;
        Ok(Some(stage))
    }

    /// The cyclic-torque estimation `cfg` asks for, new.
    fn torque_stage(cfg: &LiveConfig) -> Result<Option<TorqueStage>, LiveError> {
        let Some(t) = &cfg.torque else {
            return Ok(None);
        };
        let mut stage = TorqueStage::new(t.fit.clone(), t.select_after_cycles.max(1) * 720)?;
        stage.set_theta_tdc(cfg.theta_tdc)?;
        Ok(Some(stage))
    }

    /// Start the stage `name` afresh (`restart` control): one stopped by an error comes back,
    /// from its configured start, on the samples from now on.
    fn restart(&mut self, name: &str) -> Result<(), String> {
        let none = |flag: &str| format!("field 'stage' is '{name}': this run has none ({flag})");
        match name {
            "shaft" => {
                self.st.shaft = Some(
                    ShaftStage::new(&self.cfg.monitor, self.rate_hz).map_err(|e| e.to_string())?,
                );
                self.st.shaft_frozen = None;
            }
            "cycles" => {
                // Set up again on the next chunk, counting cycles from there.
                self.st.cycles = None;
                self.st.cycles_stopped = false;
            }
            "friction" => {
                self.friction = Some(
                    Self::friction_stage(&self.cfg)
                        .map_err(|e| e.to_string())?
                        .ok_or_else(|| none("--friction"))?,
                );
            }
            _ => {
                self.torque = Some(
                    Self::torque_stage(&self.cfg)
                        .map_err(|e| e.to_string())?
                        .ok_or_else(|| none("--torque"))?,
                );
            }
        }
        Ok(())
    }

    /// The state of the checkpointed stages as bytes (MessagePack, led by
    /// [`CHECKPOINT_VERSION`]); refused while a stage that is not checkpointed runs.
    pub fn checkpoint(&self) -> Result<Vec<u8>, LiveError> {
        if self.friction.is_some() || self.torque.is_some() || self.recorder.is_recording() {
            return Err(LiveError::Invalid(
                "a checkpoint covers the shaft monitor, the cycle statistics and the integrity \
                 checks; the friction and torque stages and a log being written are not \
                 checkpointed"
                    .into(),
            ));
        }
        rmp_serde::to_vec(&(CHECKPOINT_VERSION, &self.st))
            .map_err(|e| LiveError::Invalid(format!("writing the checkpoint: {e}")))
    }

    /// Stages of `cfg` taken up from a [`checkpoint`](Self::checkpoint)'s bytes: the next chunk
    /// goes on where the checkpointed run stopped.
    pub fn restore(cfg: LiveConfig, bytes: &[u8], emit: E) -> Result<Self, LiveError> {
        let (version, st): (u32, State) = rmp_serde::from_slice(bytes)
            .map_err(|e| LiveError::Invalid(format!("reading a checkpoint: {e}")))?;
        if version != CHECKPOINT_VERSION {
            return Err(LiveError::Invalid(format!(
                "a checkpoint of layout {version}: this physid reads layout {CHECKPOINT_VERSION}"
            )));
        }
        Self::with_state(cfg, st, emit)
    }

    /// Samples taken so far.
    pub fn samples(&self) -> usize {
        self.st.taken
    }

    /// A frame from outside refused (`input`: where from; `line`: its number there): counted and
    /// reported as an `error` event, never absorbed.
    pub fn refuse(&mut self, input: Input, line: usize, message: String) -> Result<(), LiveError> {
        self.st.dropped += 1;
        let t_s = self.st.last_t;
        self.send(&Event::Error {
            t_s,
            input,
            line,
            message: quote(&message, MAX_QUOTED).into_owned(),
        })
    }

    /// Whether the run is to end now: the stop flag of [`LiveConfig::stop`] is set, or a `stop`
    /// control came for a source that does not end itself.
    fn stopping(&self) -> bool {
        self.stop_requested
            || self
                .cfg
                .stop
                .as_ref()
                .is_some_and(|s| s.load(Ordering::Relaxed))
    }

    /// Hand one event to `emit`.
    pub fn send(&mut self, e: &Event) -> Result<(), LiveError> {
        self.st.events += 1;
        (self.emit)(e).map_err(LiveError::Output)
    }

    /// Apply the control messages waiting on `rx`; while paused, wait for more.
    fn controls(
        &mut self,
        rx: &Receiver<ControlRequest>,
        source: &mut dyn Source,
    ) -> Result<(), LiveError> {
        let mut paused_at: Option<Instant> = None;
        loop {
            let req = if self.paused {
                // A signal ends a pause too.
                if self.stopping() {
                    self.paused = false;
                    break;
                }
                paused_at.get_or_insert_with(Instant::now);
                match rx.recv_timeout(Duration::from_millis(50)) {
                    Ok(r) => r,
                    Err(RecvTimeoutError::Timeout) => continue,
                    // Nobody can resume it any more.
                    Err(RecvTimeoutError::Disconnected) => {
                        self.paused = false;
                        continue;
                    }
                }
            } else {
                match rx.try_recv() {
                    Ok(r) => r,
                    Err(_) => break,
                }
            };
            self.st.control_line += 1;
            let mut log_event = None;
            let result = req
                .text
                .clone()
                .and_then(|t| Control::parse(&t))
                .and_then(|c| {
                    match &c {
                        Control::Pause => self.paused = true,
                        Control::Resume => self.paused = false,
                        // A stop ends a pause too. The virtual cell ends itself (its last partial
                        // chunk comes); any other source is ended here.
                        Control::Stop => {
                            self.paused = false;
                            if source.control(&c).is_err() {
                                self.stop_requested = true;
                            }
                        }
                        Control::Record(Some(name)) => {
                            self.recorder.start(name)?;
                        }
                        Control::Restart(stage) => self.restart(stage)?,
                        Control::Record(None) => {
                            log_event = self
                                .recorder
                                .stop(self.st.last_t)
                                .map_err(|e| e.to_string())?;
                            if log_event.is_none() {
                                return Err("field 'stop': no log is being written".into());
                            }
                        }
                        _ => source.control(&c)?,
                    }
                    Ok(c.name())
                })
                // What an error quotes of the message is capped: a huge message is refused, not
                // echoed to every panel and kept in the backlog.
                .map_err(|e| quote(&e, MAX_QUOTED).into_owned());
            let t_s = self.st.last_t;
            let line = self.st.control_line;
            let event = match &result {
                Ok(cmd) => Event::Control {
                    t_s,
                    cmd: (*cmd).into(),
                    line,
                },
                Err(message) => Event::Error {
                    t_s,
                    input: Input::Controls,
                    line,
                    message: message.clone(),
                },
            };
            if let Some(reply) = req.reply {
                // A client that has gone does not matter.
                let _ = reply.send(result);
            }
            self.send(&event)?;
            if let Some(e) = log_event {
                self.send(&e)?;
            }
        }
        if let Some(at) = paused_at {
            self.pacer.shift(at.elapsed());
        }
        Ok(())
    }

    /// One chunk through the stages.
    pub fn chunk(&mut self, chunk: &Recording) -> Result<(), LiveError> {
        if chunk.is_empty() {
            return Ok(());
        }
        let t = chunk.values("t")?;
        self.pacer.wait_until(t[t.len() - 1]);
        if self.st.taken == 0 {
            self.st.t_first = t[0];
        }
        self.integrity(chunk)?;
        self.st.taken += t.len();
        self.st.last_t = t[t.len() - 1];
        self.samples.clear();
        self.alarms.clear();
        if let Some(stage) = self.st.shaft.as_mut() {
            let result = ShaftInputs::of(chunk)
                .and_then(|x| stage.push(&x, &mut self.samples, &mut self.alarms));
            self.shaft_error(result)?;
        }
        for k in 0..self.samples.len() {
            let s = self.samples[k];
            // The excitation supervisor's changes (and, supervised, the start), as they happen.
            if self.cfg.monitor.supervise && self.st.shaft_frozen != Some(s.frozen) {
                self.st.shaft_frozen = Some(s.frozen);
                let names = ["K", "B", "tau0"];
                let pick = |frozen: bool| -> Vec<String> {
                    names
                        .iter()
                        .zip(s.frozen)
                        .filter(|(_, f)| *f == frozen)
                        .map(|(n, _)| n.to_string())
                        .collect()
                };
                self.send(&Event::Identifiability {
                    app: App::Shaft,
                    t_s: s.t_s,
                    estimable: pick(false),
                    frozen: pick(true),
                })?;
            }
            if self
                .st
                .last_sent
                .is_none_or(|l| s.t_s - l >= self.cfg.estimate_every_s)
            {
                self.send(&Event::shaft_estimate(&s))?;
                // The latency as delivered: the estimate event handed to every output (stdout,
                // the log, the panels' and the fleet's queues).
                if let Some(l) = self.pacer.since_due(s.t_s) {
                    self.latency.add(l);
                }
                self.st.last_sent = Some(s.t_s);
                self.st.pending = None;
            } else {
                self.st.pending = Some(s);
            }
        }
        for k in 0..self.alarms.len() {
            let e = Event::shaft_alarm(&self.alarms[k]);
            self.send(&e)?;
        }
        self.cycles(chunk)?;
        if let Some(stage) = self.friction.as_mut() {
            self.friction_out.clear();
            let result = stage.push(chunk, &mut self.friction_out);
            self.friction_events(result)?;
        }
        if let Some(stage) = self.torque.as_mut() {
            self.torque_out.clear();
            let result = stage.push(chunk, &mut self.torque_out);
            self.torque_events(result)?;
        }
        match self.recorder.push(chunk, self.st.last_t) {
            Ok(Some(e)) => self.send(&e)?,
            Ok(None) => {}
            // A log that cannot be written stops; the run goes on.
            Err(e) => {
                let t_s = self.st.last_t;
                let _ = self.recorder.stop(t_s);
                self.send(&Event::Error {
                    t_s,
                    input: Input::Record,
                    line: self.st.control_line,
                    message: format!("the log stopped: {e}"),
                })?;
            }
        }
        if self.traces.is_none() {
            if let Some(p) = &self.cfg.panel {
                self.traces = Some(TraceStage::new(chunk, p, self.rate_hz)?);
            }
        }
        if let Some(tr) = self.traces.as_mut() {
            if let Some(e) = tr.push(chunk)? {
                self.send(&e)?;
            }
        }
        Ok(())
    }

    /// The integrity checks of a chunk (`physid inspect`'s, on the stream): the encoders and
    /// the TDC marker of [`AcquisitionOptions`] the source has, time against the sample step.
    fn integrity(&mut self, chunk: &Recording) -> Result<(), LiveError> {
        if self.st.integrity.is_none() {
            let opts = AcquisitionOptions::default().integrity_options(chunk, None);
            self.st.integrity = Some(IntegrityStream::new(
                &opts,
                Basis::Time,
                Some(1.0 / self.rate_hz),
            ));
        }
        let Some(stream) = self.st.integrity.as_mut() else {
            return Ok(());
        };
        self.findings.clear();
        stream.push(chunk, &mut self.findings);
        self.send_findings()
    }

    /// The integrity findings made certain, as events.
    fn send_findings(&mut self) -> Result<(), LiveError> {
        let findings = std::mem::take(&mut self.findings);
        for f in &findings {
            self.send(&Event::Finding {
                t_s: self.st.t_first + f.index as f64 / self.rate_hz,
                message: f.detail.clone(),
                kind: Some(f.kind),
                sample: Some(f.index),
            })?;
        }
        self.findings = findings;
        Ok(())
    }

    /// The cycle statistics of a chunk.
    fn cycles(&mut self, chunk: &Recording) -> Result<(), LiveError> {
        if self.st.cycles_stopped {
            return Ok(());
        }
        if self.st.cycles.is_none() {
            let which: Vec<usize> = (0..CYCLE_CHANNELS.len())
                .filter(|&k| chunk.channel(CYCLE_CHANNELS[k]).is_ok())
                .collect();
            if which.is_empty() || chunk.channel("theta_en").is_err() {
                return Ok(());
            }
            let step = self.cfg.panel.map(|p| p.curve_step_deg);
            self.st.cycles = Some((
                CycleStream::new(which.len(), self.cfg.theta_tdc, step)?,
                which,
            ));
        }
        let Some((stream, which)) = self.st.cycles.as_mut() else {
            return Ok(());
        };
        let names: Vec<&'static str> = which.iter().map(|&k| CYCLE_CHANNELS[k]).collect();
        let cols = names
            .iter()
            .map(|n| chunk.values(n))
            .collect::<Result<Vec<_>, _>>()?;
        self.done_cycles.clear();
        let pushed = stream.push(
            chunk.values("t")?,
            chunk.values("theta_en")?,
            &cols,
            &mut self.done_cycles,
        );
        if let Err(e) = pushed {
            // A value not finite (a sensor's dropout in a replayed file): the statistics stop
            // with a finding naming the channel and sample; the run goes on.
            // The stream numbers its channels: name them.
            let e = format!("{e} (channels 0, 1, …: {})", names.join(", "));
            self.st.cycles = None;
            self.st.cycles_stopped = true;
            let t_s = self.st.last_t;
            return self.send(&Event::finding(
                t_s,
                format!("cycles: {e} — the cycle statistics stopped (restart: {{\"cmd\":\"restart\",\"stage\":\"cycles\"}})"),
            ));
        }
        let step = self.cfg.panel.map_or(0.0, |p| p.curve_step_deg);
        let events: Vec<Event> = self
            .done_cycles
            .iter()
            .map(|c| Event::cycle(c, &names, step))
            .collect();
        for e in &events {
            self.st.cycles_sent += 1;
            self.send(e)?;
        }
        Ok(())
    }

    /// At the shaft monitor's error (a source without its channels, an estimator that fails),
    /// a finding, and the monitor stops; the run and the other stages go on.
    fn shaft_error(&mut self, result: Result<(), AppError>) -> Result<(), LiveError> {
        if let Err(e) = result {
            self.st.shaft = None;
            let t_s = self.st.last_t;
            self.send(&Event::finding(
                t_s,
                format!("shaft: {e} — the shaft monitor stopped"),
            ))?;
        }
        Ok(())
    }

    /// The friction stage's output as events; at its error, a finding, and the stage stops
    /// (the run goes on).
    fn friction_events(&mut self, result: Result<(), AppError>) -> Result<(), LiveError> {
        let out = std::mem::take(&mut self.friction_out);
        for o in &out {
            let e = match o {
                FrictionOutput::Selected { t_s, estimable, .. } => Event::Identifiability {
                    app: App::Friction,
                    t_s: *t_s,
                    frozen: REGRESSION_PARAMS
                        .iter()
                        .filter(|p| !estimable.iter().any(|e| e == *p))
                        .map(|p| p.to_string())
                        .collect(),
                    estimable: estimable.clone(),
                },
                FrictionOutput::Cycle(s) => {
                    let names = self
                        .friction
                        .as_ref()
                        .and_then(FrictionStage::estimable)
                        .unwrap_or_default();
                    let by_name =
                        |v: &[f64]| names.iter().cloned().zip(v.iter().copied()).collect();
                    Event::Friction {
                        cycle: s.cycle,
                        t_s: s.t_s,
                        measured: s.measured_nm,
                        predicted: s.predicted_nm,
                        nominal: s.nominal_nm,
                        truth: s.truth_nm,
                        params: by_name(&s.params),
                        std_err: by_name(&s.std_err),
                    }
                }
            };
            self.send(&e)?;
        }
        self.friction_out = out;
        if let Err(e) = result {
            self.friction = None;
            let t_s = self.st.last_t;
            self.send(&Event::finding(
                t_s,
                format!("friction: {e} — the friction characterisation stopped"),
            ))?;
        }
        Ok(())
    }

    /// The torque stage's output as events; at its error, a finding, and the stage stops (the
    /// run goes on).
    fn torque_events(&mut self, result: Result<(), AppError>) -> Result<(), LiveError> {
        let out = std::mem::take(&mut self.torque_out);
        let names: Vec<String> = self
            .torque
            .as_ref()
            .and_then(TorqueStage::estimable)
            .unwrap_or_default()
            .iter()
            .map(|s| s.to_string())
            .collect();
        for o in &out {
            let e = match o {
                TorqueOutput::Selected { t_s, estimable, .. } => Event::Identifiability {
                    app: App::Torque,
                    t_s: *t_s,
                    frozen: physid_models::cyclic_torque::PARAMS
                        .iter()
                        .filter(|p| !estimable.iter().any(|e| e == *p))
                        .map(|p| p.to_string())
                        .collect(),
                    estimable: estimable.clone(),
                },
                TorqueOutput::Cycle(c) => {
                    let by_name =
                        |v: &[f64]| names.iter().cloned().zip(v.iter().copied()).collect();
                    Event::Torque {
                        t_s: c.t_s,
                        params: by_name(&c.params),
                        std_err: by_name(&c.std_err),
                        rms_error: c.rms_error_nm,
                        rms_measured: c.rms_measured_nm,
                    }
                }
            };
            self.send(&e)?;
        }
        self.torque_out = out;
        if let Err(e) = result {
            self.torque = None;
            let t_s = self.st.last_t;
            self.send(&Event::finding(
                t_s,
                format!("torque: {e} — the cyclic-torque estimation stopped"),
            ))?;
        }
        Ok(())
    }

    /// The end of the stream: the stages' last output, the final estimate, `end`.
    pub fn finish(mut self) -> Result<Summary, LiveError> {
        if let Some(stage) = self.torque.as_mut() {
            self.torque_out.clear();
            // A replay shorter than the choice chooses on all of it.
            let result = stage.finish(&mut self.torque_out);
            self.torque_events(result)?;
        }
        if let Some(stream) = self.st.integrity.take() {
            self.findings.clear();
            stream.finish(&mut self.findings);
            self.send_findings()?;
        }
        if let Some(stage) = self.friction.as_mut() {
            self.friction_out.clear();
            // The last cycle judged; a replay shorter than the choice chooses on all its cycles.
            let result = stage.finish(&mut self.friction_out).map(|_| ());
            self.friction_events(result)?;
        }
        self.samples.clear();
        self.alarms.clear();
        if let Some(stage) = self.st.shaft.as_mut() {
            let result = stage.finish(&mut self.samples, &mut self.alarms);
            self.shaft_error(result)?;
        }
        for k in 0..self.alarms.len() {
            let e = Event::shaft_alarm(&self.alarms[k]);
            self.send(&e)?;
        }
        if let Some(s) = self.samples.last().copied().or(self.st.pending) {
            self.send(&Event::shaft_estimate(&s))?;
        }
        if let Some(e) = self.traces.as_mut().and_then(TraceStage::flush) {
            self.send(&e)?;
        }
        if let Some(e) = self.recorder.stop(self.st.last_t)? {
            self.send(&e)?;
        }
        let latency_ms =
            self.latency
                .summary_ms()
                .map(|[p50, p99, max]| LatencyMs { p50, p99, max });
        let (t_s, samples, dropped) = (self.st.last_t, self.st.taken, self.st.dropped);
        self.send(&Event::End {
            t_s,
            samples,
            dropped,
            latency_ms,
        })?;
        Ok(Summary {
            samples,
            dropped,
            shaft: self.st.shaft.as_ref().map(|s| (s.estimate(), s.std_err())),
            cycles: self.st.cycles_sent,
            events: self.st.events,
        })
    }
}

/// A latency histogram: 0.1 ms bins up to 2 s, then 10 ms bins up to 2 min (no allocation
/// after construction). A quantile is its bin's upper edge, so within 0.1 ms below 2 s and
/// within 10 ms above; a quantile among latencies beyond 2 min is the largest seen.
#[derive(Debug, Clone)]
pub struct LatencyHistogram {
    bins: Vec<u64>,
    count: u64,
    max_s: f64,
}

/// Width of a fine bin [s] and where the fine bins end.
const BIN_S: f64 = 1e-4;
const FINE_S: f64 = 2.0;
/// Width of a coarse bin [s] and where they end.
const COARSE_BIN_S: f64 = 1e-2;
const COARSE_S: f64 = 120.0;
const FINE_BINS: usize = 20_000;
const BINS: usize = FINE_BINS + 11_800;

impl Default for LatencyHistogram {
    fn default() -> Self {
        Self {
            bins: vec![0; BINS + 1],
            count: 0,
            max_s: 0.0,
        }
    }
}

impl LatencyHistogram {
    /// Count one latency [s] (negative as 0; beyond 2 min in an overflow bin).
    pub fn add(&mut self, s: f64) {
        let s = s.max(0.0);
        let k = if s < FINE_S {
            ((s / BIN_S) as usize).min(FINE_BINS - 1)
        } else if s < COARSE_S {
            (FINE_BINS + ((s - FINE_S) / COARSE_BIN_S) as usize).min(BINS - 1)
        } else {
            BINS
        };
        self.bins[k] += 1;
        self.count += 1;
        self.max_s = self.max_s.max(s);
    }

    /// The `q`-quantile [s] (the upper edge of its bin, never above the largest seen); `None`
    /// when empty.
    pub fn quantile(&self, q: f64) -> Option<f64> {
        if self.count == 0 {
            return None;
        }
        let want = (q * self.count as f64).ceil().max(1.0) as u64;
        let mut seen = 0;
        for (k, &n) in self.bins.iter().enumerate() {
            seen += n;
            if seen >= want {
                let edge = if k < FINE_BINS {
                    (k + 1) as f64 * BIN_S
                } else if k < BINS {
                    FINE_S + (k - FINE_BINS + 1) as f64 * COARSE_BIN_S
                } else {
                    self.max_s
                };
                return Some(edge.min(self.max_s));
            }
        }
        Some(self.max_s)
    }

    /// The largest [s].
    pub fn max(&self) -> f64 {
        self.max_s
    }

    /// Median, 99th percentile and largest [ms], each to 0.1 ms; `None` when empty.
    pub fn summary_ms(&self) -> Option<[f64; 3]> {
        let ms = |s: f64| (s * 1e4).round() / 10.0;
        Some([
            ms(self.quantile(0.5)?),
            ms(self.quantile(0.99)?),
            ms(self.max_s),
        ])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::source::{ScenarioSource, Source};
    use physid_sim::run::{OutputBasis, RunOptions};
    use physid_sim::scenario::{Fault, Scenario};

    fn chunks() -> (Vec<Recording>, f64) {
        let opts = RunOptions {
            duration: Some(4.0),
            faults: vec![Fault::parse("shaft.k=1000@2").unwrap()],
            basis: OutputBasis::Time(5000.0),
            ..Default::default()
        };
        let mut src =
            ScenarioSource::new(&Scenario::load("shaft-steady").unwrap(), &opts, 0.013).unwrap();
        let mut out = Vec::new();
        while let Some(c) = src.next_chunk().unwrap() {
            out.push(c);
        }
        (out, src.rate_hz())
    }

    fn json(events: &[Event]) -> Vec<String> {
        events
            .iter()
            .map(|e| serde_json::to_string(e).unwrap())
            .collect()
    }

    /// The stages checkpointed at any chunk and restored (through bytes) give the events an
    /// uninterrupted run gives, bit for bit — the alarm of a stiffness fault, the estimates,
    /// the cycles, the end.
    #[test]
    fn a_restored_checkpoint_goes_on_exactly() {
        let (chunks, rate) = chunks();
        let cfg = LiveConfig::default();
        let mut whole = Vec::new();
        let mut s = Stages::new(cfg.clone(), rate, |e: &Event| {
            whole.push(e.clone());
            Ok(())
        })
        .unwrap();
        for c in &chunks {
            s.chunk(c).unwrap();
        }
        s.finish().unwrap();
        assert!(whole.iter().any(|e| matches!(e, Event::Alarm { .. })));
        for cut in [1, chunks.len() / 3, chunks.len() - 1] {
            let mut first = Vec::new();
            let mut s = Stages::new(cfg.clone(), rate, |e: &Event| {
                first.push(e.clone());
                Ok(())
            })
            .unwrap();
            for c in &chunks[..cut] {
                s.chunk(c).unwrap();
            }
            let bytes = s.checkpoint().unwrap();
            drop(s);
            let mut second = Vec::new();
            let mut s = Stages::restore(cfg.clone(), &bytes, |e: &Event| {
                second.push(e.clone());
                Ok(())
            })
            .unwrap();
            for c in &chunks[cut..] {
                s.chunk(c).unwrap();
            }
            s.finish().unwrap();
            first.extend(second);
            assert_eq!(json(&first), json(&whole), "cut at chunk {cut}");
        }
        // Another layout is refused with a reason, not misread.
        let bad = rmp_serde::to_vec(&(CHECKPOINT_VERSION + 1, 0u8)).unwrap();
        let e = Stages::restore(cfg, &bad, |_: &Event| Ok(()))
            .err()
            .unwrap();
        assert!(e.to_string().contains("checkpoint"), "{e}");
    }

    /// Quantiles of 1 … 1000 ms: the median's bin ends at 500 ms, the 99th percentile's at
    /// 990 ms (0.1 ms bins); beyond 2 s within 10 ms (the `bench fleet` run whose p99 stuck at
    /// 2000 ms while its max was 2729 ms); beyond 2 min the largest seen.
    #[test]
    fn histogram_quantiles() {
        let mut h = LatencyHistogram::default();
        assert_eq!(h.quantile(0.5), None);
        assert_eq!(h.summary_ms(), None);
        for k in 1..=1000 {
            h.add(k as f64 * 1e-3 - 5e-5);
        }
        assert!((h.quantile(0.5).unwrap() - 0.5).abs() < 1e-9);
        assert!((h.quantile(0.99).unwrap() - 0.99).abs() < 1e-9);
        h.add(5.0);
        assert_eq!(h.max(), 5.0);
        assert!((h.quantile(1.0).unwrap() - 5.0).abs() < 1e-9);
        // Latencies 1.5 … 3.0 s: the 99th percentile is 2.985 s, within one 10 ms bin.
        let mut slow = LatencyHistogram::default();
        for k in 0..=300 {
            slow.add(1.5 + k as f64 * 0.005 + 1e-6);
        }
        let p99 = slow.quantile(0.99).unwrap();
        assert!((2.985..=2.995 + 1e-9).contains(&p99), "{p99}");
        let [p50, p99_ms, max] = slow.summary_ms().unwrap();
        // The median 2.250001 s is in the 10 ms bin [2.25, 2.26): its upper edge.
        assert_eq!((p50, max), (2260.0, 3000.0));
        assert!((p99_ms * 10.0).fract() == 0.0 && p99_ms <= max);
        slow.add(500.0);
        assert_eq!(slow.quantile(1.0), Some(500.0));
    }
}
