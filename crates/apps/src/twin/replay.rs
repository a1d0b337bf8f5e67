//! A recording's inputs replayed into the virtual cell: the scenario that drives the cell as the
//! recording's cell was driven (its speed demand and throttle against time), and the cell's
//! noiseless outputs on the recording's crank-angle grid, sample for sample against the
//! measured channels.

use crate::design::run::run_noiseless;
use crate::error::AppError;
use physid_core::{Basis, Recording};
use physid_sim::params::CellParams;
use physid_sim::run::{OutputBasis, Run, RunOptions};
use physid_sim::scenario::{Profile, Scenario, Segment, Shape};
use std::f64::consts::PI;

/// The outputs a twin matches, where the recording has them: the two speeds, the shaft
/// torque, the manifold and the cylinder pressures.
pub const OUTPUTS: &[&str] = &["omega_en", "omega_dy", "torque_shaft", "p_int", "p_cyl"];

/// How much of the recording's end is left out of the comparison: the replay's crank-angle
/// grid ends where its time does, within a few degrees of the recording's.
const END_MARGIN: f64 = 0.02;

/// What a recording's `speed_demand` channel holds: the dynamometer's demand.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Demand {
    /// A speed [rad/s]: the drive held the speed (the thesis's tests).
    Speed,
    /// A torque [N·m]: the drive applied the torque, the speed followed.
    Torque,
}

impl std::str::FromStr for Demand {
    type Err = AppError;
    fn from_str(s: &str) -> Result<Self, AppError> {
        match s {
            "speed" => Ok(Self::Speed),
            "torque" => Ok(Self::Torque),
            other => Err(AppError::Invalid(format!(
                "demand '{other}': expected speed or torque"
            ))),
        }
    }
}

/// Whether a demand's first sample `demand` can be a speed demand for a dynamometer turning at
/// `omega_dy` [rad/s]: within half of it (a step at the very start aside, a speed demand is near
/// the speed; a torque demand in N·m is far from it at any useful speed).
pub(crate) fn near_the_speed(demand: f64, omega_dy: f64) -> bool {
    (demand - omega_dy).abs() <= 0.5 * omega_dy.abs().max(1.0)
}

/// The speed [rpm] a torque-demand replay starts from so that, settling on its first torque and
/// throttle for the scenario's `settle`, the `cell`'s engine turns at the mean speed `w0`
/// [rad/s] over the first `window` [s] from t = 0 (the recording's first engine cycle: the
/// speed within a cycle ripples with the compression, its mean is smooth in the start): the
/// secant method on that mean, which rises with the start, from `guess` [rpm] (one settle per
/// iterate, to 1e-10 of `w0` — a replay's sensitivities are differences of such starts —, at
/// most 16).
pub fn start_reaching(
    scenario: &Scenario,
    cell: &CellParams,
    w0: f64,
    window: f64,
    guess: f64,
) -> Result<f64, AppError> {
    let settled = |rpm: f64| -> Result<f64, AppError> {
        let s = Scenario {
            speed_range: Some([0.05 * rpm, 1.95 * rpm]),
            duration: window,
            ..scenario.clone()
        };
        let opts = RunOptions {
            params: cell.clone(),
            basis: OutputBasis::Time(10_000.0),
            stream: true,
            ..RunOptions::default()
        };
        let mut run = Run::new(&s, &opts)?;
        run.keep_channels(&["omega_en"])?;
        run.step_until(f64::INFINITY)?;
        let rec = run.drain()?;
        let (t, w) = (rec.values("t")?, rec.values("omega_en")?);
        let n = t
            .iter()
            .take_while(|&&x| x < window)
            .count()
            .clamp(1, w.len().max(1));
        match w.get(..n) {
            Some(w) if !w.is_empty() => Ok(w.iter().sum::<f64>() / n as f64),
            _ => Err(AppError::Invalid(
                "the replay's settling gave no sample after t = 0".into(),
            )),
        }
    };
    let mut a = guess;
    let mut fa = settled(a)? - w0;
    if fa.abs() <= 1e-10 * w0 {
        return Ok(a);
    }
    // The settled speed moves about one for one with the start: the second iterate by that.
    let mut b = a - fa * 30.0 / PI;
    for _ in 0..16 {
        let fb = settled(b)? - w0;
        if fb.abs() <= 1e-10 * w0 {
            return Ok(b);
        }
        let slope = (fb - fa) / (b - a);
        if !(slope.is_finite() && slope > 0.0) {
            break;
        }
        (a, fa) = (b, fb);
        b -= fb / slope;
    }
    Err(AppError::Invalid(format!(
        "the replay found no start speed from which the cell, settling on the recording's first torque, turns at its first cycle's mean engine speed ({:.1} rpm) after t = 0",
        w0 * 30.0 / PI
    )))
}

