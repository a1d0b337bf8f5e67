//! A pulse encoder's edges and its index's, found chunk by chunk and handed on in time order
//! ([`PulseEdges`]): the raw encoder `--encoder-raw` and `--index-raw` name, for
//! [`super::sensor`].

use super::invalid;
use crate::error::AppError;
use physid_core::Recording;
use physid_signal::wheel::{in_time_order, Dropouts, EdgeDetector, EdgeOptions};

/// An edge of a pulse encoder or its index, as [`PulseEdges`] hands them on.
pub(super) enum PulsePoint {
    /// An edge of the encoder: its time [s] and sample.
    Edge(f64, usize),
    /// An index pulse: its time [s].
    Index(f64),
}

/// A pulse encoder's edges and its index's, found chunk by chunk — each channel through the
/// wheel's edge detector (the same glitch rejection; the index at the level midway in its range,
/// ±20 % hysteresis) — and handed on in time order.
pub(super) struct PulseEdges {
    channel: String,
    index: String,
    edges: EdgeDetector,
    pulses: EdgeDetector,
}

impl PulseEdges {
    pub(super) fn new(
        channel: &str,
        index: &str,
        opts: &EdgeOptions,
        range: (f64, f64),
    ) -> Result<Self, AppError> {
        let (lo, hi) = range;
        if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
            return Err(invalid(format!(
                "'{index}': the index is flat ({lo} … {hi}): no index pulse to place the angle from"
            )));
        }
        Ok(Self {
            channel: channel.to_string(),
            index: index.to_string(),
            edges: EdgeDetector::new(opts),
            pulses: EdgeDetector::new(&EdgeOptions {
                threshold: Some((
                    0.5 * (lo + hi),
                    physid_signal::wheel::HYSTERESIS * (hi - lo),
                )),
                ..EdgeOptions::default()
            }),
        })
    }

    /// The next chunk: its edges and index pulses found so far, in time order.
    pub(super) fn push(
        &mut self,
        c: &Recording,
        out: &mut impl FnMut(PulsePoint),
    ) -> Result<(), AppError> {
        let t = c.values("t")?;
        self.edges.push(t, c.values(&self.channel)?);
        self.pulses.push(t, c.values(&self.index)?);
        let (mut e, mut z) = (Vec::new(), Vec::new());
        self.edges.drain(|t, i| e.push((t, i)));
        self.pulses.drain(|t, _| z.push(t));
        Self::hand_on(&e, &z, out);
        Ok(())
    }

    fn hand_on(e: &[(f64, usize)], z: &[f64], out: &mut impl FnMut(PulsePoint)) {
        let out = std::cell::RefCell::new(out);
        in_time_order(
            e,
            z,
            |t, i| (out.borrow_mut())(PulsePoint::Edge(t, i)),
            |t| (out.borrow_mut())(PulsePoint::Index(t)),
        );
    }

    /// The end: the last edges and pulses; what the edge detectors skipped.
    pub(super) fn finish(self, out: &mut impl FnMut(PulsePoint)) -> Result<PulsesEnd, AppError> {
        let (channel, index) = (self.channel, self.index);
        let e = self
            .edges
            .finish()
            .map_err(|e| invalid(format!("'{channel}': {e}")))?;
        let z = self
            .pulses
            .finish()
            .map_err(|e| invalid(format!("'{index}': {e}")))?;
        let pairs: Vec<(f64, usize)> = e.t.iter().copied().zip(e.index.iter().copied()).collect();
        Self::hand_on(&pairs, &z.t, out);
        Ok(PulsesEnd {
            glitches: e.glitches.len(),
            first_glitch: e.glitches.first().copied().unwrap_or(0),
            dropouts: [(channel, e.dropouts), (index, z.dropouts)],
        })
    }
}

/// What [`PulseEdges`] skipped: the encoder's glitches (how many, the first's sample), and the
/// samples not finite on each channel.
pub(super) struct PulsesEnd {
    pub(super) glitches: usize,
    pub(super) first_glitch: usize,
    pub(super) dropouts: [(String, Dropouts); 2],
}
