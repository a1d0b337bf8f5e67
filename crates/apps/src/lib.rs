//! # physid-apps — the thesis's examples and applications as library functions
//!
//! Every function here returns a typed result and prints nothing; the `physid` binary turns
//! the results into tables, JSON, CSV and plots.
//!
//! * [`acquisition`] — the acquisition chain on a recording: inspection and integrity,
//!   crank-angle conversion, zero-phase filtering (thesis ch. 4).
//! * [`angle_input`] — the input plan of a file read on a crank-angle basis: where its
//!   engine angle comes from (`theta_en`, encoder counts, a raw wheel or quadrature encoder)
//!   and the passes it is read in.
//! * [`cell`] — the built-in virtual test cell's values the applications start from, and the
//!   truth of a simulated recording.
//! * [`combustion_stage`] — combustion analysis per cycle on the stream (a stage: the live
//!   service's `combustion` events).
//! * [`compression`] — the chain on a motored pressure trace: the motored model's
//!   identifiability, its estimable parameters per TDC and recursively, the TDC and loss angle.
//! * [`cycle_stage`] — per-cycle statistics of chosen channels on the stream (a stage).
//! * [`error`] — the applications' error type.
//! * [`demo`] — the chain on the built-in virtual test cell (`physid demo`).
//! * [`example_5_1`] — thesis Example 5.1's model in Rust (the reference for the expression
//!   language).
//! * [`example_5_2`] — thesis Example 5.2: RLS, RLS with forgetting and RLS with vector
//!   forgetting tracking a step in one parameter of `z = A(t)·sin(x) + B·y²`.
//! * [`excitation`] — on-line identifiability freezing the parameters an estimator's recent
//!   data no longer supports (no wind-up), and the lost-excitation demonstration.
//! * [`friction_fit`] — Application 2: adaptive characterisation of engine friction from
//!   motored cycles (thesis §7.3, Tables 7.3–7.4).
//! * [`friction_rank`] — ranking of the friction model's design parameters over an operating
//!   grid (thesis §7.2, Table 7.1).
//! * [`knock`] — knock from a cycle's pressure: band-pass, MAPO, IMPO, a flag.
//! * [`model_choice`] — a model by built-in name or formula, with its nominal values.
//! * [`pipeline`] — the qualitative adaptive identification loop (Fig. 5.7) from a TOML file.
//! * [`per_cycle`] — one cycle's figures from its pressure: pegging, IMEP, PMEP, exponents,
//!   heat release, burn angles, knock (the file's and the live stage's one analysis).
//! * [`pressure_unit`] — whether a channel can be a cylinder pressure (its unit, its values).
//! * [`pressure`] — cylinder-pressure analysis per cycle: peak, IMEP, polytropic exponents,
//!   pegging, CoV of IMEP (`physid cycles`).
//! * [`stage`] — the one shape of the data path's stages ([`stage::Stage`], [`stage::Sink`]).
//! * [`shaft_monitor`] — Application 1: coupling-shaft health monitoring (ch. 6).
//! * [`twin`] — the self-calibrated test cell: the virtual cell calibrated from a recording and
//!   checked against it (thesis §9.2).
//! * [`time_order`] — whether a recording's time only goes forward, as its chunks come.
//! * [`torque_fit`] — Application 3: identifiability and EKF/UKF estimation of the cyclic
//!   engine torque model (ch. 8).

pub mod acquisition;
pub mod angle_input;
pub mod cell;
pub mod combustion;
pub mod combustion_stage;
pub mod compression;
pub mod cycle_stage;
pub mod demo;
pub mod design;
pub mod error;
pub mod example_5_1;
pub mod example_5_2;
pub mod excitation;
pub mod fmep_model;
pub mod friction_fit;
pub mod friction_rank;
pub mod knock;
pub mod model_choice;
pub mod per_cycle;
pub mod pipeline;
pub mod pressure;
pub mod pressure_unit;
pub mod recording_rows;
pub mod shaft_monitor;
pub mod stage;
pub mod time_order;
pub mod torque_fit;
pub mod twin;
pub mod wall_heat;

/// Drop every other element of a track (the first kept): what a track bounded in length does
/// when it is full, its step doubling.
pub(crate) fn halve<T>(v: &mut Vec<T>) {
    let mut keep = false;
    v.retain(|_| {
        keep = !keep;
        keep
    });
}
