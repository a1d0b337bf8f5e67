//! A recording's inputs replayed into the virtual cell: the scenario that drives the cell as the
//! recording's cell was driven (its speed demand and throttle against time), and the cell's
//! noiseless outputs on the recording's crank-angle grid, sample for sample against the
//! measured channels.

use crate::design::run::run_noiseless;
use crate::error::AppError;
use physid_core::{Basis, Recording};
use physid_sim::params::CellParams;
use physid_sim::run::OutputBasis;
use physid_sim::scenario::{Profile, Scenario, Segment, Shape};
use std::f64::consts::PI;

/// The outputs a twin matches, where the recording has them: the two speeds, the shaft
/// torque, the manifold and the cylinder pressures.
pub const OUTPUTS: &[&str] = &["omega_en", "omega_dy", "torque_shaft", "p_int", "p_cyl"];

/// How much of the recording's end is left out of the comparison: the replay's crank-angle
/// grid ends where its time does, within a few degrees of the recording's.
const END_MARGIN: f64 = 0.02;

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
    /// The recording must be on a crank-angle basis with `t`, `theta`, `speed_demand` [rad/s]
    /// and `throttle` [deg]: the replayed cell's samples are compared with it degree by degree.
    pub fn new(rec: &Recording, channels: Option<&[String]>) -> Result<Self, AppError> {
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
                "channel 'theta': a crank-angle step of {step_deg}° between samples 0 and 1 (expected 0–10°)"
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
        // (`physid simulate` writes them), else 1 s from the first measured engine speed.
        let torque_mode = rec
            .meta
            .get("param.dyno.torque_mode")
            .is_some_and(|v| v != "0");
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
        let (demand, speed_range) = if torque_mode {
            let start = match meta("scenario.start_rpm")? {
                Some(rpm) if rpm > 0.0 => rpm,
                _ => match rec.values_in("omega_en", "rad/s")?.first() {
                    Some(w) if w.is_finite() && *w > 0.0 => w * 30.0 / PI,
                    _ => {
                        return Err(AppError::Invalid(
                            "the recording's dynamometer ran on a torque demand and neither its metadata ('scenario.start_rpm') nor its first 'omega_en' sample gives the speed it started from".into(),
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
            (demand.iter().map(|w| w * 30.0 / PI).collect(), None)
        };
        let throttle = finite(rec, "throttle")?;
        // Times from the recording's start (its grid starts at the first firing TDC).
        let t0 = t[0].min(0.0);
        let tr: Vec<f64> = t.iter().map(|x| x - t0).collect();
        let duration = tr[tr.len() - 1];
        let scenario = Scenario {
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
        run_noiseless(
            cell,
            &quiet,
            &self.scenario,
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
