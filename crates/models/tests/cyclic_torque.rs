//! The cyclic-torque model: against the virtual-work forms, exact gradients against central
//! differences, and its friction cubic fitted to the mean-value model.
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_core::{GradientEngine, ParamModel};
use physid_models::cyclic_torque::{fmep_cubic, CyclicTorque, ILLUSTRATIVE};
use physid_models::friction::thesis_preset;
use physid_models::friction_fit::{fit_cubic, fit_friction_cubic};
use physid_models::kinematics::Crank;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn nominal() -> [f64; 15] {
    ILLUSTRATIVE
}

/// Inputs `(θ, ω, α, p_cyl, p_crank, T_oil)` over two revolutions and the engine's range.
fn random_inputs(rng: &mut ChaCha8Rng) -> [f64; 6] {
    [
        rng.random_range(0.0..4.0 * std::f64::consts::PI),
        rng.random_range(50.0..600.0),
        rng.random_range(-500.0..500.0),
        rng.random_range(2e4..3e6),
        1.0e5,
        rng.random_range(20.0..90.0),
    ]
}

/// At δ = 0 the model equals the torque written with the virtual-work forms:
/// (p − p_c)·A_p·s' − M·s'·(s''ω² + s'α) − fmep·1e3·A_p·r/(2π).
#[test]
fn equals_the_virtual_work_torque() {
    let m = CyclicTorque::default();
    let p = nominal();
    let crank = Crank {
        r: p[3],
        l: p[2],
        delta: 0.0,
        bore: p[1],
        kappa: 9.5,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    for _ in 0..500 {
        let th = rng.random_range(0.0..4.0 * std::f64::consts::PI);
        let (w, a) = (
            rng.random_range(50.0..600.0),
            rng.random_range(-500.0..500.0),
        );
        let (pc, pk, t) = (
            rng.random_range(2e4..3e6),
            1.0e5,
            rng.random_range(20.0..90.0),
        );
        let n = w * 30.0 / std::f64::consts::PI;
        let fmep = fmep_cubic(&p[5..], n, t);
        let ap = crank.piston_area();
        let expect = (pc - pk) * ap * crank.ds(th)
            - p[0] * crank.ds(th) * (crank.dds(th) * w * w + crank.ds(th) * a)
            - fmep * 1e3 * ap * p[3] / (2.0 * std::f64::consts::PI);
        let got = m.eval::<f64>(&[th, w, a, pc, pk, t], &p);
        assert!(
            (got - expect).abs() <= 1e-10 * expect.abs().max(1.0),
            "{got} vs {expect}"
        );
        // The torque of a pascal of cylinder pressure: A_p·s'(θ).
        let arm = ap * crank.ds(th);
        let got = m.pressure_arm(th, &p);
        assert!(
            (got - arm).abs() <= 1e-12 * arm.abs().max(1e-6),
            "{got} vs {arm}"
        );
    }
}

/// Issue 3 verification 1 for this built-in model: the exact gradient of all 15 parameters
/// (with an offset δ ≠ 0) equals central differences, with the witness's round-off allowed for.
#[test]
fn gradient_equals_central_differences() {
    let m = CyclicTorque::default();
    let mut p = nominal();
    p[4] = 0.002;
    let free: Vec<usize> = (0..15).collect();
    let mut engine = GradientEngine::new(15);
    let mut g = [0.0; 15];
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    for _ in 0..200 {
        let u = random_inputs(&mut rng);
        let v = engine.value_and_gradient(&m, &u, &p, &free, &mut g);
        for j in 0..15 {
            let h = 1e-6 * p[j].abs().max(1e-6);
            let (mut a, mut b) = (p, p);
            a[j] += h;
            b[j] -= h;
            let fd = (m.eval::<f64>(&u, &a) - m.eval::<f64>(&u, &b)) / (2.0 * h);
            let tol = 1e-6 * fd.abs().max(1.0) + 10.0 * f64::EPSILON * v.abs().max(1.0) / h;
            assert!(
                (g[j] - fd).abs() <= tol,
                "∂τ/∂{}: {} vs {fd}",
                m.param_names()[j],
                g[j]
            );
        }
    }
}

/// The exact gradient equals sympy's symbolic derivatives of Eq. 8.2 written independently
/// with the thesis's closed forms (`golden/gen_cyclic_torque_gradient.py`, 30 digits), δ ≠ 0.
#[test]
fn gradient_equals_sympy() {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/golden/cyclic_torque_gradient.json"
    ))
    .unwrap();
    let golden: serde_json::Value = serde_json::from_str(&text).unwrap();
    let floats = |v: &serde_json::Value| -> Vec<f64> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let m = CyclicTorque::default();
    let p = floats(&golden["theta"]);
    let free: Vec<usize> = (0..15).collect();
    let mut engine = GradientEngine::new(15);
    let mut g = [0.0; 15];
    let mut worst = 0.0_f64;
    for point in golden["points"].as_array().unwrap() {
        let u = floats(&point["inputs"]);
        let want = floats(&point["gradient"]);
        let v = engine.value_and_gradient(&m, &u, &p, &free, &mut g);
        let value = point["value"].as_f64().unwrap();
        assert!((v - value).abs() <= 1e-12 * value.abs(), "{v} vs {value}");
        for j in 0..15 {
            let err = (g[j] - want[j]).abs() / want[j].abs();
            worst = worst.max(err);
            assert!(
                err <= 1e-12,
                "∂τ/∂{}: {} vs {}",
                m.param_names()[j],
                g[j],
                want[j]
            );
        }
    }
    println!("largest relative difference from sympy: {worst:.1e}");
}

