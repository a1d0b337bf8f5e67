//! The one loop the file verbs' live path, `physid live` and the fleet worker share: a chunk
//! through the integrity check and the stages, their outputs as events; controls; checkpoints.

use super::*;

impl<E: FnMut(&Event) -> Result<(), String>> Stages<E> {
    /// The stages of `cfg` for a stream at `rate_hz` [Hz].
    pub fn new(cfg: LiveConfig, rate_hz: f64, emit: E) -> Result<Self, LiveError> {
        let st = State {
            rate_hz,
            shaft: Some(ShaftStage::new(&cfg.monitor, rate_hz)?),
            cycles: Some(Self::cycle_stage(&cfg)),
            shaft_frozen: None,
            integrity: None,
            friction: Self::friction_stage(&cfg)?,
            torque: Self::torque_stage(&cfg)?,
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
        Ok(Self {
            rate_hz: st.rate_hz,
            st,
            traces: None,
            trace_out: Vec::new(),
            friction_out: Vec::new(),
            torque_out: Vec::new(),
            findings: Vec::new(),
            recorder: Recorder::new(&cfg.log_dir),
            pacer: Pacer::new(cfg.pace),
            cfg,
            emit,
            paused: false,
            stop_requested: false,
            latency: LatencyHistogram::default(),
            shaft_out: Vec::new(),
            done_cycles: Vec::new(),
        })
    }

    /// The cycle statistics of a run of `cfg`, new.
    fn cycle_stage(cfg: &LiveConfig) -> CycleStage {
        let step = cfg.panel.map(|p| p.curve_step_deg);
        CycleStage::new(&CYCLE_CHANNELS, cfg.theta_tdc, step)
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
                self.st.cycles = Some(Self::cycle_stage(&self.cfg));
            }
            "friction" => {
                self.st.friction = Some(
                    Self::friction_stage(&self.cfg)
                        .map_err(|e| e.to_string())?
                        .ok_or_else(|| none("--friction"))?,
                );
            }
            _ => {
                self.st.torque = Some(
                    Self::torque_stage(&self.cfg)
                        .map_err(|e| e.to_string())?
                        .ok_or_else(|| none("--torque"))?,
                );
            }
        }
        Ok(())
    }

    /// The state of the stages as bytes (MessagePack with field names, led by
    /// [`CHECKPOINT_VERSION`]); refused while a log is being written.
    pub fn checkpoint(&self) -> Result<Vec<u8>, LiveError> {
        if self.recorder.is_recording() {
            return Err(LiveError::Invalid(
                "a checkpoint covers the stages (shaft, cycles, integrity, friction, torque); \
                 a log being written is not checkpointed"
                    .into(),
            ));
        }
        rmp_serde::to_vec_named(&(CHECKPOINT_VERSION, &self.st))
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
    pub(super) fn stopping(&self) -> bool {
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
    pub(super) fn controls(
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
        self.shaft_out.clear();
        if let Some(stage) = self.st.shaft.as_mut() {
            let result = stage.push(chunk, &mut self.shaft_out);
            self.shaft_error(result)?;
        }
        // The stage hands on a chunk's samples, then its alarms.
        for k in 0..self.shaft_out.len() {
            let s = match &self.shaft_out[k] {
                ShaftOutput::Sample(s) => *s,
                ShaftOutput::Alarm(a) => {
                    let e = Event::shaft_alarm(a);
                    self.send(&e)?;
                    continue;
                }
            };
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
        self.cycles(chunk)?;
        if let Some(stage) = self.st.friction.as_mut() {
            self.friction_out.clear();
            let result = stage.push(chunk, &mut self.friction_out);
            self.friction_events(result)?;
        }
        if let Some(stage) = self.st.torque.as_mut() {
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
            let mut out = std::mem::take(&mut self.trace_out);
            out.clear();
            tr.push(chunk, &mut out)?;
            for e in &out {
                self.send(e)?;
            }
            self.trace_out = out;
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

    /// The cycle statistics of a chunk, as events; at their error, a finding, and they stop
    /// (the run goes on).
    fn cycles(&mut self, chunk: &Recording) -> Result<(), LiveError> {
        let Some(stage) = self.st.cycles.as_mut() else {
            return Ok(());
        };
        self.done_cycles.clear();
        if let Err(e) = stage.push(chunk, &mut self.done_cycles) {
            // A value not finite (a sensor's dropout in a replayed file): the statistics stop
            // with a finding naming the channel and sample; the run goes on.
            self.st.cycles = None;
            let t_s = self.st.last_t;
            return self.send(&Event::finding(
                t_s,
                format!("cycles: {e} — the cycle statistics stopped (restart: {{\"cmd\":\"restart\",\"stage\":\"cycles\"}})"),
            ));
        }
        let step = stage.curve_step_deg().unwrap_or(0.0);
        let events: Vec<Event> = self
            .done_cycles
            .iter()
            .map(|c| Event::cycle(c, stage.channels(), step))
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
                        .st
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
            self.st.friction = None;
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
            .st
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
            self.st.torque = None;
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
        if let Some(stage) = self.st.torque.as_mut() {
            self.torque_out.clear();
            // A replay shorter than the choice chooses on all of it.
            let result = stage.finish(&mut self.torque_out);
            self.torque_events(result)?;
        }
        if let Some(mut stream) = self.st.integrity.take() {
            self.findings.clear();
            stream.finish(&mut self.findings);
            self.send_findings()?;
        }
        if let Some(stage) = self.st.friction.as_mut() {
            self.friction_out.clear();
            // The last cycle judged; a replay shorter than the choice chooses on all its cycles.
            let result = stage.finish(&mut self.friction_out);
            self.friction_events(result)?;
        }
        self.shaft_out.clear();
        if let Some(stage) = self.st.shaft.as_mut() {
            let result = stage.finish(&mut self.shaft_out);
            self.shaft_error(result)?;
        }
        let mut last = None;
        for k in 0..self.shaft_out.len() {
            match &self.shaft_out[k] {
                ShaftOutput::Sample(s) => last = Some(*s),
                ShaftOutput::Alarm(a) => {
                    let e = Event::shaft_alarm(a);
                    self.send(&e)?;
                }
            }
        }
        if let Some(s) = last.or(self.st.pending) {
            self.send(&Event::shaft_estimate(&s))?;
        }
        if let Some(tr) = self.traces.as_mut() {
            let mut out = std::mem::take(&mut self.trace_out);
            out.clear();
            tr.finish(&mut out)?;
            for e in &out {
                self.send(e)?;
            }
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
