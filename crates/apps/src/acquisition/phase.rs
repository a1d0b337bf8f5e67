//! Which of two revolutions fires: the firing TDC told from a channel's level over the
//! revolution around each TDC (`--phase-from`, by default the cylinder pressure when the
//! recording has one), and the firing TDC's angle once it is known.

use super::invalid;
use crate::error::AppError;
use std::f64::consts::{PI, TAU};

/// The channel the firing revolution is told from when nothing is said: the cylinder
/// pressure (DESIGN.md's name) — the compression and expansion around the firing TDC against
/// the exhaust and intake around the other, fired or motored.
pub const DEFAULT_PHASE_FROM: &str = "p_cyl";

/// Where which revolution of two fires is told from (`--phase-from`).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum PhaseFrom {
    /// Nothing said: from [`DEFAULT_PHASE_FROM`] when the recording has it — and when it
    /// cannot tell (fewer than two revolutions with a finite pressure), the first TDC taken
    /// as firing, saying why; without it, the first TDC taken as firing, said to be a guess.
    #[default]
    Pressure,
    /// `--phase-from none`: the first TDC (the first marker's, or `--tdc-offset` after the
    /// sensor's first reference) taken as firing.
    First,
    /// `--phase-from NAME` (the higher mean fires) or `NAME:low` (the lower).
    Channel(String),
}

impl PhaseFrom {
    /// From the command line's `--phase-from`: absent, `none`, or a channel.
    pub fn parse(given: Option<&str>) -> Self {
        match given {
            None => Self::Pressure,
            Some("none") => Self::First,
            Some(c) => Self::Channel(c.to_string()),
        }
    }

    /// A channel told (`NAME` or `NAME:low`).
    pub fn channel(name: &str) -> Self {
        Self::Channel(name.to_string())
    }

    /// The channel to read (`NAME` or `NAME:low`) on a recording that `has` the channels it
    /// says yes to, and whether it was only implied (the default: a caller falls back to the
    /// first TDC when it cannot tell); `None`: the first TDC is taken as firing.
    pub fn resolve(&self, has: impl Fn(&str) -> bool) -> Option<(&str, bool)> {
        match self {
            Self::Pressure => has(DEFAULT_PHASE_FROM).then_some((DEFAULT_PHASE_FROM, true)),
            Self::First => None,
            Self::Channel(c) => Some((c.as_str(), false)),
        }
    }

    /// The channel it may read, without `:low` (for a reader's projection: the default's
    /// pressure, which a projection leaves out when the file does not have it).
    pub fn reads(&self) -> Option<&str> {
        match self {
            Self::Pressure => Some(DEFAULT_PHASE_FROM),
            Self::First => None,
            Self::Channel(c) => Some(c.strip_suffix(":low").unwrap_or(c)),
        }
    }

    /// The channel to read when told or already resolved (`tdc_from` defaults it to its own
    /// channel): itself if told, `channel` if nothing was said.
    pub fn or_channel(&self, channel: &str) -> Self {
        match self {
            Self::Pressure => Self::channel(channel),
            other => other.clone(),
        }
    }
}

/// The phase told from an implied channel, or — when it could not tell (`told` failed) — the
/// first TDC `first` taken as firing, the note saying why: what every phase-telling path
/// does with [`PhaseFrom::Pressure`]. A channel told explicitly keeps its error.
pub fn told_or_first<T, E: std::fmt::Display>(
    told: Result<(T, String), E>,
    implied: bool,
    first: impl FnOnce() -> (T, String),
) -> Result<(T, String), E> {
    match told {
        Ok((at, how)) if implied => Ok((
            at,
            format!(
                "{how}; '{DEFAULT_PHASE_FROM}' by default (--phase-from none takes the first TDC)"
            ),
        )),
        Ok(t) => Ok(t),
        Err(e) if implied => {
            let (at, how) = first();
            // Not "--phase-from p_cyl: …": nobody gave it.
            let why = e.to_string();
            let prefix = format!("--phase-from {DEFAULT_PHASE_FROM}: ");
            let why = why.strip_prefix(&prefix).unwrap_or(&why);
            Ok((
                at,
                format!("{how} — '{DEFAULT_PHASE_FROM}' could not tell: {why}"),
            ))
        }
        Err(e) => Err(e),
    }
}

/// The revolutions from the TDC an angle may be at to be placed in one: beyond, `f64` no
/// longer tells one revolution from the next.
const MAX_REVOLUTIONS: f64 = 4_503_599_627_370_496.0; // 2^52

/// Which of two revolutions fires, a sample at a time: the mean of a channel over the
/// revolution centred on each TDC a revolution apart (`offset + 2πk`: the samples whose angle
/// is in `[offset + 2πk − π, offset + 2πk + π)`, from the first whole one), the median over the
/// TDCs of each parity; the higher (lower with `:low`) fires. Holds two means per revolution.
#[derive(Debug, Clone)]
pub struct PhaseWindows {
    offset: f64,
    /// The first revolution not yet closed (from the first sample's angle), and the sum and
    /// count of the samples in it and in the next (they may share a sample at the border).
    k: Option<i64>,
    open: [(f64, usize); 2],
    /// The means of the closed revolutions, by the parity of `k`.
    means: [Vec<f64>; 2],
}

impl PhaseWindows {
    /// The TDCs `offset` [rad] after the sensor's reference, a revolution apart.
    pub fn new(offset: f64) -> Self {
        Self {
            offset,
            k: None,
            open: [(-0.0, 0); 2],
            means: [Vec::new(), Vec::new()],
        }
    }

