//! A steady update loop for profilers (`perf record`, `valgrind --tool=callgrind`):
//!
//! ```sh
//! cargo build --release -p physid-estim --example profile_update
//! perf record -g target/release/examples/profile_update dsfc 6 50000000
//! ```
//!
//! Arguments: method (rls, rlsf, rlsvf, kf, dsfc; default rls), p (default 2), number of updates
//! (default 10⁸/p²). Runs the standard workload of `physid_estim::workload`.

use physid_estim::workload::{standard_methods, Workload};

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().collect();
    let name = args.get(1).map_or("rls", String::as_str);
    let p: usize = match args.get(2) {
        Some(s) => s.parse().map_err(|e| format!("p '{s}': {e}"))?,
        None => 2,
    };
    let n: usize = match args.get(3) {
        Some(s) => s.parse().map_err(|e| format!("updates '{s}': {e}"))?,
        None => 100_000_000 / (p * p).max(1),
    };
    let method = standard_methods(p)
        .into_iter()
        .find(|m| m.name() == name)
        .ok_or_else(|| format!("unknown method '{name}'"))?;
    let mut w = Workload::new(method, p, 4096).map_err(|e| e.to_string())?;
    w.run(n).map_err(|e| e.to_string())?;
    println!(
        "{name} p={p}: {n} updates, estimate {:?}",
        w.estimator.estimate()
    );
    Ok(())
}
