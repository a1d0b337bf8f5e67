//! # physid-signal — the acquisition chain's signal processing (thesis ch. 4, SPEC §2.7)
//!
//! * [`filter`] — Butterworth design and zero-phase forward–backward filtering, equal to
//!   scipy's `butter` + `filtfilt` / `sosfiltfilt`.
//! * [`cycles`] — per-cycle statistics and curves on a stream (crank-angle means, extremes).
//! * [`stream`] — the same zero-phase filtering on a stream, in blocks with a lookahead: the
//!   interior equal to the whole record's to ≈ 1e-13 of the signal's scale, the end exactly,
//!   a stated latency.
pub mod crank;
pub mod cycles;
pub mod encoder;
pub mod filter;
pub mod integrity;
pub mod stream;
pub mod wheel;
