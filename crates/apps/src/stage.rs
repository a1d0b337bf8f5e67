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
    /// The value there: in JSON `"NaN"`, `"inf"` or `"-inf"` (JSON has no such numbers).
    #[serde(serialize_with = "as_text")]
    pub value: f64,
}

/// A value that is not a number as Rust writes it (`NaN`, `inf`, `-inf`).
fn as_text<S: serde::Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
    s.collect_str(v)
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

    /// What the live service and the file verbs tell: what it was, where, and what was done.
    pub fn message(&self) -> String {
        format!(
            "'{}' is {} at sample {} (t = {} s): the cycle it cuts is left out, the analysis goes on after it",
            self.channel,
            self.value,
            self.sample,
            physid_core::Num(self.t_s)
        )
    }
}

/// The dropouts of a crank-angle recording's channels as its chunks come (the file verbs that
/// take its cycles as blocks: each dropout's first sample, told once however many samples and
/// chunks it lasts). A stage on a time-basis stream finds them with its cycles
/// ([`CycleStream::push_past_dropouts`](physid_signal::cycles::CycleStream::push_past_dropouts)).
#[derive(Debug, Clone, Default)]
pub struct DropoutLog {
    /// Each dropout, at its first sample.
    pub found: Vec<Dropout>,
    /// Whether each channel's last sample was not a number.
    within: Vec<bool>,
    /// Samples seen before the next chunk.
    samples: usize,
}

impl DropoutLog {
    /// The next chunk: its `channels` (name, values), of one length with its time `t`.
    pub fn see(&mut self, channels: &[(&str, &[f64])], t: &[f64]) {
        self.within.resize(channels.len(), false);
        for ((name, v), within) in channels.iter().zip(&mut self.within) {
            for (i, x) in v.iter().enumerate() {
                let not = !x.is_finite();
                if not && !*within {
                    self.found.push(Dropout {
                        t_s: t.get(i).copied().unwrap_or(f64::NAN),
                        channel: name.to_string(),
                        sample: self.samples + i,
                        value: *x,
                    });
                }
                *within = not;
            }
        }
        self.samples += t.len();
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
