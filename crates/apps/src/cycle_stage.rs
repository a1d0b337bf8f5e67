//! Per-cycle statistics of chosen channels on the stream, as a [`Stage`]: each complete engine
//! cycle's crank-angle mean, extremes, the angle of the peak and (optionally) its curve on a
//! crank-angle grid ([`CycleStream`], cycles from a TDC angle on `theta_en`) — what the live
//! service sends as `cycle` events.
//!
//! A sample whose crank angle or one of whose channels is not a number (a sensor's dropout) is
//! left out with the samples after it up to the next whole one, as a gap in the data: the cycle
//! it cuts is not reported, the statistics go on after it, and the dropout is told once
//! ([`CycleOutput::Dropout`]). Before, it stopped the cycle statistics for the rest of the run.

use crate::error::AppError;
use crate::stage::{Dropout, Sink, Stage};
use physid_core::Recording;
use physid_signal::cycles::{CycleStream, CycleSummary};
use serde::{Deserialize, Serialize};

/// What the cycle statistics give: a complete cycle, or a dropout they left out.
#[derive(Debug, Clone, PartialEq)]
pub enum CycleOutput {
    /// A complete cycle.
    Cycle(CycleSummary),
    /// A dropout started (module docs).
    Dropout(Dropout),
}

/// The cycle statistics of the channels of `wanted` a stream has (set up on the first chunk
/// that has `theta_en` and at least one of them; until then a chunk passes untouched).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CycleStage {
    wanted: Vec<String>,
    theta_tdc: f64,
    curve_step_deg: Option<f64>,
    /// The stream and the channels it covers, once set up.
    stream: Option<(CycleStream, Vec<String>)>,
    /// The cycles a chunk completed (scratch, empty between chunks).
    #[serde(skip)]
    done: Vec<CycleSummary>,
    /// The samples of the chunks before the stream was set up (a sample's index in the stage's
    /// input is this plus its index in the stream).
    #[serde(default)]
    before: usize,
}

impl CycleStage {
    /// Statistics of those of `wanted` a stream has, cycles from `theta_tdc` + k·4π on
    /// `theta_en` [rad]; with `curve_step_deg`, each cycle's curve on that grid [deg].
    pub fn new(wanted: &[&str], theta_tdc: f64, curve_step_deg: Option<f64>) -> Self {
        Self {
            wanted: wanted.iter().map(|s| s.to_string()).collect(),
            theta_tdc,
            curve_step_deg,
            stream: None,
            done: Vec::new(),
            before: 0,
        }
    }

    /// The channels covered, in the order of a [`CycleSummary`]'s values (empty before the
    /// stream is set up).
    pub fn channels(&self) -> &[String] {
        self.stream
            .as_ref()
            .map_or(&[], |(_, names)| names.as_slice())
    }

    /// The curves' grid step [deg], if curves are made.
    pub fn curve_step_deg(&self) -> Option<f64> {
        self.curve_step_deg
    }
}

impl Stage for CycleStage {
    type Out = CycleOutput;

    /// A time that is not finite is an error naming its sample; an angle or a channel that is
    /// not a number, a dropout (module docs).
    fn push(&mut self, chunk: &Recording, out: &mut dyn Sink<CycleOutput>) -> Result<(), AppError> {
        if self.stream.is_none() {
            let names: Vec<String> = self
                .wanted
                .iter()
                .filter(|n| chunk.channel(n).is_ok())
                .cloned()
                .collect();
            if names.is_empty() || chunk.channel("theta_en").is_err() {
                self.before += chunk.len();
                return Ok(());
            }
            let stream = CycleStream::new(names.len(), self.theta_tdc, self.curve_step_deg)
                .map_err(|e| AppError::Invalid(e.to_string()))?;
            self.stream = Some((stream, names));
        }
        let Some((stream, names)) = self.stream.as_mut() else {
            return Ok(());
        };
        let cols = names
            .iter()
            .map(|n| chunk.values(n))
            .collect::<Result<Vec<_>, _>>()?;
        let (t, theta) = (chunk.values("t")?, chunk.values("theta_en")?);
        self.done.clear();
        stream
            .push_past_dropouts(t, theta, &cols, &mut self.done)
            // The stream numbers its channels: name them.
            .map_err(|e| {
                AppError::Invalid(format!("{e} (channels 0, 1, …: {})", names.join(", ")))
            })?;
        for c in self.done.drain(..) {
            out.put(CycleOutput::Cycle(c));
        }
        for d in stream.dropouts() {
            out.put(CycleOutput::Dropout(Dropout::of_cycles(
                d,
                names,
                self.before,
            )));
        }
        Ok(())
    }

    /// The cycle in progress at the end is not complete: nothing.
    fn finish(&mut self, _out: &mut dyn Sink<CycleOutput>) -> Result<(), AppError> {
        Ok(())
    }
}
