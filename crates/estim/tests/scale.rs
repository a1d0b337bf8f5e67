//! Data at the edges of double precision (issue 41, item 5): the output scaled by 1e-300,
//! 1e-150 or 1e150 scales the estimates and their standard errors by the same factor — the
//! closed form of a least-squares problem linear in `y` (from ϑ0 = 0) — instead of a standard
//! error of exactly 0 (the squared residuals underflowed) or ∞.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{all_methods, estimator, regression};
use physid_estim::Method;

#[test]
fn scaling_the_output_scales_the_estimates_and_their_standard_errors() {
    let (rows, y, _) = regression(2000, 3, 0.1, 41);
    for method in all_methods(3) {
        // The Kalman filter's standard errors come from its given noise variance R2, not the
        // data's: they do not scale with y.
        if matches!(method, Method::Kalman { .. }) {
            continue;
        }
        let run = |s: f64| {
            let mut e = estimator(method.clone(), 1e6, &[0.0; 3]);
            for (r, &yi) in rows.iter().zip(&y) {
                e.update(r, yi * s).unwrap();
            }
            (e.estimate().to_vec(), e.std_errors().unwrap())
        };
        let (theta, se) = run(1.0);
        for s in [1e-300, 1e-150, 1e150] {
            let (theta_s, se_s) = run(s);
            for j in 0..3 {
                let name = method.name();
                let rel = |a: f64, b: f64| ((a / s - b) / b).abs();
                assert!(
                    rel(theta_s[j], theta[j]) < 1e-12,
                    "{name} × {s:e}: θ{j} {} against {}",
                    theta_s[j],
                    theta[j]
                );
                assert!(
                    se_s[j] > 0.0 && rel(se_s[j], se[j]) < 1e-12,
                    "{name} × {s:e}: standard error {j} {} against {} × {s:e}",
                    se_s[j],
                    se[j]
                );
            }
        }
    }
}

/// A first residual far smaller than the rest (a start that happens to fit to 1e-120) sets a
/// scale the later residuals' squares would overflow at: the sum moves to their scale, and the
/// standard errors are those of the same run whose first residual is exactly 0 (no scale).
#[test]
fn a_tiny_first_residual_does_not_overflow_the_later_ones() {
    let (rows, y, _) = regression(500, 3, 0.1, 7);
    let run = |first: f64| {
        let mut e = estimator(Method::Rls, 1e6, &[0.0; 3]);
        // The first sample's output against the prediction at ϑ0 = 0.
        e.update(&rows[0], first).unwrap();
        for (r, &yi) in rows.iter().zip(&y).skip(1) {
            e.update(r, yi).unwrap();
        }
        e.std_errors().unwrap()
    };
    let (tiny, zero) = (run(1e-120), run(0.0));
    for (a, b) in tiny.iter().zip(&zero) {
        assert!(
            a.is_finite() && ((a - b) / b).abs() < 1e-12,
            "{tiny:?} against {zero:?}"
        );
    }
}
