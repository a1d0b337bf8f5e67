//! The verbs on recordings whose bytes are sound but whose values are not: a simulated
//! recording (`torque-steady`, 1.5 s at 5 kHz, every channel, CSV) with cells, runs of cells
//! and whole columns replaced by extreme values (±10³⁰⁰, ±9.2·10¹⁸, 10⁹, 0, −1, 5·10⁻³²⁴ …),
//! columns scaled by 10¹² or −1, rows swapped or repeated — what a bad sensor, a wrong gain or
//! a DAQ's glitch writes. The byte-level campaign (`fuzz_verbs.rs`) mostly makes files that
//! are refused as files; this one makes files every reader takes, so the stages themselves
//! meet the values. It found a crank angle of 10⁹ rad for 394 samples aborting `torque fit`
//! and the live service (10⁸ empty cycles closed until the allocator gave up).
//!
//! The verbs: `cycles --knock`, `torque fit`, `monitor shaft`, and `live --replay` with the
//! cycle, friction, cyclic-torque and combustion stages. Each run is held to 4 GiB of address
//! space and killed at `PHYSID_FUZZ_HANG_S` (default 30 s); it must end in 0 (read) or 1–2
//! (refused). Case 0 is the angle jump above; the others are drawn from a fixed-seed
//! generator. CI runs `PHYSID_FUZZ_CASES` (default 6); a longer run:
//!
//! ```text
//! PHYSID_FUZZ_CASES=300 cargo test --release -p physid --test fuzz_values -- --nocapture
//! ```
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_testkit::fuzz::{env_u64, run_within, Outcome, Rng};
use physid_testkit::Scratch;
use std::path::Path;
use std::time::Duration;

fn physid() -> &'static Path {
    Path::new(env!("CARGO_BIN_EXE_physid"))
}

/// Values a bad sensor, a wrong gain or a glitch writes.
const EXTREMES: [&str; 13] = [
    "1e300",
    "-1e300",
    "9.2e18",
    "-9.2e18",
    "0",
    "-1",
    "1e-300",
    "1e15",
    "-1e15",
    "1e9",
    "5e-324",
    "1.7976931348623157e308",
    "3e8",
];

/// The recording's header, units row and cells.
struct Table {
    header: String,
    units: String,
    rows: Vec<Vec<String>>,
}

impl Table {
    fn text(&self) -> String {
        let mut s = format!("{}\n{}\n", self.header, self.units);
        for r in &self.rows {
            s += &r.join(",");
            s.push('\n');
        }
        s
    }

    fn column(&self, name: &str) -> usize {
        self.header.split(',').position(|c| c == name).unwrap()
    }
}

/// Case `n`'s mutations of `t` (case 0: `theta_en` at 10⁹ rad for 394 samples).
fn mutate(t: &mut Table, n: u64) {
    let (rows, cols) = (t.rows.len(), t.rows[0].len());
    if n == 0 {
        let c = t.column("theta_en");
        for r in &mut t.rows[2000..2394] {
            r[c] = "1e9".into();
        }
        return;
    }
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15 ^ n.wrapping_mul(0xD1B5_4A32_D192_ED03));
    for _ in 0..1 + rng.below(3) {
        let c = rng.below(cols);
        let v = EXTREMES[rng.below(EXTREMES.len())];
        match rng.below(10) {
            0..=4 => t.rows[rng.below(rows)][c] = v.into(),
            5 | 6 => {
                let i = rng.below(rows);
                for r in t.rows.iter_mut().skip(i).take(2 + rng.below(500)) {
                    r[c] = v.into();
                }
            }
            7 => t.rows.iter_mut().for_each(|r| r[c] = v.into()),
            8 => {
                let k = [1e6, 1e-6, -1.0, 1e12][rng.below(4)];
                for r in &mut t.rows {
                    let x: f64 = r[c].parse().unwrap_or(0.0);
                    r[c] = format!("{:e}", x * k);
                }
            }
            _ => {
                let i = rng.below(rows - 1);
                if rng.below(2) == 0 {
                    t.rows.swap(i, i + 1);
                } else {
                    let copy = t.rows[i].clone();
                    t.rows.insert(i, copy);
                }
            }
        }
    }
}

#[test]
fn no_verb_panics_hangs_or_is_killed_on_extreme_values() {
    let cases = env_u64("PHYSID_FUZZ_CASES", 6);
    let hang = Duration::from_secs(env_u64("PHYSID_FUZZ_HANG_S", 30));
    let s = Scratch::new("physid-fuzz-values");
    let seed = s.file("seed.csv");
    let o = std::process::Command::new(physid())
        .args([
            "simulate",
            "--scenario",
            "torque-steady",
            "--duration",
            "1.5",
        ])
        .args(["--sample-rate", "5000", "--quiet", "--recording"])
        .arg(&seed)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&seed).unwrap();
    let mut lines = text.lines();
    let (header, units) = (lines.next().unwrap(), lines.next().unwrap());
    let rows: Vec<Vec<String>> = lines
        .map(|l| l.split(',').map(String::from).collect())
        .collect();
    assert!(rows.len() > 7000);
    let (mut runs, mut refused, mut findings) = (0, 0, Vec::new());
    for n in 0..cases {
        let mut t = Table {
            header: header.into(),
            units: units.into(),
            rows: rows.clone(),
        };
        mutate(&mut t, n);
        let f = s.file(&format!("case-{n}.csv"));
        std::fs::write(&f, t.text()).unwrap();
        let f = f.to_str().unwrap();
        for args in [
            vec!["cycles", f, "--json", "--knock"],
            vec!["torque", "fit", "--data", f, "--json"],
            vec!["monitor", "shaft", "--data", f, "--json"],
            vec![
                "live",
                "--headless",
                "--json",
                "--replay",
                f,
                "--pace",
                "max",
                "--torque",
                "--combustion",
                "--friction",
                "cell",
            ],
        ] {
            let r = run_within(physid(), &args, hang, Some(4));
            runs += 1;
            match r.outcome {
                Outcome::Done => {}
                Outcome::Refused => refused += 1,
                outcome => findings.push(format!(
                    "case {n}: {}: {outcome:?} after {:.1} s: {}",
                    args[..2].join(" "),
                    r.elapsed.as_secs_f64(),
                    String::from_utf8_lossy(&r.stderr)
                        .chars()
                        .take(400)
                        .collect::<String>()
                )),
            }
        }
        let _ = std::fs::remove_file(f);
    }
    eprintln!(
        "{cases} cases, {runs} runs: {refused} refused, {} findings",
        findings.len()
    );
    assert!(findings.is_empty(), "{}", findings.join("\n"));
}
