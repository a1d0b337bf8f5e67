//! Combustion analysis on the stream, as a [`Stage`]: the cylinder pressure of a time-basis
//! stream taken onto a crank-angle grid from `theta_en` ([`CycleStream`]: each cycle from 360°
//! before its firing TDC to 360° after, linear between the samples — as `physid cycles`
//! resamples a file; the time only at the three grid points the figures need), and each
//! complete cycle's figures by [`PerCycle`] — the one analysis the
//! file verb runs too: pegging, IMEP, PMEP, exponents, heat release, burn angles, misfire and
//! partial burn, knock; with the brake torque ([`crate::per_cycle::Brake`]) taken onto the grid
//! too, BMEP and FMEP.
//!
//! With [`CombustionStage::with_curves`], a cycle's pressure and heat release rate on a coarser
//! grid go with its figures (the live panel's view), at most one cycle's every
//! [`CURVE_INTERVAL_S`] of the stream's time.
//!
//! A sample whose crank angle or pressure (or brake torque) is not a number — a sensor's
//! dropout — is left out with the cycle it cuts, told once ([`CombustionOutput::Dropout`]);
//! the cycles after it are analysed and keep their numbers. Before, it stopped the analysis.
//!
//! Cycles are numbered as the cycle statistics number theirs ([`crate::cycle_stage`]): the
//! block of 720° that starts at the cycle's firing TDC, 0 for the first block that starts in
//! the stream — so a file converted from the same stream (`convert --crank-angle`) and
//! `physid cycles` on it give the same cycle the same number.

use crate::error::AppError;
use crate::per_cycle::{CycleFigures, CycleTimes, PerCycle, PerCycleSettings};
use crate::pressure::UnitCheck;
use crate::stage::{Dropout, Sink, Stage};
use physid_core::Recording;
use physid_signal::cycles::{CycleStream, CycleSummary};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// The shortest time between two cycles whose curves are given [s] (five a second: what a
/// person can follow, whatever the engine's speed).
pub const CURVE_INTERVAL_S: f64 = 0.2;

/// What the combustion analysis gives: a cycle's figures, or a dropout it left out. (Nearly
/// every output is a cycle, put once per cycle: not boxed.)
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
pub enum CombustionOutput {
    /// A complete cycle's figures.
    Cycle(CombustionCycle),
    /// A dropout left out with the cycle it cuts (module docs).
    Dropout(Dropout),
}

/// A cycle's figures, with its curves when they are due ([`CombustionStage::with_curves`]).
#[derive(Debug, Clone, PartialEq)]
pub struct CombustionCycle {
    /// The figures.
    pub figures: CycleFigures,
    /// The curves.
    pub curve: Option<CombustionCurve>,
}

/// A cycle's pressure and heat release rate on a grid from −360° ATDC.
#[derive(Debug, Clone, PartialEq)]
pub struct CombustionCurve {
    /// The grid's step [deg].
    pub step_deg: f64,
    /// The pressure as the figures take it (pegged, filtered) [the channel's unit].
    pub p: Vec<f64>,
    /// The apparent heat release rate [J/deg]: at each grid point the heat released over the
    /// step centred on it, `(Q(θ + Δ/2) − Q(θ − Δ/2))/Δ` — so the rates times the step add up
    /// to the heat released over the window; NaN outside the heat release's window.
    pub hrr: Vec<f64>,
}

/// The combustion figures of each complete cycle of a stream's cylinder pressure (set up on
/// the first chunk that has `theta_en` and the channel; until then a chunk passes untouched).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CombustionStage {
    channel: String,
    theta_tdc: f64,
    step_deg: f64,
    per_cycle: PerCycle,
    /// The stream over `t`, `theta_en` and the pressure, once set up, and the index (on
    /// `theta_en`, counted in 720° from `theta_tdc`) of the first block that starts in it.
    stream: Option<(CycleStream, i64)>,
    /// Scratch: the cycles a chunk completed, a cycle's angles [deg ATDC].
    #[serde(skip)]
    done: Vec<CycleSummary>,
    #[serde(skip)]
    atdc: Vec<f64>,
    /// The curves' grid step [deg] (a multiple of `step_deg`), and the time of the last cycle
    /// whose curves were given.
    #[serde(default)]
    curves: Option<(f64, f64)>,
}

