//! Whether a channel can be a cylinder pressure: its unit a pressure (or a sensor's own: V,
//! counts), and — in Pa — values that reach what a cylinder's do; checked on a whole recording
//! or as the chunks come ([`UnitCheck`]).

use physid_core::Recording;

use crate::error::AppError;

/// A cylinder pressure in Pa peaks above this (a motored engine's compression lifts it well
/// past atmospheric): below it, the values are in another unit labelled Pa.
pub const PA_PLAUSIBLE: f64 = 1e3;

/// Check that `channel` can be a cylinder pressure: its unit a pressure (or one physid does
/// not know, a sensor's own: V, counts), and — in Pa — a peak above [`PA_PLAUSIBLE`]. A unit
/// of another quantity is an error; implausible values in Pa are an error when `need_pa` (the
/// figures would be wrong), else the returned note. Both name the channel and the sample.
pub fn check_unit(
    rec: &Recording,
    channel: &str,
    need_pa: bool,
) -> Result<Option<String>, AppError> {
    let mut check = UnitCheck::new(rec, channel)?;
    check.push(&rec.channel(channel)?.values);
    check.finish(need_pa)
}

/// [`check_unit`] on a stream: the unit from the header, the peak as the samples come.
#[derive(Debug, Clone)]
pub struct UnitCheck {
    channel: String,
    in_pa: bool,
    /// The largest finite |value| and its sample.
    peak: Option<(usize, f64)>,
    seen: usize,
}

impl UnitCheck {
    /// The check of `channel` in recordings with `header`'s channels: an error now when its
    /// unit is of another quantity.
    pub fn new(header: &Recording, channel: &str) -> Result<Self, AppError> {
        let ch = header.channel(channel)?;
        if let Some(u) = physid_core::units::lookup(&ch.unit) {
            // A sensor's own units: volts, counts.
            if !["pressure", "voltage", "dimensionless"].contains(&u.dimension) {
                return Err(AppError::Invalid(format!(
                    "'{channel}' is in '{}' ({}), not a pressure: expected {} — or the sensor's own unit (V) calibrated with --scale {channel}=GAIN,OFFSET",
                    ch.unit,
                    u.dimension,
                    physid_core::units::known_for("Pa")
                )));
            }
        }
        Ok(Self {
            channel: channel.to_string(),
            in_pa: ch.unit.is_empty() || ch.unit == "Pa",
            peak: None,
            seen: 0,
        })
    }

    /// The next samples of the channel.
    pub fn push(&mut self, values: &[f64]) {
        if self.in_pa {
            for (i, &v) in values.iter().enumerate() {
                if v.is_finite() && self.peak.is_none_or(|(_, p)| v.abs() >= p.abs()) {
                    self.peak = Some((self.seen + i, v));
                }
            }
        }
        self.seen += values.len();
    }

    /// The verdict: implausible values in Pa are an error when `need_pa`, else the note.
    pub fn finish(&self, need_pa: bool) -> Result<Option<String>, AppError> {
        let Some((i, peak)) = self.peak else {
            return Ok(None);
        };
        if peak.abs() >= PA_PLAUSIBLE {
            return Ok(None);
        }
        let channel = &self.channel;
        let text = format!(
            "'{channel}' peaks at {peak} Pa (sample {i}): a cylinder pressure in Pa peaks far above {PA_PLAUSIBLE} Pa, so these are bar, MPa or a sensor's volts labelled Pa — state the unit (--map {channel}=COLUMN:bar) or calibrate into Pa (--scale {channel}=GAIN,OFFSET)"
        );
        if need_pa {
            Err(AppError::Invalid(text))
        } else {
            Ok(Some(text))
        }
    }
}
