//! Elementary functions where the step's arguments allow a cheaper exact route than the
//! library's: each equal to the library's result (bit for bit, or to round-off where stated),
//! tested against it.

/// How far [rad] [`sin_cos_near`] takes an angle from the one it knows: the series' first
/// omitted terms, d¹¹/11! and d¹²/12!, are then below 2.6e-19 — under the round-off of
/// `sin d` (≈ 0.1·1.1e-16). Two degrees of the crank, or of the machine's frame (two pole
/// pairs: the frame turns ≈ 4.2° a 2° step), are within it.
pub const NEAR: f64 = 0.1;

/// `(sin θ, cos θ)` from those of a nearby angle θ0 (`sc0`): the angle-addition formulas with
/// the Taylor series of the difference `d = θ − θ0`, for `|d| ≤` [`NEAR`]; farther, the
/// library's `sin_cos`. An RK stage's crank angle is within a step of the step's start.
pub fn sin_cos_near(theta: f64, theta0: f64, sc0: (f64, f64)) -> (f64, f64) {
    let d = theta - theta0;
    if d.abs() > NEAR {
        return theta.sin_cos();
    }
    let d2 = d * d;
    // sin d = d·(1 − d²/3! + d⁴/5! − d⁶/7! + d⁸/9!), cos d = 1 − d²/2! + … + d¹⁰/10!.
    let sd = d
        * (1.0
            + d2 * (-1.0 / 6.0
                + d2 * (1.0 / 120.0 + d2 * (-1.0 / 5040.0 + d2 * (1.0 / 362_880.0)))));
    let cd = 1.0
        + d2 * (-0.5
            + d2 * (1.0 / 24.0
                + d2 * (-1.0 / 720.0 + d2 * (1.0 / 40320.0 + d2 * (-1.0 / 3_628_800.0)))));
    let (s0, c0) = sc0;
    (s0 * cd + c0 * sd, c0 * cd - s0 * sd)
}

/// `(sin θ, cos θ)` along a sequence of angles that advance by small steps (the crank angle
/// at each solver step, the machine's frame angle at each sample): each from the one before by
/// [`sin_cos_near`], and from the library's `sin_cos` at every [`SinCosTrack::ANCHOR`]-th call
/// and wherever the angle moved more than [`NEAR`]. Each call adds at most a
/// few units of round-off (2.2e-16) to the last anchor's exact value: the results stay within
/// 2e-15 of the library's (tested), at a fraction of its cost.
#[derive(Debug, Clone, Copy, Default)]
pub struct SinCosTrack {
    /// The last angle and its sine and cosine; calls since the last anchor (`None`: none yet).
    last: Option<(f64, (f64, f64), u32)>,
}

impl SinCosTrack {
    /// Calls between anchors on the library.
    pub const ANCHOR: u32 = 16;

    /// `(sin θ, cos θ)`.
    pub fn at(&mut self, theta: f64) -> (f64, f64) {
        let (sc, n) = match self.last {
            Some((theta0, sc0, n)) if n < Self::ANCHOR && (theta - theta0).abs() <= NEAR => {
                (sin_cos_near(theta, theta0, sc0), n + 1)
            }
            _ => (theta.sin_cos(), 0),
        };
        self.last = Some((theta, sc, n));
        sc
    }
}

/// `eˣ − 1`: by [`expm1_small`] for `|x| ≤ 0.02` (no library call), the library's beyond.
pub fn expm1(x: f64) -> f64 {
    if x.abs() <= 0.02 {
        expm1_small(x)
    } else {
        x.exp_m1()
    }
}

/// `eˣ − 1` for `|x| ≤ 0.02` by its Taylor series to x⁸ (the first omitted term is below
/// 1e-19 relative, under the round-off of the result); used where the argument is known to be
/// that small.
pub fn expm1_small(x: f64) -> f64 {
    debug_assert!(x.abs() <= 0.02);
    // 1/k! for k = 8 … 2, Horner.
    const C: [f64; 7] = [
        1.0 / 40320.0,
        1.0 / 5040.0,
        1.0 / 720.0,
        1.0 / 120.0,
        1.0 / 24.0,
        1.0 / 6.0,
        0.5,
    ];
    let mut p = C[0];
    for c in &C[1..] {
        p = p * x + c;
    }
    x * (1.0 + x * p)
}

