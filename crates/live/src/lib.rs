//! # physid-live — the live service (thesis §4.4: acquisition streamed in chunks to a host)
//!
//! * [`source`] — where chunks of samples come from: the virtual test cell run as a stream
//!   ([`ScenarioSource`]), a recording replayed ([`ReplaySource`]); paced by the wall clock
//!   ([`Pace`]).
//! * [`control`] — control messages for the running cell (speed, throttle, faults, stop),
//!   parsed with errors that name the field.
//! * [`event`] — what the service emits ([`Event`]): estimates with standard errors, alarms,
//!   the end of a run; one JSON object each (`physid live --headless --json` prints them one
//!   per line).
//! * [`frames`] — frames from outside (a DAQ, a script) as JSON lines ([`FrameSource`]);
//!   a bad frame is refused with its line and the stream goes on.
//! * [`headless`] — the loop: chunks from a source through the applications' stages (the same
//!   stages the file verbs run), events out.
//!
//! Built so far: the shaft monitor's stage on a paced virtual cell or a replay, headless. Not
//! yet: the web panel, frames from outside, the other applications' stages (see the issue).

pub mod control;
pub mod event;
pub mod frames;
pub mod headless;
pub mod source;

pub use control::Control;
pub use event::Event;
pub use frames::{FrameSource, FRAME_CHANNELS};
pub use headless::{run_headless, LiveConfig, LiveError, Summary};
pub use source::{Pace, ReplaySource, ScenarioSource, Source};
