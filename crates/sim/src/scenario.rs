//! Scenarios (SPEC §3): what the drive is asked for (speed in rpm, or torque) and where the
//! throttle is, as piecewise profiles over time; parameter settings; faults. The named
//! scenarios of the thesis ship built in; others come from TOML files.
//!
//! ```toml
//! name = "my-test"
//! duration = 20.0          # s, recorded
//! settle = 1.0             # s, simulated before recording starts
//! faults = ["shaft.k=1200@5", "shaft.b=1.2@5+2"]
//! [[speed]]                # rpm (or N·m with torque_mode = true, and then
//!                          # speed_range = [800.0, 1400.0]: start in the middle, stop outside)
//! t0 = 0.0
//! t1 = 10.0
//! kind = "sine"            # constant | ramp | sine | steps | chirp | recorded
//! mean = 1000.0
//! amplitude = 200.0
//! frequency = 0.5
//! [[throttle]]             # deg above closed
//! t0 = 0.0
//! t1 = 20.0
//! kind = "constant"
//! value = 90.0
//! [set]
//! "shaft.k" = 1340.0
//! ```
//!
//! Segment fields: `constant` — `value`; `ramp` — `v0`, `v1`; `sine` — `mean`, `amplitude`,
//! `frequency` [Hz], `phase` [deg]; `steps` — `values`, `every` [s]; `chirp` — `mean`,
//! `amplitude`, `f0`, `f1` [Hz] (linear sweep); `recorded` — `file` (CSV with columns `t`
//! and `value`, time from the segment's start), or the points themselves as `t` and `v`
//! (how an FMU's resources carry them). Outside every segment a profile holds the
//! value at the nearest end.

use crate::error::SimError;
use crate::params::CellParams;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;
use std::path::Path;

/// One piece of a profile.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Shape {
    /// A constant.
    Constant {
        /// The value.
        value: f64,
    },
    /// A linear ramp over the segment.
    Ramp {
        /// Value at the start.
        v0: f64,
        /// Value at the end.
        v1: f64,
    },
    /// `mean + amplitude·sin(2π·f·τ + phase)`, τ from the segment's start.
    Sine {
        /// Mean.
        mean: f64,
        /// Amplitude.
        amplitude: f64,
        /// Frequency [Hz].
        frequency: f64,
        /// Phase [deg].
        #[serde(default)]
        phase: f64,
    },
    /// A staircase: `values[k]` during the k-th interval of `every` seconds.
    Steps {
        /// The levels.
        values: Vec<f64>,
        /// Interval [s].
        every: f64,
    },
    /// `mean + amplitude·sin(φ(τ))` with the frequency swept linearly from f0 to f1.
    Chirp {
        /// Mean.
        mean: f64,
        /// Amplitude.
        amplitude: f64,
        /// Start frequency [Hz].
        f0: f64,
        /// End frequency [Hz].
        f1: f64,
    },
    /// A recorded profile, linearly interpolated (loaded from `file` when the scenario is read,
    /// or given as `t` and `v` with no file).
    Recorded {
        /// CSV file with columns `t` and `value`.
        #[serde(default)]
        file: String,
        /// Times [s] from the segment's start.
        #[serde(default)]
        t: Vec<f64>,
        /// Values.
        #[serde(default)]
        v: Vec<f64>,
    },
}

/// A segment of a profile.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
pub struct Segment {
    /// Start [s].
    pub t0: f64,
    /// End [s].
    pub t1: f64,
    /// What it does.
    #[serde(flatten)]
    pub shape: Shape,
}

