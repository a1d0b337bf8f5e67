//! The self-calibrated test cell (thesis §9.2, issue 44): the virtual cell calibrated from a
//! recording — which of its physical parameters the recording resolves, their values and
//! intervals ([`calibrate`]) — and checked against it channel by channel ([`check`]).
//!
//! * [`replay`] — a recording's inputs as a scenario, and the cell's outputs on its grid.
//! * [`calibrate`] — ranking, bounded Gauss–Newton, covariance.
//! * [`check`] — the calibrated cell against a recording: NRMSE before and after, the
//!   residual's band predicted from the calibration's covariance and where it leaves it.
//! * [`live`] — the twin beside the stream: stepped in lock-step, adapting, alarming.

pub mod calibrate;
pub mod check;
pub mod live;
pub mod replay;

pub use calibrate::{calibrate, CalibrateConfig, Calibration};
pub use check::{check, ChannelCheck, Uncertainty};
pub use replay::{Demand, Replay};
