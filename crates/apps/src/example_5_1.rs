//! Thesis Example 5.1's model (SPEC §4), written in Rust:
//! `z = sin(A)·x + B²·y·cos(x) + sqrt(C)·x² + D·y² + E·x/y + F·2x/y`, A…F = 1…6.
//!
//! The identifiability example itself (which parameters are estimable) arrives with the
//! identifiability issue; this native model is the reference the expression language is
//! measured against (`physid bench`: `expr` vs `native`).

use physid_core::{ParamModel, Scalar};

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
