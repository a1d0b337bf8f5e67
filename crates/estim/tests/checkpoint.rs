//! The one estimator interface ([`Recursive`]): a checkpoint taken mid-run, sent through JSON
//! and restored into a freshly built estimator continues exactly as the uninterrupted run —
//! for every method — and a checkpoint that does not fit is refused. [`LinearInParams`] is
//! checked against the closed-form least-squares solution (normal equations).
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{all_methods, estimator, regression};
use nalgebra::{DMatrix, DVector};
use physid_core::{ParamModel, ParamSet};
use physid_estim::{
    CovSpec, EstimatorConfig, LinearInParams, Method, NlConfig, NlMethod, NonlinearEstimator,
    Recursive, SigmaPoints, Snapshot,
};
use physid_expr::ExprModel;

/// Feed `rows[..cut]`, checkpoint through JSON, build `fresh()`, restore, feed the rest to
/// both: the estimates, covariances and standard errors must be bit-identical.
fn check_resume(
    mut run: Box<dyn Recursive>,
    mut fresh: Box<dyn Recursive>,
    rows: &[Vec<f64>],
    y: &[f64],
    cut: usize,
) {
    let name = run.method_name();
    for (r, &yi) in rows[..cut].iter().zip(y) {
        run.update(r, yi).unwrap();
    }
    let json = serde_json::to_string(&run.snapshot()).unwrap();
    let snap: Snapshot = serde_json::from_str(&json).unwrap();
    fresh.restore(&snap).unwrap();
    assert_eq!(fresh.samples(), cut as u64, "{name}");
    for (r, &yi) in rows[cut..].iter().zip(&y[cut..]) {
        let a = run.update(r, yi).unwrap();
        let b = fresh.update(r, yi).unwrap();
        assert_eq!(a, b, "{name}: steps differ after the restore");
    }
    assert_eq!(run.estimate(), fresh.estimate(), "{name}");
    assert_eq!(run.covariance(), fresh.covariance(), "{name}");
    assert_eq!(run.std_errors(), fresh.std_errors(), "{name}");
    assert_eq!(run.samples(), rows.len() as u64, "{name}");
}

#[test]
fn every_linear_method_resumes_from_a_checkpoint_exactly() {
    let (rows, y, theta) = regression(400, 3, 0.1, 7);
    for method in all_methods(3) {
        let build =
            || -> Box<dyn Recursive> { Box::new(estimator(method.clone(), 100.0, &[0.0; 3])) };
        check_resume(build(), build(), &rows, &y, 157);
        // And the run converged (the checkpoint did not hide a broken filter).
        let mut run = build();
        for (r, &yi) in rows.iter().zip(&y) {
            run.update(r, yi).unwrap();
        }
        let est = run.estimate();
        for (e, t) in est.iter().zip(&theta) {
            assert!(
                (e - t).abs() < 0.1,
                "{}: {est:?} vs {theta:?}",
                run.method_name()
            );
        }
    }
}

#[test]
fn a_linear_checkpoint_after_a_change_of_the_free_set_moves_the_fresh_estimator_to_it() {
    let (rows, y, _) = regression(300, 3, 0.1, 11);
    let params = ParamSet::new(["p1", "p2", "p3"], vec![0.0; 3]).unwrap();
    let cfg = EstimatorConfig::new(Method::Rlsf { lambda: 0.99 });
    let build = || physid_estim::LinearEstimator::new(&cfg, &params, &params.all_free()).unwrap();
    let mut run = build();
    for (r, &yi) in rows[..100].iter().zip(&y) {
        run.update(r, yi).unwrap();
    }
    run.set_free(&params.free(&["p1", "p3"]).unwrap()).unwrap();
    let mut fresh: Box<dyn Recursive> = Box::new(build());
    let mut run: Box<dyn Recursive> = Box::new(run);
    check_resume_from(&mut run, &mut fresh, &rows[100..], &y[100..]);
    assert_eq!(fresh.free_names(), ["p1", "p3"]);
}

fn check_resume_from(
    run: &mut Box<dyn Recursive>,
    fresh: &mut Box<dyn Recursive>,
    rows: &[Vec<f64>],
    y: &[f64],
) {
    fresh.restore(&run.snapshot()).unwrap();
    for (r, &yi) in rows.iter().zip(y) {
        assert_eq!(run.update(r, yi).unwrap(), fresh.update(r, yi).unwrap());
    }
    assert_eq!(run.estimate_full(), fresh.estimate_full());
}

