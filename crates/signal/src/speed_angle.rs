//! Whether a speed channel is the derivative of its angle (issue 41, item 6): a units row that
//! lies — rpm labelled rad/s, rad/s labelled deg/s — passes every other check and gives
//! confident wrong answers (B = 0.0994 ± 7e-5 for a true 0.95). When a recording has an angle
//! and its speed (`theta_en`/`omega_en`, `theta_dy`/`omega_dy`, in SI after reading), the angle
//! travelled, `Δθ = Σ dθ`, is set against the speed integrated over the same steps,
//! `∫ω dt = Σ ½(ω_k + ω_{k−1})·Δt` (trapezoidal rule): their ratio is 1 to the sensors'
//! accuracy, and a factor of 2π/60, 180/π, 2π, 6 or 60 either way names the likely mislabel.
//!
//! A step whose angle jumps by more than π is an angle that wraps (at 2π or 4π): it counts as
//! the step less the nearest multiple of 2π, or is left out of both sums when no multiple
//! brings it within π. A step whose speed changes by more than half the sum of its two
//! samples' sizes (a factor of 3 between them: a glitch — a spike, a dropout to 0 — where a
//! mislabelled unit scales every sample alike) is left out of both sums too. The check decides only after two revolutions' worth of `Δθ` or
//! `∫ω dt` over at least [`MIN_STEPS`] steps. Allocation-free per chunk.

use physid_core::{Basis, Recording};
use std::f64::consts::{PI, TAU};

/// The angle–speed pairs checked.
pub const PAIRS: [(&str, &str); 2] = [("theta_en", "omega_en"), ("theta_dy", "omega_dy")];

/// Steps needed before the check decides.
pub const MIN_STEPS: usize = 100;

/// `Δθ / ∫ω dt` within this factor of 1 (either way): consistent.
pub const AGREE: f64 = 1.05;

/// Within this factor of a known one: that mislabel is named.
const NEAR: f64 = 1.03;

/// `Δθ / ∫ω dt` for each mislabel, and what it is (`{speed}`, `{angle}` stand for the names).
const FACTORS: [(f64, &str); 10] = [
    (TAU / 60.0, "'{speed}' looks like rpm labelled rad/s"),
    (60.0 / TAU, "'{speed}' looks like rad/s labelled rpm"),
    (
        PI / 180.0,
        "'{speed}' looks like deg/s labelled rad/s, or '{angle}' like radians labelled degrees",
    ),
    (
        180.0 / PI,
        "'{speed}' looks like rad/s labelled deg/s, or '{angle}' like degrees labelled rad",
    ),
    (TAU, "'{speed}' looks like revolutions per second labelled rad/s"),
    (
        1.0 / TAU,
        "'{speed}' looks like rad/s labelled revolutions per second, or '{angle}' like revolutions labelled rad",
    ),
    (6.0, "'{speed}' looks like rpm labelled deg/s"),
    (1.0 / 6.0, "'{speed}' looks like deg/s labelled rpm"),
    (60.0, "'{speed}' looks like revolutions per second labelled rpm"),
    (1.0 / 60.0, "'{speed}' looks like rpm labelled revolutions per second"),
];

/// One angle and its speed, checked as the chunks pass.
#[derive(Debug, Clone)]
pub struct SpeedAngle {
    angle: String,
    /// Radians per unit of the angle channel: 1, or 2π/N for an encoder's count of N pulses
    /// per revolution.
    gain: f64,
    /// What the angle channel is, for a person ("" for an angle, " (N pulses per revolution)").
    what: String,
    speed: String,
    /// The previous sample's (t, θ, ω).
    prev: Option<(f64, f64, f64)>,
    /// Σ dθ and Σ ½(ω_k + ω_{k−1})Δt over the steps counted.
    travelled: f64,
    integrated: f64,
    steps: usize,
}

impl SpeedAngle {
    fn new(angle: &str, gain: f64, what: String, speed: &str) -> Self {
        Self {
            angle: angle.into(),
            gain,
            what,
            speed: speed.into(),
            prev: None,
            travelled: 0.0,
            integrated: 0.0,
            steps: 0,
        }
    }

