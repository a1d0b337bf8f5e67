//! Standard benchmark workloads, shared by the criterion benches and `physid bench` so that both
//! measure the same thing: each method at the thesis's tuning on `p` random regressors.
//!
//! The regressors are uniform on [−1, 1) from SplitMix64 (seed 0x5eed), `y = Σ (i+1)·φ_i` plus
//! uniform noise of amplitude 0.01 — the same stream `bench/peers/peers.py` generates, so the
//! peers are timed on identical data.

use crate::{CovSpec, EstimError, EstimatorConfig, LinearEstimator, Method, VfVariant};
use physid_core::ParamSet;

/// The five linear methods at the tuning used in the thesis's experiments (λ = 0.98, §6).
pub fn standard_methods(p: usize) -> Vec<Method> {
    vec![
        Method::Rls,
        Method::Rlsf { lambda: 0.98 },
        Method::Rlsvf {
            lambdas: vec![0.98; p],
            variant: VfVariant::Published,
        },
        Method::Kalman {
            r1: CovSpec::Scaled(1e-6),
            r2: 1.0,
        },
        Method::Dsfc { lambda: 0.98 },
    ]
}

/// SplitMix64 (Steele, Lea & Flood 2014): a tiny reproducible stream, identical in the Python
/// peer script.
#[derive(Debug, Clone)]
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform on [−1, 1) from the top 53 bits.
    pub fn next_sym(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
}

/// Regressor rows (row-major, `n × p`) and outputs of the standard workload.
pub fn data(p: usize, n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut rng = SplitMix64(0x5eed);
    let mut rows = Vec::with_capacity(n * p);
    let mut y = Vec::with_capacity(n);
    for _ in 0..n {
        let mut s = 0.0;
        for i in 0..p {
            let v = rng.next_sym();
            s += (i + 1) as f64 * v;
            rows.push(v);
        }
        y.push(s + 0.01 * rng.next_sym());
    }
    (rows, y)
}

/// An estimator and its data, ready to be timed.
#[derive(Debug, Clone)]
pub struct Workload {
    /// The estimator.
    pub estimator: LinearEstimator,
    rows: Vec<f64>,
    y: Vec<f64>,
    p: usize,
    next: usize,
}

impl Workload {
    /// The standard workload for `method` at `p` parameters, cycling over `n` samples.
    pub fn new(method: Method, p: usize, n: usize) -> Result<Self, EstimError> {
        let names: Vec<String> = (1..=p).map(|i| format!("p{i}")).collect();
        let params =
            ParamSet::zeros(names).map_err(|e| EstimError::InvalidConfig(e.to_string()))?;
        let estimator =
            LinearEstimator::new(&EstimatorConfig::new(method), &params, &params.all_free())?;
        let (rows, y) = data(p, n.max(1));
        Ok(Self {
            estimator,
            rows,
            y,
            p,
            next: 0,
        })
    }

    /// Run `updates` updates (cycling over the data).
    pub fn run(&mut self, updates: usize) -> Result<(), EstimError> {
        let n = self.y.len();
        for _ in 0..updates {
            let i = self.next;
            self.estimator
                .update(&self.rows[i * self.p..(i + 1) * self.p], self.y[i])?;
            self.next = if i + 1 == n { 0 } else { i + 1 };
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The stream equals the Python implementation in `bench/peers/peers.py`
    /// (`splitmix_data(3, 2)` printed these values).
    #[test]
    fn same_data_as_the_python_peer_script() {
        let (rows, y) = data(3, 2);
        let expect_rows = [
            -0.9223025306056296,
            -0.3343977825211404,
            -0.2706362872437236,
            -0.906655420095253,
            -0.26001057979516085,
            -0.6763666929871486,
        ];
        assert_eq!(rows, expect_rows);
        assert_eq!(y, [-2.40419268518543, -3.464328400969659]);
    }
}
