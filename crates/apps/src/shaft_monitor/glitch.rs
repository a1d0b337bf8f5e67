//! Steps no shaft makes: an angle sensor's glitch in the twist `Δθ = θ_dy − θ_en`, a speed
//! sensor's in the relative speed `Δω = ω_dy − ω_en` (Eq. 6.1's regressors), a torque
//! sensor's in `τ_sh`, taken out before the low-pass ([`StepGate`]), an angle sensor that
//! stopped while its shaft turns ([`StillAngle`]) and a speed sensor that froze while its shaft
//! moves ([`StuckSpeed`]) — the estimator held while they last, and
//! reported — one glitch used to pass through the estimator as a stiffness that
//! fell to nothing and raise a K alarm (a sample of `theta_dy` dropped to 0, a spike of 10⁹
//! rad, a revolution slipped by 2π, a torque of 10⁹ N·m).

use serde::{Deserialize, Serialize};

/// Between two samples the shaft's twist moves by `Δω·Δt`: at the monitor's rates (≥ 1 kHz)
/// hundredths of a radian even in a torsional resonance (0.05 rad of twist at 100 Hz moves
/// 0.03 rad per millisecond), and a coarse encoder's count is 0.017 rad (360 per revolution). A
/// step larger than this [rad] is an angle sensor's glitch — a sample dropped to 0, a spike, a
/// revolution slipped or counted twice, a counter re-indexed — not the shaft.
pub const MAX_TWIST_STEP: f64 = 0.5;

/// The longest a glitch holds the signal [s] before its step is taken as lasting.
pub const MAX_HOLD_S: f64 = 1.0;

/// Between two samples the relative speed moves by the relative acceleration times `Δt`: a
/// step of this much [rad/s] (955 rpm) in one sample would take 10⁵ rad/s² at 1 kHz — a speed
/// sensor's glitch, not the shaft.
pub const MAX_SLIP_STEP: f64 = 100.0;

/// A signal with the steps larger than its limit taken out. At such a step the signal is held
/// at its last sample, and the samples are marked held, until a raw sample comes back within
/// the limit of where the signal was before the step (a spike, a run of glitches: the samples
/// after it pass as they came) or for `max_hold` samples at most — then the step is taken as
/// lasting (a counter re-indexed, a revolution slipped) and the signal goes on from it less the
/// offset the step left (the step replaced by the last plausible one), which the estimator's
/// τ0 never sees. A signal without such a step passes bit for bit. What it cannot see — a
/// sensor that freezes at its last value: its steps stay small, the twist drifts at the
/// rotation's speed — [`StillAngle`] finds, and the twist's gate holds those samples too.
/// Allocation-free.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepGate {
    limit: f64,
    max_hold: usize,
    /// The last raw sample, the last sample out, the last plausible step.
    last_raw: Option<f64>,
    last: f64,
    step: f64,
    /// What is taken off the raw samples.
    offset: f64,
    /// Since a step was taken out, until the signal is back or the step is taken as lasting.
    episode: Option<Episode>,
    /// Steps taken out (those that began a hold), and the first: its sample (0 = the stream's
    /// first) and size.
    count: u64,
    first: Option<(usize, f64)>,
}

/// A step taken out and the signal held since.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
struct Episode {
    /// The offset before the step, and the last sample out before it.
    offset: f64,
    level: f64,
    /// The offset the step leaves should it last.
    lasting: f64,
    /// Samples held so far.
    held: usize,
}

impl StepGate {
    /// A gate taking out steps larger than `limit` (in the signal's unit), holding the signal
    /// for `max_hold` samples at most.
    pub fn new(limit: f64, max_hold: usize) -> Self {
        Self {
            limit,
            max_hold,
            last_raw: None,
            last: 0.0,
            step: 0.0,
            offset: 0.0,
            episode: None,
            count: 0,
            first: None,
        }
    }

    /// For the twist [rad]: [`MAX_TWIST_STEP`].
    pub fn twist(max_hold: usize) -> Self {
        Self::new(MAX_TWIST_STEP, max_hold)
    }

    /// For the relative speed [rad/s]: [`MAX_SLIP_STEP`].
    pub fn slip(max_hold: usize) -> Self {
        Self::new(MAX_SLIP_STEP, max_hold)
    }