impl Segment {
    fn value(&self, t: f64) -> f64 {
        let tau = (t - self.t0).clamp(0.0, (self.t1 - self.t0).max(0.0));
        let len = (self.t1 - self.t0).max(f64::MIN_POSITIVE);
        match &self.shape {
            Shape::Constant { value } => *value,
            Shape::Ramp { v0, v1 } => v0 + (v1 - v0) * tau / len,
            Shape::Sine {
                mean,
                amplitude,
                frequency,
                phase,
            } => mean + amplitude * (2.0 * PI * frequency * tau + phase.to_radians()).sin(),
            Shape::Steps { values, every } => {
                let k = ((tau / every.max(f64::MIN_POSITIVE)) as usize)
                    .min(values.len().saturating_sub(1));
                values.get(k).copied().unwrap_or(0.0)
            }
            Shape::Chirp {
                mean,
                amplitude,
                f0,
                f1,
            } => {
                let k = (f1 - f0) / len;
                mean + amplitude * (2.0 * PI * (f0 * tau + 0.5 * k * tau * tau)).sin()
            }
            Shape::Recorded { t: ts, v, .. } => {
                if ts.is_empty() {
                    return 0.0;
                }
                let j = ts.partition_point(|&x| x <= tau);
                if j == 0 {
                    v[0]
                } else if j >= ts.len() {
                    v[ts.len() - 1]
                } else {
                    let f = (tau - ts[j - 1]) / (ts[j] - ts[j - 1]);
                    v[j - 1] + f * (v[j] - v[j - 1])
                }
            }
        }
    }
}

/// A piecewise profile.
#[derive(Debug, Clone, PartialEq, Default, Deserialize, Serialize)]
#[serde(transparent)]
pub struct Profile {
    /// Segments in time order.
    pub segments: Vec<Segment>,
}

impl Profile {
    /// A single constant.
    pub fn constant(value: f64, duration: f64) -> Self {
        Self {
            segments: vec![Segment {
                t0: 0.0,
                t1: duration,
                shape: Shape::Constant { value },
            }],
        }
    }

    /// The profile made a constant `value` at all times, its storage kept (no allocation once
    /// it has held a segment: a co-simulation's input set at every step).
    pub fn hold(&mut self, value: f64) {
        self.segments.truncate(1);
        let constant = Segment {
            t0: 0.0,
            t1: f64::MAX,
            shape: Shape::Constant { value },
        };
        match self.segments.first_mut() {
            Some(s) => *s = constant,
            None => self.segments.push(constant),
        }
    }

    /// Append a segment from the current end.
    pub fn then(mut self, len: f64, shape: Shape) -> Self {
        let t0 = self.segments.last().map_or(0.0, |s| s.t1);
        self.segments.push(Segment {
            t0,
            t1: t0 + len,
            shape,
        });
        self
    }

    /// The same profile `dt` seconds later (its start moved from 0 to `dt`).
    pub fn shifted(&self, dt: f64) -> Self {
        Self {
            segments: self
                .segments
                .iter()
                .map(|s| Segment {
                    t0: s.t0 + dt,
                    t1: s.t1 + dt,
                    shape: s.shape.clone(),
                })
                .collect(),
        }
    }

    /// The value at time t (holding the nearest end outside the segments). The segments are in
    /// time order ([`Scenario::validate`] checks a scenario's): the one containing `t` is found
    /// by bisection, so that a staircase of many segments costs no more per step than one.
    pub fn value(&self, t: f64) -> f64 {
        let j = self.segments.partition_point(|s| s.t1 < t);
        match self.segments.get(j).filter(|s| t >= s.t0) {
            Some(s) => s.value(t),
            None => match self.segments.first() {
                Some(first) if t < first.t0 => first.value(first.t0),
                _ => self
                    .segments
                    .iter()
                    .filter(|s| s.t1 <= t)
                    .max_by(|a, b| a.t1.total_cmp(&b.t1))
                    .map_or(0.0, |s| s.value(s.t1)),
            },
        }
    }
}

/// A fault: a parameter moves to `value` at time `at`, over `ramp` seconds (0: a step).
#[derive(Debug, Clone, PartialEq)]
pub struct Fault {
    /// Parameter path.
    pub path: String,
    /// Target value.
    pub value: f64,
    /// Start [s].
    pub at: f64,
    /// Ramp duration [s].
    pub ramp: f64,
}

