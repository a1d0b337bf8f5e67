//! One shape for the stages of the data path: a [`Stage`] takes a recording's chunks as they
//! come and hands what it makes to a [`Sink`]; [`Stage::finish`] gives what it still holds at
//! the end of the stream.
//!
//! A stage's whole state is `serde` data (the trait asks for it): the live service's checkpoint
//! holds every stage it runs, and a restored stage continues bit for bit.
//!
//! The file verbs and the live service drive the same stages — the shaft monitor
//! ([`ShaftStage`](crate::shaft_monitor::ShaftStage)), the friction characterisation
//! ([`FrictionStage`](crate::friction_fit::FrictionStage)), the cyclic-torque estimation
//! ([`TorqueStage`](crate::torque_fit::TorqueStage)), the integrity check
//! ([`IntegrityStream`]) — so a recording read from a file, a replay and frames from NATS give
//! the same outputs for the same samples.

use crate::error::AppError;
use physid_core::Recording;
use physid_signal::integrity::{Finding, IntegrityStream};

pub use physid_core::Sink;

/// A stage of the data path (see the module docs): its state serializable, so that it
/// checkpoints.
pub trait Stage: serde::Serialize + serde::de::DeserializeOwned {
    /// What the stage makes.
    type Out;

    /// The next chunk of the stream (samples in time order, the stream's channels); what it
    /// completes goes to `out`. An error stops the stage; the caller decides whether the run
    /// goes on without it.
    fn push(&mut self, chunk: &Recording, out: &mut dyn Sink<Self::Out>) -> Result<(), AppError>;

    /// The end of the stream: what the stage still holds goes to `out`.
    fn finish(&mut self, out: &mut dyn Sink<Self::Out>) -> Result<(), AppError>;
}

/// A dropout a stage left out — samples whose crank angle or a channel it reads is not a number
/// (a sensor's NaN), the cycle they cut left out ([`CycleStream::push_past_dropouts`]): told
/// once, at its first sample.
///
/// [`CycleStream::push_past_dropouts`]: physid_signal::cycles::CycleStream::push_past_dropouts
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Dropout {
    /// Its first sample's time [s].
    pub t_s: f64,
    /// The channel that is not a number there (`theta_en`: the crank angle).
    pub channel: String,
    /// Its first sample's index in the stage's input.
    pub sample: usize,
    /// The value there.
    pub value: f64,
}

impl Dropout {
    /// `d` of a cycle stream over `names` (its channels, in order) whose sample 0 is the
    /// stage's `before`-th.
    pub fn of_cycles<N: AsRef<str>>(
        d: &physid_signal::cycles::Dropout,
        names: &[N],
        before: usize,
    ) -> Self {
        Self {
            t_s: d.t,
            channel: d
                .channel
                .and_then(|j| names.get(j))
                .map_or("theta_en", |n| n.as_ref())
                .to_string(),
            sample: before + d.sample,
            value: d.value,
        }
    }

    /// What the live service tells: what it was and what the stage did.
    pub fn message(&self) -> String {
        format!(
            "'{}' is {} at sample {}: the cycle it cuts is left out, the stage goes on after the dropout",
            self.channel, self.value, self.sample
        )
    }

    /// The error a file verb that needs every sample makes of it: `needs`, why.
    pub fn refused(&self, needs: &str) -> AppError {
        AppError::Invalid(format!(
            "channel '{}' sample {} is {}: {needs}",
            self.channel, self.sample, self.value
        ))
    }
}

/// The post-run integrity check on the stream (`physid inspect`'s, as the chunks come): the
/// findings each chunk makes certain, and at the end those still waiting and the per-kind
/// summaries. It never fails.
impl Stage for IntegrityStream {
    type Out = Finding;

    fn push(&mut self, chunk: &Recording, out: &mut dyn Sink<Finding>) -> Result<(), AppError> {
        IntegrityStream::push(self, chunk, out);
        Ok(())
    }

    fn finish(&mut self, out: &mut dyn Sink<Finding>) -> Result<(), AppError> {
        IntegrityStream::finish(self, out);
        Ok(())
    }
}
