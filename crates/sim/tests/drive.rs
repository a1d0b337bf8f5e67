//! The dynamometer and the driveline (issue 7, verifications 3, 4, 5): the dq machine against
//! its per-phase equivalent circuit, field-oriented control, and the two-mass shaft against
//! its analytic free response.
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_sim::cell::{Inputs, TestCell};
use physid_sim::control::{nominal_flux, Demand};
use physid_sim::machine::{equivalent_circuit, Machine};
use physid_sim::params::CellParams;
use physid_sim::studies::dyno_curve;
use std::f64::consts::PI;

/// Verification 3: at 400 V, 50 Hz, over a slip sweep, the dq model — its steady state, and
/// its ODE integrated at fixed speed until settled — gives the equivalent circuit's torque and
/// current to 0.5 %; the curve's peak torque and slip likewise.
#[test]
fn dq_model_equals_the_equivalent_circuit() {
    let p = CellParams::default();
    let m = Machine::new(&p.dyno);
    let n_sync = 1500.0;
    let speeds: Vec<f64> = (0..=300)
        .map(|k| n_sync * (1.0 - k as f64 * 0.002))
        .collect();
    let curve = dyno_curve(&p, 400.0, 50.0, &speeds).unwrap();
    let (mut peak_dq, mut peak_ec) = ((0.0, 0.0), (0.0, 0.0));
    for pt in &curve {
        let ec = equivalent_circuit(&p.dyno, 400.0, 50.0, pt.slip.max(1e-9));
        if pt.slip > 0.0 {
            assert!(
                (pt.torque_nm / ec.torque_nm - 1.0).abs() < 5e-3,
                "slip {}",
                pt.slip
            );
            assert!((pt.current_a_rms / ec.current_a_rms - 1.0).abs() < 5e-3);
            assert!((pt.power_factor - ec.power_factor).abs() < 5e-3);
        }
        if pt.torque_nm > peak_dq.0 {
            peak_dq = (pt.torque_nm, pt.slip);
        }
        if ec.torque_nm > peak_ec.0 {
            peak_ec = (ec.torque_nm, ec.slip);
        }
    }
    assert!((peak_dq.0 / peak_ec.0 - 1.0).abs() < 5e-3);
    assert!((peak_dq.1 - peak_ec.1).abs() < 2e-3);
    // Nominal point (Table 4.2: 1465 rpm, 143 N·m, 41.7 A): the parameters give about that.
    let nom = equivalent_circuit(&p.dyno, 400.0, 50.0, 35.0 / 1500.0);
    assert!(
        (nom.torque_nm / 143.0 - 1.0).abs() < 0.15,
        "{}",
        nom.torque_nm
    );
    assert!(
        (nom.current_a_rms / 41.7 - 1.0).abs() < 0.15,
        "{}",
        nom.current_a_rms
    );
    // The ODE at fixed rotor speed and fixed voltage settles to the circuit's torque.
    for slip in [0.01, 0.023, 0.05] {
        let w = 2.0 * PI * 50.0;
        let w_r = (1.0 - slip) * w;
        let mut l = [0.0; 4];
        let dt = 1e-5;
        for _ in 0..300_000 {
            // RK4 at a fixed rotor speed.
            let f = |l: &[f64; 4]| m.derivatives(l, [400.0, 0.0], w, w_r);
            let add = |a: &[f64; 4], k: &[f64; 4], h: f64| {
                let mut y = *a;
                for i in 0..4 {
                    y[i] += h * k[i];
                }
                y
            };
            let k1 = f(&l);
            let k2 = f(&add(&l, &k1, dt / 2.0));
            let k3 = f(&add(&l, &k2, dt / 2.0));
            let k4 = f(&add(&l, &k3, dt));
            for i in 0..4 {
                l[i] += dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
            }
        }
        let ec = equivalent_circuit(&p.dyno, 400.0, 50.0, slip);
        assert!(
            (m.torque(&l) / ec.torque_nm - 1.0).abs() < 5e-3,
            "slip {slip}: {} vs {}",
            m.torque(&l),
            ec.torque_nm
        );
    }
}

fn inertia_cell(torque_mode: bool) -> (TestCell, f64) {
    let mut p = CellParams::default();
    p.engine.active = 0.0;
    if torque_mode {
        p.dyno.torque_mode = 1.0;
    }
    let w = 1000.0 * PI / 30.0;
    (TestCell::new(p, w, 0.0).unwrap(), w)
}

