//! The verbs under fuzzing (issue 41): the `physid` binary itself run on mutated recordings,
//! as the second fuzz campaign ran it, each run under a hang detector (killed at
//! `PHYSID_FUZZ_HANG_S`, default 20 s) and a 4 GiB address-space limit. A simulated recording
//! (`shaft-steady`, 0.3 s: 3 001 rows, 35 channels) written as Parquet, MDF4 and CSV is
//! mutated ([`physid_testkit::fuzz::mutate`], with weight on each format's metadata) and read
//! by `inspect --json` and `monitor shaft --json`; every `PHYSID_FUZZ_WIDE_EVERY`-th case
//! (default 100) is instead a CSV of 10 000, 30 000 or 100 000 columns and one row (the
//! quadratic-width case) through `inspect`, `monitor shaft` and `convert`.
//!
//! Every run must end by itself, in an exit code 0 (read), 1 or 2 (refused): a panic, a signal
//! (a crash, or an allocation refused under the limit) or a hang fails the test, naming the
//! case. CI runs `PHYSID_FUZZ_CASES` (default 12) cases; the long run (BENCHMARKS.md records
//! it) is bounded by time instead:
//!
//! ```text
//! PHYSID_FUZZ_SECONDS=1800 PHYSID_FUZZ_CASES=1000000 cargo test --release -p physid --test fuzz_verbs -- --nocapture
//! ```
//!
//! `PHYSID_FUZZ_ONLY=N` runs case N alone; `PHYSID_FUZZ_SAVE=DIR` keeps each failing input.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_testkit::fuzz::{env_u64, mutate, run_within, wide_csv, Outcome};
use physid_testkit::Scratch;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

fn physid() -> &'static Path {
    Path::new(env!("CARGO_BIN_EXE_physid"))
}

struct Seed {
    ext: &'static str,
    bytes: Vec<u8>,
    hot: std::ops::Range<usize>,
}

