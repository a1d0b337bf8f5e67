//! # physid-core — the shared vocabulary
//!
//! Every other physid crate speaks these types:
//!
//! * [`ParamSet`] — named parameters with nominal values, and [`FreeSet`], the view that says
//!   which of them are estimated (*free*) and which are held at their nominal values (*fixed*).
//!   The identifiability step chooses the free subset; an estimator works on that view, never on
//!   a new model (DESIGN.md, "The seams").
//! * [`ParamModel`] and [`Scalar`] — models written once, generic over the scalar, so that the
//!   same code gives values (`f64`) and exact gradients ([`GradientEngine`], forward-mode dual
//!   numbers).
//! * [`Recording`] — named channels with SI units on a time or crank-angle basis (DESIGN.md,
//!   "A recording is columns with units").

pub mod memory;
pub mod model;
pub mod nan_null;
pub mod num;
pub mod params;
pub mod passes;
pub mod recording;
pub mod sink;
pub mod units;

pub use model::{DynModel, Grad, GradientEngine, ParamModel, Scalar, GRADIENT_CHUNK};
pub use num::Num;
pub use params::{FreeSet, ParamError, ParamSet};
pub use passes::{ChunkKind, Recordings, Reopen};
pub use recording::{standard_unit, Basis, Channel, Recording, RecordingError, CHANNEL_TABLE};
pub use sink::Sink;
