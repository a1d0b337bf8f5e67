//! The profiles a design chooses among: families of speed-demand — or, with torque limits,
//! the dynamometer's torque-demand — and throttle profiles within the cell's limits (ranges,
//! the demand's rate, the test's duration), drawn at random from a seed, each a [`Scenario`]
//! the cell runs (`physid simulate --scenario FILE`).

use physid_sim::scenario::{Profile, Scenario, Segment, Shape};
use rand::Rng;
use serde::Serialize;
use std::f64::consts::PI;

/// The cell's limits a designed test keeps to.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Limits {
    /// Speed demand range [rpm].
    pub speed: (f64, f64),
    /// Throttle range [deg above closed].
    pub throttle: (f64, f64),
    /// The speed demand's largest rate [rpm/s].
    pub dspeed: f64,
    /// The dynamometer's torque-demand range [N·m]: given, the candidates drive the cell in
    /// torque mode, the speed range then the one the engine must stay in.
    pub torque: Option<(f64, f64)>,
    /// The torque demand's largest rate [N·m/s].
    pub dtorque: f64,
}

impl Default for Limits {
    /// 800–3000 rpm, throttle 0–90°, 500 rpm/s; speed demand (no torque range), 50 N·m/s.
    fn default() -> Self {
        Self {
            speed: (800.0, 3000.0),
            throttle: (0.0, 90.0),
            dspeed: 500.0,
            torque: None,
            dtorque: 50.0,
        }
    }
}

impl Limits {
    /// Parse `speed=LO:HI,throttle=LO:HI,dspeed=RATE,torque=LO:HI,dtorque=RATE` (any of them;
    /// the rest default; a torque range makes the candidates torque demands).
    pub fn parse(s: &str) -> Result<Self, String> {
        let mut l = Self::default();
        for item in s.split(',').map(str::trim).filter(|x| !x.is_empty()) {
            let (k, v) = item.split_once('=').ok_or_else(|| {
                format!("limit '{item}': expected NAME=VALUE, e.g. speed=800:3000")
            })?;
            let num = |x: &str| {
                x.trim()
                    .parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| format!("limit '{item}': '{x}' is not a number"))
            };
            let range = |v: &str| -> Result<(f64, f64), String> {
                let (a, b) = v
                    .split_once(':')
                    .ok_or_else(|| format!("limit '{item}': expected LO:HI"))?;
                let (a, b) = (num(a)?, num(b)?);
                if a > b {
                    return Err(format!("limit '{item}': {a} > {b}"));
                }
                Ok((a, b))
            };
            match k.trim() {
                "speed" => l.speed = range(v)?,
                "throttle" => l.throttle = range(v)?,
                "dspeed" => l.dspeed = num(v)?,
                "torque" => l.torque = Some(range(v)?),
                "dtorque" => l.dtorque = num(v)?,
                other => {
                    return Err(format!(
                        "limit '{other}': expected speed (rpm), throttle (deg), dspeed (rpm/s), torque (N·m) or dtorque (N·m/s)"
                    ))
                }
            }
        }
        l.check()?;
        Ok(l)
    }

    /// Refuse limits the cell cannot keep.
    pub fn check(&self) -> Result<(), String> {
        if self.speed.0.is_nan() || self.speed.0 < 300.0 {
            return Err(format!(
                "speed limit {} rpm: expected ≥ 300 rpm (the monitors hold below it)",
                physid_core::Num(self.speed.0)
            ));
        }
        if self.speed.1 > 9000.0 {
            return Err(format!(
                "speed limit {} rpm: expected ≤ 9000 rpm (the thesis's engine's range)",
                physid_core::Num(self.speed.1)
            ));
        }
        if !(self.throttle.0 >= 0.0 && self.throttle.1 <= 90.0) {
            return Err(format!(
                "throttle limits {}:{}°: expected within 0–90°",
                physid_core::Num(self.throttle.0),
                physid_core::Num(self.throttle.1)
            ));
        }
        if self.dspeed.is_nan() || self.dspeed <= 0.0 {
            return Err(format!(
                "dspeed {}: expected > 0 rpm/s",
                physid_core::Num(self.dspeed)
            ));
        }
        if self.dtorque.is_nan() || self.dtorque <= 0.0 {
            return Err(format!(
                "dtorque {}: expected > 0 N·m/s",
                physid_core::Num(self.dtorque)
            ));
        }
        if self.torque.is_some() && self.speed.0 >= self.speed.1 {
            return Err(format!(
                "speed limits {}:{} rpm with a torque demand: the engine's speed range must be wider than a point",
                physid_core::Num(self.speed.0),
                physid_core::Num(self.speed.1)
            ));
        }
        Ok(())
    }

    /// The demand the candidates draw: its range and largest rate (speed [rpm], or torque
    /// [N·m] with a torque range).
    pub fn demand(&self) -> ((f64, f64), f64) {
        match self.torque {
            Some(t) => (t, self.dtorque),
            None => (self.speed, self.dspeed),
        }
    }

    /// Whether a scenario keeps to the limits (its profiles sampled every 10 ms, the rate
    /// over each 10 ms with 1 % allowance). A speed demand keeps to the speed's; a torque
    /// demand to the torque's, its speed range within the speed's (the run keeps the engine
    /// in that range or stops).
    pub fn admit(&self, s: &Scenario) -> bool {
        let ((lo, hi), rate) = if s.torque_mode {
            let (Some(t), Some([a, b])) = (self.torque, s.speed_range) else {
                return false;
            };
            if a < self.speed.0 || b > self.speed.1 {
                return false;
            }
            (t, self.dtorque)
        } else {
            (self.speed, self.dspeed)
        };
        let n = (s.duration / 0.01).ceil() as usize;
        let mut last = s.speed.value(0.0);
        let tol = 1e-9 * lo.abs().max(hi.abs()).max(1.0);
        for k in 0..=n {
            let t = k as f64 * 0.01;
            let (v, th) = (s.speed.value(t), s.throttle.value(t));
            if v < lo - tol || v > hi + tol {
                return false;
            }
            if th < self.throttle.0 - 1e-9 || th > self.throttle.1 + 1e-9 {
                return false;
            }
            if k > 0 && (v - last).abs() > rate * 0.01 * 1.01 + tol {
                return false;
            }
            last = v;
        }
        true
    }
}