/// The mean engine speed [rad/s] over the recording's first engine cycle and that cycle's
/// duration [s] (`None`: no positive, finite speed there).
fn first_cycle(rec: &Recording, t: &[f64], step_deg: f64) -> Result<Option<(f64, f64)>, AppError> {
    let w = rec.values_in("omega_en", "rad/s")?;
    let n = ((720.0 / step_deg).round() as usize)
        .min(w.len())
        .min(t.len());
    if n < 2 {
        return Ok(None);
    }
    let mean = w[..n].iter().sum::<f64>() / n as f64;
    Ok((mean.is_finite() && mean > 0.0).then_some((mean, t[n - 1] - t[0])))
}

/// A recording as the twin replays it.
#[derive(Debug, Clone)]
pub struct Replay {
    /// The recording's inputs as a scenario (speed demand [rpm] and throttle [deg] against
    /// time, as recorded profiles).
    pub scenario: Scenario,
    /// The crank-angle step of the recording's grid [deg].
    pub step_deg: f64,
    /// The channels compared.
    pub channels: Vec<String>,
    /// Their measured values, the first `n` samples of each.
    pub measured: Vec<Vec<f64>>,
    /// Samples compared per channel.
    pub n: usize,
    /// The recording's time at each of them [s].
    pub t: Vec<f64>,
    /// On a torque demand whose start the metadata does not give: the start each replayed cell
    /// is given ([`start_reaching`]).
    pub start: Option<Start>,
}

/// The start of a torque-demand replay found per cell: the recording's first cycle's mean
/// engine speed `w0` [rad/s] over `window` [s], which each replayed cell reaches from its own
/// start speed; `rpm`, the nominal cell's (each search's first guess).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Start {
    /// The mean engine speed over the recording's first cycle [rad/s].
    pub w0: f64,
    /// That cycle's duration [s].
    pub window: f64,
    /// The nominal cell's start [rpm].
    pub rpm: f64,
}

/// `(t, v)` with the points inside runs of equal values left out: the same profile under
/// linear interpolation, a held input in two points.
fn compress(t: &[f64], v: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let (mut tc, mut vc) = (Vec::new(), Vec::new());
    for k in 0..t.len() {
        let inner = k > 0 && k + 1 < t.len() && v[k - 1] == v[k] && v[k + 1] == v[k];
        if !inner {
            tc.push(t[k]);
            vc.push(v[k]);
        }
    }
    (tc, vc)
}

/// A recorded input as one profile segment over `[0, duration]`.
fn recorded(t: &[f64], v: &[f64], duration: f64) -> Profile {
    let (t, v) = compress(t, v);
    Profile {
        segments: vec![Segment {
            t0: 0.0,
            t1: duration,
            shape: Shape::Recorded {
                file: String::new(),
                t,
                v,
            },
        }],
    }
}

