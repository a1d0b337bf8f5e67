//! The estimators against closed forms: regularised and exponentially weighted least squares
//! solved from the normal equations, and the exact equivalences between the methods.
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{estimator, regression, rel_err};
use nalgebra::{DMatrix, DVector};
use physid_core::ParamSet;
use physid_estim::{
    CovSpec, EstimatorConfig, GuardAction, LinearEstimator, Method, VfVariant, WindupGuard,
};

/// Normal equations of weighted, regularised least squares accumulated sample by sample:
/// `A_t = λ_t A_{t−1} + φφᵀ`, `b_t = λ_t b_{t−1} + φy`, `A_0 = P0⁻¹`, `b_0 = P0⁻¹ϑ0`; the
/// minimiser of `Σ β(t,i) e_i² + β(t,0)(ϑ−ϑ0)ᵀP0⁻¹(ϑ−ϑ0)` is `A_t⁻¹ b_t`.
struct NormalEquations {
    a: DMatrix<f64>,
    b: DVector<f64>,
}

impl NormalEquations {
    fn new(p0: f64, theta0: &[f64]) -> Self {
        let p = theta0.len();
        Self {
            a: DMatrix::identity(p, p) / p0,
            b: DVector::from_column_slice(theta0) / p0,
        }
    }
    fn add(&mut self, lambda: f64, phi: &[f64], y: f64) {
        let f = DVector::from_column_slice(phi);
        self.a = &self.a * lambda + &f * f.transpose();
        self.b = &self.b * lambda + &f * y;
    }
    fn solve(&self) -> Vec<f64> {
        self.a
            .clone()
            .cholesky()
            .unwrap()
            .solve(&self.b)
            .as_slice()
            .to_vec()
    }
}

/// Issue 2, verification 1: RLS with λ = 1, P0 = c·I is the regularised least-squares solution
/// `(ΦᵀΦ + P0⁻¹)⁻¹(Φᵀy + P0⁻¹ϑ0)` at every step; P is `(ΦᵀΦ + P0⁻¹)⁻¹`; the sum of squared
/// standardised residuals is the minimum of the regularised cost; the standard errors are
/// `√(J_min/(n−p)·[(ΦᵀΦ + P0⁻¹)⁻¹]_ii)`.
#[test]
fn rls_is_regularised_least_squares_at_every_step() {
    for (c, seed) in [(1000.0, 1), (10.0, 2), (1e6, 3)] {
        let (rows, y, _) = regression(300, 4, 0.1, seed);
        let theta0 = [0.3, -0.1, 0.2, 0.0];
        let mut est = estimator(Method::Rls, c, &theta0);
        let mut ne = NormalEquations::new(c, &theta0);
        let mut sum_w2 = 0.0;
        for (row, &yt) in rows.iter().zip(&y) {
            let s = est.update(row, yt).unwrap();
            sum_w2 += s.standardized_residual().powi(2);
            ne.add(1.0, row, yt);
            let cf = ne.solve();
            let err = rel_err(est.estimate(), &cf, 1e-300);
            assert!(err < 1e-9, "c = {c}: relative error {err:e}");
        }
        let theta = ne.solve();
        let ainv = ne.a.clone().try_inverse().unwrap();
        let p = est.covariance();
        assert!((&p - &ainv).norm() < 1e-9 * ainv.norm());
        // Minimum of the regularised cost, computed directly.
        let mut j_min: f64 = rows
            .iter()
            .zip(&y)
            .map(|(r, yt)| (yt - r.iter().zip(&theta).map(|(a, b)| a * b).sum::<f64>()).powi(2))
            .sum();
        j_min += theta
            .iter()
            .zip(&theta0)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            / c;
        assert!((sum_w2 - j_min).abs() < 1e-9 * j_min, "{sum_w2} vs {j_min}");
        let se = est.std_errors().unwrap();
        for i in 0..4 {
            let expect = (j_min / (300.0 - 4.0) * ainv[(i, i)]).sqrt();
            assert!((se[i] - expect).abs() < 1e-9 * expect);
        }
        assert!((est.noise_variance().unwrap() - j_min / 296.0).abs() < 1e-9 * j_min);
    }
}

