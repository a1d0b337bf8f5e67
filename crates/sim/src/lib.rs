//! # physid-sim — the virtual transient engine test cell (thesis ch. 3, SPEC §2–3)
//!
//! * [`params`] — every parameter with its unit and source, addressed by dotted paths;
//! * [`engine`] — the motored engine: filling and emptying, flows, heat transfer, torques;
//! * [`machine`] — the induction machine in dq, and its per-phase equivalent circuit;
//! * [`control`] — indirect field-oriented speed (or torque) control;
//! * [`cell`] — the whole cell advanced one crank step at a time;
//! * [`scenario`] — speed/throttle profiles, the named scenarios, TOML files, faults;
//! * [`studies`] — the compression check, a converged motored cycle, the torque–speed curve;
//! * [`run`] — a scenario run into a [`Recording`](physid_core::Recording) through the sensors;
//! * [`numeric`] — elementary functions by cheaper exact routes (near-angle sine and cosine,
//!   small `eˣ − 1`, `⌊x⌋`, integer powers), tested against the library.

pub mod cell;
pub mod control;
pub mod engine;
pub mod error;
pub mod machine;
pub mod numeric;
pub mod params;
pub mod run;
pub mod scenario;
pub mod studies;