/// The affine shortcut for `c1 … c10` (the model's own `value_and_gradient_with`) equals plain
/// forward mode through `eval` — value and every partial — for any subset of the parameters
/// in any order, including none and a list with repeats.
#[test]
fn affine_shortcut_equals_forward_mode() {
    use rand::seq::SliceRandom;
    let m = CyclicTorque::default();
    let mut engine = GradientEngine::new(15);
    let mut rng = ChaCha8Rng::seed_from_u64(10);
    for trial in 0..400 {
        let mut p = nominal();
        for v in &mut p {
            *v *= rng.random_range(0.8..1.2);
        }
        p[4] = rng.random_range(-0.003..0.003);
        let u = random_inputs(&mut rng);
        let mut free: Vec<usize> = (0..15).collect();
        free.shuffle(&mut rng);
        free.truncate(rng.random_range(0..=15));
        if trial % 50 == 0 {
            free = vec![0, 1, 2, 3, 4, 3, 7]; // more than five nonlinear entries
        }
        let mut g = vec![f64::NAN; free.len()];
        let v = engine.value_and_gradient(&m, &u, &p, &free, &mut g);
        let mut want = vec![0.0; free.len()];
        let vf = engine.forward(&p, &free, &mut want, |d| m.eval(&u, d));
        assert!((v - vf).abs() <= 1e-14 * vf.abs(), "{v} vs {vf}");
        for ((j, a), b) in free.iter().zip(&g).zip(&want) {
            assert!(
                (a - b).abs() <= 1e-13 * b.abs().max(1e-300),
                "∂τ/∂{}: {a} vs {b}",
                m.param_names()[*j]
            );
        }
    }
}

/// The fit recovers a known cubic exactly, and fits the thesis's mean-value friction model
/// (mechanical, at ambient intake pressure) over 750–5000 rpm, 20–90 °C.
#[test]
fn friction_cubic_fit() {
    let truth = [60.0, 0.02, 0.4, 1e-6, 1e-4, 2e-3, 1e-10, 1e-8, 1e-6, 1e-5];
    let ns: Vec<f64> = (0..12).map(|k| 750.0 + 400.0 * k as f64).collect();
    let ts: Vec<f64> = (0..8).map(|k| 20.0 + 10.0 * k as f64).collect();
    let fit = fit_cubic(&ns, &ts, |n, t| fmep_cubic(&truth, n, t)).unwrap();
    for (c, t) in fit.coefficients.iter().zip(truth) {
        assert!((c - t).abs() <= 1e-7 * t.abs(), "{c} vs {t}");
    }
    let (d, st) = thesis_preset();
    let fit = fit_friction_cubic(&d, &st, 100.1, 100.1, &ns, &ts).unwrap();
    println!(
        "friction cubic: rms {:.3} kPa, max relative {:.4}",
        fit.rms_kpa, fit.max_relative
    );
    assert!(fit.max_relative < 0.02);
    assert!(fit_cubic(&ns[..3], &ts, |_, _| 0.0).is_err());
}

/// The sigma points' batch (`eval_many`: the angle's sine and cosine and the friction
/// regressors once) equals `eval` of each parameter vector, bit for bit.
#[test]
fn eval_many_is_eval_of_each() {
    let m = CyclicTorque::default();
    let mut rng = ChaCha8Rng::seed_from_u64(47);
    for _ in 0..200 {
        let u = random_inputs(&mut rng);
        let points: Vec<[f64; 15]> = (0..21)
            .map(|_| nominal().map(|v| v * (1.0 + 0.05 * rng.random_range(-1.0..1.0))))
            .collect();
        let flat: Vec<f64> = points.iter().flatten().copied().collect();
        let mut out = [0.0; 21];
        m.eval_many(&u, &flat, &mut out);
        for (o, p) in out.iter().zip(&points) {
            assert_eq!(o.to_bits(), m.eval::<f64>(&u, p).to_bits());
        }
    }
}
