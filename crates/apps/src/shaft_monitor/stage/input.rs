//! The monitor's input side: a chunk's signals checked — samples that are not numbers (a
//! sensor's dropout), an angle that stood still or a speed that froze while its shaft turned,
//! steps no shaft makes (the glitch gates) — and the twist, relative speed and shaft torque
//! low-passed on the stream, for the estimator's grid ([`ShaftStage`]).

use super::super::dropout::SIGNALS;
use super::*;

/// A chunk of the monitor's input channels, all the same length.
#[derive(Debug, Clone, Copy)]
pub struct ShaftInputs<'a> {
    /// Time [s], uniformly spaced at the stage's rate.
    pub t: &'a [f64],
    /// Dynamometer angle [rad].
    pub theta_dy: &'a [f64],
    /// Engine angle [rad].
    pub theta_en: &'a [f64],
    /// Dynamometer speed [rad/s].
    pub omega_dy: &'a [f64],
    /// Engine speed [rad/s].
    pub omega_en: &'a [f64],
    /// Shaft torque [N·m].
    pub torque_shaft: &'a [f64],
}

impl<'a> ShaftInputs<'a> {
    /// The monitor's channels of a recording (on a uniform time basis).
    pub fn of(rec: &'a Recording) -> Result<Self, AppError> {
        Ok(Self {
            t: rec.values("t")?,
            theta_dy: rec.values("theta_dy")?,
            theta_en: rec.values("theta_en")?,
            omega_dy: rec.values("omega_dy")?,
            omega_en: rec.values("omega_en")?,
            torque_shaft: rec.values("torque_shaft")?,
        })
    }

    /// Samples `r` of every channel.
    pub fn slice(&self, r: std::ops::Range<usize>) -> Self {
        Self {
            t: &self.t[r.clone()],
            theta_dy: &self.theta_dy[r.clone()],
            theta_en: &self.theta_en[r.clone()],
            omega_dy: &self.omega_dy[r.clone()],
            omega_en: &self.omega_en[r.clone()],
            torque_shaft: &self.torque_shaft[r],
        }
    }
}

/// The gated signals: what they are and their unit.
pub(super) const GATED: [(&str, &str); 3] = [
    ("twist", "rad"),
    ("relative speed", "rad/s"),
    ("shaft torque", "N·m"),
];

/// The angle sensors checked for a stop, with their speeds.
pub(super) const STILL: [(&str, &str); 2] = [("theta_en", "omega_en"), ("theta_dy", "omega_dy")];

/// The gates of a checkpoint from before they were: held 10⁴ samples at most, the torque not
/// gated.
pub(super) fn default_gates() -> [StepGate; 3] {
    [
        StepGate::twist(10_000),
        StepGate::slip(10_000),
        StepGate::new(f64::MAX, 10_000),
    ]
}

/// A glitch taken out of a chunk's twist or relative speed ([`StepGate`]): the time of the
/// first and what it was.
#[derive(Debug, Clone, PartialEq)]
pub struct ShaftGlitch {
    /// The time of the chunk's first step taken out [s].
    pub t_s: f64,
    /// What was taken out, for a person.
    pub message: String,
}

/// The zero-phase low-pass the monitor applies at `rate_hz`: Butterworth of order 4 at the
/// cut-off, run forwards and backwards; `None` when the cut-off is at or above the Nyquist
/// frequency (the signals go in unfiltered).
pub fn lowpass(cfg: &MonitorConfig, rate_hz: f64) -> Result<Option<Sos>, AppError> {
    if cfg.cutoff_hz < rate_hz / 2.0 {
        let sos = butter(4, &[cfg.cutoff_hz], Band::Lowpass, rate_hz)
            .map_err(|e| AppError::Invalid(e.to_string()))?
            .to_sos();
        Ok(Some(sos))
    } else {
        Ok(None)
    }
}