impl CombustionStage {
    /// The figures of `channel` by `settings` (their `in_pa` is set from the stream's unit),
    /// firing TDCs at `theta_tdc` + k·4π on `theta_en` [rad], the pressure on a grid of
    /// `step_deg` [deg, a divisor of 720] — checked here.
    pub fn new(
        channel: &str,
        settings: PerCycleSettings,
        theta_tdc: f64,
        step_deg: f64,
    ) -> Result<Self, AppError> {
        if let Some(g) = &settings.geometry {
            g.validate()?;
        }
        settings.heat.validate()?;
        if let Some(k) = &settings.knock {
            k.validate().map_err(AppError::Invalid)?;
        }
        if let Some(b) = &settings.brake {
            b.validate().map_err(AppError::Invalid)?;
        }
        if let Some(lp) = &settings.lowpass {
            lp.validate().map_err(AppError::Invalid)?;
        }
        // The grid and the angle, checked once.
        CycleStream::new(2, theta_tdc - 2.0 * PI, Some(step_deg))
            .map_err(|e| AppError::Invalid(e.to_string()))?;
        Ok(Self {
            channel: channel.to_string(),
            theta_tdc,
            step_deg,
            per_cycle: PerCycle::new(settings),
            stream: None,
            done: Vec::new(),
            atdc: Vec::new(),
            curves: None,
        })
    }

    /// A cycle's curves too, on a grid of `step_deg` [deg] (rounded to a whole multiple of the
    /// stage's grid), one cycle's every [`CURVE_INTERVAL_S`] at most.
    pub fn with_curves(mut self, step_deg: f64) -> Self {
        let k = (step_deg / self.step_deg).round().max(1.0);
        self.curves = Some((k * self.step_deg, f64::NEG_INFINITY));
        self
    }

    /// The settings (`in_pa` as found once the stream is set up).
    pub fn settings(&self) -> &PerCycleSettings {
        self.per_cycle.settings()
    }

    /// The pressure channel.
    pub fn channel(&self) -> &str {
        &self.channel
    }
}

impl Stage for CombustionStage {
    type Out = CombustionOutput;