/// `y = A·exp(−B·x) + C·x` sampled on x ∈ [0, 4] with a little deterministic "noise".
fn curve() -> (Vec<Vec<f64>>, Vec<f64>) {
    let (a, b, c) = (2.0, 0.7, 0.3);
    let rows: Vec<Vec<f64>> = (0..300)
        .map(|k| vec![4.0 * (k % 100) as f64 / 100.0])
        .collect();
    let y = rows
        .iter()
        .enumerate()
        .map(|(k, r)| a * (-b * r[0]).exp() + c * r[0] + 1e-3 * ((k * 7919) % 13) as f64)
        .collect();
    (rows, y)
}

#[test]
fn every_filter_resumes_from_a_checkpoint_exactly() {
    let (rows, y) = curve();
    let params = ParamSet::new(["A", "B", "C"], vec![1.5, 0.5, 0.2]).unwrap();
    let model = ExprModel::parse("A*exp(-B*x) + C*x", &["A", "B", "C"]).unwrap();
    let sp = SigmaPoints::default();
    for (method, scaled) in [
        (NlMethod::Ekf, false),
        (NlMethod::Ukf(sp), false),
        (NlMethod::Srukf(sp), true),
    ] {
        let cfg = NlConfig {
            r2: 1e-4,
            scaled,
            bounds: vec![("B".into(), 0.01, 5.0)],
            ..NlConfig::new(method)
        };
        let build = || -> Box<dyn Recursive> {
            Box::new(
                NonlinearEstimator::new(model.clone(), &params, &params.all_free(), &cfg).unwrap(),
            )
        };
        check_resume(build(), build(), &rows, &y, 123);
    }
    // EKF over a subset: the inner Kalman filter's own indices are not the model's.
    let free = params.free(&["A", "C"]).unwrap();
    let cfg = NlConfig::new(NlMethod::Ekf);
    let build = || -> Box<dyn Recursive> {
        Box::new(NonlinearEstimator::new(model.clone(), &params, &free, &cfg).unwrap())
    };
    check_resume(build(), build(), &rows, &y, 50);
}

/// A whole filter over a formula — its model, configuration and state — written and read back
/// (what the Python package's `pickle` and `copy` use) continues bit for bit, and so does a
/// linear estimator.
#[test]
fn a_whole_estimator_serialised_mid_run_continues_exactly() {
    let (rows, y) = curve();
    let params = ParamSet::new(["A", "B", "C"], vec![1.5, 0.5, 0.2]).unwrap();
    let model = ExprModel::parse("A*exp(-B*x) + C*x", &["A", "B", "C"]).unwrap();
    let sp = SigmaPoints::default();
    for method in [NlMethod::Ekf, NlMethod::Ukf(sp), NlMethod::Srukf(sp)] {
        let cfg = NlConfig {
            r2: 1e-4,
            scaled: true,
            bounds: vec![("B".into(), 0.01, 5.0)],
            ..NlConfig::new(method)
        };
        let mut run =
            NonlinearEstimator::new(model.clone(), &params, &params.all_free(), &cfg).unwrap();
        for (r, &yi) in rows[..111].iter().zip(&y) {
            run.update(r, yi).unwrap();
        }
        // MessagePack: the work space holds NaN, which JSON cannot carry.
        let bytes = rmp_serde::to_vec_named(&run).unwrap();
        let mut copy: NonlinearEstimator<ExprModel> = rmp_serde::from_slice(&bytes).unwrap();
        assert_eq!(copy.model().text(), "A*exp(-B*x) + C*x");
        for (r, &yi) in rows[111..].iter().zip(&y[111..]) {
            assert_eq!(run.update(r, yi).unwrap(), copy.update(r, yi).unwrap());
        }
        assert_eq!(run.estimate_full(), copy.estimate_full());
        assert_eq!(run.covariance(), copy.covariance());
        assert_eq!(run.samples(), copy.samples());
    }
    let (rows, y, _) = regression(200, 3, 0.1, 5);
    let mut run = estimator(Method::Dsfc { lambda: 0.99 }, 100.0, &[0.0; 3]);
    for (r, &yi) in rows[..80].iter().zip(&y) {
        run.update(r, yi).unwrap();
    }
    let mut copy: physid_estim::LinearEstimator =
        rmp_serde::from_slice(&rmp_serde::to_vec_named(&run).unwrap()).unwrap();
    for (r, &yi) in rows[80..].iter().zip(&y[80..]) {
        assert_eq!(run.update(r, yi).unwrap(), copy.update(r, yi).unwrap());
    }
}