/// `⌊x⌋` for `|x| < 2⁶³` by truncation toward zero, corrected below zero (the library
/// `floor` is a call on baseline x86-64).
pub fn floor(x: f64) -> f64 {
    let n = x as i64 as f64;
    if n > x {
        n - 1.0
    } else {
        n
    }
}

/// `x mod 720` in [0, 720) by a floor of the quotient (a library `fmod` costs several times
/// more). For `0 ≤ x < 2⁵²` it is the exact remainder, `x.rem_euclid(720.0)` bit for bit: the
/// quotient's rounding may make the floor one off, but `x − 720·m` is then a multiple of x's
/// ulp no larger than x, so exact, and the correction by ±720 lands on the exact remainder,
/// which is representable. Below zero it stays in [0, 720) where `rem_euclid` can round up to
/// 720 itself.
pub fn wrap720(x: f64) -> f64 {
    let r = x - 720.0 * floor(x * (1.0 / 720.0));
    // The quotient's rounding can put r a hair outside [0, 720).
    if r >= 720.0 {
        r - 720.0
    } else if r < 0.0 {
        r + 720.0
    } else {
        r
    }
}

/// `x` rounded to the nearest integer, halves away from zero: the library's `round` (a call
/// on baseline x86-64) by the 2⁵² shift, which rounds to nearest even, with the halves it
/// sends toward zero sent away. Exact: for `|x| < 2⁵²` the sum `|x| + 2⁵²` rounds only its
/// fraction, and `r − |x|` is exact (Sterbenz); larger `|x|` are integers already.
pub fn round(x: f64) -> f64 {
    const SHIFT: f64 = 4_503_599_627_370_496.0; // 2⁵²
    let a = x.abs();
    if a >= SHIFT || a.is_nan() {
        return x;
    }
    let mut r = (a + SHIFT) - SHIFT;
    if r - a == -0.5 {
        r += 1.0;
    }
    r.copysign(x)
}