/// Refuse a recording whose cycle is 360° off (its θ = 0 at the gas-exchange TDC, not the
/// firing one: what a conversion to the crank angle gives without `--phase-from` half the
/// time), told by the cylinder pressure where it has one: the compression's peak, tens of
/// bar, against the gas exchange's ambient, so the mean within ±30° of 360° is far above the
/// mean within ±30° of 0° only when the phase is off. The replay starts at a firing TDC: on
/// such a recording it would compare every sample with the cell a revolution away.
fn firing_phase(rec: &Recording, theta: &[f64]) -> Result<(), AppError> {
    let Ok(p) = rec.values("p_cyl") else {
        return Ok(());
    };
    let (mut at_0, mut at_360) = ((0.0, 0usize), (0.0, 0usize));
    for (&th, &pc) in theta.iter().zip(p) {
        if !pc.is_finite() {
            continue;
        }
        let deg = th.to_degrees().rem_euclid(720.0);
        if !(30.0..690.0).contains(&deg) {
            at_0 = (at_0.0 + pc, at_0.1 + 1);
        } else if (330.0..390.0).contains(&deg) {
            at_360 = (at_360.0 + pc, at_360.1 + 1);
        }
    }
    if at_0.1 == 0 || at_360.1 == 0 {
        return Ok(());
    }
    let (m0, m360) = (at_0.0 / at_0.1 as f64, at_360.0 / at_360.1 as f64);
    if m360 > 2.0 * m0 {
        return Err(AppError::Invalid(format!(
            "the recording's cycle is 360° off: its cylinder pressure averages {:.0} kPa within ±30° of 360° and {:.0} kPa within ±30° of 0°, where the firing TDC should be — the twin replays from a firing TDC; convert the time-basis recording again with the phase taken from the pressure (physid convert IN OUT --crank-angle --phase-from p_cyl)",
            m360 / 1e3,
            m0 / 1e3
        )));
    }
    Ok(())
}

/// The values of `name`, every one finite (else the sample named).
fn finite<'a>(rec: &'a Recording, name: &str) -> Result<&'a [f64], AppError> {
    let v = rec.values(name)?;
    if let Some(k) = v.iter().position(|x| !x.is_finite()) {
        return Err(AppError::Invalid(format!(
            "channel '{name}', sample {k}: {} — the twin needs every sample of the channels it replays and matches",
            v[k]
        )));
    }
    Ok(v)
}

