//! A steady evaluation loop for profilers:
//! `cargo build --release -p physid-expr --example profile_eval &&
//!  perf record target/release/examples/profile_eval value` (or `gradient`).

use physid_core::{GradientEngine, ParamModel};
use physid_expr::ExprModel;

const EX51: &str = "sin(A)*x + B^2*y*cos(x) + sqrt(C)*x^2 + D*y^2 + E*x/y + F*2*x/y";

fn main() -> Result<(), String> {
    let what = std::env::args().nth(1).unwrap_or_else(|| "value".into());
    let m = ExprModel::parse(EX51, &["A", "B", "C", "D", "E", "F"]).map_err(|e| e.to_string())?;
    let p = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
    let free: Vec<usize> = (0..6).collect();
    let mut engine = GradientEngine::new(6);
    let mut g = [0.0; 6];
    let mut s = 0.0;
    for i in 0..20_000_000u64 {
        let u = [
            1.2 + (i % 1000) as f64 * 1e-3,
            1.0 + (i % 777) as f64 * 1e-3,
        ];
        s += if what == "gradient" {
            engine.value_and_gradient(&m, &u, &p, &free, &mut g)
        } else {
            m.eval::<f64>(&u, &p)
        };
    }
    println!("{s}");
    Ok(())
}