/// Paths a fault may change during a run (the others are fixed when the cell is built: use
/// `--set`).
pub const FAULT_PATHS: &[&str] = &[
    "shaft.k",
    "shaft.b",
    "engine.m_rec",
    "engine.friction_scale",
    "engine.t_oil",
    "dyno.speed_sensor.gain",
    "dyno.speed_sensor.offset",
    "dyno.speed_sensor.noise",
    "sensors.lost_pulses_en",
    "sensors.torque_shaft.gain",
    "sensors.torque_shaft.offset",
    "sensors.torque_shaft.noise",
    "sensors.torque_engine.offset",
    "sensors.p_cyl.offset",
    "sensors.p_cyl.gain",
];

impl Fault {
    /// Parse `PATH=VALUE@T[+RAMP]`.
    pub fn parse(spec: &str) -> Result<Self, SimError> {
        let bad = || {
            format!("fault '{spec}': expected PATH=VALUE@T[+RAMP], e.g. shaft.k=1200@5 or shaft.b=1.2@5+2")
        };
        let (path, rest) = spec.split_once('=').ok_or_else(bad)?;
        let (value, when) = rest.split_once('@').ok_or_else(bad)?;
        let (at, ramp) = match when.split_once('+') {
            Some((a, r)) => (a, r),
            None => (when, "0"),
        };
        let num = |s: &str| s.trim().parse::<f64>().ok().filter(|v| v.is_finite());
        let (value, at, ramp) = match (num(value), num(at), num(ramp)) {
            (Some(v), Some(a), Some(r)) if a >= 0.0 && r >= 0.0 => (v, a, r),
            _ => return Err(SimError::Invalid(bad())),
        };
        let path = path.trim().to_string();
        if CellParams::default().get(&path).is_none() {
            CellParams::default().set(&path, 0.0)?;
        }
        if !FAULT_PATHS.contains(&path.as_str()) {
            return Err(SimError::Invalid(format!(
                "fault '{spec}': '{path}' cannot change during a run (set it with --set); faults act on {}",
                FAULT_PATHS.join(", ")
            )));
        }
        // The value within the parameter's range, as `--set` has it (the ranges of the paths
        // a fault moves are each the parameter's own, whatever the others are; a ramp stays
        // between two values within it).
        CellParams::default()
            .set_checked(&path, value)
            .map_err(|e| SimError::Invalid(format!("fault '{spec}': {e}")))?;
        Ok(Self {
            path,
            value,
            at,
            ramp,
        })
    }

    /// How far the fault has gone at time t: 0 before it, 1 once stepped or ramped.
    pub fn progress(&self, t: f64) -> f64 {
        if self.ramp > 0.0 {
            ((t - self.at) / self.ramp).clamp(0.0, 1.0)
        } else if t >= self.at {
            1.0
        } else {
            0.0
        }
    }

    /// Apply the faults to `params` at time t, from the values in `base`.
    pub fn apply_all(faults: &[Fault], base: &CellParams, params: &mut CellParams, t: f64) {
        for f in faults {
            let v0 = base.get(&f.path).unwrap_or(0.0);
            let x = f.progress(t);
            if x > 0.0 {
                let _ = params.set(&f.path, v0 + (f.value - v0) * x);
            }
        }
    }
}

