//! The cylinder's dense output between the solver's steps (`run/dense.rs`): where the output
//! grid falls between steps, the cylinder pressure, its temperature and the torques that follow
//! from it are as close to the converged solution as at the steps themselves — against RK4 at
//! 0.05° (whose steps fall on every point), and against the linear interpolation of the same
//! run's own step values.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_core::Recording;
use physid_sim::params::{CellParams, SensorParams};
use physid_sim::run::{simulate, OutputBasis, RunOptions};
use physid_sim::scenario::{named, Scenario};

/// The channels compared: those the dense output gives (the sensors ideal).
const DENSE: [&str; 6] = [
    "p_cyl",
    "true_T_cyl",
    "true_torque_indicated",
    "torque_engine",
    "true_torque_reciprocating",
    "alpha_en",
];

/// `scenario` recorded for 0.1 s after 0.3 s of settling, on a crank basis of `out_deg`, the
/// solver of `order` at `step_deg`, fired with `burn_q` [J] (the scenario's own if 0).
fn run(scenario: &str, order: f64, step_deg: f64, out_deg: f64, burn_q: f64) -> Recording {
    let scenario = Scenario {
        settle: 0.3,
        ..named(scenario).unwrap()
    };
    let mut params = CellParams {
        order,
        step_deg,
        ..CellParams::default()
    };
    params.sensors.p_cyl = SensorParams::IDEAL;
    params.sensors.torque_engine = SensorParams::IDEAL;
    if burn_q > 0.0 {
        params.engine.burn_q = burn_q;
    }
    let opts = RunOptions {
        params,
        duration: Some(0.1),
        basis: OutputBasis::Crank(out_deg),
        ..Default::default()
    };
    simulate(&scenario, &opts, |_| {}).unwrap()
}

/// Per channel of [`DENSE`], the largest error against `fine` as a fraction of the channel's
/// largest magnitude there: `[on the steps, between them, between them carried linearly from
/// the steps]`. Every `per`-th sample of `coarse` is on a step; between two such, the others.
fn errors(fine: &Recording, coarse: &Recording, per: usize) -> Vec<[f64; 3]> {
    DENSE
        .iter()
        .map(|name| {
            let (f, c) = (fine.values(name).unwrap(), coarse.values(name).unwrap());
            let n = f.len().min(c.len());
            let scale = f[..n].iter().fold(0.0f64, |a, x| a.max(x.abs()));
            let mut e = [0.0f64; 3];
            for k in 0..n {
                let on = k % per == 0;
                e[usize::from(!on)] = e[usize::from(!on)].max((c[k] - f[k]).abs());
                if !on && k / per * per + per < n {
                    let (a, b) = (k / per * per, k / per * per + per);
                    let w = (k - a) as f64 / per as f64;
                    let linear = c[a] + w * (c[b] - c[a]);
                    e[2] = e[2].max((linear - f[k]).abs());
                }
            }
            let e = e.map(|x| x / scale);
            println!(
                "{name:<26} on the steps {:.2e}, between {:.2e} (linear {:.2e})",
                e[0], e[1], e[2]
            );
            e
        })
        .collect()
}

/// At the default one-degree step with a half-degree grid, and at two-degree steps with a
/// one-degree grid, motored and fired (100 J at 1000 rpm; 250 J at 1500 rpm): between the
/// steps within 1.3× the error on them (measured 0.7–1.1×); carried linearly, the pressure
/// between steps is 2.2–9× worse.
#[test]
fn between_the_steps_as_close_as_on_them() {
    for (scenario, burn_q) in [
        ("torque-steady", 0.0),
        ("torque-steady", 100.0),
        ("fired-steady", 0.0),
    ] {
        for (step, out) in [(1.0, 0.5), (2.0, 1.0)] {
            println!("{scenario}, burn {burn_q} J, {step}° steps, {out}° grid:");
            let fine = run(scenario, 4.0, 0.05, out, burn_q);
            let coarse = run(scenario, 2.0, step, out, burn_q);
            let e = errors(&fine, &coarse, (step / out) as usize);
            for (name, [on, between, _]) in DENSE.iter().zip(&e) {
                assert!(
                    *between <= 1.3 * on.max(1e-5),
                    "{scenario}, {step}°: {name} between {between:.2e}, on {on:.2e}"
                );
            }
            let [_, between, linear] = e[0];
            assert!(linear > 2.0 * between, "{scenario}, {step}°: the pressure carried linearly {linear:.2e}, dense {between:.2e}");
        }
    }
}

/// The same on a time basis (24 kHz at 1000 rpm: four samples a degree, at every fraction of a
/// step), motored, at 1° and 2° steps: each sample against the converged solution at the same
/// engine angle (RK4 at 0.05° on a 0.05° grid, interpolated there; a time basis compares
/// angles, not the solvers' slightly different phases) — within 1.3× the error on the steps
/// on the crank basis.
#[test]
fn on_a_time_basis_as_close_as_on_the_steps() {
    let record = |order: f64, step_deg: f64, basis| {
        let scenario = Scenario {
            settle: 0.3,
            ..named("torque-steady").unwrap()
        };
        let mut params = CellParams {
            order,
            step_deg,
            ..CellParams::default()
        };
        params.sensors.p_cyl = SensorParams::IDEAL;
        let opts = RunOptions {
            params,
            duration: Some(0.25),
            basis,
            ..Default::default()
        };
        simulate(&scenario, &opts, |_| {}).unwrap()
    };
    let fine = record(4.0, 0.05, OutputBasis::Crank(0.05));
    let (fp, fth) = (
        fine.values("p_cyl").unwrap(),
        fine.values("theta_en").unwrap(),
    );
    let peak = fp.iter().fold(0.0f64, |a, x| a.max(*x));
    for step in [1.0, 2.0] {
        let on_steps = {
            let coarse = record(2.0, step, OutputBasis::Crank(step));
            let c = coarse.values("p_cyl").unwrap();
            let per = (step / 0.05).round() as usize;
            (0..c.len().min(fp.len() / per))
                .map(|k| (c[k] - fp[k * per]).abs())
                .fold(0.0f64, f64::max)
                / peak
        };
        let timed = record(2.0, step, OutputBasis::Time(24_000.0));
        let (cp, cth) = (
            timed.values("p_cyl").unwrap(),
            timed.values("theta_en").unwrap(),
        );
        let (mut e, mut n) = (0.0f64, 0);
        for (&p, &th) in cp.iter().zip(cth) {
            let i = fth.partition_point(|&x| x <= th);
            if i == 0 || i >= fth.len() {
                continue;
            }
            let w = (th - fth[i - 1]) / (fth[i] - fth[i - 1]);
            e = e.max((p - (fp[i - 1] + w * (fp[i] - fp[i - 1]))).abs() / peak);
            n += 1;
        }
        println!("{step}° steps, 24 kHz: p_cyl within {e:.2e} of the peak over {n} samples (on the steps {on_steps:.2e})");
        assert!(n > 2000, "{n} samples compared");
        assert!(
            e <= 1.3 * on_steps,
            "{step}°: {e:.2e} against {on_steps:.2e} on the steps"
        );
    }
}
