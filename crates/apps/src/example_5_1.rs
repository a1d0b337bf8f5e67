//! Thesis Example 5.1 (§5.2, SPEC §4): which parameters of
//! `z = sin(A)·x + B²·y·cos(x) + sqrt(C)·x² + D·y² + E·x/y + F·2x/y`, A…F = 1…6, are estimable.
//! Expected: `[D, C, B, A, F]` in that order, E unidentifiable (its sensitivity `x/y` is half
//! of F's `2x/y`, whatever the data).
//!
//! The thesis's inputs (Fig. 5.3) are not in its text, and the order among D, C, B, A depends on
//! them (SPEC §4). Ours, sampled at 100 Hz for 20 s, each plus unit white Gaussian noise (as
//! the thesis's), with unit white noise on z:
//!
//! * `x(t) = 30·sin(0.7·t)` — large, so that `x²` (C) outranks `y·cos x` (B);
//! * `y(t) = 30 + 3·cos(0.45·t)` — far from zero, and nearly constant, so that `2x/y` (F) is
//!   nearly explained by `x` (A) and ranks after it.
//!
//! With y near 3 instead of 30 F outranks A, and with x of amplitude 10 B outranks C — the E/F
//! dependence is the only part of the result that does not depend on the experiment.
//!
//! The native model here is also the reference the expression language is measured against
//! (`physid bench`: `expr` vs `native`).

use physid_core::{ParamModel, Scalar};
use physid_ident::{analyse, Analysis, Data, IdentConfig, IdentError};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// The model's text in the expression language.
pub const EXPRESSION: &str = "sin(A)*x + B^2*y*cos(x) + sqrt(C)*x^2 + D*y^2 + E*x/y + F*2*x/y";

/// Nominal values A…F.
pub const NOMINAL: [f64; 6] = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];

/// Example 5.1's model in Rust.
#[derive(Debug, Clone)]
pub struct Model51 {
    params: Vec<String>,
    inputs: Vec<String>,
}

impl Default for Model51 {
    fn default() -> Self {
        Self {
            params: ["A", "B", "C", "D", "E", "F"]
                .iter()
                .map(|s| s.to_string())
                .collect(),
            inputs: vec!["x".into(), "y".into()],
        }
    }
}

impl ParamModel for Model51 {
    fn param_names(&self) -> &[String] {
        &self.params
    }
    fn input_names(&self) -> &[String] {
        &self.inputs
    }
    fn eval<T: Scalar>(&self, u: &[f64], p: &[T]) -> T {
        let (x, y) = (u[0], u[1]);
        p[0].sin() * x
            + p[1] * p[1] * (y * x.cos())
            + p[2].sqrt() * (x * x)
            + p[3] * (y * y)
            + p[4] * (x / y)
            + p[5] * (2.0 * x / y)
    }
}

/// The example's data: inputs and the noisy output.
#[derive(Debug, Clone)]
pub struct Example51Data {
    /// Time [s].
    pub t: Vec<f64>,
    /// Input x.
    pub x: Vec<f64>,
    /// Input y.
    pub y: Vec<f64>,
    /// Output z (model at the nominal values plus unit noise).
    pub z: Vec<f64>,
}

/// Generate the example's data (documented in the module), reproducibly from `seed`.
pub fn example_5_1_data(seed: u64) -> Example51Data {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = 2000;
    let model = Model51::default();
    let mut d = Example51Data {
        t: Vec::with_capacity(n),
        x: Vec::with_capacity(n),
        y: Vec::with_capacity(n),
        z: Vec::with_capacity(n),
    };
    for i in 0..n {
        let t = i as f64 * 0.01;
        let nx: f64 = StandardNormal.sample(&mut rng);
        let ny: f64 = StandardNormal.sample(&mut rng);
        let nz: f64 = StandardNormal.sample(&mut rng);
        let x = 30.0 * (0.7 * t).sin() + nx;
        let y = 30.0 + 3.0 * (0.45 * t).cos() + ny;
        d.t.push(t);
        d.x.push(x);
        d.y.push(y);
        d.z.push(model.eval::<f64>(&[x, y], &NOMINAL) + nz);
    }
    d
}

/// The identifiability analysis of the example (thesis scaling, the model's output at the
/// nominal values, as the thesis does).
pub fn example_5_1(data: &Example51Data) -> Result<Analysis, IdentError> {
    let d = Data {
        inputs: vec![&data.x, &data.y],
        y: None,
    };
    analyse(
        &Model51::default(),
        &d,
        &NOMINAL,
        &[],
        IdentConfig::default(),
    )
}