/// A scenario.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Name.
    pub name: String,
    /// What it is for.
    #[serde(default)]
    pub description: String,
    /// Recorded duration [s].
    pub duration: f64,
    /// Simulated before recording [s].
    #[serde(default = "default_settle")]
    pub settle: f64,
    /// Speed demand [rpm] (torque demand [N·m] in torque mode).
    pub speed: Profile,
    /// Throttle opening [deg].
    pub throttle: Profile,
    /// The drive in torque mode.
    #[serde(default)]
    pub torque_mode: bool,
    /// Torque mode: the engine's speed range [rpm] — the run starts at its middle and stops
    /// with an error once the engine leaves it (a cell's speed trips; the torque demand alone
    /// does not hold a speed). `None`: it starts at 1000 rpm, unguarded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed_range: Option<[f64; 2]>,
    /// Parameter settings.
    #[serde(default)]
    pub set: std::collections::BTreeMap<String, f64>,
    /// Faults (`PATH=VALUE@T[+RAMP]`).
    #[serde(default)]
    pub faults: Vec<String>,
}

fn default_settle() -> f64 {
    1.0
}

/// Names and one-line descriptions of the built-in scenarios.
pub const NAMED: &[(&str, &str)] = &[
    ("fig314", "model demo (Fig. 3.14): speed sinusoid for 10 s then constant, throttle tip-in/tip-out at 13–18 s; 20 s"),
    ("shaft-steady", "T01 shaft monitoring: 1000 rpm, wide-open throttle; 30 s"),
    ("shaft-ramp", "T02 shaft monitoring: 750 → 1500 rpm ramp, wide-open throttle; 30 s"),
    ("friction-sweep", "friction tests 1–4: 750/1000/1250/1500 rpm, manifold pressure swept from ambient to ≈ 70 kPa; the engine's friction 0.45 of the nominal model; 4 × 40 s"),
    ("torque-steady", "T1 cyclic torque: 1000 rpm, wide-open throttle; 10 s"),
    ("torque-ramp", "T2 cyclic torque: 800 → 1400 rpm in 5 s, wide-open throttle"),
    ("torque-validation", "T3 cyclic torque: four ramps 800 ↔ 1400 rpm, 2 min"),
    ("transient-10min", "the 10-minute mixed test (Fig. 4.6): speed and throttle steps and ramps"),
    ("fired-steady", "beyond the thesis: the engine fired (a Wiebe burn of 250 J per cycle from 15° before TDC over 50°), 1500 rpm, wide-open throttle; 10 s"),
];

/// Throttle [deg] that gives ≈ 70 kPa in the manifold at each friction-sweep speed (found by
/// simulating this engine; see `tests/scenarios.rs`).
const SWEEP_THROTTLE_END: [(f64, f64); 4] = [
    (750.0, 1.28),
    (1000.0, 2.16),
    (1250.0, 2.94),
    (1500.0, 3.68),
];

