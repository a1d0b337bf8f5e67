//! A run whose solution leaves the physical domain ends with an error that says when and what
//! — never a panic, never a recording of NaN.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_sim::cell::{Inputs, TestCell};
use physid_sim::control::Demand;
use physid_sim::params::CellParams;
use physid_sim::run::{simulate, RunOptions, SimError};
use physid_sim::scenario::named;
use std::f64::consts::PI;

/// A burn of 2 kJ a cycle (ten times a real one) in the T1 scenario: both solvers stop with
/// `Diverged`, its time on the recording's clock — in the settling second, before the
/// recording starts, said so.
#[test]
fn a_diverging_run_is_an_error_with_its_time() {
    let scenario = named("torque-steady").unwrap();
    for order in [2.0, 4.0] {
        let mut params = CellParams {
            order,
            ..CellParams::default()
        };
        params.engine.burn_q = 2000.0;
        let opts = RunOptions {
            params,
            duration: Some(0.5),
            ..Default::default()
        };
        let e = simulate(&scenario, &opts, |_| {}).unwrap_err();
        let SimError::Diverged { t, .. } = &e else {
            panic!("order {order}: {e}")
        };
        assert!(
            (-scenario.settle..-scenario.settle + 0.1).contains(t),
            "order {order}: t = {t}"
        );
        let message = e.to_string();
        assert!(message.contains("before the recording starts"), "{message}");
    }
}

/// The cell stepped directly from firing TDC with ambient air in the cylinder and a 200 J burn
/// (the clearance volume's few tens of mg heated by thousands of kelvin): the state leaves the
/// physical domain and the samples say so with non-finite values, the drive's limits never
/// panic on them (RK4, whose stages carry a NaN into the machine's currents within the step).
#[test]
fn the_drive_carries_a_diverged_state_without_panicking() {
    let w = 1000.0 * PI / 30.0;
    let mut params = CellParams {
        order: 4.0,
        ..CellParams::default()
    };
    params.engine.burn_q = 200.0;
    let mut cell = TestCell::new(params, w, 0.0).unwrap();
    let inputs = Inputs {
        demand: Demand::Speed(w),
        throttle_deg: 90.0,
    };
    let mut finite = true;
    for _ in 0..3600 {
        let s = cell.step(&inputs);
        finite &= s.gas.p.iter().all(|p| p.is_finite()) && s.omega_en.is_finite();
    }
    assert!(
        !finite,
        "the cold start with a 200 J burn no longer diverges: update this test"
    );
}
