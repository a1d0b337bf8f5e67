//! Mutation fuzzing on stable Rust, shared by the readers' in-process harness
//! (`crates/io/tests/fuzz.rs`) and the verbs' harness that runs the `physid` binary
//! (`crates/cli/tests/fuzz_verbs.rs`): a fixed-seed generator (a case is reproduced by its
//! number), the byte mutations, a run of a command under a deadline and a memory limit, and
//! what became of it.

use std::io::{Read, Write};
use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::Path;
use std::process::{Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

/// A campaign's setting from the environment (`PHYSID_FUZZ_CASES` …), or `default`.
pub fn env_u64(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(default)
}

/// SplitMix64: a small fixed-seed generator, so a case is reproducible by its number.
#[derive(Debug, Clone)]
pub struct Rng(pub u64);

impl Rng {
    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A number in `0..n` (0 when `n` is 0).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n.max(1) as u64) as usize
    }
}

/// Integers written over lengths and counts.
const INTERESTING: [u64; 12] = [
    0,
    1,
    0x7F,
    0xFF,
    0xFFFF,
    0x7FFF_FFFF,
    0x8000_0000,
    0xFFFF_FFFF,
    1 << 33,
    1 << 40,
    1 << 60,
    u64::MAX,
];

/// A Thrift compact-protocol field (id 100) holding a list that claims 2³¹ − 1 booleans, in
/// 9 bytes: what made a Parquet page header cost ≈ 8 s of decoding (issue 41, item 1).
pub const THRIFT_CLAIM: [u8; 9] = [0x09, 0xC8, 0x01, 0xF1, 0xFF, 0xFF, 0xFF, 0xFF, 0x07];

/// One mutated copy of `seed` (case `case` of its stream): one to four of bit flips, random
/// bytes, interesting integers over 1–8 bytes, bytes inserted, deleted and duplicated, a
/// Thrift claim written over, the file cut. `hot`: where the format keeps its metadata (a byte
/// range mutated half the time).
pub fn mutate(seed: &[u8], case: u64, hot: std::ops::Range<usize>) -> Vec<u8> {
    let mut r = Rng(case.wrapping_mul(0xA24B_AED4_963E_E407) ^ seed.len() as u64);
    let mut b = seed.to_vec();
    let rounds = 1 + r.below(4);
    for _ in 0..rounds {
        if b.is_empty() {
            b.push(0);
        }
        let at = if r.below(2) == 0 && hot.end <= b.len() && !hot.is_empty() {
            hot.start + r.below(hot.len())
        } else {
            r.below(b.len())
        };
        match r.below(8) {
            0 => b[at] ^= 1 << r.below(8),
            1 => b[at] = r.next_u64() as u8,
            2 => {
                // An interesting integer over 1, 2, 4 or 8 bytes, little-endian.
                let v = INTERESTING[r.below(INTERESTING.len())].to_le_bytes();
                let w = [1, 2, 4, 8][r.below(4)];
                for (k, byte) in v.iter().take(w).enumerate() {
                    if at + k < b.len() {
                        b[at + k] = *byte;
                    }
                }
            }
            3 => {
                let n = 1 + r.below(16);
                let bytes: Vec<u8> = (0..n).map(|_| r.next_u64() as u8).collect();
                b.splice(at..at, bytes);
            }
            4 => {
                let n = (1 + r.below(64)).min(b.len() - at);
                b.drain(at..at + n);
            }
            5 => {
                let n = (1 + r.below(256)).min(b.len() - at);
                let chunk = b[at..at + n].to_vec();
                let to = r.below(b.len());
                b.splice(to..to, chunk);
            }
            6 => {
                for (k, byte) in THRIFT_CLAIM.iter().enumerate() {
                    if at + k < b.len() {
                        b[at + k] = *byte;
                    }
                }
            }
            _ => b.truncate(at),
        }
    }
    b
}

/// A CSV file of `n` columns `c0 … c{n-1}` and one row (the many-columns case of issue 41).
pub fn wide_csv(path: &Path, n: usize) -> std::io::Result<()> {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path)?);
    let names: Vec<String> = (0..n).map(|k| format!("c{k}")).collect();
    writeln!(f, "{}", names.join(","))?;
    writeln!(f, "{}", vec!["1.5"; n].join(","))?;
    f.flush()
}

/// What became of a command run by [`run_within`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Outcome {
    /// It exited 0.
    Done,
    /// It exited with an error (1 or 2): refused, as it should refuse bad input.
    Refused,
    /// It panicked (exit code 101, or "panicked at" on stderr).
    Panic,
    /// A signal ended it (SIGSEGV, SIGABRT — an allocation refused under the memory limit …).
    Signal(i32),
    /// Another exit code.
    Code(i32),
    /// Still running at the deadline: killed.
    Hang,
}