/// RLSF (Alg. 5.3) and the time-varying forgetting of Eq. 5.24 are exponentially weighted
/// regularised least squares: `A_t = λ_t A_{t−1} + φφᵀ`.
#[test]
fn forgetting_is_exponentially_weighted_least_squares() {
    let (rows, y, _) = regression(400, 3, 0.2, 7);
    // constant λ
    let mut est = estimator(Method::Rlsf { lambda: 0.95 }, 1000.0, &[0.0; 3]);
    let mut ne = NormalEquations::new(1000.0, &[0.0; 3]);
    for (row, &yt) in rows.iter().zip(&y) {
        est.update(row, yt).unwrap();
        ne.add(0.95, row, yt);
        let err = rel_err(est.estimate(), &ne.solve(), 1e-300);
        assert!(err < 1e-9, "RLSF: {err:e}");
    }
    // time-varying λ(t) = λ0·λ(t−1) + (1 − λ0), λ(0) = 0.9, λ0 = 0.99
    let mut est = estimator(
        Method::RlsfTv {
            lambda0: 0.99,
            lambda_init: 0.9,
        },
        1000.0,
        &[0.0; 3],
    );
    let mut ne = NormalEquations::new(1000.0, &[0.0; 3]);
    let mut lambda = 0.9;
    for (row, &yt) in rows.iter().zip(&y) {
        lambda = 0.99 * lambda + 0.01;
        est.update(row, yt).unwrap();
        ne.add(lambda, row, yt);
        let err = rel_err(est.estimate(), &ne.solve(), 1e-300);
        assert!(err < 1e-9, "time-varying RLSF: {err:e}");
        assert!((est.lambda() - lambda).abs() < 1e-15);
    }
    // closed form of Eq. 5.24: λ(t) = 1 − (1 − λ(0))·λ0^t
    assert!((est.lambda() - (1.0 - 0.1 * 0.99f64.powi(400))).abs() < 1e-12);
}

fn run(method: Method, p0: f64, rows: &[Vec<f64>], y: &[f64]) -> Vec<Vec<f64>> {
    let mut est = estimator(method, p0, &[0.0; 3]);
    rows.iter()
        .zip(y)
        .map(|(r, &yt)| {
            est.update(r, yt).unwrap();
            est.estimate().to_vec()
        })
        .collect()
}

fn assert_same_path(a: &[Vec<f64>], b: &[Vec<f64>], what: &str) {
    let worst = a
        .iter()
        .zip(b)
        .map(|(x, y)| rel_err(x, y, 1.0))
        .fold(0.0, f64::max);
    assert!(worst < 1e-9, "{what}: worst relative difference {worst:e}");
}

/// Issue 2, verifications 4 (first half) and 5: DSFC = RLSF(λ); vector forgetting with Λ = λI:
/// symmetric = RLSF(λ), published = RLSF(λ²) from P0·λ²; Kalman with R1 = 0, R2 = 1 = RLS.
#[test]
fn exact_equivalences_between_methods() {
    let (rows, y, _) = regression(500, 3, 0.3, 11);
    let l = 0.97;
    let rlsf = run(Method::Rlsf { lambda: l }, 1000.0, &rows, &y);
    assert_same_path(
        &run(Method::Dsfc { lambda: l }, 1000.0, &rows, &y),
        &rlsf,
        "DSFC vs RLSF",
    );
    let vf = |variant| Method::Rlsvf {
        lambdas: vec![l; 3],
        variant,
    };
    assert_same_path(
        &run(vf(VfVariant::Symmetric), 1000.0, &rows, &y),
        &rlsf,
        "VF symmetric vs RLSF",
    );
    assert_same_path(
        &run(vf(VfVariant::Published), 1000.0, &rows, &y),
        &run(Method::Rlsf { lambda: l * l }, 1000.0 * l * l, &rows, &y),
        "VF published vs RLSF(λ²)",
    );
    let kf = Method::Kalman {
        r1: CovSpec::Scaled(0.0),
        r2: 1.0,
    };
    assert_same_path(
        &run(kf, 1000.0, &rows, &y),
        &run(Method::Rls, 1000.0, &rows, &y),
        "KF vs RLS",
    );
    // DSFC's P = S·Sᵀ equals RLSF's P.
    let mut a = estimator(Method::Dsfc { lambda: l }, 1000.0, &[0.0; 3]);
    let mut b = estimator(Method::Rlsf { lambda: l }, 1000.0, &[0.0; 3]);
    for (r, &yt) in rows.iter().zip(&y) {
        a.update(r, yt).unwrap();
        b.update(r, yt).unwrap();
    }
    let (pa, pb) = (a.covariance(), b.covariance());
    assert!((&pa - &pb).norm() < 1e-9 * pb.norm());
    assert!((a.covariance_trace() - pb.trace()).abs() < 1e-9 * pb.trace());
    let (sa, sb) = (a.std_errors().unwrap(), b.std_errors().unwrap());
    assert!(rel_err(&sa, &sb, 1e-300) < 1e-9);
}

