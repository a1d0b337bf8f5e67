//! Helpers shared by the integration tests (data generation, builders).
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]
#![allow(dead_code)]

use physid_core::ParamSet;
use physid_estim::{CovSpec, EstimatorConfig, LinearEstimator, Method, VfVariant};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde_json::Value;

/// A well-conditioned regression: n rows of p regressors (N(0,1) plus a constant), and y with
/// noise `sigma`. Returns (rows, y, true θ).
pub fn regression(
    n: usize,
    p: usize,
    sigma: f64,
    seed: u64,
) -> (Vec<Vec<f64>>, Vec<f64>, Vec<f64>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let theta: Vec<f64> = (0..p)
        .map(|i| 1.0 + i as f64 * 0.5 * if i % 2 == 0 { 1.0 } else { -1.0 })
        .collect();
    let mut rows = Vec::with_capacity(n);
    let mut y = Vec::with_capacity(n);
    for _ in 0..n {
        let row: Vec<f64> = (0..p)
            .map(|j| {
                if j == 0 {
                    1.0
                } else {
                    rng.sample::<f64, _>(StandardNormal)
                }
            })
            .collect();
        let noise: f64 = rng.sample(StandardNormal);
        y.push(row.iter().zip(&theta).map(|(a, b)| a * b).sum::<f64>() + sigma * noise);
        rows.push(row);
    }
    (rows, y, theta)
}

/// An estimator of all parameters named p1..pn with nominal values `theta0`.
pub fn estimator(method: Method, p0: f64, theta0: &[f64]) -> LinearEstimator {
    let names: Vec<String> = (1..=theta0.len()).map(|i| format!("p{i}")).collect();
    let params = ParamSet::new(names, theta0.to_vec()).unwrap();
    let cfg = EstimatorConfig {
        method,
        p0: CovSpec::Scaled(p0),
        guard: None,
    };
    LinearEstimator::new(&cfg, &params, &params.all_free()).unwrap()
}

/// ‖a − b‖ / max(‖b‖, floor).
pub fn rel_err(a: &[f64], b: &[f64], floor: f64) -> f64 {
    let num: f64 = a
        .iter()
        .zip(b)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        .sqrt();
    let den: f64 = b.iter().map(|y| y * y).sum::<f64>().sqrt();
    num / den.max(floor)
}

/// Every linear method at typical tuning, for `p` free parameters.
pub fn all_methods(p: usize) -> Vec<Method> {
    vec![
        Method::Rls,
        Method::Rlsf { lambda: 0.98 },
        Method::RlsfTv {
            lambda0: 0.99,
            lambda_init: 0.95,
        },
        Method::Rlsvf {
            lambdas: vec![0.98; p],
            variant: VfVariant::Published,
        },
        Method::Rlsvf {
            lambdas: vec![0.98; p],
            variant: VfVariant::Symmetric,
        },
        Method::Kalman {
            r1: CovSpec::Scaled(1e-4),
            r2: 0.01,
        },
        Method::Dsfc { lambda: 0.98 },
    ]
}

/// A golden file of `tests/golden/`.
pub fn load(name: &str) -> Value {
    let path = format!("{}/tests/golden/{name}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    serde_json::from_str(&text).unwrap()
}

/// A JSON array of arrays of numbers.
pub fn matrix(v: &Value) -> Vec<Vec<f64>> {
    v.as_array().unwrap().iter().map(vector).collect()
}

/// A JSON array of numbers.
pub fn vector(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}