/// A built-in scenario by name.
pub fn named(name: &str) -> Option<Scenario> {
    let wot = 90.0;
    let base = |name: &str, duration: f64, speed: Profile, throttle: Profile| Scenario {
        name: name.into(),
        description: NAMED
            .iter()
            .find(|n| n.0 == name)
            .map_or(String::new(), |n| n.1.to_string()),
        duration,
        settle: 1.0,
        speed,
        throttle,
        torque_mode: false,
        speed_range: None,
        set: Default::default(),
        faults: Vec::new(),
    };
    let c = |v: f64| Shape::Constant { value: v };
    let ramp = |v0: f64, v1: f64| Shape::Ramp { v0, v1 };
    Some(match name {
        "fig314" => base(
            name,
            20.0,
            Profile::default()
                .then(
                    10.0,
                    Shape::Sine {
                        mean: 1000.0,
                        amplitude: 300.0,
                        frequency: 0.5,
                        phase: 0.0,
                    },
                )
                .then(10.0, c(1000.0)),
            Profile::default()
                .then(13.0, c(15.0))
                .then(5.0, c(wot))
                .then(2.0, c(15.0)),
        ),
        "shaft-steady" => base(
            name,
            30.0,
            Profile::constant(1000.0, 30.0),
            Profile::constant(wot, 30.0),
        ),
        "shaft-ramp" => base(
            name,
            30.0,
            Profile::default().then(30.0, ramp(750.0, 1500.0)),
            Profile::constant(wot, 30.0),
        ),
        "friction-sweep" => {
            let mut speed = Profile::default();
            let mut thr = Profile::default();
            for (n, end) in SWEEP_THROTTLE_END {
                speed = speed.then(40.0, c(n));
                thr = thr.then(5.0, c(wot)).then(35.0, ramp(15.0, end));
            }
            let mut s = base(name, 160.0, speed, thr);
            s.set.insert("engine.friction_scale".into(), 0.45);
            s
        }
        "torque-steady" => base(
            name,
            10.0,
            Profile::constant(1000.0, 10.0),
            Profile::constant(wot, 10.0),
        ),
        "torque-ramp" => base(
            name,
            5.0,
            Profile::default().then(5.0, ramp(800.0, 1400.0)),
            Profile::constant(wot, 5.0),
        ),
        "torque-validation" => {
            let mut speed = Profile::default();
            for _ in 0..4 {
                speed = speed
                    .then(15.0, ramp(800.0, 1400.0))
                    .then(15.0, ramp(1400.0, 800.0));
            }
            base(name, 120.0, speed, Profile::constant(wot, 120.0))
        }
        "transient-10min" => {
            let levels = [1000.0, 1250.0, 800.0, 1500.0, 1100.0, 900.0, 1400.0, 1000.0];
            let throttles = [90.0, 20.0, 60.0, 10.0, 45.0, 90.0, 15.0, 30.0];
            let mut speed = Profile::default();
            let mut thr = Profile::default();
            let mut prev = 1000.0;
            for (k, (&n, &th)) in levels.iter().zip(&throttles).enumerate() {
                speed = speed.then(15.0, ramp(prev, n)).then(60.0, c(n));
                thr = thr.then(
                    15.0 + 60.0,
                    if k % 2 == 0 {
                        c(th)
                    } else {
                        ramp(th, th * 0.5 + 10.0)
                    },
                );
                prev = n;
            }
            base(name, 600.0, speed, thr)
        }
        "fired-steady" => {
            let mut s = base(
                name,
                10.0,
                Profile::constant(1500.0, 10.0),
                Profile::constant(wot, 10.0),
            );
            s.set.insert("engine.burn_q".into(), 250.0);
            s
        }
        _ => return None,
    })
}

impl Scenario {
    /// A named scenario or a TOML file.
    pub fn load(name_or_file: &str) -> Result<Self, SimError> {
        if let Some(s) = named(name_or_file) {
            return Ok(s);
        }
        let path = Path::new(name_or_file);
        if !path.exists() {
            let names: Vec<&str> = NAMED.iter().map(|n| n.0).collect();
            return Err(SimError::Invalid(format!(
                "'{name_or_file}' is neither a built-in scenario ({}) nor a file",
                names.join(", ")
            )));
        }
        let text = std::fs::read_to_string(path).map_err(|e| format!("{name_or_file}: {e}"))?;
        let mut s: Scenario = toml::from_str(&text).map_err(|e| format!("{name_or_file}: {e}"))?;
        let dir = path.parent().unwrap_or(Path::new("."));
        for p in [&mut s.speed, &mut s.throttle] {
            for seg in &mut p.segments {
                if let Shape::Recorded { file, t, v } = &mut seg.shape {
                    if file.is_empty() {
                        continue; // the points given in the file itself
                    }
                    let (tt, vv) = load_profile(&dir.join(file.as_str()))
                        .map_err(|e| format!("{name_or_file}: recorded profile {file}: {e}"))?;
                    *t = tt;
                    *v = vv;
                }
            }
        }
        s.validate().map_err(|e| format!("{name_or_file}: {e}"))?;
        Ok(s)
    }

    /// The engine's speed a torque-demand run starts (and settles) from [rpm]: the middle of
    /// [`speed_range`](Self::speed_range), else 1000 rpm.
    pub fn torque_start_rpm(&self) -> f64 {
        self.speed_range.map_or(1000.0, |[lo, hi]| 0.5 * (lo + hi))
    }

