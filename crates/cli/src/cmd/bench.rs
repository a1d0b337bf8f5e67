//! `physid bench`: updates per second of every estimator on one core, against the real-time
//! need of 108 000 samples/s (thesis Eq. 4.1: 9000 rpm at one sample per crank degree).

use crate::out::outln;
use miette::{IntoDiagnostic, Result};
use physid_estim::workload::{standard_methods, Workload};
use serde_json::json;
use std::time::{Duration, Instant};

/// The real-time need: 9000 rpm · 360 samples/rev / 60 s (Eq. 4.1).
pub const REALTIME_SAMPLES_PER_S: f64 = 108_000.0;

/// Arguments of `physid bench`.
#[derive(clap::Args)]
pub struct Args {
    /// Print the results as JSON.
    #[arg(long)]
    pub json: bool,
    /// Time spent on each measurement [s].
    #[arg(long, default_value_t = 0.5)]
    pub seconds: f64,
}

/// The machine: CPU model and core count.
pub fn machine() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_string());
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    format!("{cpu}, {cores} cores, {}", std::env::consts::OS)
}

/// Updates per second of `w`: repeated batches until `budget` has passed; the best of three
/// rounds (the least disturbed by the rest of the machine).
fn rate(w: &mut Workload, budget: Duration) -> Result<f64> {
    const BATCH: usize = 4096;
    w.run(BATCH).into_diagnostic()?; // warm-up
    let mut best: f64 = 0.0;
    for _ in 0..3 {
        let start = Instant::now();
        let mut n = 0usize;
        while start.elapsed() < budget / 3 {
            w.run(std::hint::black_box(BATCH)).into_diagnostic()?;
            n += BATCH;
        }
        best = best.max(n as f64 / start.elapsed().as_secs_f64());
    }
    std::hint::black_box(w.estimator.estimate());
    Ok(best)
}

/// Run the benchmark.
pub fn run(args: &Args) -> Result<()> {
    let budget = Duration::from_secs_f64(args.seconds.clamp(0.01, 60.0));
    let mut results = Vec::new();
    if !args.json {
        outln!("machine: {}", machine());
        outln!("real-time need: {REALTIME_SAMPLES_PER_S:.0} samples/s (thesis Eq. 4.1)\n");
        outln!(
            "{:<8} {:>4} {:>16} {:>14}",
            "method",
            "p",
            "updates/s",
            "× real time"
        );
    }
    for p in [2usize, 6, 20] {
        for method in standard_methods(p) {
            let name = method.name();
            let mut w = Workload::new(method, p, 4096).into_diagnostic()?;
            let r = rate(&mut w, budget)?;
            if !args.json {
                outln!(
                    "{name:<8} {p:>4} {r:>16.0} {:>14.0}",
                    r / REALTIME_SAMPLES_PER_S
                );
            }
            results.push(json!({"name": name, "p": p, "updates_per_s": r}));
        }
    }
    if args.json {
        let out = json!({"machine": machine(), "results": results});
        outln!("{}", serde_json::to_string_pretty(&out).into_diagnostic()?);
    }
    Ok(())
}
