//! Encoder decoding on a simulated encoder: exact on ideal counts where it must be, and the
//! noise of each estimator equal to its closed form (uniform quantisation errors).
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_signal::encoder::{counts_from_angle, first_marker, marker_edges, Encoder};
use std::f64::consts::TAU;

fn rms(a: &[f64], b: &[f64]) -> f64 {
    (a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / a.len() as f64).sqrt()
}

/// ω(t) = ω0 + a·sin(2πft), θ = ∫ω; sampled at 1 kHz for 20 s.
fn simulated(ppr: u32) -> (Vec<f64>, Vec<f64>, Vec<f64>, f64) {
    let (w0, a, f, dt) = (100.0, 5.0, 1.0, 1e-3);
    let n = 20_000;
    let t: Vec<f64> = (0..n).map(|i| i as f64 * dt).collect();
    let theta: Vec<f64> = t
        .iter()
        .map(|t| w0 * t + a / (TAU * f) * (1.0 - (TAU * f * t).cos()))
        .collect();
    let omega: Vec<f64> = t.iter().map(|t| w0 + a * (TAU * f * t).sin()).collect();
    let alpha: Vec<f64> = t
        .iter()
        .map(|t| a * TAU * f * (TAU * f * t).cos())
        .collect();
    let _ = theta.len();
    (counts_from_angle(&theta, ppr), omega, alpha, dt)
}

#[test]
fn speed_noise_matches_the_closed_forms() {
    for ppr in [360u32, 1024] {
        let enc = Encoder { ppr };
        let (c, omega, _, dt) = simulated(ppr);
        let q = enc.quantum();
        // Eq. 4.3: backward difference ≈ ω(t − dt/2); the quantisation noise dominates.
        let w = enc.speed_counts(&c, dt);
        let r = rms(&w[1..], &omega[1..]);
        let predicted = q / (dt * 6f64.sqrt());
        assert!(
            (r / predicted - 1.0).abs() < 0.05,
            "ppr {ppr}: {r} vs {predicted}"
        );
        // Local fit, h = 10. Its quantisation errors are not independent: over a few samples
        // the angle advances δ = ω·dt/q pulses a sample, so the errors are e_k = {c + k·δ} − ½,
        // whose correlation (c uniform) is R(x) = 1/12 − {x}(1 − {x})/2 at lag x = (j − k)·δ.
        // The slope's variance is then (q/dt)²·Σ_j Σ_k j·k·R((j − k)·δ) / (Σk²)², averaged
        // over the run's δ(t) — 22 % (360) and 11 % (1024) above the independent-errors form
        // q/(dt·√(12·Σk²)), which the difference estimator (one lag) hardly feels.
        let h = 10;
        let wf = enc.speed_fit(&c, dt, h);
        let rf = rms(&wf[h..c.len() - h], &omega[h..c.len() - h]);
        let hi = h as i64;
        let sum_k2: f64 = (-hi..=hi).map(|k| (k * k) as f64).sum();
        let corr = |x: f64| {
            let f = x - x.floor();
            1.0 / 12.0 - f * (1.0 - f) / 2.0
        };
        let (mut var, mut n) = (0.0, 0);
        for w in omega[h..c.len() - h].iter().step_by(7) {
            let d = w * dt / q;
            let mut v = 0.0;
            for j in -hi..=hi {
                for k in -hi..=hi {
                    v += (j * k) as f64 * corr((j - k) as f64 * d);
                }
            }
            var += v / (sum_k2 * sum_k2);
            n += 1;
        }
        let pf = q / dt * (var / f64::from(n)).sqrt();
        assert!((rf / pf - 1.0).abs() < 0.05, "ppr {ppr}: fit {rf} vs {pf}");
        let independent = q / (dt * (12.0 * sum_k2).sqrt());
        assert!(rf / independent > 1.05, "ppr {ppr}: {rf} vs {independent}");
        assert!(r / rf > 25.0, "ppr {ppr}: fit improves {}×", r / rf);
    }
}

#[test]
fn acceleration_estimators() {
    let enc = Encoder { ppr: 1024 };
    let (c, _, alpha, dt) = simulated(1024);
    let q = enc.quantum();
    // Eq. 4.4: second difference, noise q/dt²·√(6/12)·… — at least it is centred on α.
    let a = enc.accel_counts(&c, dt);
    let mean_err = a[2..]
        .iter()
        .zip(&alpha[1..])
        .map(|(x, y)| x - y)
        .sum::<f64>()
        / (a.len() - 2) as f64;
    assert!(mean_err.abs() < 0.5, "{mean_err}");
    // Second difference of independent uniform errors: variance 6·(1/12) counts².
    let r = rms(&a[2..], &alpha[1..c.len() - 1]);
    let predicted = q / (dt * dt) * 0.5f64.sqrt();
    assert!((r / predicted - 1.0).abs() < 0.05, "{r} vs {predicted}");
    // The parabola fit over 101 samples: orders of magnitude better.
    let h = 50;
    let af = enc.accel_fit(&c, dt, h);
    let rf = rms(&af[h..c.len() - h], &alpha[h..c.len() - h]);
    assert!(rf < predicted / 1000.0, "{rf}");
}