    /// A time that is not finite is an error naming its sample, an angle or a value that is
    /// not a number a dropout (module docs); a pressure channel in a unit of another quantity
    /// is refused.
    fn push(
        &mut self,
        chunk: &Recording,
        out: &mut dyn Sink<CombustionOutput>,
    ) -> Result<(), AppError> {
        if self.stream.is_none() {
            if chunk.channel(&self.channel).is_err() || chunk.channel("theta_en").is_err() {
                return Ok(());
            }
            UnitCheck::new(chunk, &self.channel)?;
            if let Some(b) = &self.per_cycle.settings().brake {
                crate::pressure::check_torque_unit(chunk, &b.channel)?;
            }
            let in_pa = chunk.channel(&self.channel)?.unit == "Pa";
            self.per_cycle = PerCycle::new(PerCycleSettings {
                in_pa,
                ..self.per_cycle.settings().clone()
            });
            // Cycles start 360° before their firing TDC; the grid's angles [deg ATDC], and the
            // times at its first and last points and its TDC's.
            let points = (720.0 / self.step_deg).round() as usize;
            grid(&mut self.atdc, points, self.step_deg);
            let marks = [0, points - 1, CycleTimes::tdc_index(&self.atdc)];
            let channels = 1 + usize::from(self.per_cycle.settings().brake.is_some());
            let stream = CycleStream::new(channels, self.theta_tdc - 2.0 * PI, Some(self.step_deg))
                .and_then(|s| s.with_times_at(&marks))
                .map_err(|e| AppError::Invalid(e.to_string()))?
                .curves_only();
            // The first block that starts in the stream: the one its first sample begins, when
            // it sits on a firing TDC, else the next.
            let theta0 = chunk.values("theta_en")?.first().copied().unwrap_or(0.0);
            let first = ((theta0 - self.theta_tdc) / (4.0 * PI)).ceil() as i64;
            self.stream = Some((stream, first));
        }
        let Some((stream, first)) = self.stream.as_mut() else {
            return Ok(());
        };
        let (t, theta) = (chunk.values("t")?, chunk.values("theta_en")?);
        self.done.clear();
        let p = chunk.values(&self.channel)?;
        let pushed = match &self.per_cycle.settings().brake {
            Some(b) => stream
                .push_past_dropouts(t, theta, &[p, chunk.values(&b.channel)?], &mut self.done)
                .map_err(|e| format!("{e} (channels 0, 1: {}, {})", self.channel, b.channel)),
            None => stream
                .push_past_dropouts(t, theta, &[p], &mut self.done)
                .map_err(|e| format!("{e} (channel 0: {})", self.channel)),
        };
        pushed.map_err(AppError::Invalid)?;
        if !stream.dropouts().is_empty() {
            let brake = self.per_cycle.settings().brake.as_ref();
            let names = [
                Some(self.channel.as_str()),
                brake.map(|b| b.channel.as_str()),
            ];
            let names: Vec<&str> = names.into_iter().flatten().collect();
            for d in stream.dropouts() {
                out.put(CombustionOutput::Dropout(Dropout::of_cycles(d, &names, 0)));
            }
        }
        for c in self.done.drain(..) {
            let Some(curve) = c.curve else { continue };
            let p = &curve[0];
            // (The grid is not kept in a checkpoint.)
            grid(&mut self.atdc, p.len(), self.step_deg);
            let [t_first, t_last, t_tdc] = c.times[..] else {
                return Err(AppError::Invalid(
                    "the combustion stage's stream has no times at its grid points (a checkpoint of another layout?)".into(),
                ));
            };
            let times = CycleTimes {
                first: t_first,
                last: t_last,
                tdc: t_tdc,
            };
            // The block its firing TDC starts: the stream's cycle k (absolute) starts 2π before
            // the TDC at θ_TDC + 4πk.
            let cycle = c.cycle + stream.first_index() - *first;
            let figures = self.per_cycle.figures(
                cycle,
                times,
                &self.atdc,
                p,
                curve.get(1).map(Vec::as_slice),
            );
            stream.recycle(curve);
            let due = match self.curves {
                Some((step, last)) if figures.t_start_s - last >= CURVE_INTERVAL_S => {
                    self.curves = Some((step, figures.t_start_s));
                    Some(step)
                }
                _ => None,
            };
            let curve = due.map(|step| {
                coarse_curve(
                    &self.per_cycle,
                    &self.atdc,
                    self.step_deg,
                    step,
                    figures.rpm,
                )
            });
            out.put(CombustionOutput::Cycle(CombustionCycle { figures, curve }));
        }
        Ok(())
    }

    /// The cycle in progress at the end is not complete: nothing.
    fn finish(&mut self, _out: &mut dyn Sink<CombustionOutput>) -> Result<(), AppError> {
        Ok(())
    }
}

/// `atdc` made the grid of `points` angles `step_deg` apart from −360° ATDC, unless it is.
fn grid(atdc: &mut Vec<f64>, points: usize, step_deg: f64) {
    if atdc.len() != points {
        atdc.clear();
        atdc.extend((0..points).map(|k| -360.0 + k as f64 * step_deg));
    }
}

/// The last cycle `per_cycle` analysed (on the grid `atdc` of `fine_deg` steps, at `rpm`), its
/// curves on the coarse grid of `step_deg` (see [`CombustionCurve`]).
fn coarse_curve(
    per_cycle: &PerCycle,
    atdc: &[f64],
    fine_deg: f64,
    step_deg: f64,
    rpm: f64,
) -> CombustionCurve {
    let k = (step_deg / fine_deg).round() as usize;
    let (p, _) = per_cycle.pegged();
    let heat = per_cycle.last_heat(atdc, rpm);
    let (half, points) = (k / 2, p.len().div_ceil(k));
    let hrr = (0..points)
        .map(|j| {
            let Some(h) = &heat else { return f64::NAN };
            let (i, last) = (j * k, h.from + h.q.len() - 1);
            if i < h.from || i > last {
                return f64::NAN;
            }
            // The step centred on the point, within the window.
            let (lo, hi) = (i.saturating_sub(half).max(h.from), (i + k - half).min(last));
            if hi <= lo {
                return f64::NAN;
            }
            (h.q[hi - h.from] - h.q[lo - h.from]) / (atdc[hi] - atdc[lo])
        })
        .collect();
    CombustionCurve {
        step_deg,
        p: p.iter().step_by(k).copied().collect(),
        hrr,
    }
}