/// A family of profiles.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Family {
    /// One operating point held.
    Constant,
    /// A staircase of 2–8 speed levels, the steps at the rate limit.
    Steps,
    /// Ramps up and down between two speeds.
    Ramps,
    /// An amplitude-modulated pseudo-random sequence: levels held 0.2–2 s.
    Aprbs,
    /// A sum of sines of the demand in a band, at the rate limit.
    Multisine,
}

/// Every family.
pub const FAMILIES: [Family; 5] = [
    Family::Constant,
    Family::Steps,
    Family::Ramps,
    Family::Aprbs,
    Family::Multisine,
];

impl Family {
    /// Its name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Constant => "constant",
            Self::Steps => "steps",
            Self::Ramps => "ramps",
            Self::Aprbs => "aprbs",
            Self::Multisine => "multisine",
        }
    }
}

/// Levels held for the given times, each change a ramp at `rate` [/s]: the segments from 0 to
/// `duration` (a level whose ramp does not fit is cut short).
fn held_levels(levels: &[(f64, f64)], rate: f64, duration: f64) -> Profile {
    let mut p = Profile::default();
    let mut t = 0.0;
    let mut last: Option<f64> = None;
    for &(v, hold) in levels {
        if t >= duration {
            break;
        }
        if let Some(prev) = last {
            let ramp = (v - prev).abs() / rate;
            if ramp > 0.0 {
                let len = ramp.min(duration - t);
                let end = prev + (v - prev) * len / ramp;
                p = p.then(len, Shape::Ramp { v0: prev, v1: end });
                t += len;
                if len < ramp {
                    break;
                }
            }
        }
        let len = hold.min(duration - t);
        if len > 0.0 {
            p = p.then(len, Shape::Constant { value: v });
            t += len;
        }
        last = Some(v);
    }
    if p.segments.is_empty() {
        p = Profile::constant(levels.first().map_or(0.0, |l| l.0), duration);
    }
    p
}

/// How a candidate's throttle is drawn: what the application's parameters respond to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ThrottleDraw {
    /// Levels uniform over the range (the shaft: the gas torque's pulsation grows with the
    /// opening over the whole range).
    #[default]
    Linear,
    /// Levels uniform in the logarithm of the opening from [`PRESSURE_MIN_DEG`] (the manifold
    /// pressure moves at small openings and hardly above 15°: the friction's pumping terms),
    /// and slow ramps between two levels, as the thesis's friction sweeps.
    Pressure,
}

/// The smallest opening a [`ThrottleDraw::Pressure`] draw takes [deg]: below it the motored
/// engine's manifold empties towards a vacuum the friction tests do not run at.
pub const PRESSURE_MIN_DEG: f64 = 1.0;

