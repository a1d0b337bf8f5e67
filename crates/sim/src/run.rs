//! Running a scenario: the cell stepped one crank increment at a time with the scenario's
//! demand, throttle and faults, then the acquisition — resampling to the output basis and the
//! sensors (SPEC §2.7) — into a [`Recording`] with the DESIGN.md channel names.
//!
//! Sensors act on the output samples: `y = gain·lag(x) + offset + noise`, quantised; the
//! encoders count `floor(θ/q)` pulses (a lost-pulse fault drops pulses at random, for good);
//! the TDC marker is 1 on the first sample of each engine revolution (θ_en passing a multiple
//! of 2π from firing TDC). The true torque components and the cylinder temperature come along
//! as `true_*` channels, the parameters and faults in the metadata: the ground truth that
//! identification results are checked against.

use crate::cell::{Inputs, Sample, TestCell};
use crate::control::{inverse_park, Demand};
use crate::params::{CellParams, SensorParams};
use crate::scenario::{Fault, Scenario};
use physid_core::{Basis, Channel, Recording};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use std::f64::consts::{PI, TAU};
use thiserror::Error;

/// Errors of a run.
#[derive(Debug, Error, PartialEq)]
pub enum SimError {
    /// A bad parameter, scenario or fault, explained.
    #[error("{0}")]
    Invalid(String),
    /// The solution left the physical domain (a volume emptied, a temperature went
    /// negative): the step, time and what.
    #[error("the simulation diverged at t = {t:.6} s: {what}; try a smaller solver.step_deg")]
    Diverged {
        /// Time [s].
        t: f64,
        /// What went wrong.
        what: String,
    },
}

/// The output basis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum OutputBasis {
    /// Uniform time steps at this rate [Hz].
    Time(f64),
    /// One sample per this many crank degrees from the first firing TDC.
    Crank(f64),
}

/// How to run.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// Base parameters. The scenario's own `set` is applied over them: to override one of a
    /// scenario's settings, put it in the scenario's `set` (as `physid simulate --set` does).
    pub params: CellParams,
    /// Recorded duration [s] (the scenario's if `None`).
    pub duration: Option<f64>,
    /// Extra faults (`--fault`).
    pub faults: Vec<Fault>,
    /// Output basis.
    pub basis: OutputBasis,
}

impl Default for RunOptions {
    fn default() -> Self {
        Self {
            params: CellParams::default(),
            duration: None,
            faults: Vec::new(),
            basis: OutputBasis::Time(10_000.0),
        }
    }
}

/// The truth at every solver step, column by column.
#[derive(Debug, Default)]
struct Raw {
    cols: Vec<Vec<f64>>,
}

/// Names and units of the raw columns, in order.
const RAW: [(&str, &str); 30] = [
    ("t", "s"),
    ("theta_en", "rad"),
    ("theta_dy", "rad"),
    ("omega_en", "rad/s"),
    ("omega_dy", "rad/s"),
    ("alpha_en", "rad/s^2"),
    ("alpha_dy", "rad/s^2"),
    ("torque_shaft", "N*m"),
    ("torque_engine", "N*m"),
    ("torque_dy", "N*m"),
    ("p_cyl", "Pa"),
    ("p_int", "Pa"),
    ("p_exh", "Pa"),
    ("T_int", "K"),
    ("T_exh", "K"),
    ("T_oil", "K"),
    ("throttle", "deg"),
    ("speed_demand", "rad/s"),
    ("i_a", "A"),
    ("i_b", "A"),
    ("i_c", "A"),
    ("v_a", "V"),
    ("v_b", "V"),
    ("v_c", "V"),
    ("true_torque_indicated", "N*m"),
    ("true_torque_reciprocating", "N*m"),
    ("true_torque_friction", "N*m"),
    ("true_T_cyl", "K"),
    ("true_shaft_k", "N*m/rad"),
    ("true_shaft_b", "N*m*s/rad"),
];

