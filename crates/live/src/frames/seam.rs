//! A sender that starts again — a DAQ whose software restarted while `physid live --frames`
//! runs: its `seq` back at 0, its clock back at its start, its angle counters at their zero —
//! is joined to the stream as a gap in the data, so that every stage goes on as after frames
//! lost. Before, each of its frames was refused ("t starts at 0 s, not after the previous
//! frame's …") until its clock passed the last time taken: in practice for ever.
//!
//! The sender's later samples are shifted, all by the same amounts until it starts again:
//!
//! * the crank angle `theta_en` by whole cycles (4π rad), so that each sample keeps its place
//!   in the cycle (the firing TDC) and the angle advances across the gap by what the crank
//!   turns in it at the mean of the speeds `omega_en` on either side — and by more than a
//!   cycle, so that the stages that count cycles leave out the cycle the gap cuts, as after
//!   frames lost ([`physid_signal::cycles`]);
//! * the dynamometer's angle `theta_dy` by whole turns (2π rad), so that the shaft's twist
//!   `theta_dy − theta_en` is where it was before the gap, to within a turn;
//! * the time `t` so that the gap lasts the time the crank takes to turn that advance at that
//!   speed: the wall-clock time between the two frames to within half a cycle (the sender's
//!   clock started again and cannot tell); at rest (below [`TURNING`]), the wall clock's. A
//!   sender whose clock went on (only its `seq` started again) keeps its time. Either way the
//!   gap is at least a sample step and the advance at [`MAX_CRANK_SPEED`].

use physid_signal::cycles::{MAX_ADVANCE, MAX_CRANK_SPEED};
use std::f64::consts::TAU;

/// The slowest crank speed the gap's time is made to agree with [rad/s] (≈ 95 rpm, below a
/// starter's cranking speed): a slower crank is taken as at rest, its angle's advance across
/// the gap given no time of its own.
pub const TURNING: f64 = 10.0;

/// One sample of the frame channels the seam joins.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Time [s].
    pub t: f64,
    /// Engine crank angle [rad].
    pub theta_en: f64,
    /// Dynamometer angle [rad].
    pub theta_dy: f64,
    /// Engine speed [rad/s].
    pub omega_en: f64,
}

/// What is added to a sender's time and angles: zero until it first starts again.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Shift {
    /// Added to `t` [s].
    pub t: f64,
    /// Added to `theta_en` [rad]: a whole number of cycles (4π).
    pub theta_en: f64,
    /// Added to `theta_dy` [rad]: a whole number of turns (2π).
    pub theta_dy: f64,
}

impl Shift {
    /// The shift that joins a new segment whose first sample, as sent, is `first`, to the
    /// stream whose last sample (shifted, as the stages took it) is `last`; `wall_s` [s] the
    /// wall-clock time between the two frames, `dt` [s] the sample step.
    pub fn join(self, last: &Sample, first: &Sample, wall_s: f64, dt: f64) -> Shift {
        let clock = first.t + self.t - last.t;
        let clock_went_on = clock >= dt * (1.0 - 1e-3);
        let gap = if clock_went_on { clock } else { wall_s.max(dt) };
        let speed = 0.5 * (last.omega_en + first.omega_en);
        let speed = if speed >= TURNING { speed } else { 0.0 };
        // The angle's advance: its place in the cycle kept, the nearest to what the crank
        // turns in the gap, more than a cycle.
        let place = (first.theta_en + self.theta_en - last.theta_en).rem_euclid(MAX_ADVANCE);
        let least = if place > 0.0 { 1.0 } else { 2.0 };
        let cycles = ((speed * gap - place) / MAX_ADVANCE).round().max(least);
        let advance = place + cycles * MAX_ADVANCE;
        // Without the sender's clock, the gap is the time the crank takes for that advance.
        let gap = if !clock_went_on && speed > 0.0 {
            advance / speed
        } else {
            gap
        };
        let gap = gap.max(advance / MAX_CRANK_SPEED).max(dt);
        let whole = |x: f64, unit: f64| (x / unit).round() * unit;
        let theta_en = self.theta_en
            + whole(
                last.theta_en + advance - first.theta_en - self.theta_en,
                MAX_ADVANCE,
            );
        let twist = last.theta_dy - last.theta_en;
        let theta_dy = self.theta_dy
            + whole(
                first.theta_en + theta_en + twist - first.theta_dy - self.theta_dy,
                TAU,
            );
        Shift {
            t: if gap == clock {
                self.t
            } else {
                last.t + gap - first.t
            },
            theta_en,
            theta_dy,
        }
    }