/// A throttle held at its upper limit (a third of the draws: the largest pulsation, often the
/// most informative), held at a level drawn in the range (a third), or a staircase of 2–4
/// levels; with [`ThrottleDraw::Pressure`], levels drawn in the logarithm and a quarter of the
/// draws slow ramps between two levels.
fn throttle<R: Rng>(rng: &mut R, l: &Limits, duration: f64, how: ThrottleDraw) -> Profile {
    let (lo, hi) = l.throttle;
    let draw = |rng: &mut R| match how {
        ThrottleDraw::Linear if hi > lo => rng.random_range(lo..=hi),
        ThrottleDraw::Pressure => {
            let a = lo.max(PRESSURE_MIN_DEG).min(hi);
            if hi > a {
                (rng.random_range(a.ln()..=hi.ln())).exp().clamp(lo, hi)
            } else {
                hi
            }
        }
        _ => lo,
    };
    let options = match how {
        ThrottleDraw::Linear => 3,
        ThrottleDraw::Pressure => 4,
    };
    match rng.random_range(0..options) {
        0 => return Profile::constant(hi, duration),
        1 => return Profile::constant(draw(rng), duration),
        3 => {
            // 1–4 legs between two levels, back and forth.
            let (a, b) = (draw(rng), draw(rng));
            let legs = rng.random_range(1..=4);
            let leg = duration / legs as f64;
            let mut p = Profile::default();
            for k in 0..legs {
                let (v0, v1) = if k % 2 == 0 { (a, b) } else { (b, a) };
                p = p.then(leg, Shape::Ramp { v0, v1 });
            }
            return p;
        }
        _ => {}
    }
    let n = rng.random_range(2..=4);
    let values: Vec<f64> = (0..n).map(|_| draw(rng)).collect();
    Profile {
        segments: vec![Segment {
            t0: 0.0,
            t1: duration,
            shape: Shape::Steps {
                values,
                every: duration / n as f64,
            },
        }],
    }
}

/// The band a multisine's frequencies are drawn in by default [Hz].
pub const MULTISINE_BAND: (f64, f64) = (0.05, 2.0);

/// A candidate of `family` drawn within `l`, `duration` seconds long, named `name`; a
/// multisine's frequencies within `band` [Hz].
pub fn draw<R: Rng>(
    rng: &mut R,
    family: Family,
    l: &Limits,
    duration: f64,
    name: &str,
    how: ThrottleDraw,
    band: (f64, f64),
) -> Scenario {
    let ((lo, hi), rate_limit) = l.demand();
    let level = |rng: &mut R| {
        if hi > lo {
            rng.random_range(lo..=hi)
        } else {
            lo
        }
    };
    let speed = match family {
        Family::Constant => Profile::constant(level(rng), duration),
        Family::Steps => {
            let n = rng.random_range(2..=8);
            let hold = duration / n as f64;
            let levels: Vec<(f64, f64)> = (0..n).map(|_| (level(rng), hold)).collect();
            held_levels(&levels, rate_limit, duration)
        }
        Family::Ramps => {
            let (a, b) = (level(rng), level(rng));
            let rate = rng.random_range(0.2..=1.0) * rate_limit;
            let leg = ((a - b).abs() / rate).max(0.5);
            let mut p = Profile::default();
            let mut t = 0.0;
            let mut up = true;
            while t < duration {
                let len = leg.min(duration - t);
                let (v0, v1) = if up { (a, b) } else { (b, a) };
                p = p.then(
                    len,
                    Shape::Ramp {
                        v0,
                        v1: v0 + (v1 - v0) * len / leg,
                    },
                );
                t += len;
                up = !up;
            }
            p
        }
        Family::Aprbs => {
            let mut levels = Vec::new();
            let mut t = 0.0;
            while t < duration {
                let hold = rng.random_range(0.2..=2.0);
                levels.push((level(rng), hold));
                t += hold;
            }
            held_levels(&levels, rate_limit, duration)
        }
        Family::Multisine => multisine(rng, (lo, hi), rate_limit, duration, band),
    };
    let demand = match l.torque {
        Some(_) => format!(
            "torque-demand profile within {lo}–{hi} N·m, ≤ {rate_limit} N·m/s, the engine within {}–{} rpm",
            l.speed.0, l.speed.1
        ),
        None => format!("speed profile within {lo}–{hi} rpm, ≤ {rate_limit} rpm/s"),
    };
    Scenario {
        name: name.into(),
        description: format!(
            "designed by physid design: {} {demand}; throttle within {}–{}°",
            family.name(),
            l.throttle.0,
            l.throttle.1
        ),
        duration,
        settle: 1.0,
        speed,
        throttle: throttle(rng, l, duration, how),
        torque_mode: l.torque.is_some(),
        speed_range: l.torque.map(|_| [l.speed.0, l.speed.1]),
        set: Default::default(),
        faults: Vec::new(),
    }
}

