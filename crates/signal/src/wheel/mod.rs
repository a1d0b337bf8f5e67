//! Trigger wheels: the crank angle from the raw signal of a sensor over an N−M toothed wheel
//! (N tooth pitches per revolution, M consecutive teeth left out to mark the reference) — an
//! inductive (variable-reluctance) pickup's analog voltage or a Hall sensor's digital one.
//! Generic: nothing engine-specific is assumed; the TDC's position relative to the wheel is a
//! parameter ([`Tdc`]).
//!
//! Three steps:
//! 1. [`EdgeDetector`] — tooth edges from the samples, as they come: a comparator with
//!    hysteresis whose level follows the signal's envelope tooth by tooth (an inductive
//!    pickup's amplitude grows with speed), or a level given. The edge time is interpolated
//!    linearly between the two samples either side of the level. A pulse narrower than
//!    [`GLITCH_WIDTH`] of the teeth before it is a glitch: rejected, counted, never a tooth. A
//!    sample that is NaN or ±∞ is a dropout ([`Dropouts`]): skipped, no edge interpolated
//!    across it — an edge it hides is lost, and step 2 counts it as a missing tooth.
//! 2. [`index_teeth`] — each edge's angle on the wheel: a tooth period against the median of
//!    its neighbours counts its pitches (1 for a tooth, M + 1 across the gap, more where edges
//!    are missing; a period much shorter than a pitch is an extra edge and dropped); the gap is
//!    the position, modulo N pitches, where most periods of M + 1 pitches end. Angle 0 is the
//!    first tooth edge after the first gap. Missing and extra edges, and a gap out of its
//!    place, are integrity findings at their sample.
//! 3. [`WheelAngles::angle_at`] — the angle at any time, interpolated between edges by a
//!    monotone piecewise-cubic Hermite curve (Fritsch–Carlson, as scipy's `PchipInterpolator`),
//!    so that a speed changing within a tooth (or across the gap) bends the curve.
//!
//! A pulse encoder with a separate index pulse is a wheel of N pitches and no gap whose
//! reference the index gives (`index_pulse.rs`: [`IndexSurvey`] in place of [`GapSurvey`]).
//!
//! Here: the wheel ([`Wheel`]), the edge options and the errors. By concern: `edges.rs` (step
//! 1), `recognise.rs` (which wheel, when not given), `index.rs` (step 2), `index_pulse.rs`
//! (step 2 from an index pulse), `pchip.rs` (step 3); every public item is re-exported here.

use crate::integrity::{Finding, FindingKind};
use std::collections::VecDeque;
use std::f64::consts::TAU;
use std::str::FromStr;
use thiserror::Error;

mod edges;
mod index;
mod index_pulse;
mod pchip;
mod recognise;
mod teeth;

pub use edges::*;
pub use index::*;
pub use index_pulse::*;
pub use pchip::*;
pub use recognise::*;
use teeth::*;

/// A toothed wheel: `teeth` pitches per revolution, `missing` of them left out (60−2, 36−1,
/// 60−3 …).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Wheel {
    /// Tooth pitches per revolution (N).
    pub teeth: u32,
    /// Consecutive teeth left out (M ≥ 1).
    pub missing: u32,
}

impl Wheel {
    /// The angle of one pitch `2π/N` [rad].
    pub fn pitch(&self) -> f64 {
        TAU / self.teeth as f64
    }

    /// The teeth on the wheel (N − M), edges per revolution.
    pub fn present(&self) -> u32 {
        self.teeth - self.missing
    }
}

impl std::fmt::Display for Wheel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}-{}", self.teeth, self.missing)
    }
}

impl FromStr for Wheel {
    type Err = String;

    /// `N-M` (or `N−M`): e.g. `60-2`, `36-1`, `60-3`.
    fn from_str(s: &str) -> Result<Self, String> {
        let bad =
            || format!("wheel '{s}': expected N-M (tooth pitches − missing teeth), e.g. 60-2");
        let (n, m) = s
            .split_once('-')
            .or_else(|| s.split_once('−'))
            .ok_or_else(bad)?;
        let teeth: u32 = n.trim().parse().map_err(|_| bad())?;
        let missing: u32 = m.trim().parse().map_err(|_| bad())?;
        if missing == 0 {
            return Err(format!(
                "wheel '{s}': no missing tooth, so no reference on the wheel — decode such an encoder's counts with --encoder CHANNEL=PPR and a TDC marker"
            ));
        }
        if teeth < missing + 4 {
            return Err(format!(
                "wheel '{s}': at least 4 teeth must remain between gaps (N − M ≥ 4)"
            ));
        }
        Ok(Self { teeth, missing })
    }
}

/// Which crossing of the level is the tooth's edge.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Edge {
    /// The signal rising through the level (a Hall sensor: a tooth's leading edge).
    #[default]
    Rising,
    /// The signal falling through it (an inductive pickup's steep flank after its peak).
    Falling,
}

impl FromStr for Edge {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "rising" => Ok(Self::Rising),
            "falling" => Ok(Self::Falling),
            _ => Err(format!("edge '{s}': expected rising or falling")),
        }
    }
}

/// How the edges are found.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct EdgeOptions {
    /// Rising or falling crossings.
    pub edge: Edge,
    /// A fixed level and hysteresis (half-band) in the signal's unit; `None`: automatic.
    pub threshold: Option<(f64, f64)>,
}

/// The samples whose 2nd and 98th percentiles give the automatic level's start (midway) and
/// hysteresis (±[`HYSTERESIS`] of their distance); from the first tooth on, each tooth's own
/// peak and trough.
pub const START_SAMPLES: usize = 4096;

/// The hysteresis either side of the automatic level, as a fraction of the last teeth's
/// peak-to-trough swing.
pub const HYSTERESIS: f64 = 0.2;

/// A pulse narrower than this fraction of the median width of the last teeth's pulses is a
/// glitch, not a tooth.
pub const GLITCH_WIDTH: f64 = 0.3;

/// Without an edge for this many tooth periods (the last), the automatic level starts again
/// from the signal's swing since: longer than any gap of a wheel with N − M ≥ 4 teeth
/// between gaps and M ≤ 6.
pub const SILENCE: f64 = 8.0;

/// Errors of the decoding.
#[derive(Debug, Clone, Error, PartialEq)]
pub enum WheelError {
    /// Time not increasing.
    #[error("the time does not increase at sample {index} ({prev} → {next} s)")]
    Time {
        /// Sample index.
        index: usize,
        /// Time before.
        prev: f64,
        /// Time at the index.
        next: f64,
    },
    /// The data cannot be decoded as the wheel given, explained.
    #[error("{0}")]
    Invalid(String),
}
