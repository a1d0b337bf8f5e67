//! The one loop the file verbs' live path, `physid live` and the fleet worker share: a chunk
//! through the integrity check and the stages, their outputs as events; controls; checkpoints.

use super::*;
use physid_core::Sink;

impl<E: FnMut(&Event) -> Result<(), String>> Stages<E> {
    /// The stages of `cfg` for a stream at `rate_hz` [Hz].
    pub fn new(cfg: LiveConfig, rate_hz: f64, emit: E) -> Result<Self, LiveError> {
        let st = State {
            rate_hz,
            stages: StageSlots::start(&cfg, rate_hz)?,
            t_first: f64::NAN,
            events: 0,
            taken: 0,
            dropped: 0,
            control_line: 0,
            last_t: f64::NAN,
        };
        Self::with_state(cfg, st, emit)
    }

    fn with_state(cfg: LiveConfig, st: State, emit: E) -> Result<Self, LiveError> {
        Ok(Self {
            rate_hz: st.rate_hz,
            st,
            traces: None,
            recorder: Recorder::new(&cfg.log_dir),
            pacer: Pacer::new(cfg.pace),
            cfg,
            emit,
            paused: false,
            stop_requested: false,
            latency: LatencyHistogram::default(),
        })
    }

    /// Start the stage `name` afresh (`restart` control): one stopped by an error comes back,
    /// from its configured start, on the samples from now on.
    fn restart(&mut self, name: &str) -> Result<(), String> {
        let (cfg, rate_hz) = (&self.cfg, self.rate_hz);
        match self
            .st
            .stages
            .in_chunk_order()
            .into_iter()
            .find(|s| s.name() == name)
        {
            Some(stage) => stage.restart(cfg, rate_hz),
            None => Err(format!("field 'stage' is '{name}': no stage of that name")),
        }
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
        let read =
            |e: rmp_serde::decode::Error| LiveError::Invalid(format!("reading a checkpoint: {e}"));
        // The layout first: a state of another layout would not read as this one's `State`.
        let (version, _): (u32, serde::de::IgnoredAny) =
            rmp_serde::from_slice(bytes).map_err(read)?;
        if version != CHECKPOINT_VERSION {
            return Err(LiveError::Invalid(format!(
                "a checkpoint of layout {version}: this physid reads layout {CHECKPOINT_VERSION}"
            )));
        }
        let (_, st): (u32, State) = rmp_serde::from_slice(bytes).map_err(read)?;
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

    /// One chunk through the stages, in order; then into the log and the panel's traces.
    pub fn chunk(&mut self, chunk: &Recording) -> Result<(), LiveError> {
        if chunk.is_empty() {
            return Ok(());
        }
        let t = chunk.values("t")?;
        self.pacer.wait_until(t[t.len() - 1]);
        if self.st.taken == 0 {
            self.st.t_first = t[0];
        }
        self.st.taken += t.len();
        self.st.last_t = t[t.len() - 1];
        self.tell(false, |stages, _, at, events| {
            for stage in stages.in_chunk_order() {
                stage.push(chunk, at, events);
            }
            Ok(())
        })?;
        match self.recorder.push(chunk, self.st.last_t) {
            Ok(Some(e)) => self.send(&e)?,
            Ok(None) => {}
            // A log that cannot go on stops, keeping what it can; the run goes on.
            Err(stopped) => {
                self.send(&Event::Error {
                    t_s: self.st.last_t,
                    input: Input::Record,
                    line: self.st.control_line,
                    message: stopped.message,
                })?;
                self.send(&stopped.last)?;
            }
        }
        if self.traces.is_none() {
            if let Some(p) = &self.cfg.panel {
                self.traces = Some(TraceStage::new(chunk, p, self.rate_hz)?);
            }
        }
        self.tell(false, |_, traces, _, events| match traces {
            Some(tr) => tr.push(chunk, events),
            None => Ok(()),
        })
    }

    /// `run` on the stages and the panel's traces, what telling their outputs needs to know of
    /// the run (during the stream, or at its `end`) and the sink their events go to; `emit`'s
    /// first error, or `run`'s, is the result.
    fn tell(
        &mut self,
        end: bool,
        run: impl FnOnce(
            &mut StageSlots,
            Option<&mut TraceStage>,
            At,
            &mut dyn Sink<Event>,
        ) -> Result<(), AppError>,
    ) -> Result<(), LiveError> {
        let at = At {
            cfg: &self.cfg,
            rate_hz: self.rate_hz,
            t_first: self.st.t_first,
            last_t: self.st.last_t,
            end,
        };
        let mut events = Emit::new(
            &mut self.emit,
            &mut self.st.events,
            &mut self.latency,
            &self.pacer,
            end,
        );
        let result = run(&mut self.st.stages, self.traces.as_mut(), at, &mut events);
        events.result()?;
        Ok(result?)
    }

    /// The end of the stream: the stages' last output, the final estimate, `end`.
    pub fn finish(mut self) -> Result<Summary, LiveError> {
        self.tell(true, |stages, traces, at, events| {
            for stage in stages.in_finish_order() {
                stage.finish(at, events);
            }
            match traces {
                Some(tr) => tr.finish(events),
                None => Ok(()),
            }
        })?;
        match self.recorder.stop(self.st.last_t) {
            Ok(Some(e)) => self.send(&e)?,
            Ok(None) => {}
            // A log that cannot be closed (its disk full) is said, with what its file keeps;
            // the run still ends as it should.
            Err(e) => self.send(&Event::Error {
                t_s: self.st.last_t,
                input: Input::Record,
                line: self.st.control_line,
                message: format!("closing the log: {e}"),
            })?,
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
            shaft: (self.st.stages.shaft.stage()).map(|s| (s.estimate(), s.std_err())),
            cycles: *self.st.stages.cycles.told(),
            events: self.st.events,
        })
    }
}