    /// Whether it shifts nothing.
    pub fn is_none(&self) -> bool {
        *self == Shift::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    const DT: f64 = 1e-4;

    fn sample(t: f64, theta_en: f64, theta_dy: f64, omega_en: f64) -> Sample {
        Sample {
            t,
            theta_en,
            theta_dy,
            omega_en,
        }
    }

    fn cycles(x: f64) -> f64 {
        x / (4.0 * PI)
    }

    /// A DAQ restarted after 2 s at 1000 rpm, its clock at 0 and its angles within a cycle (an
    /// absolute encoder): the angle advances by what the crank turns in the wall clock's 2 s to
    /// within half a cycle, the gap is the time it takes at the crank's speed, each angle keeps its place in the cycle (and
    /// the dynamometer's in its turn), and the twist is where it was.
    #[test]
    fn a_restart_is_a_gap_of_the_wall_clock_at_the_crank_speed() {
        let w = 1000.0 * TAU / 60.0;
        let last = sample(10.0, 1047.3, 1047.3 - 0.02, w);
        let first = sample(0.0, 3.1, 3.1 - 0.02 + TAU, w);
        let s = Shift::default().join(&last, &first, 2.0, DT);
        let (t, en, dy) = (
            first.t + s.t,
            first.theta_en + s.theta_en,
            first.theta_dy + s.theta_dy,
        );
        let turned = en - last.theta_en;
        assert!((cycles(turned) - cycles(w * 2.0)).abs() <= 0.5, "{turned}");
        assert!((t - last.t - turned / w).abs() < 1e-12, "{t}");
        let whole = |x: f64, unit: f64| ((x / unit).round() - x / unit).abs() < 1e-9;
        assert!(whole(s.theta_en, 4.0 * PI), "{}", s.theta_en);
        assert!(whole(s.theta_dy, TAU), "{}", s.theta_dy);
        assert!(((dy - en) - (-0.02)).abs() < 1e-9, "twist {}", dy - en);
    }

    /// Frames piped from a file come at once (no wall-clock time between them): the gap is the
    /// time the crank needs for the least advance that keeps the angle's place, more than a
    /// cycle; at rest, that advance at 25 000 rpm. The stages that count cycles accept both.
    #[test]
    fn without_wall_clock_time_the_gap_is_the_crank_s_own() {
        let w = 1000.0 * TAU / 60.0;
        for (speed, place) in [(w, 1.0), (w, 0.0), (0.0, 1.0), (3.0, 1.0)] {
            let last = sample(5.0, 40.0 * PI, 40.0 * PI, speed);
            let first = sample(0.0, place, place, speed);
            let s = Shift::default().join(&last, &first, 0.0, DT);
            let advance = first.theta_en + s.theta_en - last.theta_en;
            let gap = first.t + s.t - last.t;
            let want = if place > 0.0 {
                4.0 * PI + place
            } else {
                8.0 * PI
            };
            assert!((advance - want).abs() < 1e-9, "{speed} {place}: {advance}");
            assert!(advance > MAX_ADVANCE);
            let want_gap = if speed >= TURNING {
                advance / speed
            } else {
                advance / MAX_CRANK_SPEED
            };
            assert!((gap - want_gap).abs() < 1e-12, "{speed} {place}: {gap}");
            assert!(advance / gap <= MAX_CRANK_SPEED * (1.0 + 1e-12));
        }
    }

    /// A sender whose clock went on (only its `seq` started again) keeps its time; a second
    /// restart shifts on from the first's shift.
    #[test]
    fn a_clock_that_went_on_is_kept_and_shifts_add_up() {
        let w = 100.0;
        let last = sample(3.0, 300.0, 300.0, w);
        let first = sample(4.0, 2.0, 2.0, w);
        let s = Shift::default().join(&last, &first, 0.0, DT);
        assert_eq!(s.t, 0.0);
        let advance = first.theta_en + s.theta_en - last.theta_en;
        assert!(
            (cycles(advance) - cycles(w * 1.0)).abs() <= 0.5,
            "{advance}"
        );
        // Again, 1 s later by the wall clock, its clock back at 0.
        let last2 = sample(4.5, 2.0 + s.theta_en + 50.0, 2.0 + s.theta_dy + 50.0, w);
        let first2 = sample(0.0, 1.0, 1.0, w);
        let s2 = s.join(&last2, &first2, 1.0, DT);
        let advance2 = first2.theta_en + s2.theta_en - last2.theta_en;
        assert!((cycles(advance2) - cycles(w)).abs() <= 0.5, "{advance2}");
        assert!((first2.t + s2.t - last2.t - advance2 / w).abs() < 1e-12);
    }
}