    /// The pairs of [`PAIRS`] a time-basis recording with `header`'s channels has, and each
    /// encoder count of `encoders` (channel, pulses per revolution) with its shaft's speed: the
    /// dynamometer's (`omega_dy`) for a count whose name ends in `_dy`, the engine's otherwise.
    pub fn pairs(header: &Recording, encoders: &[(String, u32)]) -> Vec<Self> {
        if header.basis != Basis::Time || header.channel("t").is_err() {
            return Vec::new();
        }
        let has = |n: &str| header.channel(n).is_ok();
        let angles = PAIRS
            .iter()
            .filter(|(a, s)| has(a) && has(s))
            .map(|(a, s)| Self::new(a, 1.0, String::new(), s));
        let counts = encoders
            .iter()
            .filter(|(c, ppr)| has(c) && *ppr > 0)
            .map(|(c, ppr)| {
                let speed = if c.ends_with("_dy") {
                    "omega_dy"
                } else {
                    "omega_en"
                };
                (c, *ppr, speed)
            })
            .filter(|(_, _, s)| has(s))
            .map(|(c, ppr, s)| {
                Self::new(
                    c,
                    TAU / f64::from(ppr),
                    format!(" ({ppr} pulses per revolution)"),
                    s,
                )
            });
        angles.chain(counts).collect()
    }

    /// Take a chunk of the recording (it must have `t` and the pair; otherwise it is passed).
    pub fn push(&mut self, chunk: &Recording) {
        let (Ok(t), Ok(th), Ok(w)) = (
            chunk.values("t"),
            chunk.values(&self.angle),
            chunk.values(&self.speed),
        ) else {
            return;
        };
        for ((&t, &th), &w) in t.iter().zip(th).zip(w) {
            let th = th * self.gain;
            if !(t.is_finite() && th.is_finite() && w.is_finite()) {
                self.prev = None;
                continue;
            }
            if let Some((t0, th0, w0)) = self.prev {
                let dt = t - t0;
                let mut d = th - th0;
                if d.abs() > PI {
                    d -= TAU * (d / TAU).round();
                }
                let glitch = (w - w0).abs() > 0.5 * (w.abs() + w0.abs());
                if dt > 0.0 && d.abs() <= PI && !glitch {
                    self.travelled += d;
                    self.integrated += 0.5 * (w + w0) * dt;
                    self.steps += 1;
                }
            }
            self.prev = Some((t, th, w));
        }
    }

    /// `Δθ / ∫ω dt` so far, once the check can decide (`None` before).
    pub fn ratio(&self) -> Option<f64> {
        (self.steps >= MIN_STEPS && self.integrated.abs().max(self.travelled.abs()) >= 2.0 * TAU)
            .then(|| self.travelled / self.integrated)
    }

