//! `update` never touches the heap: a counting global allocator sees no allocation across
//! 10 000 updates of every method, with all parameters free and with a fixed subset, with and
//! without the wind-up guard, for the non-linear filters (an expression model and the
//! cyclic-torque model with its own gradient), and for the detectors.
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use physid_core::ParamSet;
use physid_estim::{
    CovSpec, Cusum, EstimatorConfig, GuardAction, LinearEstimator, NlConfig, NlMethod,
    NonlinearEstimator, RelativeErrorDetector, SigmaPoints, WindupGuard,
};
use physid_testkit::{allocations as allocs, Counting};

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn updates_do_not_allocate() {
    let (rows, y, _) = common::regression(10_000, 4, 0.1, 1);
    let params = ParamSet::zeros(["a", "b", "c", "d"]).unwrap();
    let subset = params.free(&["a", "c", "d"]).unwrap();
    for (free, p) in [(params.all_free(), 4), (subset, 3)] {
        for method in common::all_methods(p) {
            for guard in [
                None,
                Some(WindupGuard {
                    max_trace: 10.0,
                    action: GuardAction::Scale,
                }),
            ] {
                let cfg = EstimatorConfig {
                    method: method.clone(),
                    p0: CovSpec::Scaled(1000.0),
                    guard,
                };
                let built = allocs();
                let mut est = LinearEstimator::new(&cfg, &params, &free).unwrap();
                // the counter is live: construction allocates
                assert!(allocs() > built);
                let mut se = vec![0.0; p];
                let before = allocs();
                for (r, &yt) in rows.iter().zip(&y) {
                    est.update(r, yt).unwrap();
                    est.std_errors_into(&mut se).unwrap_or(());
                }
                let after = allocs();
                assert_eq!(
                    after - before,
                    0,
                    "{} allocated {} times",
                    method.name(),
                    after - before
                );
            }
        }
    }
    // EKF and UKF through an expression model (exact gradients via dual numbers).
    for method in [
        NlMethod::Ekf,
        NlMethod::Ukf(SigmaPoints::default()),
        NlMethod::Srukf(SigmaPoints::default()),
    ] {
        let model =
            physid_expr::ExprModel::parse("A*exp(-B*x) + C*x^2 + sin(D)*y", &["A", "B", "C", "D"])
                .unwrap();
        let params = ParamSet::new(["A", "B", "C", "D"], vec![1.0, 0.5, 0.2, 0.3]).unwrap();
        let cfg = NlConfig {
            r1: CovSpec::Scaled(1e-6),
            ..NlConfig::new(method)
        };
        let mut est = NonlinearEstimator::new(model, &params, &params.all_free(), &cfg).unwrap();
        // The formula's tape (the UKF's sigma points at once) sizes its registers on a
        // thread's first evaluation, once: counted from the second update on.
        est.update(&[rows[0][1], rows[0][2]], y[0]).unwrap();
        let before = allocs();
        for (r, &yt) in rows.iter().zip(&y).skip(1) {
            est.update(&[r[1], r[2]], yt).unwrap();
        }
        assert_eq!(allocs() - before, 0, "{} allocated", method.name());
    }
    // The cyclic-torque model computes its own gradient (forward mode for the geometry, the
    // friction cubic's regressors for c1 … c10): EKF on a mix of both kinds, every sample.
    {
        use physid_core::ParamModel;
        use physid_models::cyclic_torque::{CyclicTorque, ILLUSTRATIVE, PARAMS};
        // Data from the model at the illustrative values; the filter runs 5 % off them (the
        // fixed parameters too).
        let model = CyclicTorque::default();
        let start: Vec<f64> = ILLUSTRATIVE.iter().map(|v| v * 1.05).collect();
        let params = ParamSet::new(PARAMS, start).unwrap();
        let free = params.free(&["M_rec", "L", "c1", "c2", "c6"]).unwrap();
        let cfg = NlConfig {
            r1: CovSpec::Scaled(1e-9),
            ..NlConfig::new(NlMethod::Ekf)
        };
        let mut est = NonlinearEstimator::new(model.clone(), &params, &free, &cfg).unwrap();
        let before = allocs();
        for k in 0..7200 {
            let th = (k as f64).to_radians();
            let u = [
                th,
                104.7,
                2.0,
                1e5 + 1.5e6 * (-(th % 12.566 - 0.1).powi(2) * 8.0).exp(),
                1e5,
                60.0,
            ];
            let y = model.eval::<f64>(&u, &ILLUSTRATIVE);
            est.update(&u, y).unwrap();
        }
        assert_eq!(allocs() - before, 0, "EKF on the cyclic torque allocated");
    }
    let mut det = RelativeErrorDetector::new(
        vec!["K".into(), "B".into()],
        vec![1.0, 1.0],
        vec![0.5, 0.5],
        3,
    )
    .unwrap();
    let mut cusum = Cusum::new(2);
    let before = allocs();
    for i in 0..10_000 {
        det.update(&[1.0 + 1e-5 * i as f64, 1.0]).unwrap();
        cusum.push((i as f64).sin());
    }
    assert_eq!(allocs() - before, 0);
}