/// A model whose text no longer parses is refused when read, not rebuilt wrong.
#[test]
fn a_serialised_formula_that_does_not_parse_is_refused() {
    let bad = r#"{"text":"A*(x","params":["A"]}"#;
    assert!(serde_json::from_str::<ExprModel>(bad).is_err());
    let unused = r#"{"text":"x","params":["A"]}"#;
    assert!(serde_json::from_str::<ExprModel>(unused).is_err());
}

#[test]
fn a_checkpoint_that_does_not_fit_is_refused_and_changes_nothing() {
    let (rows, y, _) = regression(50, 3, 0.1, 3);
    let mut rls = estimator(Method::Rls, 100.0, &[0.0; 3]);
    for (r, &yi) in rows.iter().zip(&y) {
        rls.update(r, yi).unwrap();
    }
    let snap = Recursive::snapshot(&rls);
    // Another method.
    let mut dsfc = estimator(Method::Dsfc { lambda: 1.0 }, 100.0, &[0.0; 3]);
    let err = Recursive::restore(&mut dsfc, &snap)
        .unwrap_err()
        .to_string();
    assert!(err.contains("taken of a rls estimator"), "{err}");
    // Another size.
    let mut small = estimator(Method::Rls, 100.0, &[0.0; 2]);
    assert!(Recursive::restore(&mut small, &snap).is_err());
    // A non-finite state.
    let mut bad = snap.clone();
    bad.state[1] = f64::NAN;
    let mut fresh = estimator(Method::Rls, 100.0, &[0.0; 3]);
    let err = Recursive::restore(&mut fresh, &bad)
        .unwrap_err()
        .to_string();
    assert!(err.contains("non-finite"), "{err}");
    assert_eq!(Recursive::samples(&fresh), 0);
    assert_eq!(fresh.estimate(), &[0.0; 3]);
    // A linear snapshot into a filter.
    let params = ParamSet::new(["A", "B", "C"], vec![1.0; 3]).unwrap();
    let model = ExprModel::parse("A*x + B + C", &["A", "B", "C"]).unwrap();
    let mut ekf = NonlinearEstimator::new(
        model,
        &params,
        &params.all_free(),
        &NlConfig::new(NlMethod::Ekf),
    )
    .unwrap();
    assert!(Recursive::restore(&mut ekf, &snap).is_err());
}

/// RLS with a vague prior (P0 = 1e8·I) through a model's gradient equals the least-squares
/// solution of the normal equations ΦᵀΦ ϑ = Φᵀy, solved by nalgebra's LU.
#[test]
fn linear_in_params_matches_the_normal_equations() {
    let model = ExprModel::parse("a*u + b*v*v + c", &["a", "b", "c"]).unwrap();
    let params = ParamSet::new(["a", "b", "c"], vec![0.0; 3]).unwrap();
    let cfg = EstimatorConfig {
        p0: CovSpec::Scaled(1e8),
        ..EstimatorConfig::new(Method::Rls)
    };
    let mut est = LinearInParams::new(model.clone(), &params, &params.all_free(), &cfg).unwrap();
    let mut phi = DMatrix::zeros(200, 3);
    let mut y = DVector::zeros(200);
    for k in 0..200 {
        let (u, v) = ((k as f64 * 0.37).sin(), (k as f64 * 0.11).cos());
        let yk = 1.5 * u - 0.25 * v * v + 0.75 + 0.01 * ((k * 31) % 7) as f64;
        phi.set_row(k, &nalgebra::RowDVector::from_row_slice(&[u, v * v, 1.0]));
        y[k] = yk;
        // Model inputs in the model's order.
        let inputs: Vec<f64> = model
            .input_names()
            .iter()
            .map(|n| if n == "u" { u } else { v })
            .collect();
        est.update(&inputs, yk).unwrap();
    }
    let ls = (phi.transpose() * &phi)
        .lu()
        .solve(&(phi.transpose() * &y))
        .unwrap();
    for (e, l) in est.estimate().iter().zip(ls.iter()) {
        assert!((e - l).abs() < 1e-6 * l.abs().max(1.0), "{e} vs {l}");
    }
    // A model that is not linear in its parameters is refused on the first sample.
    let nl = ExprModel::parse("a*exp(b*u) + c", &["a", "b", "c"]).unwrap();
    let params = ParamSet::new(["a", "b", "c"], vec![1.0; 3]).unwrap();
    let mut est = LinearInParams::new(nl, &params, &params.all_free(), &cfg).unwrap();
    let err = est.update(&[0.5], 1.0).unwrap_err().to_string();
    assert!(err.contains("not linear"), "{err}");
}
