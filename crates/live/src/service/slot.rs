//! One stage of a live run, whatever its type. A [`Slot`] holds an application's [`Stage`]:
//! it pushes each chunk through it, tells the stage's outputs as events through [`Tell`], stops
//! it at its error with a finding (the run and the other stages go on) and starts it afresh at
//! a `restart`. [`Run`] is a slot with its type taken away, so that [`Stages`] is a list of
//! them; [`Emit`] is where their events go.

use super::*;
use physid_core::Sink;
use serde::de::DeserializeOwned;

/// What telling a stage's outputs needs to know of the run.
#[derive(Clone, Copy)]
pub(super) struct At<'a> {
    /// The run's configuration.
    pub cfg: &'a LiveConfig,
    /// The stream's sample rate [Hz].
    pub rate_hz: f64,
    /// The time of the stream's first sample [s].
    pub t_first: f64,
    /// The time of its latest sample [s].
    pub last_t: f64,
    /// Whether the stream has ended (the stages' `finish`).
    pub end: bool,
}

/// An application's stage as the live service runs it: how it is started from the run's
/// configuration and how its outputs are told as events.
pub(super) trait Tell: Stage + Sized {
    /// Its name: in a `restart` control ([`STAGES`](crate::control::STAGES)) and in the finding
    /// that says it stopped.
    const NAME: &'static str;
    /// What that finding says after the error: "the shaft monitor stopped".
    const STOPPED: &'static str;
    /// The flag that asks for it, for a `restart` of a stage the run does not have.
    const FLAG: &'static str;
    /// What the telling remembers from one output to the next (checkpointed with the stage).
    type Told: Default + Serialize + DeserializeOwned;

    /// The stage the run's configuration asks for, new (`None`: the run has none).
    fn start(cfg: &LiveConfig, rate_hz: f64) -> Result<Option<Self>, LiveError>;

    /// One output, as events.
    fn tell(&self, told: &mut Self::Told, out: &Self::Out, at: At, events: &mut dyn Sink<Event>);

    /// At the end, after the stage's last outputs (and when it stopped earlier too): what is
    /// still to tell.
    fn tell_end(_told: &mut Self::Told, _at: At, _events: &mut dyn Sink<Event>) {}

    /// A `restart`: what the telling forgets.
    fn restarted(_told: &mut Self::Told) {}
}

/// One stage of the run and what telling its outputs remembers; checkpointed whole.
#[derive(Serialize, Deserialize)]
#[serde(bound = "")]
pub(super) struct Slot<S: Tell> {
    /// The stage (`None`: the run has none, or it stopped at an error).
    stage: Option<S>,
    told: S::Told,
    /// Its outputs of one chunk, told at once (kept: no allocation per chunk).
    #[serde(skip)]
    out: Vec<S::Out>,
}

impl<S: Tell> Slot<S> {
    /// The stage `cfg` asks for, new.
    pub fn start(cfg: &LiveConfig, rate_hz: f64) -> Result<Self, LiveError> {
        Ok(Self {
            stage: S::start(cfg, rate_hz)?,
            told: S::Told::default(),
            out: Vec::new(),
        })
    }

    /// The stage, while it runs.
    pub fn stage(&self) -> Option<&S> {
        self.stage.as_ref()
    }

    /// What telling its outputs remembers.
    pub fn told(&self) -> &S::Told {
        &self.told
    }

    /// The outputs of `result` (the stage's push or finish) as events; at its error, a finding,
    /// and the stage stops.
    fn tell_all(&mut self, result: Result<(), AppError>, at: At, events: &mut dyn Sink<Event>) {
        if let Some(stage) = &self.stage {
            for o in &self.out {
                stage.tell(&mut self.told, o, at, events);
            }
        }
        if let Err(e) = result {
            self.stage = None;
            events.put(Event::finding(
                at.last_t,
                format!("{}: {e} — {}", S::NAME, S::STOPPED),
            ));
        }
    }
}

/// A [`Slot`] with its stage's type taken away: what [`Stages`] runs a chunk through.
pub(super) trait Run {
    /// The stage's name ([`Tell::NAME`]).
    fn name(&self) -> &'static str;
    /// One chunk through the stage, its outputs told to `events`.
    fn push(&mut self, chunk: &Recording, at: At, events: &mut dyn Sink<Event>);
    /// The end of the stream: the stage's last outputs and what is still to tell.
    fn finish(&mut self, at: At, events: &mut dyn Sink<Event>);
    /// Start the stage afresh, from its configuration; refused when the run has none.
    fn restart(&mut self, cfg: &LiveConfig, rate_hz: f64) -> Result<(), String>;
}

impl<S: Tell> Run for Slot<S> {
    fn name(&self) -> &'static str {
        S::NAME
    }

    fn push(&mut self, chunk: &Recording, at: At, events: &mut dyn Sink<Event>) {
        let Some(stage) = self.stage.as_mut() else {
            return;
        };
        self.out.clear();
        let result = stage.push(chunk, &mut self.out);
        self.tell_all(result, at, events);
    }

    fn finish(&mut self, at: At, events: &mut dyn Sink<Event>) {
        if let Some(stage) = self.stage.as_mut() {
            self.out.clear();
            let result = stage.finish(&mut self.out);
            self.tell_all(result, at, events);
        }
        S::tell_end(&mut self.told, at, events);
    }

    fn restart(&mut self, cfg: &LiveConfig, rate_hz: f64) -> Result<(), String> {
        let stage = S::start(cfg, rate_hz).map_err(|e| e.to_string())?;
        self.stage = Some(stage.ok_or_else(|| {
            format!(
                "field 'stage' is '{}': this run has none ({})",
                S::NAME,
                S::FLAG
            )
        })?);
        S::restarted(&mut self.told);
        Ok(())
    }
}

/// Where the stages' events go: `emit`, each counted. The first error of `emit` is kept (the
/// run stops with it) and nothing more is sent. The shaft monitor's estimates as the stream
/// runs (not at its end) add their delivery latency to the histogram.
pub(super) struct Emit<'a, E> {
    emit: &'a mut E,
    events: &'a mut usize,
    latency: &'a mut LatencyHistogram,
    pacer: &'a Pacer,
    end: bool,
    error: Option<LiveError>,
}

impl<'a, E: FnMut(&Event) -> Result<(), String>> Emit<'a, E> {
    /// Events to `emit`, counted in `events`; at the stream's `end` or during it.
    pub fn new(
        emit: &'a mut E,
        events: &'a mut usize,
        latency: &'a mut LatencyHistogram,
        pacer: &'a Pacer,
        end: bool,
    ) -> Self {
        Self {
            emit,
            events,
            latency,
            pacer,
            end,
            error: None,
        }
    }

    /// `emit`'s first error, if it failed.
    pub fn result(self) -> Result<(), LiveError> {
        self.error.map_or(Ok(()), Err)
    }
}

impl<E: FnMut(&Event) -> Result<(), String>> Sink<Event> for Emit<'_, E> {
    fn put(&mut self, e: Event) {
        if self.error.is_some() {
            return;
        }
        *self.events += 1;
        if let Err(m) = (self.emit)(&e) {
            self.error = Some(LiveError::Output(m));
            return;
        }
        // The latency as delivered: the estimate event handed to every output (stdout, the
        // log, the panels' and the fleet's queues).
        if let (
            false,
            Event::Estimate {
                app: App::Shaft,
                t_s,
                ..
            },
        ) = (self.end, &e)
        {
            if let Some(l) = self.pacer.since_due(*t_s) {
                self.latency.add(l);
            }
        }
    }
}
