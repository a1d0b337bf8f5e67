//! A steady non-linear update loop for profilers:
//! `perf record target/release/examples/profile_nonlinear ukf 200000` (ekf, ukf, srukf).

use physid_estim::workload::NonlinearWorkload;
use physid_estim::{NlMethod, SigmaPoints};

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().collect();
    let method = match args.get(1).map_or("ukf", String::as_str) {
        "ekf" => NlMethod::Ekf,
        "ukf" => NlMethod::Ukf(SigmaPoints::default()),
        "srukf" => NlMethod::Srukf(SigmaPoints::default()),
        m => return Err(format!("unknown method '{m}'")),
    };
    let n: usize = match args.get(2) {
        Some(s) => s.parse().map_err(|e| format!("updates '{s}': {e}"))?,
        None => 200_000,
    };
    let mut w = NonlinearWorkload::new(method, 720).map_err(|e| e.to_string())?;
    w.run(n).map_err(|e| e.to_string())?;
    println!("{:?}", w.estimator.estimate());
    Ok(())
}