#[test]
fn exact_on_quadratic_angles_and_markers() {
    // Counts that are an exact quadratic in the sample index: the fits are exact.
    let enc = Encoder { ppr: 360 };
    let dt = 0.01;
    let c: Vec<f64> = (0..200).map(|i| (3 * i + i * i) as f64).collect();
    let q = enc.quantum();
    let w = enc.speed_fit(&c, dt, 5);
    let a = enc.accel_fit(&c, dt, 5);
    for i in 5..195 {
        let exact = q * (3.0 + 2.0 * i as f64) / dt;
        assert!((w[i] - exact).abs() < 1e-9 * exact, "{i}");
        assert!((a[i] - q * 2.0 / (dt * dt)).abs() < 1e-6, "{i}: {}", a[i]);
    }
    let theta = enc.angle(&c, 10);
    assert_eq!(theta[10], 0.0);
    assert!((theta[11] - q * (c[11] - c[10])).abs() < 1e-15);
    let marker = [0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0];
    assert_eq!(first_marker(&marker), Some(2));
    assert_eq!(marker_edges(&marker), vec![2, 6]);
    assert_eq!(first_marker(&[1.0, 0.0]), Some(0));
    assert_eq!(first_marker(&[0.0; 4]), None);
}

/// The counts of a 60−3 wheel's 57 real teeth, taken for a 57-pulse encoder, are found out
/// (one step per revolution lasts four), at constant speed and through a speed ramp and a
/// cyclic fluctuation; an even encoder's counts, with the same speed changes and sampling, are
/// not.
#[test]
fn counts_not_equally_spaced_in_angle_are_found() {
    use physid_signal::encoder::uneven_spacing;
    // 100 kHz, as a lab system samples a pickup (≈ 100 samples a tooth at 1000 rpm).
    let fs = 100_000.0;
    let t: Vec<f64> = (0..400_000).map(|i| i as f64 / fs).collect();
    // Crank angle [rad]: 1000 rpm ramping to 1300 rpm, ±3 % cyclic fluctuation.
    let theta: Vec<f64> = t
        .iter()
        .map(|&t| {
            let w = 104.7 * (1.0 + 0.075 * t);
            w * t + 0.03 * (2.0 * std::f64::consts::PI * 8.0 * t).sin()
        })
        .collect();
    // 60−3: teeth at multiples of 6° except the three after each 0° (teeth 57, 58, 59 missing).
    let tooth = |th: f64| {
        let rev = (th / std::f64::consts::TAU).floor();
        let k = ((th / std::f64::consts::TAU - rev) * 60.0)
            .floor()
            .min(56.0);
        rev * 57.0 + k
    };
    let wheel: Vec<f64> = theta.iter().map(|&th| tooth(th)).collect();
    let e = uneven_spacing(&t, &wheel, 57).expect("a 60−3 wheel's counts");
    assert!(e.contains("not equally spaced"), "{e}");
    // A chunk at a time, however cut (the sample period is the first 65 536 samples'), the
    // same verdict.
    let chunked = |t: &[f64], counts: &[f64], ppr: u32, n: usize| {
        let mut check = physid_signal::encoder::SpacingCheck::new(ppr);
        for (t, c) in t.chunks(n).zip(counts.chunks(n)) {
            check.push(t, c);
        }
        check.finish()
    };
    for n in [1, 57, 4096, 65_549, 400_000] {
        assert_eq!(chunked(&t, &wheel, 57, n), Some(e.clone()), "{n}");
        let even = counts_from_angle(&theta, 360);
        assert_eq!(chunked(&t, &even, 360, n), None, "{n}");
    }
    // An even 360-pulse encoder on the same shaft: fine.
    let even = counts_from_angle(&theta, 360);
    assert_eq!(uneven_spacing(&t, &even, 360), None);
    let even57 = counts_from_angle(&theta, 57);
    assert_eq!(uneven_spacing(&t, &even57, 57), None);
    // Pulses not resolved in time (10 kHz against 6000 pulses a second): no judgement.
    let coarse: Vec<f64> = t.iter().step_by(10).copied().collect();
    let even: Vec<f64> = even.iter().step_by(10).copied().collect();
    assert_eq!(uneven_spacing(&coarse, &even, 360), None);
}
