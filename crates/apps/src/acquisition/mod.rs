//! The thesis's acquisition chain on a [`Recording`] (ch. 4, SPEC §2.7): inspection with the
//! post-run integrity check, conversion between a time basis and one sample per crank
//! degree, zero-phase filtering of chosen channels. The `physid inspect`, `convert` and
//! `filter` verbs are thin wrappers over these.
//!
//! Here: the options (which channel is the angle, which sensor) and the error. By concern:
//! * `inspect.rs` — what is in a recording, its integrity, a wheel recognised;
//! * `angle.rs` — the engine angle from an encoder's counts and marker, the first TDC;
//! * [`sensor`] — the angle decoded from a raw trigger wheel, pulse encoder or quadrature
//!   encoder, in passes;
//! * `pulse_edges.rs` — a raw pulse encoder's edges and its index's, in time order;
//! * `phase.rs` — which of two revolutions fires, from a channel's level around each TDC;
//! * `crank.rs` — a time basis resampled to the crank angle, whole and in chunks;
//! * `time.rs` — a crank basis back to a uniform time basis, and the uniform-step check;
//! * `filter.rs` — zero-phase filtering of chosen channels, whole and on the stream.
//!
//! Every public item of the private modules is re-exported here.

use crate::error::AppError;
use physid_core::{Basis, Channel, Recording, RecordingError, Recordings, Reopen};
use physid_signal::encoder::{first_marker, CountSteps, Encoder, SpacingCheck};
use physid_signal::filter::{butter, Band, FilterError};
use physid_signal::integrity::{
    mean_step, median_step, Finding, FindingKind, Integrity, IntegrityCheck, IntegrityOptions,
    JITTER, NOMINAL_SAMPLES,
};
use physid_signal::wheel::{recognise, EdgeDetector, EdgeOptions, ToothReport, Wheel};
use sensor::{sensor_calibration, sensor_crank_angle_chunks, sensor_decoded, SensorFound};
use serde::Serialize;
use std::f64::consts::PI;
use thiserror::Error;

mod angle;
mod crank;
mod filter;
mod inspect;
mod marker_phase;
mod phase;
mod pulse_edges;
pub mod sensor;
mod time;

pub use angle::*;
pub use crank::*;
pub use filter::*;
pub use inspect::*;
pub use marker_phase::*;
pub use phase::*;
pub use time::*;