/// The simulated recording in the three formats.
fn seeds(s: &Scratch) -> Vec<Seed> {
    let pq = s.file("seed.parquet");
    let o = std::process::Command::new(physid())
        .args([
            "simulate",
            "--scenario",
            "shaft-steady",
            "--duration",
            "0.3",
        ])
        .args(["--quiet", "--recording", pq.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut v = Vec::new();
    for ext in ["parquet", "mf4", "csv"] {
        let f = s.file(&format!("seed.{ext}"));
        if ext != "parquet" {
            let o = std::process::Command::new(physid())
                .args(["convert", pq.to_str().unwrap(), f.to_str().unwrap()])
                .output()
                .unwrap();
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        }
        let bytes = std::fs::read(&f).unwrap();
        let n = bytes.len();
        let hot = match ext {
            // The footer and the last column chunks.
            "parquet" => n.saturating_sub(8192)..n,
            // The header blocks (identification, header, data group, channel group, channels).
            "mf4" => 0..8192.min(n),
            // The header (and units) rows.
            _ => 0..1024.min(n),
        };
        v.push(Seed { ext, bytes, hot });
    }
    v
}

/// A run that did not end as it should.
#[derive(Debug)]
struct Finding {
    case: u64,
    verb: String,
    outcome: Outcome,
    secs: f64,
    stderr: String,
}

#[derive(Default)]
struct Tally {
    runs: u64,
    read: u64,
    refused: u64,
    slowest: (f64, u64, String),
    findings: Vec<Finding>,
}

/// One case: its file, then each verb on it.
fn case(n: u64, seeds: &[Seed], dir: &Path, hang: Duration, wide_every: u64, tally: &Mutex<Tally>) {
    let (file, verbs): (PathBuf, Vec<Vec<String>>) =
        if wide_every > 0 && n % wide_every == wide_every - 1 {
            let width = [10_000, 30_000, 100_000][(n / wide_every % 3) as usize];
            let f = dir.join(format!("case-{n}.csv"));
            wide_csv(&f, width).unwrap();
            let out = dir.join(format!("case-{n}-out.parquet"));
            let fs = f.to_str().unwrap().to_string();
            (
                f,
                vec![
                    vec!["inspect".into(), fs.clone(), "--json".into()],
                    vec![
                        "monitor".into(),
                        "shaft".into(),
                        "--data".into(),
                        fs.clone(),
                    ],
                    vec!["convert".into(), fs, out.to_str().unwrap().into()],
                ],
            )
        } else {
            let seed = &seeds[(n % seeds.len() as u64) as usize];
            let f = dir.join(format!("case-{n}.{}", seed.ext));
            std::fs::write(&f, mutate(&seed.bytes, n, seed.hot.clone())).unwrap();
            let fs = f.to_str().unwrap().to_string();
            (
                f,
                vec![
                    vec!["inspect".into(), fs.clone(), "--json".into()],
                    vec![
                        "monitor".into(),
                        "shaft".into(),
                        "--data".into(),
                        fs,
                        "--json".into(),
                    ],
                ],
            )
        };
    for args in &verbs {
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        let r = run_within(physid(), &a, hang, Some(4));
        let secs = r.elapsed.as_secs_f64();
        let mut t = tally.lock().unwrap();
        t.runs += 1;
        let verb = a[..if a[0] == "monitor" { 2 } else { 1 }].join(" ");
        if secs > t.slowest.0 {
            t.slowest = (secs, n, verb.clone());
        }
        match r.outcome {
            Outcome::Done => t.read += 1,
            Outcome::Refused => t.refused += 1,
            outcome => {
                if let Ok(save) = std::env::var("PHYSID_FUZZ_SAVE") {
                    let _ = std::fs::copy(&file, Path::new(&save).join(file.file_name().unwrap()));
                }
                let stderr = String::from_utf8_lossy(&r.stderr);
                t.findings.push(Finding {
                    case: n,
                    verb,
                    outcome,
                    secs,
                    stderr: stderr
                        .chars()
                        .rev()
                        .take(600)
                        .collect::<Vec<_>>()
                        .into_iter()
                        .rev()
                        .collect(),
                });
            }
        }
    }
    let _ = std::fs::remove_file(&file);
}

#[test]
fn no_verb_panics_hangs_or_is_killed_on_mutated_recordings() {
    let cases = env_u64("PHYSID_FUZZ_CASES", 12);
    let seconds = env_u64("PHYSID_FUZZ_SECONDS", 0);
    let hang = Duration::from_secs(env_u64("PHYSID_FUZZ_HANG_S", 20));
    let wide_every = env_u64("PHYSID_FUZZ_WIDE_EVERY", 100);
    let only = std::env::var("PHYSID_FUZZ_ONLY")
        .ok()
        .and_then(|s| s.parse::<u64>().ok());
    let scratch = Scratch::new("physid-fuzz-verbs");
    let seeds = Arc::new(seeds(&scratch));
    let dir = scratch.file("cases");
    std::fs::create_dir_all(&dir).unwrap();
    let (from, to) = only.map_or((0, cases), |c| (c, c + 1));
    let next = Arc::new(AtomicU64::new(from));
    let tally = Arc::new(Mutex::new(Tally::default()));
    let start = Instant::now();
    let workers: Vec<_> = (0..2)
        .map(|_| {
            let (seeds, next, tally, dir) =
                (seeds.clone(), next.clone(), tally.clone(), dir.clone());
            std::thread::spawn(move || loop {
                if seconds > 0 && start.elapsed() > Duration::from_secs(seconds) {
                    return;
                }
                let n = next.fetch_add(1, Ordering::Relaxed);
                if n >= to {
                    return;
                }
                case(n, &seeds, &dir, hang, wide_every, &tally);
            })
        })
        .collect();
    for w in workers {
        w.join().unwrap();
    }
    let t = tally.lock().unwrap();
    let done = next.load(Ordering::Relaxed).min(to) - from;
    println!(
        "{done} cases, {} runs in {:.0} s: {} read, {} refused, {} findings (panics, signals, hangs over {} s); slowest run {:.2} s ({} on case {})",
        t.runs,
        start.elapsed().as_secs_f64(),
        t.read,
        t.refused,
        t.findings.len(),
        hang.as_secs(),
        t.slowest.0,
        t.slowest.2,
        t.slowest.1,
    );
    for f in &t.findings {
        println!(
            "case {} ({}): {:?} after {:.1} s — PHYSID_FUZZ_ONLY={} — {}",
            f.case, f.verb, f.outcome, f.secs, f.case, f.stderr
        );
    }
    assert!(
        t.findings.is_empty(),
        "{} findings: {:?}",
        t.findings.len(),
        t.findings
    );
    assert!(t.runs > 0);
}
