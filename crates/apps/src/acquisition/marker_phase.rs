//! Which revolution fires when the TDC comes from a marker once per revolution (an encoder's
//! index, the thesis's cell's `tdc` channel): the marker says where a TDC is, not whether the
//! cylinder fires there or exchanges gas. `--phase-from CHANNEL` tells it as it does for a
//! trigger wheel ([`PhaseWindows`]): the revolution whose TDC has the higher mean of the
//! channel (the cylinder pressure, a cam sensor) over the revolution around it fires — from
//! the first [`PHASE_REVOLUTIONS`] revolutions after the first marker, so that a stream knows it
//! after a bounded stretch and a whole recording gives the same answer.

use super::phase::PhaseWindows;
use super::AcquisitionError;
use std::f64::consts::{PI, TAU};

/// The revolutions after the first marker the phase is told from.
pub const PHASE_REVOLUTIONS: f64 = 8.0;

/// How the firing revolution was told on a recording whose TDC came from its first marker
/// (`marker`), `told` by [`MarkerPhase::finish`] when `--phase-from` was given: what the
/// recording's `phase` metadata says, and `cycles` repeats in its notes.
pub fn phase_note(marker: bool, told: Option<String>) -> Option<String> {
    told.or_else(|| marker.then(|| first_guess(true)))
}

/// The first TDC taken as firing, for a person: the first marker's (`marker`) or the first
/// multiple of 4π on `theta_en` (the simulator's convention).
pub fn first_guess(marker: bool) -> String {
    if marker {
        "the first TDC marker taken as firing: a marker once per revolution cannot tell which revolution fires (--phase-from p_cyl tells it from the pressure)".to_string()
    } else {
        "the first multiple of 720° on 'theta_en' taken as the firing TDC".to_string()
    }
}

/// The phase of a marker's TDC, a sample `(θ, channel)` at a time.
#[derive(Debug, Clone)]
pub struct MarkerPhase {
    /// The channel as given (`NAME` or `NAME:low`).
    from: String,
    /// The first marker's angle [rad], once known.
    marker: Option<f64>,
    /// The samples before it was known.
    before: Vec<(f64, f64)>,
    windows: Option<PhaseWindows>,
    done: bool,
}

impl MarkerPhase {
    /// The phase from `from` (`NAME` or `NAME:low`).
    pub fn new(from: &str) -> Self {
        Self {
            from: from.to_string(),
            marker: None,
            before: Vec::new(),
            windows: None,
            done: false,
        }
    }

    /// The channel it reads.
    pub fn channel(&self) -> &str {
        self.from.strip_suffix(":low").unwrap_or(&self.from)
    }

    /// The first marker is at `theta` [rad] (the TDC, firing or not).
    pub fn marker_at(&mut self, theta: f64) {
        if self.marker.is_some() {
            return;
        }
        self.marker = Some(theta);
        let mut w = PhaseWindows::new(theta);
        for (th, p) in self.before.drain(..) {
            w.push(th, p);
        }
        self.windows = Some(w);
    }

    /// The first marker's angle [rad], once known.
    pub fn first_marker(&self) -> Option<f64> {
        self.marker
    }

    /// Whether the first marker's angle is known.
    pub fn has_marker(&self) -> bool {
        self.marker.is_some()
    }

    /// The next sample: the engine angle [rad] and the channel there.
    pub fn push(&mut self, theta: f64, p: f64) {
        if self.done {
            return;
        }
        match (&mut self.windows, self.marker) {
            (Some(w), Some(a)) => {
                w.push(theta, p);
                self.done = theta >= a + (PHASE_REVOLUTIONS + 0.5) * TAU + PI;
            }
            _ => self.before.push((theta, p)),
        }
    }

    /// Whether it has seen all it looks at.
    pub fn done(&self) -> bool {
        self.done
    }

    /// The firing TDC's angle [rad] — the first marker's, or a revolution on — and how it was
    /// told, for a person.
    pub fn finish(self) -> Result<(f64, String), AcquisitionError> {
        let (name, low) = (self.channel().to_string(), self.from.ends_with(":low"));
        let (Some(a), Some(w)) = (self.marker, self.windows) else {
            return Err(AcquisitionError::Invalid(format!(
                "--phase-from {}: no TDC marker and no engine angle to tell the phase at",
                self.from
            )));
        };
        let (parity, _) = w
            .finish(&self.from, 0.0)
            .map_err(|e| AcquisitionError::Invalid(e.to_string()))?;
        let told = format!(
            "the firing TDC at {} TDC marker ('{name}' {} in the revolution around it than a revolution away, over the first {PHASE_REVOLUTIONS} revolutions)",
            if parity == 1 { "the second" } else { "the first" },
            if low { "lower" } else { "higher" }
        );
        Ok((a + TAU * parity as f64, told))
    }
}