impl Replay {
    /// The replay of `rec`, matching `channels` (by default every one of [`OUTPUTS`] it has).
    /// The recording must be on a crank-angle basis with `t`, `theta`, `speed_demand` and
    /// `throttle` [deg]: the replayed cell's samples are compared with it degree by degree.
    /// On a torque demand the replay starts where the recording's run started: its metadata's
    /// `scenario.settle` and `scenario.start_rpm` (`physid simulate` writes them), else after
    /// a settling second each replayed cell from the speed at which it turns at the recording's
    /// first cycle's mean engine speed over that cycle ([`start_reaching`]; the `nominal`
    /// cell's is each search's first guess).
    /// `demand` says what `speed_demand` holds; by default the recording's metadata
    /// (`param.dyno.torque_mode`, which `physid simulate` writes), else a speed — refused, with
    /// the reason, where its first sample is far from the dynamometer's speed (unless `demand`
    /// says it is a speed).
    pub fn new(
        rec: &Recording,
        channels: Option<&[String]>,
        demand: Option<Demand>,
        nominal: &CellParams,
    ) -> Result<Self, AppError> {
        if rec.basis != Basis::CrankAngle {
            return Err(AppError::Invalid(
                "the twin compares the cell with a recording degree by degree: the recording is on a time basis — convert it first (physid convert IN OUT --crank-angle)".into(),
            ));
        }
        let t = finite(rec, "t")?;
        let theta = finite(rec, "theta")?;
        if t.len() < 10 {
            return Err(AppError::Invalid(format!(
                "the recording has {} samples: too few to calibrate on",
                t.len()
            )));
        }
        let step_deg = (theta[1] - theta[0]).to_degrees();
        if !(step_deg > 0.0 && step_deg <= 10.0) {
            return Err(AppError::Invalid(format!(
                "channel 'theta': a crank-angle step of {}° between samples 0 and 1 (expected 0–10°)",
                physid_core::Num(step_deg)
            )));
        }
        if let Some(k) = t.windows(2).position(|w| w[1] <= w[0]) {
            return Err(AppError::Invalid(format!(
                "channel 't', sample {}: time does not increase ({} after {})",
                k + 1,
                t[k + 1],
                t[k]
            )));
        }
        // The dynamometer's demand: a speed [rad/s → rpm], or on a torque demand the torque
        // [N·m] (the cell records it in the same channel), replayed open loop from where the
        // recording's run started — its settling time and start speed from its metadata
        // (`physid simulate` writes them), else 1 s from the speed that reaches the first
        // cycle's mean engine speed ([`Start`]).
        let demand_said = demand;
        let torque_mode = match demand {
            Some(d) => d == Demand::Torque,
            None => rec
                .meta
                .get("param.dyno.torque_mode")
                .is_some_and(|v| v != "0"),
        };
        let meta = |key: &str| -> Result<Option<f64>, AppError> {
            rec.meta
                .get(key)
                .map(|v| {
                    v.parse::<f64>()
                        .ok()
                        .filter(|x| x.is_finite() && *x >= 0.0)
                        .ok_or_else(|| {
                            AppError::Invalid(format!(
                                "the recording's metadata '{key}' = '{v}': expected a number ≥ 0"
                            ))
                        })
                })
                .transpose()
        };
        let settle = meta("scenario.settle")?.unwrap_or(1.0);
        // On a torque demand without the start in the metadata: the first cycle's mean engine
        // speed, to be reached after the settling.
        let mut reach = None;
        let (demand, speed_range) = if torque_mode {
            let start = match meta("scenario.start_rpm")? {
                Some(rpm) if rpm > 0.0 => rpm,
                _ => match first_cycle(rec, t, step_deg)? {
                    Some((w, window)) => {
                        reach = Some((w, window));
                        w * 30.0 / PI
                    }
                    _ => {
                        return Err(AppError::Invalid(
                            "the recording's dynamometer ran on a torque demand and neither its metadata ('scenario.start_rpm') nor its first cycle's 'omega_en' gives the speed it started from".into(),
                        ))
                    }
                },
            };
            // Wide: a guard against a replay that runs away, not a limit of the test.
            (
                finite(rec, "speed_demand")?.to_vec(),
                Some([0.05 * start, 1.95 * start]),
            )
        } else {
            let demand = rec.values_in("speed_demand", "rad/s")?;
            if let Some(k) = demand.iter().position(|x| !x.is_finite()) {
                return Err(AppError::Invalid(format!(
                    "channel 'speed_demand', sample {k}: not a number"
                )));
            }
            if let (None, Ok(w)) = (demand_said, rec.values_in("omega_dy", "rad/s")) {
                if let (Some(&d), Some(&w)) = (demand.first(), w.first()) {
                    if !near_the_speed(d, w) {
                        return Err(AppError::Invalid(format!(
                            "channel 'speed_demand', sample 0: {d:.3} is far from the dynamometer's speed ({w:.3} rad/s) — not a speed demand: a dynamometer on a torque demand records the torque [N·m] there; say so (physid twin --demand torque, Python demand=\"torque\")"
                        )));
                    }
                }
            }
            (demand.iter().map(|w| w * 30.0 / PI).collect(), None)
        };
        let throttle = finite(rec, "throttle")?;
        firing_phase(rec, theta)?;
        // Times from the recording's start (its grid starts at the first firing TDC).
        let t0 = t[0].min(0.0);
        let tr: Vec<f64> = t.iter().map(|x| x - t0).collect();
        let duration = tr[tr.len() - 1];
        let mut scenario = Scenario {
            name: "twin-replay".into(),
            description: format!(
                "the inputs of {} replayed: {} demand and throttle as recorded",
                rec.meta.get("source").map_or("a recording", String::as_str),
                if torque_mode { "torque" } else { "speed" }
            ),
            duration,
            settle,
            speed: recorded(&tr, &demand, duration),
            throttle: recorded(&tr, throttle, duration),
            torque_mode,
            speed_range,
            set: Default::default(),
            faults: Vec::new(),
        };
        let start = match reach {
            Some((w0, window)) => {
                let rpm = start_reaching(&scenario, nominal, w0, window, w0 * 30.0 / PI)?;
                scenario.speed_range = Some([0.05 * rpm, 1.95 * rpm]);
                Some(Start { w0, window, rpm })
            }
            None => None,
        };
        let names: Vec<String> = match channels {
            Some(c) => c.to_vec(),
            None => OUTPUTS
                .iter()
                .filter(|c| rec.channel(c).is_ok())
                .map(|c| c.to_string())
                .collect(),
        };
        if names.is_empty() {
            return Err(AppError::Invalid(format!(
                "the recording has none of the channels a twin matches ({})",
                OUTPUTS.join(", ")
            )));
        }
        let n = ((t.len() as f64) * (1.0 - END_MARGIN)) as usize;
        let mut measured = Vec::with_capacity(names.len());
        for c in &names {
            if !OUTPUTS.contains(&c.as_str()) {
                return Err(AppError::Invalid(format!(
                    "channel '{c}': the twin matches {}",
                    OUTPUTS.join(", ")
                )));
            }
            let unit = physid_core::standard_unit(c).unwrap_or("");
            let v = rec.values_in(c, unit)?;
            if let Some(k) = v[..n].iter().position(|x| !x.is_finite()) {
                return Err(AppError::Invalid(format!(
                    "channel '{c}', sample {k}: not a number — the twin compares every sample"
                )));
            }
            measured.push(v[..n].to_vec());
        }
        Ok(Self {
            scenario,
            step_deg,
            channels: names,
            measured,
            n,
            t: t[..n].to_vec(),
            start,
        })
    }

