//! The coupling-shaft model (Eq. 6.1): its exact gradient is the regressor, and on the
//! closed-form free vibration of two inertias coupled by the shaft, least squares on the
//! regressor recovers K, B and the encoder-offset torque exactly (the measured torque is `−J_r·x''`
//! from the solution, not from Eq. 6.1).
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use nalgebra::{DMatrix, DVector};
use physid_core::{GradientEngine, ParamModel};
use physid_models::shaft::{Shaft, INPUTS};

#[test]
fn gradient_is_the_regressor() {
    for offset in [false, true] {
        let m = Shaft::new(offset);
        assert_eq!(m.input_names(), INPUTS);
        let p = if offset {
            vec![1340.0, 0.9, -2.5]
        } else {
            vec![1340.0, 0.9]
        };
        let free: Vec<usize> = (0..p.len()).collect();
        let mut engine = GradientEngine::new(p.len());
        let mut grad = vec![0.0; p.len()];
        let mut phi = vec![0.0; p.len()];
        let u = [12.345, 12.3, 160.0, 158.5];
        let y = engine.value_and_gradient(&m, &u, &p, &free, &mut grad);
        m.regressor(&u, &mut phi);
        assert_eq!(grad, phi);
        let lin: f64 = phi.iter().zip(&p).map(|(a, b)| a * b).sum();
        assert!((y - lin).abs() < 1e-12 * y.abs());
        assert!((phi[0] - 0.045).abs() < 1e-12 && phi[1] == 1.5);
    }
}

/// Two inertias J1, J2 coupled by K, B and otherwise free: the twist x = θ_dy − θ_en obeys
/// `J_r·x'' + B·x' + K·x = 0`, `J_r = J1·J2/(J1 + J2)` — solved in closed form (underdamped).
/// Both shafts also spin at a common mean speed; the encoders disagree by a zero offset.
#[test]
fn least_squares_on_free_vibration_recovers_k_b_and_offset() {
    let (k, b, j1, j2): (f64, f64, f64, f64) = (1340.0, 0.9, 0.25, 0.08);
    let jr = j1 * j2 / (j1 + j2);
    let wn = (k / jr).sqrt();
    let zeta = b / (2.0 * (k * jr).sqrt());
    let wd = wn * (1.0 - zeta * zeta).sqrt();
    let (x0, v0, theta_off, w_mean) = (0.02, 0.0, 0.013, 157.0);
    let (c1, c2) = (x0, (v0 + zeta * wn * x0) / wd);
    let m = Shaft::new(true);
    let n = 2000;
    let mut a = DMatrix::zeros(n, 3);
    let mut y = DVector::zeros(n);
    let mut phi = [0.0; 3];
    for i in 0..n {
        let t = i as f64 * 1e-4;
        let e = (-zeta * wn * t).exp();
        let x = e * (c1 * (wd * t).cos() + c2 * (wd * t).sin());
        let osc = e * wd * (-c1 * (wd * t).sin() + c2 * (wd * t).cos());
        let v = -zeta * wn * x + osc;
        let acc = -zeta * wn * v - zeta * wn * osc - wd * wd * x;
        // The engine side; the dynamometer leads by the twist; the encoders add the offset.
        let theta_en = w_mean * t;
        let u = [theta_en + x + theta_off, theta_en, w_mean + v, w_mean];
        m.regressor(&u, &mut phi);
        for j in 0..3 {
            a[(i, j)] = phi[j];
        }
        // The transducer measures the torque that decelerates the twist: τ = −J_r·x''.
        y[i] = -jr * acc;
    }
    let est = a.svd(true, true).solve(&y, 1e-14).unwrap();
    assert!((est[0] - k).abs() < 1e-8 * k, "K {}", est[0]);
    assert!((est[1] - b).abs() < 1e-8 * b, "B {}", est[1]);
    assert!(
        (est[2] + k * theta_off).abs() < 1e-8 * k * theta_off,
        "tau0 {} vs {}",
        est[2],
        -k * theta_off
    );
}