/// Verification 4: after a speed step the speed settles without steady error, the rotor flux
/// stays at its reference, and the torque is (p/2)(L_m/L_r)·λ_rd·i_sq (Eq. 3.61) to 1 %.
#[test]
fn field_oriented_speed_control() {
    let (mut cell, w0) = inertia_cell(false);
    let w1 = w0 * 1.2;
    let input = Inputs {
        demand: Demand::Speed(w1),
        throttle_deg: 90.0,
    };
    let mut last = cell.step(&input);
    while cell.time() < 6.0 {
        last = cell.step(&input);
    }
    assert!(
        (last.omega_dy / w1 - 1.0).abs() < 1e-4,
        "{} vs {w1}",
        last.omega_dy
    );
    assert!((last.omega_en / w1 - 1.0).abs() < 1e-4);
    let p = CellParams::default();
    let m = Machine::new(&p.dyno);
    let x = cell.state();
    let flux_ref = nominal_flux(&p.dyno, &m);
    let flux = (x[14] * x[14] + x[15] * x[15]).sqrt();
    assert!((flux / flux_ref - 1.0).abs() < 0.01, "{flux} vs {flux_ref}");
    // During the acceleration: torque against the field-oriented formula.
    let (mut cell, _) = inertia_cell(false);
    let mut worst: f64 = 0.0;
    while cell.time() < 1.0 {
        let s = cell.step(&input);
        let x = cell.state();
        let i = m.currents(&[x[12], x[13], x[14], x[15]]);
        let lrd = (x[14] * x[14] + x[15] * x[15]).sqrt();
        let predicted = m.pole_pairs * m.lm / m.lr * lrd * i[1];
        if s.torque_dy.abs() > 20.0 {
            worst = worst.max((m.torque(&[x[12], x[13], x[14], x[15]]) / predicted - 1.0).abs());
        }
    }
    assert!(worst < 0.01, "{worst}");
}

/// Verification 5: with the engine a pure inertia and the machine unexcited (no torque), a
/// twist rings at the analytic two-mass frequency and decays at the analytic rate (1 %). (With
/// the drive energised, its current loops — bandwidth ≈ 29 Hz, near the 34 Hz shaft mode —
/// take part in the oscillation: that is the cell's behaviour, not the shaft's.)
#[test]
fn two_mass_shaft_free_response() {
    for order in [4.0, 2.0] {
        two_mass_free_response(order);
    }
}

fn two_mass_free_response(order: f64) {
    let mut p = CellParams::default();
    p.engine.active = 0.0;
    p.dyno.flux_ref = 1e-9;
    p.dyno.torque_mode = 1.0;
    p.order = order;
    let w = 1000.0 * PI / 30.0;
    let mut cell = TestCell::new(p.clone(), w, 0.0).unwrap();
    let (k, b, j1, j2) = (p.shaft.k, p.shaft.b, p.dyno.inertia, p.engine.inertia);
    let jr = j1 * j2 / (j1 + j2);
    let wn = (k / jr).sqrt();
    let zeta = b / (2.0 * (k * jr).sqrt());
    let wd = wn * (1.0 - zeta * zeta).sqrt();
    cell.twist(0.01);
    let free = Inputs {
        demand: Demand::Torque(0.0),
        throttle_deg: 0.0,
    };
    let mut twist = Vec::new();
    let mut t = Vec::new();
    while cell.time() < 0.6 {
        let s = cell.step(&free);
        assert!(s.torque_dy.abs() < 1e-6, "{}", s.torque_dy);
        twist.push(s.theta_dy - s.theta_en);
        t.push(s.t);
    }
    // No torque anywhere: the twist oscillates about zero.
    let z = twist;
    let mut crossings = Vec::new();
    for i in 1..z.len() {
        if z[i - 1] < 0.0 && z[i] >= 0.0 {
            let f = -z[i - 1] / (z[i] - z[i - 1]);
            crossings.push(t[i - 1] + f * (t[i] - t[i - 1]));
        }
    }
    let n = crossings.len() - 1;
    let period = (crossings[n] - crossings[1]) / (n - 1) as f64;
    let wd_sim = 2.0 * PI / period;
    assert!((wd_sim / wd - 1.0).abs() < 0.01, "{wd_sim} vs {wd}");
    // Decay: successive positive peaks shrink by exp(−ζω_n·T).
    let mut peaks = Vec::new();
    for i in 1..z.len() - 1 {
        if z[i] > z[i - 1] && z[i] >= z[i + 1] && z[i] > 0.0 {
            peaks.push((t[i], z[i]));
        }
    }
    let (a, bpk) = (peaks[1], peaks[peaks.len() - 2]);
    let rate = (a.1 / bpk.1).ln() / (bpk.0 - a.0);
    assert!(
        (rate / (zeta * wn) - 1.0).abs() < 0.01,
        "{rate} vs {}",
        zeta * wn
    );
}