/// A free subset with the rest fixed at nominal values is least squares of `y − φ_fixedᵀϑ0_fixed`
/// on the free regressors.
#[test]
fn free_subset_holds_the_rest_at_nominal_values() {
    let (rows, y, _) = regression(300, 4, 0.1, 5);
    let params = ParamSet::new(["a", "b", "c", "d"], vec![0.9, -0.4, 2.1, -0.6]).unwrap();
    let free = params.free(&["d", "b"]).unwrap();
    let cfg = EstimatorConfig::new(Method::Rls);
    let mut est = LinearEstimator::new(&cfg, &params, &free).unwrap();
    assert_eq!(est.free_names(), vec!["b", "d"]);
    let mut ne = NormalEquations::new(1000.0, &[-0.4, -0.6]);
    for (row, &yt) in rows.iter().zip(&y) {
        est.update(row, yt).unwrap();
        ne.add(1.0, &[row[1], row[3]], yt - 0.9 * row[0] - 2.1 * row[2]);
        assert!(rel_err(est.estimate(), &ne.solve(), 1e-300) < 1e-9);
    }
    let full = est.estimate_full();
    assert_eq!((full[0], full[2]), (0.9, 2.1));
    assert_eq!((full[1], full[3]), (est.estimate()[0], est.estimate()[1]));
}

/// Wind-up: with no excitation for 2000 samples, RLSF's trace(P) grows as λ^(−t); the guard
/// holds it at its bound (scale) or resets it to P0, and the estimate is not disturbed.
#[test]
fn windup_guard_bounds_the_covariance() {
    let (rows, y, _) = regression(300, 2, 0.05, 9);
    let lambda: f64 = 0.98;
    let mk = |guard| {
        let params = ParamSet::zeros(["a", "b"]).unwrap();
        let cfg = EstimatorConfig {
            method: Method::Rlsf { lambda },
            p0: CovSpec::Scaled(1000.0),
            guard,
        };
        LinearEstimator::new(&cfg, &params, &params.all_free()).unwrap()
    };
    let mut plain = mk(None);
    let mut scaled = mk(Some(WindupGuard {
        max_trace: 50.0,
        action: GuardAction::Scale,
    }));
    let mut reset = mk(Some(WindupGuard {
        max_trace: 5000.0,
        action: GuardAction::Reset,
    }));
    for (r, &yt) in rows.iter().zip(&y) {
        for e in [&mut plain, &mut scaled, &mut reset] {
            e.update(r, yt).unwrap();
        }
    }
    let tr0 = plain.covariance_trace();
    let theta = scaled.estimate().to_vec();
    // No excitation: φ = 0, y = 0.
    for _ in 0..2000 {
        for e in [&mut plain, &mut scaled, &mut reset] {
            e.update(&[0.0, 0.0], 0.0).unwrap();
        }
    }
    let growth = plain.covariance_trace() / tr0;
    assert!((growth - lambda.powi(-2000)).abs() < 1e-9 * growth); // closed form λ^(−t)
    assert!((scaled.covariance_trace() - 50.0).abs() < 1e-9);
    assert!(scaled.guard_activations() > 0 && reset.guard_activations() > 0);
    let tr = reset.covariance_trace();
    assert!((2000.0..=5000.0).contains(&tr), "trace after resets {tr}");
    assert_eq!(scaled.estimate(), &theta[..]);
}

/// A configuration written as data (here JSON; TOML maps the same way) builds the same estimator
/// as one built in code: same estimates on the same data.
#[test]
fn configuration_as_plain_data() {
    let text = r#"{"method": {"kind": "rlsvf", "lambdas": [0.97, 1.0], "variant": "symmetric"},
                  "p0": {"diagonal": [1000.0, 500.0]},
                  "guard": {"max_trace": 1e6, "action": "scale"}}"#;
    let from_data: EstimatorConfig = serde_json::from_str(text).unwrap();
    let in_code = EstimatorConfig {
        method: Method::Rlsvf {
            lambdas: vec![0.97, 1.0],
            variant: VfVariant::Symmetric,
        },
        p0: CovSpec::Diagonal(vec![1000.0, 500.0]),
        guard: Some(WindupGuard {
            max_trace: 1e6,
            action: GuardAction::Scale,
        }),
    };
    assert_eq!(from_data, in_code);
    let minimal: EstimatorConfig = serde_json::from_str(r#"{"method": {"kind": "rls"}}"#).unwrap();
    assert_eq!(minimal, EstimatorConfig::new(Method::Rls)); // P0 = 1000·I, no guard by default
    let bad = serde_json::from_str::<EstimatorConfig>(r#"{"method": {"kind": "lms"}}"#);
    assert!(bad
        .unwrap_err()
        .to_string()
        .contains("unknown variant `lms`"));
}