impl ShaftStage {
    /// The next filtered sample's index, time and whether it is held (standstill, a sensor's
    /// glitch), when it is on the estimator's grid (one input sample in `every`).
    pub(super) fn on_grid(&mut self) -> Option<(usize, f64, bool)> {
        let i = self.next;
        self.next += 1;
        let t = self.times.pop_front().unwrap_or(f64::NAN);
        let speed = self.speeds.pop_front().unwrap_or(f64::NAN);
        let suspect = self.suspect.pop_front().unwrap_or(false);
        // A shaft that does not turn resolves no damping and drifts the estimator's
        // memory, and a sensor's glitch tells nothing of the shaft: the estimates and the
        // alarm detector are held until it turns again, until the glitch has passed.
        i.is_multiple_of(self.every)
            .then_some((i, t, speed.abs() < STANDSTILL_RAD_S || suspect))
    }

    /// A chunk's Δθ, Δω and τ_sh through the low-pass into `filtered`.
    pub(super) fn filter_chunk(&mut self, x: &ShaftInputs) -> Result<(), AppError> {
        let n = x.t.len();
        let cols = [
            x.theta_dy,
            x.theta_en,
            x.omega_dy,
            x.omega_en,
            x.torque_shaft,
        ];
        if cols.iter().any(|c| c.len() != n) {
            return Err(AppError::Invalid(
                "a chunk's channels have different lengths".into(),
            ));
        }
        if self.t0.is_none() {
            self.t0 = x.t.first().copied();
        }
        let first = self.next + self.times.len();
        // Samples that are not numbers: held at their signals' last values, the columns
        // filled into buffers of the stage's (taken out here, put back at the end).
        let found = self.dropouts.fill(
            [
                x.theta_dy,
                x.theta_en,
                x.omega_dy,
                x.omega_en,
                x.torque_shaft,
            ],
            first,
        );
        let filled = std::mem::take(&mut self.dropouts.filled);
        let dropped = std::mem::take(&mut self.dropouts.held);
        let with_filled;
        let x = match &found {
            None => x,
            Some(_) => {
                with_filled = ShaftInputs {
                    t: x.t,
                    theta_dy: &filled[0],
                    theta_en: &filled[1],
                    omega_dy: &filled[2],
                    omega_en: &filled[3],
                    torque_shaft: &filled[4],
                };
                &with_filled
            }
        };
        for r in &mut self.raw {
            r.clear();
        }
        self.raw[0].extend(x.theta_dy.iter().zip(x.theta_en).map(|(a, b)| a - b));
        self.raw[1].extend(x.omega_dy.iter().zip(x.omega_en).map(|(a, b)| a - b));
        self.raw[2].extend_from_slice(x.torque_shaft);
        if let Some(i) = x.t.iter().position(|v| !v.is_finite()) {
            return Err(AppError::Invalid(format!(
                "sample {}: the time is not finite",
                first + i
            )));
        }
        // The steps no shaft makes out, before the low-pass spreads them.
        self.glitches.clear();
        self.held_raw.clear();
        self.held_raw.resize(n, false);
        if let Some(started) = &found {
            for (h, d) in self.held_raw.iter_mut().zip(&dropped) {
                *h |= *d;
            }
            for d in started {
                self.glitches.push(ShaftGlitch {
                    t_s: x.t[d.at],
                    message: format!(
                        "'{}' is not a number from sample {}: held at its last value and taken out as a sensor's dropout, not the shaft ({} in this chunk)",
                        SIGNALS[d.signal],
                        first + d.at,
                        d.count
                    ),
                });
            }
        }
        self.still_raw.clear();
        self.still_raw.resize(n, false);
        self.stuck_raw.clear();
        self.stuck_raw.resize(n, false);
        // An angle that stopped while its shaft turns: held first, so that the twist's gate
        // holds the twist there instead of taking its drift.
        let pairs = [(x.theta_en, x.omega_en), (x.theta_dy, x.omega_dy)];
        for ((still, (theta, omega)), (angle, speed)) in self.still.iter_mut().zip(pairs).zip(STILL)
        {
            if let Some(i) = still.apply(theta, omega, self.dt, &mut self.still_raw, first) {
                self.glitches.push(ShaftGlitch {
                    t_s: x.t[i],
                    message: format!(
                        "'{angle}' stood still while '{speed}' turned it more than {MAX_STILL_TURN} rad, from sample {}: held as a stopped sensor, not the shaft",
                        first + i
                    ),
                });
            }
        }
        // A speed that froze while its shaft moves away from it: its samples held by the
        // relative speed's gate.
        for ((stuck, (theta, omega)), (angle, speed)) in self.stuck.iter_mut().zip(pairs).zip(STILL)
        {
            if let Some(i) = stuck.apply(theta, omega, self.dt, &mut self.stuck_raw, first) {
                self.glitches.push(ShaftGlitch {
                    t_s: x.t[i],
                    message: format!(
                        "'{speed}' stood at one value for {STUCK_MIN_S} s or more while '{angle}' turned away from it, from sample {}: held as a frozen sensor, not the shaft",
                        first + i
                    ),
                });
            }
        }
        for (k, ((gate, r), what)) in self
            .gates
            .iter_mut()
            .zip(&mut self.raw)
            .zip(GATED)
            .enumerate()
        {
            let untrusted = match k {
                0 => Some(&self.still_raw[..]),
                1 => Some(&self.stuck_raw[..]),
                _ => None,
            };
            if let Some((i, step, count)) = gate.apply(r, untrusted, &mut self.held_raw, first) {
                self.glitches.push(ShaftGlitch {
                    t_s: x.t[i],
                    message: format!(
                        "the {} stepped by {step:.4e} {} between two samples at sample {} (more than {} {}): taken out as a sensor's glitch, not the shaft ({count} in this chunk)",
                        what.0, what.1, first + i, gate.limit(), what.1
                    ),
                });
            }
        }
        self.times.extend(x.t);
        self.speeds.extend(x.omega_en);
        // Held: the samples the gates held and `guard` on either side (those before are still
        // in the filters: the guard is within their latency).
        for &h in &self.held_raw {
            if h {
                let back = self.suspect.len().saturating_sub(self.guard);
                if self.quarantine == 0 {
                    for s in self.suspect.range_mut(back..) {
                        *s = true;
                    }
                }
                self.quarantine = self.guard + 1;
            }
            self.suspect.push_back(self.quarantine > 0);
            self.quarantine = self.quarantine.saturating_sub(1);
        }
        for f in &mut self.filtered {
            f.clear();
        }
        // A regressors-only stage leaves the torque out.
        let channels = if self.regressors_only { 2 } else { 3 };
        match &mut self.filters {
            Some(filters) => {
                for ((f, r), o) in filters
                    .iter_mut()
                    .zip(&self.raw)
                    .zip(&mut self.filtered)
                    .take(channels)
                {
                    f.push(r, o).map_err(|e| AppError::Invalid(e.to_string()))?;
                }
            }
            None => {
                for (r, o) in self.raw.iter().zip(&mut self.filtered).take(channels) {
                    o.extend_from_slice(r);
                }
            }
        }
        (self.dropouts.filled, self.dropouts.held) = (filled, dropped);
        Ok(())
    }

    /// The last samples out of the filters into `filtered`.
    pub(super) fn flush_filters(&mut self) -> Result<(), AppError> {
        for f in &mut self.filtered {
            f.clear();
        }
        // No sample at all (a run stopped before its first): nothing to flush, nothing wrong.
        if self.t0.is_none() {
            return Ok(());
        }
        let channels = if self.regressors_only { 2 } else { 3 };
        if let Some(filters) = &mut self.filters {
            for (f, o) in filters.iter_mut().zip(&mut self.filtered).take(channels) {
                f.finish(o).map_err(|e| AppError::Invalid(e.to_string()))?;
            }
        }
        Ok(())
    }
}