/// Verification 5 (steady state): with the engine running at constant speed the mean twist is
/// the mean shaft torque over K.
#[test]
fn steady_twist_is_torque_over_stiffness() {
    let p = CellParams::default();
    let w = 1000.0 * PI / 30.0;
    let mut cell = TestCell::new(p.clone(), w, 0.0).unwrap();
    let input = Inputs {
        demand: Demand::Speed(w),
        throttle_deg: 90.0,
    };
    while cell.time() < 2.0 {
        cell.step(&input);
    }
    // Time averages (samples are one crank degree apart, not equally spaced in time).
    let (mut tw, mut tq, mut n) = (0.0, 0.0, 0.0);
    let start = cell.theta_en();
    while cell.theta_en() < start + 20.0 * 4.0 * PI {
        let t0 = cell.time();
        let s = cell.step(&input);
        let dt = cell.time() - t0;
        tw += (s.theta_dy - s.theta_en) * dt;
        tq += s.torque_shaft * dt;
        n += dt;
    }
    let (tw, tq) = (tw / n, tq / n);
    assert!(tq > 0.5, "the dynamometer drives the engine: {tq}");
    assert!(
        (tw - tq / p.shaft.k).abs() < 0.005 * tw.abs(),
        "{tw} vs {}",
        tq / p.shaft.k
    );
}

/// The integrators' energy error on the undamped shaft mode at one-degree steps (1000 rpm), the
/// mode's own energy `½·K·Δθ² + ½·J_r·Δω²` (the rigid rotation, far larger, is left out): 34
/// periods of the ≈ 34 Hz mode, ≈ 176 steps per period. Against each method's stability
/// function on the imaginary axis, `|R(iy)|²` with `y = ω_n·dt` (a closed form, independent of
/// the code): RK4 `1 − y⁶/72 + y⁸/576`, Heun's rule (the fast solver's driveline) `1 + y⁴/4`.
/// Stated in docs/simulate.md and BENCHMARKS.md.
#[test]
fn undamped_shaft_energy_error() {
    for order in [4.0, 2.0] {
        let mut p = CellParams::default();
        p.engine.active = 0.0;
        p.dyno.flux_ref = 1e-9;
        p.dyno.torque_mode = 1.0;
        p.shaft.b = 0.0;
        p.order = order;
        let mut cell = TestCell::new(p.clone(), 1000.0 * PI / 30.0, 0.0).unwrap();
        cell.twist(0.01);
        let free = Inputs {
            demand: Demand::Torque(0.0),
            throttle_deg: 0.0,
        };
        let (j1, j2) = (p.dyno.inertia, p.engine.inertia);
        let jr = j1 * j2 / (j1 + j2);
        let wn = (p.shaft.k / jr).sqrt();
        let energy = |s: &physid_sim::cell::Sample| {
            let dw = s.omega_dy - s.omega_en;
            0.5 * p.shaft.k * (s.theta_dy - s.theta_en).powi(2) + 0.5 * jr * dw * dw
        };
        let s0 = cell.step(&free);
        let (e0, mut t_prev) = (energy(&s0), s0.t);
        // ln of the product of |R(i·ω_n·dt)|² over the steps taken.
        let (mut ln_gain, mut e1) = (0.0, e0);
        while cell.time() < 1.0 {
            let s = cell.step(&free);
            let y = wn * (s.t - t_prev);
            let r2: f64 = if order == 4.0 {
                1.0 - y.powi(6) / 72.0 + y.powi(8) / 576.0
            } else {
                1.0 + y.powi(4) / 4.0
            };
            ln_gain += r2.ln();
            (e1, t_prev) = (energy(&s), s.t);
        }
        let drift = e1 / e0 - 1.0;
        let expect = ln_gain.exp() - 1.0;
        println!("order {order}: mode energy drift over 34 periods {drift:.3e} (closed form {expect:.3e})");
        // RK4 loses, Heun's rule gains, each as its stability function says (to 5 %).
        assert!(
            drift.signum() == expect.signum() && (drift / expect - 1.0).abs() < 0.05,
            "order {order}: {drift:e} vs {expect:e}"
        );
    }
}
