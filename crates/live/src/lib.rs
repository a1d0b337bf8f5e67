//! # physid-live — the live service (thesis §4.4: acquisition streamed in chunks to a host)
//!
//! * [`source`] — where chunks of samples come from: the virtual test cell run as a stream
//!   ([`ScenarioSource`]), a recording replayed ([`ReplaySource`]); paced by the wall clock
//!   ([`Pace`]).
//! * [`frames`] — frames from outside (a DAQ, a script) as JSON lines ([`FrameSource`]);
//!   a bad frame is refused with its line and the stream goes on.
//! * [`control`] — control messages for the running cell (speed, throttle, faults, pause,
//!   resume, stop), parsed with errors that name the field.
//! * [`service`] — the loop: chunks from a source through the applications' stages (the same
//!   stages the file verbs run: the shaft monitor, the cycle statistics; the panel's traces),
//!   events out.
//! * [`trace`] — the panel's time traces (bin means at a display rate).
//! * [`event`] — what the service emits ([`Event`]), one JSON object each
//!   (`physid live --headless --json` prints them one per line).
//! * [`record`] — logging the live data to Parquet as it comes (the panel's logging control).
//! * [`hub`] — between the loop and the panel's clients: numbered, kept for late clients,
//!   broadcast without ever making the loop wait.
//! * [`panel`] — the web panel's server: embedded page, event stream, controls, the token rule.
//! * [`layout`] — the panel's layout (plots, channels, window), from the page or a file.

pub mod control;
pub mod event;
pub mod fleet;
pub mod frames;
pub mod hub;
pub mod layout;
pub mod message;
pub mod panel;
pub mod record;
pub mod serve;
pub mod service;
pub mod source;
pub mod trace;
pub mod wire;

pub use control::{forward_control_lines, Control, ControlRequest, MAX_CONTROL_BYTES};
pub use event::{App, Event, Input, LogState};
#[cfg(unix)]
pub use frames::SocketFrames;
pub use frames::{FrameLines, FrameSource, PipedFrames, FRAME_CHANNELS, MAX_FRAME_BYTES};
pub use hub::Hub;
pub use layout::Layout;
pub use message::{Hello, PanelMessage, Reply};
pub use panel::{Access, Panel};
pub use service::{
    run_live, CombustionLive, FrictionLive, LiveConfig, LiveError, PanelFeed, Stages, Summary,
    TorqueLive,
};
pub use source::{Pace, ReplaySource, ScenarioSource, Source};
