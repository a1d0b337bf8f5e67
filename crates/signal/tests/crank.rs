//! Crank-angle resampling, cycle indexing, per-cycle statistics and IMEP against closed forms.
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_signal::crank::{crank_grid, cycle_position, cycle_stats, imep, interp, CrankError};
use std::f64::consts::PI;

#[test]
fn grid_from_constant_speed_is_exact() {
    let w = 104.7; // rad/s
    let dt = 1.0 / 20_000.0;
    let t: Vec<f64> = (0..40_000).map(|i| i as f64 * dt).collect();
    let theta: Vec<f64> = t.iter().map(|t| w * t + 0.3).collect();
    let tdc = 1.0; // rad: the first marker
    let g = crank_grid(&t, &theta, tdc, 1.0).unwrap();
    assert_eq!(g.theta[0], 0.0);
    for (k, (&th, &tt)) in g.theta.iter().zip(&g.t).enumerate() {
        assert!((th - (k as f64).to_radians()).abs() < 1e-12);
        assert!((tt - (th + tdc - 0.3) / w).abs() < 1e-12, "{k}");
    }
    assert_eq!(g.cycle[719], 0.0);
    assert_eq!((g.cycle[720], g.crank_deg[720]), (1.0, 0.0));
    assert!((g.crank_deg[725] - 5.0).abs() < 1e-9);
    let last = *theta.last().unwrap() - tdc;
    assert_eq!(g.theta.len(), (last.to_degrees()).floor() as usize + 1);
}

#[test]
fn resampling_round_trip() {
    // Accelerating engine: θ = ω0 t + a t²/2.
    let dt = 1.0 / 50_000.0;
    let t: Vec<f64> = (0..100_000).map(|i| i as f64 * dt).collect();
    let theta: Vec<f64> = t.iter().map(|t| 100.0 * t + 20.0 * t * t).collect();
    let x: Vec<f64> = theta.iter().map(|th| (3.0 * th).sin()).collect();
    let g = crank_grid(&t, &theta, 0.0, 1.0).unwrap();
    let xa = interp(&theta, &x, &g.theta);
    for (th, v) in g.theta.iter().zip(&xa) {
        assert!((v - (3.0 * th).sin()).abs() < 1e-4);
    }
    // Back to time at 5 kHz.
    let tb: Vec<f64> = (0..9000).map(|i| 0.01 + i as f64 * 2e-4).collect();
    let xb = interp(&g.t, &xa, &tb);
    for (tt, v) in tb.iter().zip(&xb) {
        let th = 100.0 * tt + 20.0 * tt * tt;
        assert!((v - (3.0 * th).sin()).abs() < 5e-3, "{tt}");
    }
}

#[test]
fn cycles_stats_and_imep() {
    assert_eq!(cycle_position(0.0), (0.0, 0.0));
    let (c, d) = cycle_position(4.0 * PI + PI / 2.0);
    assert_eq!(c, 1.0);
    assert!((d - 90.0).abs() < 1e-9);
    assert_eq!(cycle_position(-0.1).0, -1.0);
    // Three cycles at 1°; V = V0 + A(1 − cos θ), p = p0 + P sin θ: ∮p dV = 2πPA per 720°.
    let (v0, a, p0, pp) = (5e-5, 6e-5, 1e5, 2e6);
    let theta: Vec<f64> = (0..3 * 720).map(|k| (k as f64).to_radians()).collect();
    let cycle: Vec<f64> = theta.iter().map(|&th| cycle_position(th).0).collect();
    let v: Vec<f64> = theta.iter().map(|th| v0 + a * (1.0 - th.cos())).collect();
    let p: Vec<f64> = theta.iter().map(|th| p0 + pp * th.sin()).collect();
    let vd = 2.0 * a;
    let w = imep(&cycle, &p, &v, vd, 720);
    assert_eq!(w.len(), 3);
    let exact = 2.0 * PI * pp * a / vd;
    for (c, m) in &w {
        assert!((m / exact - 1.0).abs() < 1e-4, "cycle {c}: {m} vs {exact}");
    }
    // An incomplete last cycle is not reported.
    assert_eq!(imep(&cycle[..2000], &p, &v, vd, 720).len(), 2);
    let s = cycle_stats(&cycle, &p);
    assert_eq!(s.len(), 3);
    assert!((s[0].mean - p0).abs() < 1e-6 * p0);
    assert!((s[1].max - (p0 + pp)).abs() < 1e-6 * pp && (s[1].min - (p0 - pp)).abs() < 1e-6 * pp);
    assert_eq!(s[2].samples, 720);
}

#[test]
fn errors_say_where() {
    let t = [0.0, 1.0, 2.0, 3.0];
    let e = crank_grid(&t, &[0.0, 1.0, 1.0, 2.0], 0.0, 1.0).unwrap_err();
    assert_eq!(
        e,
        CrankError::NotIncreasing {
            what: "the crank angle",
            index: 2,
            prev: 1.0,
            next: 1.0
        }
    );
    assert!(crank_grid(&t, &[0.0, 1.0, 2.0, 3.0], 0.0, 0.0).is_err());
    assert!(crank_grid(&t, &[0.0, 1.0], 0.0, 1.0).is_err());
}
