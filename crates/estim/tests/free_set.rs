//! Changing the free set of a running estimator (`set_free`): after freezing, the estimator
//! continues exactly as a fresh one built on the remaining parameters with the kept covariance
//! block; a released parameter re-enters with the variance it had when frozen; misuse is
//! refused.
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use physid_core::ParamSet;
use physid_estim::{CovSpec, EstimatorConfig, LinearEstimator};

#[test]
fn freezing_equals_a_fresh_estimator_on_the_rest() {
    let (rows, y, _) = common::regression(600, 4, 0.1, 7);
    let params = ParamSet::zeros(["a", "b", "c", "d"]).unwrap();
    for method in common::all_methods(4) {
        let name = method.name();
        let config = EstimatorConfig {
            p0: CovSpec::Diagonal(vec![100.0, 200.0, 300.0, 400.0]),
            ..EstimatorConfig::new(method)
        };
        let mut est = LinearEstimator::new(&config, &params, &params.all_free()).unwrap();
        for (r, &yi) in rows[..300].iter().zip(&y) {
            est.update(r, yi).unwrap();
        }
        let before = est.estimate_full();
        let p = est.covariance();
        let keep = params.free(&["a", "c", "d"]).unwrap();
        est.set_free(&keep).unwrap();
        assert_eq!(est.free_names(), ["a", "c", "d"], "{name}");
        assert_eq!(
            est.estimate_full(),
            before,
            "{name}: freezing moves nothing"
        );
        // The fresh estimator: nominal = the current estimates, P0 = the kept block.
        let idx = [0usize, 2, 3];
        let block: Vec<Vec<f64>> = idx
            .iter()
            .map(|&i| idx.iter().map(|&j| p[(i, j)]).collect())
            .collect();
        let mut fresh_cfg = config.clone();
        fresh_cfg.p0 = CovSpec::Full(block);
        if let physid_estim::Method::Rlsvf { lambdas, .. } = &mut fresh_cfg.method {
            *lambdas = idx.iter().map(|&i| lambdas[i]).collect();
        }
        if let physid_estim::Method::Kalman { r1, .. } = &mut fresh_cfg.method {
            let m = r1.to_matrix(4, "R1").unwrap();
            *r1 = CovSpec::Full(
                idx.iter()
                    .map(|&i| idx.iter().map(|&j| m[(i, j)]).collect())
                    .collect(),
            );
        }
        // λ(t) carries on: the fresh estimator starts where the running one is.
        if let physid_estim::Method::RlsfTv { lambda_init, .. } = &mut fresh_cfg.method {
            *lambda_init = est.lambda();
        }
        let fixed = ParamSet::new(["a", "b", "c", "d"], before.clone()).unwrap();
        let mut fresh = LinearEstimator::new(&fresh_cfg, &fixed, &keep).unwrap();
        for (r, &yi) in rows[300..].iter().zip(&y[300..]) {
            est.update(r, yi).unwrap();
            fresh.update(r, yi).unwrap();
        }
        let (a, b) = (est.estimate_full(), fresh.estimate_full());
        assert!(
            common::rel_err(&a, &b, 1e-12) < 1e-9,
            "{name}: {a:?} vs {b:?}"
        );
        assert_eq!(a[1], before[1], "{name}: b stays frozen");

        // Release b: it resumes with the variance it had when frozen, uncorrelated.
        est.set_free(&params.all_free()).unwrap();
        let q = est.covariance();
        // Exactly for P; DSFC holds S, and (√v)² is v to within an ulp.
        let ulps = if name == "dsfc" {
            2.0 * f64::EPSILON
        } else {
            0.0
        };
        assert!(
            (q[(1, 1)] - p[(1, 1)]).abs() <= ulps * p[(1, 1)],
            "{name}: {} vs {}",
            q[(1, 1)],
            p[(1, 1)]
        );
        for j in [0, 2, 3] {
            assert_eq!(q[(1, j)], 0.0);
        }
        assert_eq!(est.samples(), 600);
    }
}

#[test]
fn only_parameters_of_the_original_free_set_can_be_freed() {
    let params = ParamSet::zeros(["a", "b", "c"]).unwrap();
    let free = params.free(&["a", "b"]).unwrap();
    let mut est = LinearEstimator::new(
        &EstimatorConfig::new(physid_estim::Method::Rls),
        &params,
        &free,
    )
    .unwrap();
    let e = est.set_free(&params.all_free()).unwrap_err().to_string();
    assert!(e.contains("parameter c was fixed"), "{e}");
    est.set_free(&params.free(&["b"]).unwrap()).unwrap();
    est.set_free(&free).unwrap();
    assert_eq!(est.free_names(), ["a", "b"]);
}