    /// The TDC `k` revolutions on, from the offset (where an angle's distance from the offset
    /// is measured: an offset of 10²⁹⁸ rad, a marker's angle scaled so, absorbs `2πk`, and the
    /// revolutions never passed — a hang).
    fn centre(k: i64) -> f64 {
        TAU * k as f64
    }

    /// The next sample: its angle `theta` [rad] (not decreasing) and the channel's value `p`.
    /// An angle beyond 2⁵² revolutions (a glitch's 10²⁴ rad) has no place in one: it is passed
    /// over; one that jumps ahead by many revolutions is placed at once, not a revolution at a
    /// time (10²³ steps: a hang).
    pub fn push(&mut self, theta: f64, p: f64) {
        // From the offset on.
        let theta = theta - self.offset;
        let revolutions = theta / TAU;
        if revolutions.is_nan() || revolutions.abs() >= MAX_REVOLUTIONS {
            return;
        }
        let mut k = *self
            .k
            .get_or_insert_with(|| ((theta + PI) / TAU).ceil() as i64);
        // The revolutions this sample is past: their means (the samples in them, not NaN).
        while Self::centre(k) + PI <= theta {
            let (sum, n) = self.open[0];
            if n > 0 {
                let mean = sum / n as f64;
                if mean.is_finite() {
                    self.means[k.rem_euclid(2) as usize].push(mean);
                }
            }
            self.open = [self.open[1], (-0.0, 0)];
            k += 1;
            if self.open[0].1 == 0 {
                // Nothing open: on to the first revolution not behind this sample at once.
                k = k.max(((theta - PI) / TAU).floor() as i64 + 1);
            }
        }
        self.k = Some(k);
        for j in 0..2 {
            let angle = Self::centre(k + j);
            if angle - PI <= theta && theta < angle + PI {
                let o = &mut self.open[j as usize];
                *o = (o.0 + p, o.1 + 1);
            }
        }
    }

    /// The firing parity (0: the TDCs `offset + 4πk`; 1: a revolution on) and how it was
    /// told, for a person; `from` is the channel as given (`NAME` or `NAME:low`).
    pub fn finish(mut self, from: &str, tdc_offset_deg: f64) -> Result<(i64, String), AppError> {
        let (name, low) = match from.strip_suffix(":low") {
            Some(n) => (n, true),
            None => (from, false),
        };
        if self.means[0].is_empty() || self.means[1].is_empty() {
            return Err(invalid(format!(
                "--phase-from {from}: the recording spans fewer than two whole revolutions around TDCs (with finite '{name}'), so which one fires cannot be told"
            )));
        }
        let level = |v: &mut Vec<f64>| {
            v.sort_unstable_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let (l0, l1) = (level(&mut self.means[0]), level(&mut self.means[1]));
        let parity = usize::from((l1 > l0) != low);
        let (fire, other) = if parity == 1 { (l1, l0) } else { (l0, l1) };
        Ok((
            parity as i64,
            format!(
                "the firing TDC {tdc_offset_deg:.3}° after the reference of {} revolutions ('{name}' {} there: mean {fire:.4e} over the revolution around it against {other:.4e} a revolution away, medians over the TDCs)",
                if parity == 1 { "odd" } else { "even" },
                if low { "lower" } else { "higher" }
            ),
        ))
    }
}

/// The first TDC after a sensor's reference taken as firing, for a person.
pub fn no_phase(tdc_offset_deg: f64) -> String {
    format!("the TDC {tdc_offset_deg}° after the first reference taken as firing (--phase-from p_cyl tells it from the pressure)")
}

/// The firing TDC's angle [rad]: the first of parity `parity` (see [`PhaseWindows::finish`])
/// at or after the first sample's angle `theta0`.
pub fn firing_tdc(offset: f64, parity: i64, theta0: f64) -> f64 {
    let mut tdc = offset + TAU * parity as f64;
    tdc += 4.0 * PI * ((theta0 - tdc) / (4.0 * PI)).ceil();
    tdc
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 20 revolutions of a pressure high around the odd TDCs, at 1°; then `jump`.
    fn told(jump: &[f64]) -> i64 {
        let mut w = PhaseWindows::new(0.0);
        for i in 0..20 * 360 {
            let theta = (i as f64).to_radians();
            let odd = ((theta + PI) / TAU).floor() as i64 % 2 == 1;
            w.push(theta, if odd { 10.0 } else { 1.0 });
        }
        for &theta in jump {
            w.push(theta, 5.0);
        }
        w.finish("p_cyl", 0.0).map(|(parity, _)| parity).unwrap()
    }

    /// An angle that jumps 10¹⁴ revolutions ahead is placed at once (a revolution at a time it
    /// took 10¹⁴ steps), one at 10²⁴ rad is passed over; neither changes what the 20
    /// revolutions tell.
    #[test]
    fn an_angle_that_jumps_far_ahead_is_placed_at_once() {
        assert_eq!(told(&[]), 1);
        assert_eq!(told(&[1e15, 1e15 + 1.0, 1e24, f64::INFINITY, f64::NAN]), 1);
    }

    /// A marker's angle scaled by 10³⁰⁰ (`--scale theta_en=1e300,0`) puts the TDCs at
    /// 10²⁹⁸ rad, where `2πk` added to it changes nothing: the revolutions were never passed
    /// (a hang of `convert --crank-angle`). From the offset on, the samples at the offset are
    /// placed and those beyond 2⁵² revolutions passed over.
    #[test]
    fn a_marker_at_an_angle_beyond_f64s_revolutions_does_not_hang() {
        let mut w = PhaseWindows::new(1.7e298);
        for theta in [1.7e298, 1.7e298, 3.4e298, 5.1e298] {
            w.push(theta, 1.0);
        }
        assert!(w.finish("p_cyl", 0.0).is_err());
    }
}