impl Raw {
    fn push(&mut self, s: &Sample, p: &CellParams) {
        if self.cols.is_empty() {
            self.cols = vec![Vec::new(); RAW.len()];
        }
        let sc = s.theta_syn.sin_cos();
        let i = inverse_park(s.i_dq, sc);
        let v = inverse_park(s.v_dq, sc);
        let row = [
            s.t,
            s.theta_en,
            s.theta_dy,
            s.omega_en,
            s.omega_dy,
            s.alpha_en,
            s.alpha_dy,
            s.torque_shaft,
            s.torque_engine,
            s.torque_dy,
            s.gas.p[1],
            s.gas.p[0],
            s.gas.p[2],
            s.temperatures[0],
            s.temperatures[2],
            p.engine.t_oil,
            s.throttle_deg,
            s.demand,
            i[0],
            i[1],
            i[2],
            v[0],
            v[1],
            v[2],
            s.torque_indicated,
            s.torque_reciprocating,
            s.torque_friction,
            s.temperatures[1],
            p.shaft.k,
            p.shaft.b,
        ];
        for (c, v) in self.cols.iter_mut().zip(row) {
            c.push(v);
        }
    }
}

/// How a raw column is carried from the solver's steps to the output grid.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Between {
    /// Linear interpolation (the states and what follows from them).
    Linear,
    /// The value of the step that contains the point: for what the cell holds over a step
    /// (the throttle, the demand, the parameters a fault changes), so that a stepped input or
    /// fault never shows a value between its two levels. A point within 1 % of a step's length
    /// before the next step counts as on it (the crank-angle grid's steps land within 0.1 %).
    Hold,
}

/// Where the points `at` fall among the raw abscissae `x` (increasing): for each, the raw
/// interval `j` and the fraction `f` into it (clamped to the ends). Computed once per run and
/// applied to every column.
struct Resampler {
    at: Vec<(usize, f64)>,
}