/// An invalid input to the acquisition chain, as the error every verb reports.
fn invalid(e: String) -> AppError {
    AppError::Acquisition(AcquisitionError::Invalid(e))
}

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
    /// angle, also where the recording has a `theta_en` ([`raw_sensor`]; `--wheel CHANNEL=N-M`,
    /// `--quadrature A,B[,Z]=LINES`).
    pub sensor: Option<AngleSpec>,
    /// Without a sensor: which revolution of two fires when the marker comes once per
    /// revolution ([`MarkerPhase`]): by default from `p_cyl` when the recording has it;
    /// [`PhaseFrom::First`]: the first marker's TDC is taken as firing (without a marker, the
    /// first multiple of 4π on `theta_en`).
    pub phase_from: PhaseFrom,
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
    /// A single-channel pulse encoder (analog or digital, forward only) and its index, once per
    /// revolution on a channel of its own (`physid_signal::wheel::IndexSurvey`).
    Pulses {
        /// The pulses' channel.
        channel: String,
        /// Pulses per revolution.
        pulses: u32,
        /// The index's channel.
        index: String,
        /// Which edges of the pulses, which level (the index's level is midway in its range).
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
    /// A trigger wheel's sensor from `CHANNEL=N-M` (e.g. `enc=60-2`: N tooth pitches, M
    /// missing), its edges found as `edges` says. The error names the option (`wheel '…': …`;
    /// the command line puts `--` before it).
    pub fn parse_wheel(spec: &str, edges: EdgeOptions) -> Result<Self, String> {
        let (channel, wheel) = spec
            .split_once('=')
            .ok_or_else(|| format!("wheel '{spec}': expected CHANNEL=N-M, e.g. enc=60-2"))?;
        let wheel: Wheel = wheel.trim().parse()?;
        Ok(Self::Wheel {
            channel: channel.trim().to_string(),
            wheel,
            edges,
        })
    }

    /// A pulse encoder from `CHANNEL=PULSES` (e.g. `enc=360`) and its index channel, its edges
    /// found as `edges` says. The error names the option (`encoder-raw '…': …`).
    pub fn parse_pulses(spec: &str, index: &str, edges: EdgeOptions) -> Result<Self, String> {
        let bad = || {
            format!("encoder-raw '{spec}': expected CHANNEL=PULSES (pulses per revolution, 4 or more), e.g. enc=360")
        };
        let (channel, pulses) = spec.split_once('=').ok_or_else(bad)?;
        let pulses: u32 = pulses
            .trim()
            .parse()
            .ok()
            .filter(|p| *p >= 4)
            .ok_or_else(bad)?;
        let (channel, index) = (channel.trim(), index.trim());
        if channel.is_empty() || index.is_empty() || channel == index {
            return Err(format!(
                "encoder-raw '{spec}' with index-raw '{index}': expected two different channels"
            ));
        }
        Ok(Self::Pulses {
            channel: channel.to_string(),
            pulses,
            index: index.to_string(),
            edges,
        })
    }

    /// A quadrature encoder from `A,B[,Z]=LINES` (e.g. `enc_a,enc_b,enc_z=500`); the error
    /// names the option (`quadrature '…': …`).
    pub fn parse_quadrature(spec: &str) -> Result<Self, String> {
        let bad = || {
            format!("quadrature '{spec}': expected A,B,Z=LINES (the channels, the lines per revolution > 0), e.g. enc_a,enc_b,enc_z=500")
        };
        let (names, lines) = spec.split_once('=').ok_or_else(bad)?;
        let lines: u32 = lines
            .trim()
            .parse()
            .ok()
            .filter(|l| *l > 0)
            .ok_or_else(bad)?;
        let names: Vec<String> = names.split(',').map(|n| n.trim().to_string()).collect();
        if !(2..=3).contains(&names.len()) || names.iter().any(String::is_empty) {
            return Err(bad());
        }
        Ok(Self::Quadrature {
            a: names[0].clone(),
            b: names[1].clone(),
            z: names.get(2).cloned(),
            lines,
        })
    }

    /// What it is, in words: "a trigger wheel", "a pulse encoder" or "a quadrature encoder".
    pub fn kind(&self) -> &'static str {
        match self {
            Self::Wheel { .. } => "a trigger wheel",
            Self::Pulses { .. } => "a pulse encoder",
            Self::Quadrature { .. } => "a quadrature encoder",
        }
    }

    /// The raw channels it reads.
    pub fn channels(&self) -> Vec<&str> {
        match self {
            Self::Wheel { channel, .. } => vec![channel.as_str()],
            Self::Pulses { channel, index, .. } => vec![channel.as_str(), index.as_str()],
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
    /// suffix `:low` the lower (a cam that marks the other revolution); by default `p_cyl` when
    /// the recording has it. [`PhaseFrom::First`]: the TDC `tdc_offset_deg` after the first
    /// reference edge is taken as the firing one.
    pub phase_from: PhaseFrom,
}

impl AngleSpec {
    /// `sensor` with the firing TDC `tdc_offset_deg` after its reference, checked to lie in
    /// [0, 360): the error is `"{value}: expected …"`, for the caller to name the option.
    pub fn new(
        sensor: AngleSensor,
        tdc_offset_deg: f64,
        phase_from: PhaseFrom,
    ) -> Result<Self, String> {
        if !(tdc_offset_deg.is_finite() && (0.0..360.0).contains(&tdc_offset_deg)) {
            return Err(format!(
                "{}: expected an angle in [0, 360) degrees",
                physid_core::Num(tdc_offset_deg)
            ));
        }
        Ok(Self {
            sensor,
            tdc_offset_deg,
            phase_from,
        })
    }
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
            phase_from: PhaseFrom::Pressure,
        }
    }
}

/// A wheel sensor's fixed level and hysteresis (half-band) from `LEVEL,HYSTERESIS` in the
/// channel's unit (e.g. `1.5,0.3`); the error names the option (`threshold '…': …`).
pub fn parse_threshold(s: &str) -> Result<(f64, f64), String> {
    s.split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<Vec<f64>, _>>()
        .ok()
        .filter(|v| v.len() == 2 && v.iter().all(|x| x.is_finite()) && v[1] > 0.0)
        .map(|v| (v[0], v[1]))
        .ok_or_else(|| {
            format!("threshold '{s}': expected LEVEL,HYSTERESIS (numbers, the hysteresis > 0), e.g. 1.5,0.3")
        })
}

impl AcquisitionOptions {
    /// An encoder's counter channel and pulses per revolution from `CHANNEL=PPR` (e.g.
    /// `count_en=360`); the error names the option (`encoder '…': …`).
    pub fn parse_encoder(e: &str) -> Result<(String, u32), String> {
        let (c, p) = e
            .split_once('=')
            .ok_or_else(|| format!("encoder '{e}': expected CHANNEL=PPR, e.g. count_en=360"))?;
        let ppr: u32 = p
            .trim()
            .parse()
            .ok()
            .filter(|v| *v > 0)
            .ok_or_else(|| format!("encoder '{e}': '{p}' is not a pulse count > 0"))?;
        Ok((c.trim().to_string(), ppr))
    }

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
