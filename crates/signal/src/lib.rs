//! # physid-signal — the acquisition chain's signal processing (thesis ch. 4, SPEC §2.7)
//!
//! * [`filter`] — Butterworth design and zero-phase forward–backward filtering, equal to
//!   scipy's `butter` + `filtfilt` / `sosfiltfilt`.
pub mod crank;
pub mod encoder;
pub mod filter;
pub mod integrity;