    /// The scenario as a file [`load`](Self::load) reads back to the same scenario.
    pub fn to_toml(&self) -> Result<String, SimError> {
        toml::to_string(self).map_err(|e| SimError::Invalid(format!("scenario {}: {e}", self.name)))
    }

    /// Check durations, segments and the settings' paths.
    pub fn validate(&self) -> Result<(), SimError> {
        if !(self.duration.is_finite() && self.duration > 0.0) {
            return Err(SimError::Invalid(format!(
                "duration {}: expected > 0 s",
                physid_core::Num(self.duration)
            )));
        }
        if !(self.settle.is_finite() && self.settle >= 0.0) {
            return Err(SimError::Invalid(format!(
                "settle {}: expected ≥ 0 s",
                physid_core::Num(self.settle)
            )));
        }
        for (what, p) in [("speed", &self.speed), ("throttle", &self.throttle)] {
            if p.segments.is_empty() {
                return Err(SimError::Invalid(format!(
                    "the {what} profile has no segments"
                )));
            }
            for (s, next) in p.segments.iter().zip(&p.segments[1..]) {
                if next.t0 < s.t1 {
                    return Err(SimError::Invalid(format!(
                        "{what} segment {}–{} s starts before the previous one ({}–{} s) ends: expected the segments in time order, not overlapping",
                        next.t0, next.t1, s.t0, s.t1
                    )));
                }
            }
            for s in &p.segments {
                if let Shape::Recorded { t, v, .. } = &s.shape {
                    if t.is_empty() || t.len() != v.len() {
                        return Err(SimError::Invalid(format!(
                            "{what} segment {}–{} s: a recorded profile needs its points (a `file`, or `t` and `v` of the same length)",
                            s.t0, s.t1
                        )));
                    }
                }
                if s.t1 < s.t0 || s.t1.is_nan() || s.t0.is_nan() {
                    return Err(SimError::Invalid(format!(
                        "{what} segment {}–{} s ends before it starts",
                        s.t0, s.t1
                    )));
                }
            }
        }
        if let Some([lo, hi]) = self.speed_range {
            if !(lo.is_finite() && hi.is_finite() && 0.0 < lo && lo < hi) {
                return Err(SimError::Invalid(format!(
                    "speed_range [{lo}, {hi}] rpm: expected 0 < low < high"
                )));
            }
        }
        let mut p = CellParams::default();
        for (k, v) in &self.set {
            p.set(k, *v)?;
        }
        for f in &self.faults {
            Fault::parse(f)?;
        }
        Ok(())
    }
}

/// Read a two-column CSV profile (`t,value` header).
fn load_profile(path: &Path) -> Result<(Vec<f64>, Vec<f64>), String> {
    let mut rdr = csv::Reader::from_path(path).map_err(|e| e.to_string())?;
    let headers = rdr.headers().map_err(|e| e.to_string())?.clone();
    let col = |n: &str| headers.iter().position(|h| h.trim() == n);
    let (it, iv) = match (col("t"), col("value")) {
        (Some(a), Some(b)) => (a, b),
        _ => return Err("expected columns 't' and 'value'".into()),
    };
    let (mut t, mut v) = (Vec::new(), Vec::new());
    for (k, rec) in rdr.records().enumerate() {
        let rec = rec.map_err(|e| e.to_string())?;
        let num = |i: usize| -> Result<f64, String> {
            rec.get(i)
                .and_then(|s| s.trim().parse().ok())
                .ok_or_else(|| format!("line {}: not a number", k + 2))
        };
        let tt = num(it)?;
        if t.last().is_some_and(|&last| tt <= last) {
            return Err(format!("line {}: time does not increase", k + 2));
        }
        t.push(tt);
        v.push(num(iv)?);
    }
    if t.is_empty() {
        return Err("no rows".into());
    }
    Ok((t, v))
}
