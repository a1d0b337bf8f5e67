//! # physid-signal — the acquisition chain's signal processing (thesis ch. 4, SPEC §2.7)
//!
//! * [`filter`] — Butterworth design and zero-phase forward–backward filtering, equal to
//!   scipy's `butter` + `filtfilt` / `sosfiltfilt`.
//! * [`cycles`] — per-cycle statistics and curves on a stream (crank-angle means, extremes).
//! * [`stream`] — the same zero-phase filtering on a stream, in blocks with a lookahead: the
//!   interior equal to the whole record's to ≈ 1e-13 of the signal's scale, the end exactly,
//!   a stated latency.
//! * [`wheel`] — the crank angle from a trigger wheel's raw signal (N−M teeth, analog or
//!   digital): edges, teeth, gap, missing and extra edges, the angle at every sample.
//! * [`quadrature`] — the angle, both ways, from a quadrature encoder's A/B (and Z) signals.
//! * [`resample`] — a time basis to one sample per crank step and back, on a stream, equal to
//!   the whole record.
pub mod crank;
pub mod cycles;
pub mod encoder;
pub mod filter;
pub mod integrity;
pub mod quadrature;
pub mod resample;
pub mod speed_angle;
pub mod stream;
pub mod wheel;