    /// For the shaft torque [N·m]: what a shaft of stiffness `k` [N·m/rad] and damping `b`
    /// [N·m·s/rad] (the healthy ones) carries across the largest twist and slip steps,
    /// `|k|·MAX_TWIST_STEP + |b|·MAX_SLIP_STEP` (Eq. 6.1) — 720 N·m for Table 6.1's shaft.
    pub fn torque(k: f64, b: f64, max_hold: usize) -> Self {
        let limit = k.abs() * MAX_TWIST_STEP + b.abs() * MAX_SLIP_STEP;
        let limit = if limit.is_finite() && limit > 0.0 {
            limit
        } else {
            f64::MAX
        };
        Self::new(limit, max_hold)
    }

    /// The limit, rounded to 10⁻⁶ for a person.
    pub fn limit(&self) -> f64 {
        (self.limit * 1e6).round() / 1e6
    }

    /// Take the steps out of a chunk `x` (finite samples) in place, setting `held[i]` for
    /// each sample held (`held` as long as `x`); `at` is the sample number of the chunk's
    /// first. A sample `untrusted` (a check before found it wrong: an angle that stood still,
    /// [`StillAngle`]) is held at the last sample and its raw value not taken as the
    /// signal's. Returns the first step taken out in the chunk (its index in the chunk and its
    /// size) and how many were.
    pub fn apply(
        &mut self,
        x: &mut [f64],
        untrusted: Option<&[bool]>,
        held: &mut [bool],
        at: usize,
    ) -> Option<(usize, f64, u64)> {
        let before = self.count;
        let mut chunk_first = None;
        for (i, (v, h)) in x.iter_mut().zip(held).enumerate() {
            let raw = *v;
            if untrusted.is_some_and(|u| u[i]) && self.last_raw.is_some() {
                *h = true;
                *v = self.last;
                if let Some(e) = &mut self.episode {
                    e.held += 1;
                }
                continue;
            }
            let Some(prev) = self.last_raw.replace(raw) else {
                self.last = raw;
                continue;
            };
            let d = raw - prev;
            match &mut self.episode {
                // Back within the limit of where it was: the step's offset is dropped.
                Some(e) if (raw - e.offset - e.level).abs() <= self.limit => {
                    self.offset = e.offset;
                    self.episode = None;
                    *v = raw - self.offset;
                }
                // Held long enough: the step lasts.
                Some(e) if e.held >= self.max_hold => {
                    self.offset = e.lasting;
                    self.episode = None;
                    *v = raw - self.offset;
                }
                Some(e) => {
                    e.held += 1;
                    *v = self.last;
                    *h = true;
                }
                None if d.abs() > self.limit => {
                    self.count += 1;
                    self.first.get_or_insert((at + i, d));
                    chunk_first.get_or_insert((i, d));
                    self.episode = Some(Episode {
                        offset: self.offset,
                        level: self.last,
                        lasting: raw - (self.last + self.step),
                        held: 1,
                    });
                    *v = self.last;
                    *h = true;
                }
                None => {
                    self.step = d;
                    if self.offset != 0.0 {
                        *v = raw - self.offset;
                    }
                }
            }
            self.last = *v;
        }
        chunk_first.map(|(i, d)| (i, d, self.count - before))
    }

    /// Steps taken out so far.
    pub fn count(&self) -> u64 {
        self.count
    }

    /// What was taken out, for a person (`None` when nothing was): `what` names the signal,
    /// `unit` its unit.
    pub fn finding(&self, what: &str, unit: &str) -> Option<String> {
        let (at, size) = self.first?;
        Some(format!(
            "{} step(s) of the {what} larger than {} {unit} between two samples taken out as a sensor's glitch, not the shaft, the estimator held meanwhile (the first at sample {at}: {size:.6e} {unit})",
            self.count,
            self.limit()
        ))
    }
}

/// The stretches a sensor check ([`StillAngle`], [`StuckSpeed`]) found: whether one lasts now,
/// how many began, and the first's sample (0 = the stream's first).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
struct Stretches {
    #[serde(default)]
    on: bool,
    count: u64,
    first: Option<usize>,
}