    /// What is wrong, for a person (`None` when the pair agrees or the check cannot decide).
    pub fn finding(&self) -> Option<String> {
        let r = self.ratio()?;
        if r > 0.0 && r.max(1.0 / r) <= AGREE {
            return None;
        }
        let head = format!(
            "'{}'{} and '{}' disagree: the angle travelled {:.6e} rad while the speed integrates to {:.6e} rad over the same {} steps (a factor {r:.4})",
            self.angle, self.what, self.speed, self.travelled, self.integrated, self.steps
        );
        let named = FACTORS
            .iter()
            .find(|(f, _)| r > 0.0 && (r / f).max(f / r) <= NEAR)
            .map(|(_, why)| {
                why.replace("{speed}", &self.speed)
                    .replace("{angle}", &self.angle)
            });
        // An encoder's count: the pulses per revolution its travel implies.
        let pulses = (TAU / self.gain * r).round();
        if self.gain != 1.0 && named.is_none() && r > 0.0 {
            return Some(format!(
                "{head}: the count goes {pulses:.0} pulses per revolution of '{}' — check the encoder's pulses per revolution (--encoder NAME=N) or the speed's unit",
                self.speed
            ));
        }
        Some(match named {
            Some(why) => format!(
                "{head}: {why} — correct the unit (--map NAME=COLUMN:UNIT) and read the file again"
            ),
            None if r < 0.0 => format!(
                "{head}: they turn opposite ways — a sign convention differs (negate one with --scale NAME=-1,0)"
            ),
            None => format!("{head}: check the units and the calibration of both"),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use physid_core::Channel;

    /// An engine turning at 150 + 20·sin(3t) rad/s for 2 s at 10 kHz, the angle wrapped at
    /// 4π (a cycle), the speed's numbers multiplied by `factor`.
    fn run(factor: f64) -> Recording {
        let n = 20_001;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-4).collect();
        let theta: Vec<f64> = t
            .iter()
            .map(|&t| (150.0 * t + 20.0 / 3.0 * (1.0 - (3.0 * t).cos())).rem_euclid(2.0 * TAU))
            .collect();
        let omega: Vec<f64> = t
            .iter()
            .map(|&t| factor * (150.0 + 20.0 * (3.0 * t).sin()))
            .collect();
        let mut r = Recording::new(Basis::Time);
        for (name, unit, values) in [
            ("t", "s", t),
            ("theta_en", "rad", theta),
            ("omega_en", "rad/s", omega),
        ] {
            r.push(Channel {
                name: name.into(),
                unit: unit.into(),
                values,
            })
            .unwrap_or_else(|e| panic!("{e}"));
        }
        r
    }

    fn check(rec: &Recording) -> Option<String> {
        let mut pairs = SpeedAngle::pairs(rec, &[]);
        assert_eq!(pairs.len(), 1);
        // In chunks of 777 rows, as a file is read.
        let mut at = 0;
        while at < rec.len() {
            let end = (at + 777).min(rec.len());
            pairs[0].push(&rec.slice(at..end));
            at = end;
        }
        pairs[0].finding()
    }

    #[test]
    fn a_speed_that_is_its_angles_derivative_passes() {
        let r = run(1.0);
        assert_eq!(check(&r), None);
        let mut p = SpeedAngle::pairs(&r, &[]);
        p[0].push(&r);
        assert!((p[0].ratio().unwrap_or(0.0) - 1.0).abs() < 1e-6);
    }

    /// An encoder's count (360 pulses per revolution, floor of the angle) against the speed:
    /// right with its pulses per revolution, a factor 2 off when told 720.
    #[test]
    fn an_encoder_count_is_checked_at_its_pulses_per_revolution() {
        let mut r = run(1.0);
        let count: Vec<f64> = r
            .values("t")
            .unwrap_or_default()
            .iter()
            .map(|&t| (360.0 * (150.0 * t + 20.0 / 3.0 * (1.0 - (3.0 * t).cos())) / TAU).floor())
            .collect();
        r.push(Channel {
            name: "count_en".into(),
            unit: String::new(),
            values: count,
        })
        .unwrap_or_else(|e| panic!("{e}"));
        for (ppr, ok) in [(360, true), (720, false)] {
            let mut p = SpeedAngle::pairs(&r, &[("count_en".into(), ppr)]);
            assert_eq!(p.len(), 2);
            p[1].push(&r);
            let f = p[1].finding();
            assert_eq!(f.is_none(), ok, "{ppr}: {f:?}");
            if let Some(f) = f {
                assert!(
                    f.contains("'count_en' (720 pulses per revolution)")
                        && f.contains("the count goes 360 pulses per revolution"),
                    "{f}"
                );
            }
        }
    }

    /// A speed sensor's spike of 10⁹ rad/s and its dropout to 0, one sample each, are left
    /// out: the pair still agrees (the spike alone made it a factor 0.006, "check the units").
    #[test]
    fn a_speed_glitch_is_no_mislabel() {
        let mut r = run(1.0);
        let mut w = r.values("omega_en").unwrap_or_default().to_vec();
        w[5000] = 1e9;
        w[9000] = 0.0;
        r.replace_values("omega_en", w)
            .unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(check(&r), None);
    }

    #[test]
    fn each_mislabel_is_named() {
        for (factor, want) in [
            (60.0 / TAU, "looks like rpm labelled rad/s"),
            (PI / 180.0, "looks like rad/s labelled deg/s"),
            (180.0 / PI, "looks like deg/s labelled rad/s"),
            (
                1.0 / TAU,
                "looks like revolutions per second labelled rad/s",
            ),
            (-1.0, "turn opposite ways"),
            (1.5, "check the units and the calibration"),
        ] {
            let f = check(&run(factor)).unwrap_or_default();
            assert!(f.contains(want), "× {factor}: {f}");
        }
    }

    #[test]
    fn too_little_motion_decides_nothing() {
        let r = run(60.0 / TAU).slice(0..50);
        assert_eq!(check(&r), None);
    }
}