    /// The cell `cell` driven by the recording's inputs, without sensor noise: the compared
    /// channels, `n` samples each.
    pub fn simulate(&self, cell: &CellParams) -> Result<Vec<Vec<f64>>, AppError> {
        let quiet: Vec<&str> = CellParams::TABLE
            .iter()
            .map(|(p, _, _)| *p)
            .filter(|p| p.ends_with(".noise") || p.ends_with(".quantum"))
            .collect();
        let keep: Vec<&str> = self.channels.iter().map(String::as_str).collect();
        let mut out: Vec<Vec<f64>> = vec![Vec::with_capacity(self.n + 64); keep.len()];
        // Each cell from its own start: the one that reaches the recording's first cycle.
        let started;
        let scenario = match &self.start {
            Some(s) => {
                let rpm = start_reaching(&self.scenario, cell, s.w0, s.window, s.rpm)?;
                started = Scenario {
                    speed_range: Some([0.05 * rpm, 1.95 * rpm]),
                    ..self.scenario.clone()
                };
                &started
            }
            None => &self.scenario,
        };
        run_noiseless(
            cell,
            &quiet,
            scenario,
            OutputBasis::Crank(self.step_deg),
            &keep,
            |chunk| {
                for (o, c) in out.iter_mut().zip(&keep) {
                    o.extend_from_slice(chunk.values(c)?);
                }
                Ok(())
            },
        )?;
        for (o, c) in out.iter_mut().zip(&keep) {
            if o.len() < self.n {
                return Err(AppError::Invalid(format!(
                    "the replayed cell gave {} samples of '{c}' against the recording's {}: its crank angle fell behind the recording's",
                    o.len(),
                    self.n
                )));
            }
            o.truncate(self.n);
        }
        Ok(out)
    }
}