impl Stretches {
    /// Sample `i` of a chunk whose first is sample `at` is in a stretch: one begun here is
    /// counted, and its index noted in `begun` if the chunk's first.
    fn hold(&mut self, at: usize, i: usize, begun: &mut Option<usize>) {
        if !self.on {
            self.on = true;
            self.count += 1;
            self.first.get_or_insert(at + i);
            begun.get_or_insert(i);
        }
    }
}

/// An angle that stands still while its shaft's speed turns it this far [rad] (14°: more than
/// a count of any encoder of 26 counts a revolution or finer) is a sensor that stopped (a
/// counter halted, a cable off), not a shaft at rest.
pub const MAX_STILL_TURN: f64 = 0.25;

/// Below this speed [rad/s] an angle standing still is a shaft at rest (the monitor's
/// standstill, 300 rpm): nothing is counted.
const STILL_MIN_SPEED: f64 = super::STANDSTILL_RAD_S;

/// An angle sensor that stopped while its shaft turns: the angle unchanged while its speed,
/// integrated since the angle last moved, passes [`MAX_STILL_TURN`] — the twist then drifts at
/// the rotation's speed, which no step shows. Allocation-free.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct StillAngle {
    /// The angle's last value, and `∫|ω| dt` since it last moved [rad].
    last: Option<f64>,
    turned: f64,
    /// The stretches it stood still.
    #[serde(flatten)]
    found: Stretches,
}

impl StillAngle {
    /// Mark in `held` the samples of a chunk of the angle `theta` [rad] that stand still while
    /// `omega` [rad/s] turns it (samples `dt` [s] apart; `at` the sample number of the chunk's
    /// first). Returns the index in the chunk of the first stretch begun in it.
    pub fn apply(
        &mut self,
        theta: &[f64],
        omega: &[f64],
        dt: f64,
        held: &mut [bool],
        at: usize,
    ) -> Option<usize> {
        let mut begun = None;
        for (i, ((&th, &w), h)) in theta.iter().zip(omega).zip(held).enumerate() {
            if self.last != Some(th) || w.abs() < STILL_MIN_SPEED {
                self.last = Some(th);
                self.turned = 0.0;
                self.found.on = false;
                continue;
            }
            self.turned += w.abs() * dt;
            if self.turned > MAX_STILL_TURN {
                self.found.hold(at, i, &mut begun);
                *h = true;
            }
        }
        begun
    }

    /// What was found, for a person (`None` when nothing was): `angle` and `speed` name the
    /// channels.
    pub fn finding(&self, angle: &str, speed: &str) -> Option<String> {
        let at = self.found.first?;
        Some(format!(
            "'{angle}' stood still while '{speed}' turned it more than {MAX_STILL_TURN} rad, {} time(s), from sample {at} first: a stopped sensor, not the shaft — the estimator held meanwhile",
            self.found.count
        ))
    }
}

/// A speed that stands bit for bit at one value for this long [s] (a live speed sensor updates
/// at 50 Hz or faster: a CAN signal's usual period is 10–20 ms)…
pub const STUCK_MIN_S: f64 = 0.02;

/// …while its angle's rate leaves it: the angle turns more or less than the speed says by more
/// than this fraction of what it turned (a speed in whole rpm at 1000 rpm misses by 5·10⁻⁴ of
/// it at most)…
pub const STUCK_RELATIVE_MISS: f64 = 1e-3;

/// …and by more than this many times the largest step by which one sample of the angle left
/// the speed's (an encoder's count, its noise): the miss is the angle's drift, not its
/// resolution.
pub const STUCK_MISS_STEPS: f64 = 2.0;

/// A speed sensor that froze while its shaft moves: its speed bit for bit unchanged for
/// [`STUCK_MIN_S`] while its angle's rate leaves it ([`STUCK_RELATIVE_MISS`],
/// [`STUCK_MISS_STEPS`]) — the dual of [`StillAngle`], found within tens of milliseconds
/// while the shaft vibrates. The engine speed frozen on a steady run loses the shaft's
/// vibration from the relative speed (Eq. 6.1's regressor): B read three times its value and
/// raised an alarm 0.24 s after the freeze, for a fault that was the sensor's. A speed held for a
/// revolution or updated more slowly than 50 Hz cannot follow that vibration either, and is
/// found the same. The angle's own glitches (a step off the speed's by more than
/// [`MAX_TWIST_STEP`]) do not count, and below the standstill's 300 rpm (by the speed and by
/// the angle) nothing is: a shaft at rest whose speed reads 0 (a tooth period's least) while
/// its angle's noise wanders is not a frozen sensor. Allocation-free.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct StuckSpeed {
    /// The speed it stands at [rad/s] and the last angle [rad].
    value: Option<f64>,
    last_angle: f64,
    /// Since the speed last changed: the angle turned (its glitches left out) [rad], the
    /// samples, the largest step by which a sample of the angle left the speed's [rad].
    turned: f64,
    samples: u64,
    largest_step_miss: f64,
    /// The stretches it stood frozen.
    #[serde(flatten)]
    found: Stretches,
}