/// `mean + Σ a·sin(2π·f_k·t + φ_k)`: 3–8 sines of random frequencies in `band` [Hz] and
/// random phases, scaled to the demand's range `(lo, hi)` and the rate limit `rate`; as points
/// every 20 ms (a band reaching 25 Hz, half their rate, is cut there).
fn multisine<R: Rng>(
    rng: &mut R,
    (lo, hi): (f64, f64),
    rate: f64,
    duration: f64,
    band: (f64, f64),
) -> Profile {
    let mean = 0.5 * (lo + hi);
    let n = rng.random_range(3..=8);
    let top = band.1.min(25.0);
    let bottom = band.0.min(top);
    let sines: Vec<(f64, f64)> = (0..n)
        .map(|_| {
            (
                rng.random_range(bottom..=top),
                rng.random_range(0.0..2.0 * PI),
            )
        })
        .collect();
    let dt = 0.02;
    let m = (duration / dt).ceil() as usize;
    let t: Vec<f64> = (0..=m).map(|k| (k as f64 * dt).min(duration)).collect();
    let raw: Vec<f64> = t
        .iter()
        .map(|&t| {
            sines
                .iter()
                .map(|&(f, ph)| (2.0 * PI * f * t + ph).sin())
                .sum()
        })
        .collect();
    let peak = raw.iter().fold(0.0f64, |a, v| a.max(v.abs())).max(1e-12);
    // The largest rate of the unit sum: Σ 2π·f_k bounds it.
    let max_rate: f64 = sines.iter().map(|&(f, _)| 2.0 * PI * f).sum();
    let amp = (0.5 * (hi - lo) / peak)
        .min(rate * 0.99 / max_rate.max(1e-12))
        .max(0.0);
    let v: Vec<f64> = raw.iter().map(|x| (mean + amp * x).clamp(lo, hi)).collect();
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

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// Every family's candidates keep to the limits, and round-trip through a scenario file.
    #[test]
    fn candidates_keep_to_the_limits() {
        let l = Limits::parse("speed=800:3000,throttle=0:60,dspeed=500").unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for fam in FAMILIES {
            for k in 0..40 {
                let how = [ThrottleDraw::Linear, ThrottleDraw::Pressure][k % 2];
                let s = draw(
                    &mut rng,
                    fam,
                    &l,
                    30.0,
                    &format!("c{k}"),
                    how,
                    MULTISINE_BAND,
                );
                assert!(l.admit(&s), "{fam:?} {k}: {s:?}");
                s.validate().unwrap();
                let text = toml::to_string(&s).unwrap();
                let back: Scenario = toml::from_str(&text).unwrap();
                assert_eq!(back, s);
            }
        }
        // With a torque range: torque demands within it, the engine's speed range the limits'.
        let lt = Limits::parse("speed=800:1600,torque=-2:3,dtorque=20").unwrap();
        for fam in FAMILIES {
            for k in 0..20 {
                let s = draw(
                    &mut rng,
                    fam,
                    &lt,
                    10.0,
                    &format!("t{k}"),
                    ThrottleDraw::Linear,
                    (0.1, 5.0),
                );
                assert!(
                    s.torque_mode && s.speed_range == Some([800.0, 1600.0]),
                    "{s:?}"
                );
                assert!(lt.admit(&s), "{fam:?} {k}: {s:?}");
                s.validate().unwrap();
                let back: Scenario = toml::from_str(&toml::to_string(&s).unwrap()).unwrap();
                assert_eq!(back, s);
                // Against speed limits only (no torque range) a torque demand is not admitted.
                assert!(!Limits::default().admit(&s));
            }
        }
        // A thesis test outside these limits is seen to be.
        let steady = physid_sim::scenario::named("shaft-steady").unwrap();
        assert!(!l.admit(&steady), "90° throttle is outside 0–60°");
        assert!(Limits::default().admit(&steady));
    }

    /// Bad limits are refused with what was expected.
    #[test]
    fn bad_limits_are_refused() {
        for (s, want) in [
            ("speed=3000:800", "3000 > 800"),
            ("speed=100:800", "≥ 300"),
            ("throttle=0:120", "0–90"),
            ("dspeed=0", "> 0"),
            ("force=1:2", "expected speed"),
            ("dtorque=0", "> 0 N·m/s"),
            ("speed=900:900,torque=0:2", "wider than a point"),
            ("speed", "NAME=VALUE"),
            ("speed=a:9", "not a number"),
        ] {
            let e = Limits::parse(s).unwrap_err();
            assert!(e.contains(want), "{s}: {e}");
        }
    }
}
