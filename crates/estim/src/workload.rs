//! Standard benchmark workloads, shared by the criterion benches and `physid bench` so that both
//! measure the same thing: each method at the thesis's tuning on `p` random regressors.
//!
//! The regressors are uniform on [−1, 1) from SplitMix64 (seed 0x5eed), `y = Σ (i+1)·φ_i` plus
//! uniform noise of amplitude 0.01 — the same stream `bench/peers/peers.py` generates, so the
//! peers are timed on identical data.

use crate::{CovSpec, EstimError, EstimatorConfig, LinearEstimator, Method, VfVariant};
use physid_core::{ParamModel, ParamSet};

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
    use physid_core::{GradientEngine, ParamModel};

    /// The benchmark model's exact gradient equals central differences, and every filter runs
    /// on its workload.
    #[test]
    fn bench10_gradient_and_workloads() {
        let m = Bench10::default();
        let mut engine = GradientEngine::new(10);
        let free: Vec<usize> = (0..10).collect();
        let mut g = [0.0; 10];
        for k in [0, 37, 500, 9001] {
            let u = Bench10::inputs_at(k);
            let p = Bench10::NOMINAL;
            engine.value_and_gradient(&m, &u, &p, &free, &mut g);
            for j in 0..10 {
                let h = 1e-6 * p[j].abs();
                let (mut a, mut b) = (p, p);
                a[j] += h;
                b[j] -= h;
                let fd = (m.eval::<f64>(&u, &a) - m.eval::<f64>(&u, &b)) / (2.0 * h);
                // The witness's own round-off: ≈ ε·|y|/h.
                let y = m.eval::<f64>(&u, &p).abs();
                let tol = 1e-6 * fd.abs().max(1.0) + 10.0 * f64::EPSILON * y / h;
                assert!(
                    (g[j] - fd).abs() <= tol,
                    "k{}: {} vs {fd} (tol {tol:e})",
                    j + 1,
                    g[j]
                );
            }
        }
        // The sigma points' batch equals eval of each, bit for bit.
        let points: Vec<f64> = (0..21)
            .flat_map(|k| Bench10::NOMINAL.map(|v| v * (1.0 + 0.001 * k as f64)))
            .collect();
        let mut out = [0.0; 21];
        let u = Bench10::inputs_at(123);
        m.eval_many(&u, &points, &mut out);
        for (o, p) in out.iter().zip(points.chunks_exact(10)) {
            assert_eq!(o.to_bits(), m.eval::<f64>(&u, p).to_bits());
        }
        // The same model in bench/peers/peers.py (written independently in Python) gives:
        let py = [
            (37, 1.0, -170.84784064532332),
            (500, 1.02, -207.84001031091015),
        ];
        for (k, factor, expect) in py {
            let p: Vec<f64> = Bench10::NOMINAL.iter().map(|v| v * factor).collect();
            let v = m.eval::<f64>(&Bench10::inputs_at(k), &p);
            assert!(
                (v - expect).abs() <= 1e-12 * expect.abs(),
                "{v} vs {expect}"
            );
        }
        for method in [
            crate::NlMethod::Ekf,
            crate::NlMethod::Ukf(crate::SigmaPoints::default()),
            crate::NlMethod::Srukf(crate::SigmaPoints::default()),
        ] {
            let mut w = NonlinearWorkload::new(method, 720).unwrap();
            w.run(5000).unwrap();
            assert!(w.estimator.estimate().iter().all(|v| v.is_finite()));
        }
    }

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

/// A 10-parameter model with the cost profile of the cyclic-torque model (SPEC §9) — square
/// roots and trigonometry of a slider-crank term plus a polynomial — for benchmarking the
/// non-linear estimators until that model exists. Inputs: an angle `q`, rates `w`, `a`, a load
/// `f` and a temperature-like `s`; parameters `k1 … k10`.
#[derive(Debug, Clone)]
pub struct Bench10 {
    params: Vec<String>,
    inputs: Vec<String>,
}

impl Default for Bench10 {
    fn default() -> Self {
        Self {
            params: (1..=10).map(|i| format!("k{i}")).collect(),
            inputs: ["q", "w", "a", "f", "s"]
                .iter()
                .map(|s| s.to_string())
                .collect(),
        }
    }
}

impl Bench10 {
    /// Nominal parameter values.
    pub const NOMINAL: [f64; 10] = [
        0.8, 0.054, 0.088, 0.0257, 1.2, -0.3, 0.05, 0.02, -0.01, 0.004,
    ];

    /// A sample of inputs for step `k` (deterministic).
    pub fn inputs_at(k: usize) -> [f64; 5] {
        let q = (k as f64 * 0.0174533) % std::f64::consts::TAU;
        [
            q,
            104.7 + 10.0 * (k as f64 * 1e-3).sin(),
            5.0 * (k as f64 * 7e-3).cos(),
            3e5 * (1.0 + q.cos()),
            0.3 + 0.1 * (k as f64 * 1e-4).sin(),
        ]
    }
}

impl physid_core::ParamModel for Bench10 {
    fn param_names(&self) -> &[String] {
        &self.params
    }
    fn input_names(&self) -> &[String] {
        &self.inputs
    }
    fn eval<T: physid_core::Scalar>(&self, u: &[f64], k: &[T]) -> T {
        self.eval_at(u, k, u[0].sin_cos())
    }

    /// The sigma points share the inputs: `sin q`, `cos q` once for all of them.
    fn eval_many(&self, inputs: &[f64], params: &[f64], out: &mut [f64]) {
        let trig = inputs[0].sin_cos();
        let len = params.len().checked_div(out.len()).unwrap_or(0);
        for (k, o) in out.iter_mut().enumerate() {
            *o = self.eval_at(inputs, &params[k * len..(k + 1) * len], trig);
        }
    }
}