/// `aⁿ` by repeated squaring, inline (a run-time exponent otherwise costs a library call;
/// the same sequence of products as that call's, so the same result).
pub fn powi(mut a: f64, mut n: u32) -> f64 {
    let mut r = 1.0;
    loop {
        if n & 1 == 1 {
            r *= a;
        }
        n /= 2;
        if n == 0 {
            return r;
        }
        a *= a;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap720_is_the_euclidean_remainder() {
        for x in [-1e-9, -0.5, -720.0, -1000.25, -720.0 * (1.0 + f64::EPSILON)] {
            let r = wrap720(x);
            assert!((0.0..720.0).contains(&r), "{x} → {r}");
            let d = (r - x.rem_euclid(720.0)).abs();
            assert!(d < 1e-9 || (720.0 - d).abs() < 1e-9, "{x}: {r}");
        }
        // Not negative: the exact remainder, bit for bit — at and around every multiple of 720
        // up to 2⁴⁰ and at angles in degrees of a long run.
        let mut xs = vec![0.0, 1e-12, 359.5, 719.999999, 720.0 - 1e-13, 123_456.789];
        for k in (0..40)
            .map(|e| 2f64.powi(e))
            .chain((0..2000).map(f64::from))
        {
            let m = 720.0 * k;
            xs.extend([
                m,
                m.next_up(),
                m.next_down(),
                m + 0.5,
                m * (1.0 + f64::EPSILON),
            ]);
        }
        let mut a = 0.37_f64;
        for _ in 0..100_000 {
            a = (a * 1.618_033_988_749_895 + 0.1).fract();
            xs.push(a * 3.6e6);
        }
        for x in xs.into_iter().filter(|&x| x >= 0.0) {
            assert_eq!(wrap720(x).to_bits(), x.rem_euclid(720.0).to_bits(), "{x}");
        }
    }

    #[test]
    fn small_argument_series_equal_the_library() {
        for k in -200..=200 {
            let x = f64::from(k) * 1e-4;
            let lib = x.exp_m1();
            assert!(
                (expm1_small(x) - lib).abs() <= 2.0 * f64::EPSILON * lib.abs(),
                "{x}"
            );
            assert!((expm1(x) - lib).abs() <= 2.0 * f64::EPSILON * lib.abs());
            // Beyond the series' range, the library's own.
            let far = x * 10.0 + 0.03f64.copysign(x);
            assert_eq!(expm1(far), far.exp_m1());
        }
        // sin/cos near a base angle, against the library at the angle itself.
        for k in 0..720 {
            let th0 = f64::from(k).to_radians() * 1.37;
            for d in [
                -0.1, -0.05, -0.0174, -1e-9, 0.0, 1e-7, 0.0087, 0.0174, 0.049, 0.073, 0.1, 0.2,
            ] {
                let (s, c) = sin_cos_near(th0 + d, th0, th0.sin_cos());
                let (ls, lc) = (th0 + d).sin_cos();
                assert!(
                    (s - ls).abs() < 4e-16 && (c - lc).abs() < 4e-16,
                    "{th0} {d}"
                );
            }
        }
    }

    /// Along steps of one crank degree, of the machine frame's 2.1° and 4.2° (at 1° and 2°
    /// steps), of varied small steps and across jumps: within 2e-15 of the library, and the
    /// library's own value where it anchors.
    #[test]
    fn sin_cos_track_stays_on_the_library() {
        let mut a = 0.61_f64;
        let mut next = || {
            a = (a * 1.618_033_988_749_895 + 0.1).fract();
            a
        };
        for step in [
            1f64.to_radians(),
            2.1f64.to_radians(),
            4.2f64.to_radians(),
            0.0,
            -0.03,
            0.0499,
            0.0999,
        ] {
            let mut track = SinCosTrack::default();
            let mut theta = -3.0;
            let mut worst = 0.0_f64;
            for k in 0..200_000 {
                theta += match k % 1000 {
                    // Now and then a jump (the library's again), or a varied step.
                    999 => 1.0,
                    _ if step == 0.0 => 0.05 * (2.0 * next() - 1.0),
                    _ => step * (1.0 + 1e-3 * next()),
                };
                let (s, c) = track.at(theta);
                let (ls, lc) = theta.sin_cos();
                worst = worst.max((s - ls).abs()).max((c - lc).abs());
                if k % 1000 == 999 {
                    assert_eq!((s, c), (ls, lc));
                }
            }
            println!("step {step}: worst {worst:.1e}");
            assert!(worst < 2e-15, "{step}: {worst:e}");
        }
    }

    #[test]
    fn round_is_the_library_round() {
        let mut xs = vec![
            0.0,
            -0.0,
            0.5,
            1.5,
            2.5,
            0.49999999999999994,
            4_503_599_627_370_495.5,
            4_503_599_627_370_496.0,
            9.1e15 + 1.0,
            1e300,
            f64::INFINITY,
            f64::MIN_POSITIVE,
        ];
        for k in -2000..=2000 {
            let x = f64::from(k) * 0.25;
            xs.extend([x, x + 1e-9, x - 1e-9, x * 1.000_000_1, x * 7.3e5]);
        }
        for x in xs {
            for v in [x, -x] {
                assert_eq!(round(v).to_bits(), v.round().to_bits(), "{v}");
            }
        }
        assert!(round(f64::NAN).is_nan());
    }

    #[test]
    fn powi_is_the_library_power() {
        for n in 0..=12 {
            for a in [0.0, 1e-3, 0.3, 0.7, 0.99, 1.0, 1.7] {
                assert_eq!(powi(a, n), a.powi(n as i32), "{a}^{n}");
            }
        }
    }
}
