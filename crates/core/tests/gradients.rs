//! Exact gradients through the model seam against central finite differences (the one place
//! finite differences appear: as the independent witness).
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_core::{GradientEngine, ParamModel, Scalar};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A 12-parameter model using every elementary function, so the gradient takes two chunks.
struct Mixed {
    params: Vec<String>,
    inputs: Vec<String>,
}

impl Mixed {
    fn new() -> Self {
        Self {
            params: (1..=12).map(|i| format!("p{i}")).collect(),
            inputs: vec!["x".into(), "y".into()],
        }
    }
}

impl ParamModel for Mixed {
    fn param_names(&self) -> &[String] {
        &self.params
    }
    fn input_names(&self) -> &[String] {
        &self.inputs
    }
    fn eval<T: Scalar>(&self, u: &[f64], p: &[T]) -> T {
        let (x, y) = (u[0], u[1]);
        p[0].sin() * x
            + p[1] * p[1] * y * x.cos()
            + p[2].sqrt() * x * x
            + p[3].exp() * 0.1
            + p[4].ln() * y
            + (p[5] * x * 0.3).tan() * 0.2
            + (p[6] * 0.3).asin()
            + (p[7] * 0.3).acos()
            + p[8].atan() * y
            + p[9].powf(2.5)
            + p[10].powd(p[11]) / (p[0] * x + 3.0)
            + (p[4] - 2.0).abs()
    }
}

fn central_difference<M: ParamModel>(m: &M, u: &[f64], p: &[f64], j: usize) -> f64 {
    let h = 1e-6 * p[j].abs().max(1e-3);
    let mut a = p.to_vec();
    let mut b = p.to_vec();
    a[j] += h;
    b[j] -= h;
    (m.eval::<f64>(u, &a) - m.eval::<f64>(u, &b)) / (2.0 * h)
}

#[test]
fn gradients_equal_central_differences_at_random_points() {
    let m = Mixed::new();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut engine = GradientEngine::new(12);
    let all: Vec<usize> = (0..12).collect();
    let subset = [11usize, 2, 7];
    for _ in 0..200 {
        let u = [rng.random_range(-2.0..2.0), rng.random_range(0.5..2.0)];
        let p: Vec<f64> = (0..12).map(|_| rng.random_range(0.3..1.5)).collect();
        let mut g = vec![0.0; 12];
        let v = engine.value_and_gradient(&m, &u, &p, &all, &mut g);
        let plain = m.eval::<f64>(&u, &p);
        assert!(
            (v - plain).abs() <= 1e-14 * plain.abs().max(1.0),
            "{v} vs {plain}"
        );
        for (j, &gj) in g.iter().enumerate() {
            let fd = central_difference(&m, &u, &p, j);
            assert!(
                (gj - fd).abs() <= 1e-6 * fd.abs().max(1.0),
                "∂h/∂p{}: exact {gj} vs FD {fd}",
                j + 1
            );
        }
        // A subset in any order gives the same partials.
        let mut gs = vec![0.0; 3];
        engine.value_and_gradient(&m, &u, &p, &subset, &mut gs);
        for (k, &j) in subset.iter().enumerate() {
            assert_eq!(gs[k], g[j]);
        }
    }
}