impl Bench10 {
    /// The model with `(sin q, cos q)` given.
    fn eval_at<T: physid_core::Scalar>(&self, u: &[f64], k: &[T], (sin_q, cos_q): (f64, f64)) -> T {
        let (w, a, f, s) = (u[1], u[2], u[3], u[4]);
        let (m, b, l, r) = (k[0], k[1], k[2], k[3]);
        // slider-crank: ψ = 1 − (r sin q / L)², G = sin q + √((1−ψ)/ψ)·cos q, written as
        // |r sin q / L|/√ψ: the same value, but √ of 0 at q = 0 has an infinite derivative
        // (∞·0 = NaN under automatic differentiation) while this form does not.
        let rs = r * sin_q / l;
        let psi = -(rs * rs) + 1.0;
        let g = rs.abs() / psi.sqrt() * cos_q + sin_q;
        let g1 = r * ((r / l) * cos_q / (psi * psi.sqrt()) + 1.0) * cos_q;
        let area = b * b * (std::f64::consts::PI / 4.0);
        let ind = area * r * g * f;
        let rec = m * r * g * (g1 * (w * w) + r * g * a);
        let fric = k[4] + k[5] * w + k[6] * s + k[7] * (w * w) + k[8] * (w * s) + k[9] * (s * s);
        ind - rec - fric
    }
}

/// [`Bench10`] written as a formula (`physid estimate --expr`, `physid.UKF` from Python): the
/// slider-crank term written out wherever it occurs, as a user would type it. Parameters
/// [`BENCH10_FORMULA_PARAMS`] (Bench10's `k1 … k4` are `m b l r`).
pub const BENCH10_FORMULA: &str =
    "(b^2*0.7853981633974483)*r*(abs(r*sin(q)/l)/sqrt(1-(r*sin(q)/l)^2)*cos(q)+sin(q))*f \
     - m*r*(abs(r*sin(q)/l)/sqrt(1-(r*sin(q)/l)^2)*cos(q)+sin(q))\
     *(r*((r/l)*cos(q)/((1-(r*sin(q)/l)^2)*sqrt(1-(r*sin(q)/l)^2))+1)*cos(q)*w^2 \
     + r*(abs(r*sin(q)/l)/sqrt(1-(r*sin(q)/l)^2)*cos(q)+sin(q))*a) \
     - (k5 + k6*w + k7*s + k8*w^2 + k9*w*s + k10*s^2)";

/// The parameters of [`BENCH10_FORMULA`], in [`Bench10::NOMINAL`]'s order.
pub const BENCH10_FORMULA_PARAMS: [&str; 10] =
    ["m", "b", "l", "r", "k5", "k6", "k7", "k8", "k9", "k10"];

/// An estimator of every parameter of [`Bench10`] (or of the same model as a formula) and its
/// input stream, ready to be timed.
#[derive(Debug, Clone)]
pub struct NonlinearWorkload<M: ParamModel = Bench10> {
    /// The estimator.
    pub estimator: crate::NonlinearEstimator<M>,
    inputs: Vec<Vec<f64>>,
    y: Vec<f64>,
    next: usize,
}

impl NonlinearWorkload<Bench10> {
    /// `method` over [`Bench10`] written in Rust (see [`with_model`](Self::with_model)).
    pub fn new(method: crate::NlMethod, n: usize) -> Result<Self, EstimError> {
        Self::with_model(Bench10::default(), method, n)
    }
}

impl<M: ParamModel> NonlinearWorkload<M> {
    /// `method` at scaled coordinates (P0 = 1e-4·I, i.e. 1 % per parameter), R2 = 1, over `n`
    /// cycled samples of [`Bench10::inputs_at`] (taken by input name: `q w a f s`), the output
    /// from the nominal parameters perturbed by 2 %.
    pub fn with_model(model: M, method: crate::NlMethod, n: usize) -> Result<Self, EstimError> {
        const NAMES: [&str; 5] = ["q", "w", "a", "f", "s"];
        let order = model
            .input_names()
            .iter()
            .map(|name| {
                NAMES.iter().position(|n| n == name).ok_or_else(|| {
                    EstimError::InvalidConfig(format!("input '{name}': not one of {NAMES:?}"))
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let truth: Vec<f64> = Bench10::NOMINAL.iter().map(|v| v * 1.02).collect();
        let inputs: Vec<Vec<f64>> = (0..n.max(1))
            .map(|k| {
                let u = Bench10::inputs_at(k);
                order.iter().map(|&i| u[i]).collect()
            })
            .collect();
        let y = inputs
            .iter()
            .map(|u| model.eval::<f64>(u, &truth))
            .collect();
        let params = ParamSet::new(model.param_names().to_vec(), Bench10::NOMINAL.to_vec())
            .map_err(|e| EstimError::InvalidConfig(e.to_string()))?;
        let cfg = crate::NlConfig {
            p0: CovSpec::Scaled(1e-4),
            scaled: true,
            ..crate::NlConfig::new(method)
        };
        let estimator = crate::NonlinearEstimator::new(model, &params, &params.all_free(), &cfg)?;
        Ok(Self {
            estimator,
            inputs,
            y,
            next: 0,
        })
    }

    /// Run `updates` updates (cycling over the data).
    pub fn run(&mut self, updates: usize) -> Result<(), EstimError> {
        let n = self.y.len();
        for _ in 0..updates {
            let i = self.next;
            self.estimator.update(&self.inputs[i], self.y[i])?;
            self.next = if i + 1 == n { 0 } else { i + 1 };
        }
        Ok(())
    }
}