impl StuckSpeed {
    /// Mark in `held` the samples of a chunk of the speed `omega` [rad/s] that stand while its
    /// angle `theta` [rad] leaves it (samples `dt` [s] apart; `at` the sample number of the
    /// chunk's first). Returns the index in the chunk of the first stretch begun in it.
    pub fn apply(
        &mut self,
        theta: &[f64],
        omega: &[f64],
        dt: f64,
        held: &mut [bool],
        at: usize,
    ) -> Option<usize> {
        let mut begun = None;
        for (i, ((&th, &w), h)) in theta.iter().zip(omega).zip(held).enumerate() {
            let d = th - std::mem::replace(&mut self.last_angle, th);
            if self.value != Some(w) {
                *self = Self {
                    value: Some(w),
                    last_angle: th,
                    found: Stretches {
                        on: false,
                        ..self.found
                    },
                    ..Self::default()
                };
                continue;
            }
            // A step of the angle off the speed's by more than a glitch's: the speed's share.
            let said = w * dt;
            let step_miss = (d - said).abs();
            if step_miss > MAX_TWIST_STEP {
                self.turned += said;
            } else {
                self.turned += d;
                self.largest_step_miss = self.largest_step_miss.max(step_miss);
            }
            self.samples += 1;
            let elapsed = self.samples as f64 * dt;
            let miss = (self.turned - said * self.samples as f64).abs();
            // Below the standstill's speed, by the angle and by the speed, a speed that stands
            // is a shaft at rest (a speed from a tooth's period reads 0 below its least).
            let turning = (self.turned / elapsed).abs().max(w.abs()) >= STILL_MIN_SPEED;
            if self.found.on
                || (elapsed >= STUCK_MIN_S
                    && turning
                    && miss > STUCK_RELATIVE_MISS * self.turned.abs()
                    && miss > STUCK_MISS_STEPS * self.largest_step_miss)
            {
                self.found.hold(at, i, &mut begun);
                *h = true;
            }
        }
        begun
    }