/// A command's run: its outcome, its output and how long it took.
#[derive(Debug, Clone)]
pub struct Ran {
    /// What became of it.
    pub outcome: Outcome,
    /// Its exit status (`None` when killed at the deadline).
    pub status: Option<ExitStatus>,
    /// What it printed.
    pub stdout: Vec<u8>,
    /// What it printed on stderr.
    pub stderr: Vec<u8>,
    /// Wall-clock time to its end (or the deadline).
    pub elapsed: Duration,
}

/// Run `program ARGS`, killed at `deadline`, under an address-space limit of `mem_gib` GiB
/// when given (`ulimit -v` in `sh`, so no unsafe code here); the output read as it comes (a
/// full pipe would stall the child).
pub fn run_within(program: &Path, args: &[&str], deadline: Duration, mem_gib: Option<u64>) -> Ran {
    let mut cmd = match mem_gib {
        Some(g) => {
            let mut c = Command::new("sh");
            c.arg("-c")
                .arg(format!("ulimit -v {} && exec \"$0\" \"$@\"", g << 20))
                .arg(program)
                .args(args);
            c
        }
        None => {
            let mut c = Command::new(program);
            c.args(args);
            c
        }
    };
    let start = Instant::now();
    // A process group of its own, so the deadline ends whatever it started too.
    let mut child = match cmd
        .process_group(0)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
    {
        Ok(c) => c,
        Err(e) => {
            return Ran {
                outcome: Outcome::Code(-1),
                status: None,
                stdout: Vec::new(),
                stderr: format!("could not start {}: {e}", program.display()).into_bytes(),
                elapsed: start.elapsed(),
            }
        }
    };
    let drain = |r: Option<Box<dyn Read + Send>>| {
        std::thread::spawn(move || {
            let mut buf = Vec::new();
            if let Some(mut r) = r {
                let _ = r.read_to_end(&mut buf);
            }
            buf
        })
    };
    let out = drain(
        child
            .stdout
            .take()
            .map(|s| Box::new(s) as Box<dyn Read + Send>),
    );
    let err = drain(
        child
            .stderr
            .take()
            .map(|s| Box::new(s) as Box<dyn Read + Send>),
    );
    let mut status = None;
    while start.elapsed() < deadline {
        match child.try_wait() {
            Ok(Some(s)) => {
                status = Some(s);
                break;
            }
            Ok(None) => std::thread::sleep(Duration::from_millis(5)),
            Err(_) => break,
        }
    }
    let elapsed = start.elapsed();
    if status.is_none() {
        let _ = Command::new("kill")
            .args(["-KILL", "--", &format!("-{}", child.id())])
            .status();
        let _ = child.kill();
        let _ = child.wait();
    }
    let stdout = out.join().unwrap_or_default();
    let stderr = err.join().unwrap_or_default();
    let panicked = String::from_utf8_lossy(&stderr).contains("panicked at");
    let outcome = match status {
        None => Outcome::Hang,
        Some(s) => match (s.code(), s.signal()) {
            (_, Some(sig)) => Outcome::Signal(sig),
            (Some(101), _) => Outcome::Panic,
            _ if panicked => Outcome::Panic,
            (Some(0), _) => Outcome::Done,
            (Some(1 | 2), _) => Outcome::Refused,
            (Some(c), _) => Outcome::Code(c),
            (None, None) => Outcome::Code(-1),
        },
    };
    Ran {
        outcome,
        status,
        stdout,
        stderr,
        elapsed,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_case_is_reproduced_by_its_number() {
        let seed: Vec<u8> = (0..=255).collect();
        for case in 0..50 {
            assert_eq!(mutate(&seed, case, 0..16), mutate(&seed, case, 0..16));
        }
        assert_ne!(mutate(&seed, 1, 0..16), mutate(&seed, 2, 0..16));
    }

    #[test]
    fn outcomes_are_told_apart() {
        let sh = Path::new("sh");
        let d = Duration::from_secs(20);
        assert_eq!(
            run_within(sh, &["-c", "true"], d, None).outcome,
            Outcome::Done
        );
        assert_eq!(
            run_within(sh, &["-c", "exit 1"], d, None).outcome,
            Outcome::Refused
        );
        assert_eq!(
            run_within(sh, &["-c", "exit 101"], d, None).outcome,
            Outcome::Panic
        );
        assert_eq!(
            run_within(sh, &["-c", "kill -SEGV $$"], d, None).outcome,
            Outcome::Signal(11)
        );
        let r = run_within(sh, &["-c", "sleep 5"], Duration::from_millis(100), Some(4));
        assert_eq!(r.outcome, Outcome::Hang);
        assert!(r.elapsed < Duration::from_secs(5));
        assert!(r.stdout.is_empty());
        let r = run_within(sh, &["-c", "echo hi"], d, Some(4));
        assert_eq!((r.outcome, r.stdout), (Outcome::Done, b"hi\n".to_vec()));
    }
}
