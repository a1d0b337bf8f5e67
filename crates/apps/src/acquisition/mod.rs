//! The thesis's acquisition chain on a [`Recording`] (ch. 4, SPEC §2.7): inspection with the
//! post-run integrity check, conversion between a time basis and one sample per crank
//! degree, zero-phase filtering of chosen channels. The `physid inspect`, `convert` and
//! `filter` verbs are thin wrappers over these.
//!
//! Here: the options (which channel is the angle, which sensor) and the error. By concern:
//! * `inspect.rs` — what is in a recording, its integrity, a wheel recognised;
//! * `angle.rs` — the engine angle from an encoder's counts and marker, the first TDC;
//! * [`sensor`] — the angle decoded from a raw trigger wheel or quadrature encoder, in passes;
//! * `crank.rs` — a time basis resampled to the crank angle, whole and in chunks;
//! * `time.rs` — a crank basis back to a uniform time basis, and the uniform-step check;
//! * `filter.rs` — zero-phase filtering of chosen channels, whole and on the stream.
//!
//! Every public item of the private modules is re-exported here.

use crate::error::AppError;
use physid_core::{Basis, Channel, Recording, RecordingError};
use physid_signal::encoder::{first_marker, CountSteps, Encoder, SpacingCheck};
use physid_signal::filter::{butter, Band, FilterError};
use physid_signal::integrity::{
    median_step, Finding, FindingKind, Integrity, IntegrityCheck, IntegrityOptions, NOMINAL_SAMPLES,
};
use physid_signal::wheel::{recognise, EdgeDetector, EdgeOptions, ToothReport, Wheel};
use sensor::{
    sensor_calibration, sensor_crank_angle_chunks, sensor_decoded, SensorAhead, SensorFound,
};
use serde::Serialize;
use std::f64::consts::PI;
use thiserror::Error;

mod angle;
mod crank;
mod filter;
mod inspect;
pub mod sensor;
mod time;

pub use angle::*;
pub use crank::*;
pub use filter::*;
pub use inspect::*;
pub use time::*;

/// Errors of the acquisition functions.
#[derive(Debug, Error)]
pub enum AcquisitionError {
    /// A channel problem.
    #[error(transparent)]
    Recording(#[from] RecordingError),
    /// A filter problem, with the channel.
    #[error("channel '{channel}': {source}")]
    Filter {
        /// The channel.
        channel: String,
        /// What went wrong.
        source: FilterError,
    },
    /// Anything else, explained.
    #[error("{0}")]
    Invalid(String),
}

/// Where the encoders and the TDC marker are.
#[derive(Debug, Clone)]
pub struct AcquisitionOptions {
    /// Encoder counter channels with their pulses per revolution; the TDC marker belongs to the
    /// first (the engine's).
    pub encoders: Vec<(String, u32)>,
    /// The TDC marker channel.
    pub marker: String,
    /// A raw angle sensor (a trigger wheel or a quadrature encoder), decoded into the engine
    /// angle when the recording has no `theta_en` (`--wheel CHANNEL=N-M`,
    /// `--quadrature A,B[,Z]=LINES`).
    pub sensor: Option<AngleSpec>,
}

/// A raw angle sensor on the crankshaft.
#[derive(Debug, Clone, PartialEq)]
pub enum AngleSensor {
    /// A toothed wheel's sensor (analog or digital).
    Wheel {
        /// The sensor's channel.
        channel: String,
        /// The wheel (N−M).
        wheel: Wheel,
        /// Which edges, which level.
        edges: EdgeOptions,
    },
    /// A quadrature encoder's channels A, B and optionally the index Z.
    Quadrature {
        /// Channel A.
        a: String,
        /// Channel B (a quarter line behind A turning forward).
        b: String,
        /// The index, once per revolution.
        z: Option<String>,
        /// Lines per revolution.
        lines: u32,
    },
}

impl AngleSensor {
    /// The raw channels it reads.
    pub fn channels(&self) -> Vec<&str> {
        match self {
            Self::Wheel { channel, .. } => vec![channel.as_str()],
            Self::Quadrature { a, b, z, .. } => [Some(a), Some(b), z.as_ref()]
                .into_iter()
                .flatten()
                .map(String::as_str)
                .collect(),
        }
    }
}

/// A raw angle sensor and where the firing TDC lies on it.
#[derive(Debug, Clone, PartialEq)]
pub struct AngleSpec {
    /// The sensor.
    pub sensor: AngleSensor,
    /// The crank angle from the sensor's reference — a wheel's first tooth edge after the gap,
    /// an encoder's index pulse turning forward — to the next TDC [deg], in [0, 360).
    pub tdc_offset_deg: f64,
    /// Which revolution of two fires: the one whose TDC has the higher mean of this channel
    /// over the revolution centred on it — the cylinder pressure (compression and expansion
    /// against exhaust and intake), a cam sensor high or pulsing in that revolution; with the
    /// suffix `:low` the lower (a cam that marks the other revolution). `None`: the TDC
    /// `tdc_offset_deg` after the first reference edge is taken as the firing one.
    pub phase_from: Option<String>,
}

/// The TDC marker channel of the thesis's test cell (and physid's simulator).
pub const TDC_MARKER: &str = "tdc";

impl Default for AcquisitionOptions {
    /// The thesis's test cell: `count_en` (360 pulses/rev), `count_dy` (1024), marker `tdc`.
    fn default() -> Self {
        Self {
            encoders: vec![("count_en".into(), 360), ("count_dy".into(), 1024)],
            marker: TDC_MARKER.into(),
            sensor: None,
        }
    }
}

impl AcquisitionOptions {
    /// The integrity checks of these encoders and marker on a recording with `header`'s
    /// channels (those it lacks are not checked); the marker is the first encoder's (the
    /// engine's, by default).
    pub fn integrity_options(
        &self,
        header: &Recording,
        samples_per_cycle: Option<usize>,
    ) -> IntegrityOptions {
        IntegrityOptions {
            encoders: self
                .encoders
                .iter()
                .filter(|(n, _)| header.channel(n).is_ok())
                .cloned()
                .collect(),
            marker: header
                .channel(&self.marker)
                .ok()
                .map(|_| self.marker.clone()),
            marker_encoder: self.encoders.first().map(|e| e.0.clone()),
            samples_per_cycle,
        }
    }
}