    /// What was found, for a person (`None` when nothing was): `speed` and `angle` name the
    /// channels.
    pub fn finding(&self, speed: &str, angle: &str) -> Option<String> {
        let at = self.found.first?;
        Some(format!(
            "'{speed}' stood at one value for {STUCK_MIN_S} s or more while '{angle}' turned away from it, {} time(s), from sample {at} first: a frozen sensor (or one updated too rarely for the shaft's vibration), not the shaft — the estimator held meanwhile",
            self.found.count
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_spike_and_a_lasting_jump_are_taken_out() {
        // A ramp of 0.01 per sample with a spike at 3 and a jump of 2π from 7 on.
        let truth: Vec<f64> = (0..10).map(|k| 0.01 * k as f64).collect();
        let mut x = truth.clone();
        x[3] = 1e9;
        for v in &mut x[7..] {
            *v += std::f64::consts::TAU;
        }
        // Held at most 2 samples; in two chunks: the gate carries its state across.
        let mut g = StepGate::twist(2);
        let mut held = [false; 10];
        let (a, b) = x.split_at_mut(5);
        let (ha, hb) = held.split_at_mut(5);
        assert_eq!(g.apply(a, None, ha, 0), Some((3, 1e9 - 0.02, 1)));
        assert!(
            matches!(g.apply(b, None, hb, 5), Some((2, d, 1)) if (d - 0.01 - std::f64::consts::TAU).abs() < 1e-9)
        );
        // The spike held at the sample before it, the samples after it as they came; the
        // jump held for 2 samples, then the ramp less 2π.
        let want = [0.0, 0.01, 0.02, 0.02, 0.04, 0.05, 0.06, 0.06, 0.06, 0.09];
        for (k, (v, t)) in x.iter().zip(want).enumerate() {
            assert!((v - t).abs() < 1e-9, "sample {k}: {v} against {t}");
        }
        assert_eq!(x[4], truth[4]);
        let marked: Vec<usize> = (0..10).filter(|&k| held[k]).collect();
        assert_eq!(marked, [3, 7, 8]);
        assert_eq!(g.count(), 2);
        let f = g.finding("twist", "rad").unwrap();
        assert!(
            f.starts_with("2 step(s) of the twist larger than 0.5 rad"),
            "{f}"
        );
        assert!(f.contains("the first at sample 3: 1.000000e9 rad"), "{f}");
    }

    /// A spike just over the limit whose way back is just under it: the way back is the return
    /// to where the signal was, not a step kept (a twist left 0.5 rad off raised a K alarm).
    #[test]
    fn a_spike_at_the_limit_is_taken_out_whole() {
        let truth: Vec<f64> = (0..10).map(|k| 0.001 * k as f64).collect();
        let mut x = truth.clone();
        x[5] -= 0.5015;
        let mut g = StepGate::twist(100);
        g.apply(&mut x, None, &mut [false; 10], 0);
        assert_eq!(g.count(), 1);
        assert_eq!(x[5], truth[4]);
        assert_eq!(&x[6..], &truth[6..]);
    }

    /// An angle that stops for 50 samples while its speed says 250 rad/s (0.025 rad a sample):
    /// held once it has missed 0.25 rad, until it moves again; a shaft at rest (speed 0) is not.
    #[test]
    fn an_angle_that_stops_while_its_shaft_turns_is_held() {
        let theta: Vec<f64> = (0..100)
            .map(|k| 0.01 * (if (20..70).contains(&k) { 19 } else { k }) as f64)
            .collect();
        let omega = [250.0; 100];
        let mut s = StillAngle::default();
        let mut held = [false; 100];
        let (a, b) = held.split_at_mut(50);
        assert_eq!(s.apply(&theta[..50], &omega[..50], 1e-4, a, 0), Some(30));
        assert_eq!(s.apply(&theta[50..], &omega[50..], 1e-4, b, 50), None);
        let marked: Vec<usize> = (0..100).filter(|&k| held[k]).collect();
        assert_eq!(marked, (30..70).collect::<Vec<_>>());
        let f = s.finding("theta_en", "omega_en").unwrap();
        assert!(f.contains("1 time(s), from sample 30 first"), "{f}");
        let mut rest = StillAngle::default();
        let mut held = vec![false; 100];
        assert_eq!(
            rest.apply(&[1.0; 100], &[0.0; 100], 1e-4, &mut held, 0),
            None
        );
        assert!(held.iter().all(|h| !h));
    }

    /// At 10 kHz for `n` samples, a shaft at `w(t)` [rad/s] whose angle [rad] is `angle(t)`,
    /// its speed as `read` gives it from the true one and the time.
    fn shaft(
        n: usize,
        angle: impl Fn(f64) -> f64,
        w: impl Fn(f64) -> f64,
        read: &dyn Fn(f64, f64) -> f64,
    ) -> (Vec<f64>, Vec<f64>) {
        (0..n)
            .map(|k| {
                let t = k as f64 * 1e-4;
                (angle(t), read(w(t), t))
            })
            .unzip()
    }

    /// A shaft at 104.7 rad/s vibrating by ±2 rad/s at 17 Hz, the angle's integral.
    const W0: f64 = 104.7;
    fn vibrating(t: f64) -> f64 {
        W0 + 2.0 * (2.0 * std::f64::consts::PI * 17.0 * t).cos()
    }
    fn vibrating_angle(t: f64) -> f64 {
        let w = 2.0 * std::f64::consts::PI * 17.0;
        W0 * t + 2.0 / w * (w * t).sin()
    }

    /// A CAN speed (updated every 10 ms) that freezes at 1 s on a vibrating shaft: found
    /// within 0.03 s of the freeze, held until it moves again at 1.5 s; a spike of the angle
    /// meanwhile changes nothing. The same speed that speeds up at 10 rad/s² without
    /// vibration: found once the angle's drift (5·t²) passes 10⁻³ of its turn (0.11·t), at
    /// 22 ms.
    #[test]
    fn a_speed_that_freezes_while_its_shaft_moves_is_held() {
        let can = |w: f64, t: f64| w + 1e-9 * (t / 0.01).floor();
        let frozen = |w: f64, t: f64| can(w, if (1.0..1.5).contains(&t) { 1.0 } else { t });
        let (mut theta, omega) = shaft(20_000, vibrating_angle, vibrating, &|_, t| {
            frozen(vibrating(t.min(1.0)), t)
        });
        theta[12_000] += 1e9;
        let mut s = StuckSpeed::default();
        let mut held = vec![false; 20_000];
        let (a, b) = held.split_at_mut(10_000);
        assert_eq!(
            s.apply(&theta[..10_000], &omega[..10_000], 1e-4, a, 0),
            None
        );
        let start = 10_000
            + s.apply(&theta[10_000..], &omega[10_000..], 1e-4, b, 10_000)
                .unwrap();
        assert!((10_200..10_300).contains(&start), "{start}");
        let marked: Vec<usize> = (0..20_000).filter(|&k| held[k]).collect();
        assert_eq!(marked, (start..15_000).collect::<Vec<_>>());
        let f = s.finding("omega_en", "theta_en").unwrap();
        assert!(
            f.contains(&format!("1 time(s), from sample {start} first")),
            "{f}"
        );
        let (theta, omega) = shaft(
            20_000,
            |t| 100.0 * t + 5.0 * t * t,
            |t| 100.0 + 10.0 * t,
            &|_, t| 100.0 + 10.0 * if (1.0..1.5).contains(&t) { 1.0 } else { t },
        );
        let mut held = vec![false; 20_000];
        let start = StuckSpeed::default().apply(&theta, &omega, 1e-4, &mut held, 0);
        assert!(matches!(start, Some(10_220..=10_225)), "{start:?}");
    }

    /// Not frozen, each with a spike of the angle: the vibrating shaft's speed updated every
    /// 10 ms; a speed in whole rpm at a steady 1000.4 rpm over an encoder of 360 counts for
    /// 60 s; a shaft at rest; one creeping at 20 rpm with a noisy angle, its speed read 0.
    #[test]
    fn a_live_speed_is_not_frozen() {
        let rpm = std::f64::consts::PI / 30.0;
        let whole_rpm = |w: f64, _| (w / rpm).round() * rpm;
        let count = std::f64::consts::TAU / 360.0;
        for (n, angle, w, read) in [
            (
                20_000,
                &vibrating_angle as &dyn Fn(f64) -> f64,
                &vibrating as &dyn Fn(f64) -> f64,
                &(|_, t| vibrating(t - t % 0.01)) as &dyn Fn(f64, f64) -> f64,
            ),
            (
                600_000,
                &|t| (1000.4 * rpm * t / count).floor() * count,
                &|_| 1000.4 * rpm,
                &whole_rpm as &dyn Fn(f64, f64) -> f64,
            ),
            (10_000, &|_| 1.0, &|_| 0.0, &|_, _| 0.0),
            (
                10_000,
                &|t| 2.1 * t + 1e-4 * (t * 7.3e4).sin(),
                &|_| 2.1,
                &|_, _| 0.0,
            ),
        ] {
            let (mut theta, omega) = shaft(n, angle, w, read);
            theta[n / 2] += 1e9;
            let mut s = StuckSpeed::default();
            let mut held = vec![false; n];
            assert_eq!(s.apply(&theta, &omega, 1e-4, &mut held, 0), None, "{n}");
            assert!(s.finding("w", "a").is_none());
        }
    }

    #[test]
    fn a_plausible_signal_passes_bit_for_bit() {
        let x: Vec<f64> = (0..1000).map(|k| 0.3 * (k as f64 * 0.1).sin()).collect();
        let mut y = x.clone();
        let mut g = StepGate::twist(100);
        let mut held = vec![false; 1000];
        assert_eq!(g.apply(&mut y, None, &mut held, 0), None);
        assert_eq!(x, y);
        assert!(held.iter().all(|h| !h));
        assert_eq!(g.count(), 0);
        assert!(g.finding("twist", "rad").is_none());
    }
}