impl Resampler {
    fn new(x: &[f64], at: &[f64]) -> Self {
        let mut j = 0;
        let at = at
            .iter()
            .map(|&a| {
                while j + 2 < x.len() && x[j + 1] < a {
                    j += 1;
                }
                let (x0, x1) = (x[j], x[j + 1]);
                let f = if x1 > x0 {
                    ((a - x0) / (x1 - x0)).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                (j, f)
            })
            .collect();
        Self { at }
    }

    /// `y` at the points, `how` between the raw points.
    fn apply(&self, y: &[f64], how: Between) -> Vec<f64> {
        self.at
            .iter()
            .map(|&(j, f)| match how {
                Between::Linear => y[j] + f * (y[j + 1] - y[j]),
                Between::Hold if f >= 0.99 => y[j + 1],
                Between::Hold => y[j],
            })
            .collect()
    }
}

/// A sensor's state over the output samples.
struct SensorState {
    lagged: Option<f64>,
}

impl SensorState {
    fn measure(&mut self, s: &SensorParams, x: f64, dt: f64, rng: &mut ChaCha8Rng) -> f64 {
        let l = match (self.lagged, s.lag > 0.0) {
            (Some(prev), true) => prev + (x - prev) * (1.0 - (-dt / s.lag).exp()),
            _ => x,
        };
        self.lagged = Some(l);
        let noise: f64 = if s.noise > 0.0 {
            s.noise * rng.sample::<f64, _>(StandardNormal)
        } else {
            0.0
        };
        let y = s.gain * l + s.offset + noise;
        if s.quantum > 0.0 {
            (y / s.quantum).round() * s.quantum
        } else {
            y
        }
    }
}

/// Run a scenario.
pub fn simulate(
    scenario: &Scenario,
    opts: &RunOptions,
    mut progress: impl FnMut(f64),
) -> Result<Recording, SimError> {
    scenario.validate().map_err(SimError::Invalid)?;
    let mut base = opts.params.clone();
    for (k, v) in &scenario.set {
        base.set(k, *v).map_err(SimError::Invalid)?;
    }
    base.validate().map_err(SimError::Invalid)?;
    let mut faults: Vec<Fault> = scenario
        .faults
        .iter()
        .map(|f| Fault::parse(f))
        .collect::<Result<_, _>>()
        .map_err(SimError::Invalid)?;
    faults.extend(opts.faults.iter().cloned());
    let duration = opts.duration.unwrap_or(scenario.duration);
    if !(duration.is_finite() && duration > 0.0) {
        return Err(SimError::Invalid(format!(
            "duration {duration}: expected > 0 s"
        )));
    }
    let torque_mode = scenario.torque_mode || base.dyno.torque_mode != 0.0;
    let demand_at = |t: f64| {
        let v = scenario.speed.value(t.max(0.0));
        if torque_mode {
            Demand::Torque(v)
        } else {
            Demand::Speed(v * PI / 30.0)
        }
    };
    let w0 = if torque_mode {
        1000.0 * PI / 30.0
    } else {
        scenario.speed.value(0.0) * PI / 30.0
    };
    // The cell starts at BDC before firing TDC so the first cycle begins with compression.
    let mut cell = TestCell::new(base.clone(), w0.max(1.0), -PI).map_err(SimError::Invalid)?;
    let mut rng = ChaCha8Rng::seed_from_u64(base.sensors.seed as u64);
    let settle = scenario.settle;
    let mut raw = Raw::default();
    let mut speed_sensor = SensorState { lagged: None };
    let mut last_report = -1.0;
    loop {
        let t_rel = cell.time() - settle;
        Fault::apply_all(&faults, &base, &mut cell.params, t_rel.max(0.0));
        cell.refresh_live_parameters();
        let inputs = Inputs {
            demand: demand_at(t_rel),
            throttle_deg: scenario.throttle.value(t_rel.max(0.0)),
        };
        let w_true = cell.state()[9];
        let ss = cell.params.dyno.speed_sensor;
        let w_meas = speed_sensor.measure(&ss, w_true, 0.0, &mut rng);
        let s = cell.step_with(&inputs, w_meas);
        check(&s, base.engine.active != 0.0)?;
        // From the step that spans t = 0 on, so that the output grid starts at 0.
        if cell.time() - settle > 0.0 {
            let mut s = s;
            s.t = t_rel;
            raw.push(&s, &cell.params);
        }
        if t_rel - last_report >= duration / 100.0 {
            progress((t_rel / duration).clamp(0.0, 1.0));
            last_report = t_rel;
        }
        // One sample past the end, so that the output grid reaches it.
        if t_rel > duration {
            break;
        }
    }
    progress(1.0);
    acquire(&raw, &base, &faults, opts.basis, scenario, duration)
}

/// Catch a state that left the physical domain.
fn check(s: &Sample, engine_active: bool) -> Result<(), SimError> {
    let bad = |what: String| Err(SimError::Diverged { t: s.t, what });
    for (k, name) in ["intake", "cylinder", "exhaust"]
        .iter()
        .enumerate()
        .filter(|_| engine_active)
    {
        if !(s.gas.p[k].is_finite() && s.gas.p[k] > 0.0) {
            return bad(format!("{name} pressure {}", s.gas.p[k]));
        }
        if !(s.temperatures[k].is_finite() && s.temperatures[k] > 0.0) {
            return bad(format!("{name} temperature {}", s.temperatures[k]));
        }
    }
    if !s.omega_en.is_finite() || !s.omega_dy.is_finite() || !s.torque_dy.is_finite() {
        return bad("speeds or machine torque not finite".into());
    }
    Ok(())
}

/// Resample the truth to the output basis and measure it with the sensors.
fn acquire(
    raw: &Raw,
    base: &CellParams,
    faults: &[Fault],
    basis: OutputBasis,
    scenario: &Scenario,
    duration: f64,
) -> Result<Recording, SimError> {
    let col = |name: &str| {
        RAW.iter()
            .position(|c| c.0 == name)
            .map(|i| raw.cols[i].as_slice())
            .unwrap_or(&[])
    };
    let t_raw = col("t");
    let th_raw = col("theta_en");
    if t_raw.len() < 2 {
        return Err(SimError::Invalid(
            "the run produced fewer than 2 samples".into(),
        ));
    }
    // Output grid in the raw columns' abscissa.
    let (abscissa, grid): (&[f64], Vec<f64>) = match basis {
        OutputBasis::Time(rate) => {
            if !(rate.is_finite() && rate > 0.0) {
                return Err(SimError::Invalid(format!(
                    "output rate {rate} Hz: expected > 0"
                )));
            }
            // On the rate's grid from 0 (the first recorded step starts at or before 0).
            let k0 = (t_raw[0] * rate).ceil().max(0.0) as usize;
            let n = (duration * rate).floor() as usize + 1;
            let last = t_raw[t_raw.len() - 1];
            (
                t_raw,
                (k0..n)
                    .map(|i| i as f64 / rate)
                    .filter(|t| *t <= last)
                    .collect(),
            )
        }
        OutputBasis::Crank(step) => {
            if !(step.is_finite() && step > 0.0) {
                return Err(SimError::Invalid(format!(
                    "crank step {step}°: expected > 0"
                )));
            }
            if th_raw.windows(2).any(|w| w[1] <= w[0]) {
                return Err(SimError::Invalid(
                    "the engine stopped or turned back: a crank-angle basis needs it turning forwards".into(),
                ));
            }
            let first = (th_raw[0] / (4.0 * PI)).ceil() * 4.0 * PI;
            let last = th_raw[th_raw.len() - 1];
            let h = step.to_radians();
            let n = ((last - first) / h).floor().max(-1.0) as i64 + 1;
            (
                th_raw,
                (0..n.max(0)).map(|k| first + k as f64 * h).collect(),
            )
        }
    };
    let resampler = Resampler::new(abscissa, &grid);
    let at = |name: &str| resampler.apply(col(name), Between::Linear);
    let held = |name: &str| resampler.apply(col(name), Between::Hold);
    let t = match basis {
        OutputBasis::Time(_) => grid.clone(),
        OutputBasis::Crank(_) => at("t"),
    };
    let mut rec = Recording::new(match basis {
        OutputBasis::Time(_) => Basis::Time,
        OutputBasis::Crank(_) => Basis::CrankAngle,
    });
    let mut rng = ChaCha8Rng::seed_from_u64(base.sensors.seed as u64 ^ 0x5e5e);
    let push = |rec: &mut Recording, name: &str, unit: &str, values: Vec<f64>| {
        rec.push(Channel {
            name: name.into(),
            unit: unit.into(),
            values,
        })
        .map_err(|e| SimError::Invalid(e.to_string()))
    };
    push(&mut rec, "t", "s", t.clone())?;
    let theta_en = at("theta_en");
    if let OutputBasis::Crank(_) = basis {
        let first = grid.first().copied().unwrap_or(0.0);
        push(
            &mut rec,
            "theta",
            "rad",
            grid.iter().map(|g| g - first).collect(),
        )?;
        push(
            &mut rec,
            "cycle",
            "-",
            grid.iter()
                .map(|g| ((g - first) / (4.0 * PI) + 1e-9).floor())
                .collect(),
        )?;
        push(
            &mut rec,
            "crank_deg",
            "deg",
            grid.iter()
                .map(|g| {
                    let d = (g - first).to_degrees().rem_euclid(720.0);
                    if d > 720.0 - 1e-6 {
                        0.0
                    } else {
                        d
                    }
                })
                .collect(),
        )?;
    }
    // Sensor parameters in force at each output time (faults included).
    let params_at = |ti: f64| {
        let mut p = base.clone();
        Fault::apply_all(faults, base, &mut p, ti);
        p
    };
    let sensor_faulted = faults.iter().any(|f| f.path.starts_with("sensors."));
    let sensed = |rng: &mut ChaCha8Rng, x: Vec<f64>, pick: fn(&CellParams) -> SensorParams| {
        let mut st = SensorState { lagged: None };
        // Without a sensor fault the sensor's parameters are the same at every sample.
        let constant = pick(base);
        let mut out = Vec::with_capacity(x.len());
        for (k, &xi) in x.iter().enumerate() {
            let dt = if k > 0 { t[k] - t[k - 1] } else { 0.0 };
            let s = if sensor_faulted {
                pick(&params_at(t[k]))
            } else {
                constant
            };
            out.push(st.measure(&s, xi, dt, rng));
        }
        out
    };
    let theta_dy = at("theta_dy");
    push(&mut rec, "theta_en", "rad", theta_en.clone())?;
    push(&mut rec, "theta_dy", "rad", theta_dy.clone())?;
    let speed = sensed(&mut rng, at("omega_en"), |p| p.sensors.speed);
    push(&mut rec, "omega_en", "rad/s", speed)?;
    let speed = sensed(&mut rng, at("omega_dy"), |p| p.sensors.speed);
    push(&mut rec, "omega_dy", "rad/s", speed)?;
    push(&mut rec, "alpha_en", "rad/s^2", at("alpha_en"))?;
    push(&mut rec, "alpha_dy", "rad/s^2", at("alpha_dy"))?;
    let v = sensed(&mut rng, at("torque_shaft"), |p| p.sensors.torque_shaft);
    push(&mut rec, "torque_shaft", "N*m", v)?;
    let v = sensed(&mut rng, at("torque_engine"), |p| p.sensors.torque_engine);
    push(&mut rec, "torque_engine", "N*m", v)?;
    push(&mut rec, "torque_dy", "N*m", at("torque_dy"))?;
    let v = sensed(&mut rng, at("p_cyl"), |p| p.sensors.p_cyl);
    push(&mut rec, "p_cyl", "Pa", v)?;
    let v = sensed(&mut rng, at("p_int"), |p| p.sensors.p_manifold);
    push(&mut rec, "p_int", "Pa", v)?;
    let v = sensed(&mut rng, at("p_exh"), |p| p.sensors.p_manifold);
    push(&mut rec, "p_exh", "Pa", v)?;
    push(&mut rec, "p_crank", "Pa", vec![base.ambient.p; t.len()])?;
    push(&mut rec, "p_atm", "Pa", vec![base.ambient.p; t.len()])?;
    let v = sensed(&mut rng, held("T_oil"), |p| p.sensors.temperature);
    push(&mut rec, "T_oil", "K", v)?;
    let v = sensed(&mut rng, at("T_int"), |p| p.sensors.temperature);
    push(&mut rec, "T_int", "K", v)?;
    let v = sensed(&mut rng, at("T_exh"), |p| p.sensors.temperature);
    push(&mut rec, "T_exh", "K", v)?;
    push(&mut rec, "throttle", "deg", held("throttle"))?;
    push(&mut rec, "speed_demand", "rad/s", held("speed_demand"))?;
    for ch in ["i_a", "i_b", "i_c"] {
        push(&mut rec, ch, "A", at(ch))?;
    }
    for ch in ["v_a", "v_b", "v_c"] {
        push(&mut rec, ch, "V", at(ch))?;
    }
    // Encoders and the TDC marker from the true angles.
    let q_en = TAU / base.sensors.ppr_en;
    let q_dy = TAU / base.sensors.ppr_dy;
    let mut lost = 0.0;
    let mut count_en = Vec::with_capacity(t.len());
    let mut prev_ideal: Option<f64> = None;
    for (k, th) in theta_en.iter().enumerate() {
        let ideal = (th / q_en).floor();
        if let Some(pi) = prev_ideal {
            let p_lost = if sensor_faulted {
                params_at(t[k]).sensors.lost_pulses_en
            } else {
                base.sensors.lost_pulses_en
            };
            if p_lost > 0.0 {
                for _ in 0..((ideal - pi).max(0.0) as usize) {
                    if rng.random::<f64>() < p_lost {
                        lost += 1.0;
                    }
                }
            }
        }
        prev_ideal = Some(ideal);
        count_en.push(ideal - lost);
    }
    push(&mut rec, "count_en", "-", count_en)?;
    push(
        &mut rec,
        "count_dy",
        "-",
        theta_dy.iter().map(|th| (th / q_dy).floor()).collect(),
    )?;
    let mut tdc = vec![0.0; t.len()];
    for k in 1..t.len() {
        if (theta_en[k] / TAU).floor() > (theta_en[k - 1] / TAU).floor() {
            tdc[k] = 1.0;
        }
    }
    if let OutputBasis::Crank(_) = basis {
        tdc[0] = 1.0;
    }
    push(&mut rec, "tdc", "-", tdc)?;
    for (name, unit) in RAW.iter().filter(|c| c.0.starts_with("true_")) {
        // The shaft's parameters are held over a step; the true torques and T_cyl are states'.
        let values = if name.starts_with("true_shaft_") {
            held(name)
        } else {
            at(name)
        };
        push(&mut rec, name, unit, values)?;
    }
    rec.meta.insert("source".into(), "physid simulate".into());
    rec.meta.insert("scenario".into(), scenario.name.clone());
    rec.meta.insert(
        "faults".into(),
        faults
            .iter()
            .map(|f| format!("{}={}@{}+{}", f.path, f.value, f.at, f.ramp))
            .collect::<Vec<_>>()
            .join(" "),
    );
    for (path, _, _) in CellParams::TABLE {
        if let Some(v) = base.get(path) {
            rec.meta.insert(format!("param.{path}"), format!("{v}"));
        }
    }
    Ok(rec)
}

/// The true value of a cell parameter at times `t`, from a simulated recording's metadata (its
/// `param.PATH` value and the faults on PATH); `None` for a recording that does not carry it
/// (measured data).
pub fn parameter_truth(rec: &Recording, path: &str, t: &[f64]) -> Option<Vec<f64>> {
    let v0: f64 = rec.meta.get(&format!("param.{path}"))?.parse().ok()?;
    let faults: Vec<Fault> = rec
        .meta
        .get("faults")
        .map(|s| {
            s.split_whitespace()
                .filter_map(|f| Fault::parse(f).ok())
                .filter(|f| f.path == path)
                .collect()
        })
        .unwrap_or_default();
    Some(
        t.iter()
            .map(|&ti| {
                // As `Fault::apply_all`: each fault moves from the base value; a later one on
                // the same path overrides an earlier one once it has started.
                faults.iter().fold(v0, |v, f| match f.progress(ti) {
                    x if x > 0.0 => v0 + (f.value - v0) * x,
                    _ => v,
                })
            })
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::{Between, Resampler};

    /// Linear between the raw points; held at the containing step's value, a point within 1 %
    /// of a step before the next counting as on it; clamped at the ends.
    #[test]
    fn resample_linear_and_held() {
        let x = [0.0, 1.0, 2.0, 3.0];
        let y = [10.0, 20.0, 30.0, 40.0];
        let at = [-1.0, 0.5, 0.995, 1.0, 1.5, 2.999, 3.0, 4.0];
        let r = Resampler::new(&x, &at);
        let lin = r.apply(&y, Between::Linear);
        let want = [10.0, 15.0, 19.95, 20.0, 25.0, 39.99, 40.0, 40.0];
        for (a, b) in lin.iter().zip(want) {
            assert!((a - b).abs() < 1e-12, "{a} vs {b}");
        }
        let held = r.apply(&y, Between::Hold);
        assert_eq!(held, [10.0, 10.0, 20.0, 20.0, 20.0, 40.0, 40.0, 40.0]);
    }
}
