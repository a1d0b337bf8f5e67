//! No data lost (docs/live.md): a live log being written survives SIGTERM, SIGINT and SIGHUP
//! (closed, readable as it is), its events' reader going away, and `kill -9` (readable as it is for MDF4, after `physid recover` for
//! Parquet), at seeded random moments; what it holds is a stretch of `physid simulate`'s
//! samples for the same scenario, bit for bit, missing at most the last second of wall-clock
//! time before the kill. `simulate` and `convert` stopped by SIGTERM leave their output
//! closed and readable too.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::physid;
use physid_core::Recording;
use serde_json::Value;
use std::io::{BufRead, BufReader, Write};
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// A seeded xorshift: the kill moments, the same on every run.
struct Seeded(u64);

impl Seeded {
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        lo + (hi - lo) * (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// `sig` to process `pid` (`kill -s SIG PID`).
fn signal(pid: u32, sig: &str) {
    let ok = Command::new("kill")
        .args(["-s", sig, &pid.to_string()])
        .status()
        .unwrap()
        .success();
    assert!(ok, "kill -s {sig} {pid}");
}

/// `physid live --headless` on the shaft-steady cell for `duration` s at 4× real time, its
/// controls on its stdin (returned, open) and a log `name` in `dir` started at once.
fn live_logging(
    dir: &std::path::Path,
    name: &str,
    duration: &str,
    stderr: Stdio,
) -> (std::process::Child, std::process::ChildStdin) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_physid"))
        .args([
            "live",
            "--headless",
            "--json",
            "--scenario",
            "shaft-steady",
            "--duration",
            duration,
            "--pace",
            "4",
            "--controls",
            "-",
            "--log-dir",
            dir.to_str().unwrap(),
        ])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(stderr)
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    writeln!(stdin, r#"{{"cmd":"record","file":"{name}"}}"#).unwrap();
    (child, stdin)
}

/// The first logged time's place in `sim`, and every channel of `logged` equal to `sim`'s
/// from there, bit for bit, with its unit.
fn a_stretch_of(logged: &Recording, sim: &Recording, what: &str) {
    assert!(!logged.is_empty(), "{what}: no sample");
    let t0 = logged.values("t").unwrap()[0];
    let k0 = sim
        .values("t")
        .unwrap()
        .iter()
        .position(|&t| t == t0)
        .unwrap_or_else(|| panic!("{what}: the first logged time {t0} is not simulated"));
    assert_eq!(logged.channels().len(), sim.channels().len(), "{what}");
    for c in logged.channels() {
        let want = &sim.values(&c.name).unwrap()[k0..k0 + logged.len()];
        assert!(c.values == want, "{what}: channel {} differs", c.name);
        assert_eq!(
            c.unit,
            sim.channel(&c.name).unwrap().unit,
            "{what}: {}",
            c.name
        );
    }
}

#[test]
fn a_live_log_survives_every_stop() {
    let s = physid_testkit::Scratch::new("physid-no-data-lost");
    let sim_path = s.file("sim.parquet");
    let o = physid(&[
        "simulate",
        "--scenario",
        "shaft-steady",
        "--duration",
        "14",
        "--recording",
        sim_path.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let sim = physid_io::read_parquet(&sim_path, None).unwrap();
    let mut rng = Seeded(0x5eed_1234_abcd_0042);
    let cases = [
        ("TERM", "parquet"),
        ("INT", "mf4"),
        ("KILL", "parquet"),
        ("KILL", "mf4"),
        ("TERM", "mf4"),
        ("INT", "parquet"),
        ("KILL", "parquet"),
        ("HUP", "mf4"),
        ("HUP", "parquet"),
    ];
    for (i, (sig, ext)) in cases.into_iter().enumerate() {
        let dir = s.file(&format!("logs-{i}"));
        let name = format!("run.{ext}");
        let (mut child, stdin) = live_logging(&dir, &name, "14", Stdio::null());
        // The events as they come, each with the wall-clock moment it was read.
        let (tx, rx) = mpsc::channel::<(Instant, Value)>();
        let out = BufReader::new(child.stdout.take().unwrap());
        let reader = std::thread::spawn(move || {
            for line in out.lines().map_while(Result::ok) {
                if let Ok(v) = serde_json::from_str(&line) {
                    let _ = tx.send((Instant::now(), v));
                }
            }
        });
        let mut seen: Vec<(Instant, Value)> = Vec::new();
        let deadline = Instant::now() + Duration::from_secs(30);
        // The log has started: its first `log` event.
        while !seen.iter().any(|(_, e)| e["type"] == "log") {
            let e = rx
                .recv_timeout(deadline - Instant::now())
                .expect("a log event");
            seen.push(e);
        }
        let wait = Duration::from_secs_f64(rng.uniform(0.3, 2.0));
        let kill_at = Instant::now() + wait;
        while let Ok(e) = rx.recv_timeout(kill_at.saturating_duration_since(Instant::now())) {
            seen.push(e);
        }
        let killed = Instant::now();
        if sig == "KILL" {
            child.kill().unwrap();
        } else {
            signal(child.id(), sig);
        }
        let status = child.wait().unwrap();
        drop(stdin);
        reader.join().unwrap();
        seen.extend(rx.try_iter());
        let what = format!(
            "case {i}: SIG{sig} after {:.2} s, {name}",
            wait.as_secs_f64()
        );
        let file = dir.join(&name);
        if sig != "KILL" {
            assert!(status.success(), "{what}: {status}");
            // Closed by the run: readable as it is, its last `log` event says what it holds.
            let closed = seen
                .iter()
                .rev()
                .find(|(_, e)| e["type"] == "log" && e["state"] == "closed")
                .unwrap_or_else(|| panic!("{what}: no closing log event"));
            let logged = physid_io::read(&file, &Default::default()).unwrap();
            assert_eq!(
                closed.1["samples"].as_u64().unwrap() as usize,
                logged.len(),
                "{what}"
            );
            assert!(logged.len() > 1000, "{what}: {} samples", logged.len());
            a_stretch_of(&logged, &sim, &what);
            continue;
        }
        if ext == "parquet" {
            let o = physid(&["recover", file.to_str().unwrap()]);
            assert!(
                o.status.success(),
                "{what}: {}",
                String::from_utf8_lossy(&o.stderr)
            );
        }
        let logged =
            physid_io::read(&file, &Default::default()).unwrap_or_else(|e| panic!("{what}: {e}"));
        a_stretch_of(&logged, &sim, &what);
        // Every sample the run had processed a second and a half before the kill is there
        // (commits each second; the estimate events follow their chunk).
        let t_last = *logged.values("t").unwrap().last().unwrap();
        let processed = seen
            .iter()
            .filter(|(at, e)| {
                e["type"] == "estimate" && *at + Duration::from_millis(1500) <= killed
            })
            .filter_map(|(_, e)| e["t_s"].as_f64())
            .fold(f64::NEG_INFINITY, f64::max);
        assert!(
            t_last >= processed,
            "{what}: the log ends at {t_last} s; {processed} s had been processed 1.5 s before"
        );
    }
}

/// `simulate` stopped by SIGTERM keeps its output closed and readable: the first samples of
/// the whole run, bit for bit.
#[test]
fn simulate_stopped_by_a_signal_keeps_what_it_wrote() {
    let s = physid_testkit::Scratch::new("physid-sim-signal");
    let whole = s.file("whole.parquet");
    let part = s.file("part.mf4");
    let o = physid(&[
        "simulate",
        "--scenario",
        "shaft-steady",
        "--duration",
        "6",
        "--recording",
        whole.to_str().unwrap(),
    ]);
    assert!(o.status.success());
    let whole = physid_io::read_parquet(&whole, None).unwrap();
    let child = Command::new(env!("CARGO_BIN_EXE_physid"))
        .args([
            "simulate",
            "--scenario",
            "shaft-steady",
            "--duration",
            "600",
            "--recording",
            part.to_str().unwrap(),
        ])
        .stderr(Stdio::piped())
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    // Until it has written a few seconds.
    let deadline = Instant::now() + Duration::from_secs(60);
    while std::fs::metadata(&part).map_or(0, |m| m.len()) < 4_000_000 {
        assert!(Instant::now() < deadline, "simulate wrote nothing in 60 s");
        std::thread::sleep(Duration::from_millis(20));
    }
    signal(child.id(), "TERM");
    let o = child.wait_with_output().unwrap();
    assert!(!o.status.success(), "an interrupted simulate says so");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("interrupted by a signal"), "{err}");
    let got = physid_io::read(&part, &Default::default()).unwrap();
    assert!(
        err.contains(&format!("the first {} samples", got.len())),
        "{err}"
    );
    let n = got.len().min(whole.len());
    assert!(n > 10_000, "{} samples", got.len());
    for c in got.channels() {
        assert!(
            c.values[..n] == whole.values(&c.name).unwrap()[..n],
            "channel {}",
            c.name
        );
    }
}

/// `physid recover` on files it has nothing to do for, and on one that is not a log.
#[test]
fn recover_says_what_it_did() {
    let s = physid_testkit::Scratch::new("physid-recover");
    let f = s.file("ok.parquet");
    common::simulated(&f, "shaft-steady", "20");
    let o = physid(&["recover", f.to_str().unwrap()]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("nothing to recover"));
    // Cut mid-file: the row groups committed before the cut come back.
    let bytes = std::fs::read(&f).unwrap();
    let whole = physid_io::read_parquet(&f, None).unwrap();
    let torn = s.file("torn.parquet");
    std::fs::write(&torn, &bytes[..bytes.len() / 2]).unwrap();
    let o = physid(&["recover", torn.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let got = physid_io::read_parquet(&torn, None).unwrap();
    assert!(!got.is_empty() && got.len() < whole.len(), "{}", got.len());
    assert!(got.values("t").unwrap()[..] == whole.values("t").unwrap()[..got.len()]);
    // A torn CSV line.
    let csv = s.file("torn.csv");
    std::fs::write(&csv, "t,x\n0,1\n1,2\n2,").unwrap();
    let o = physid(&["recover", csv.to_str().unwrap()]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("2 bytes cut off"));
    assert_eq!(std::fs::read_to_string(&csv).unwrap(), "t,x\n0,1\n1,2\n");
    let junk = s.file("junk.parquet");
    std::fs::write(&junk, b"hello").unwrap();
    let o = physid(&["recover", junk.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("not a Parquet file"));
}

/// `physid live` recording into `dir` through `sh -c script` (the script's `$1` is `physid`,
/// `$2` the directory): its events, once it has ended.
fn live_through_shell(script: &str, dir: &std::path::Path, ext: &str, pace: &str) -> Vec<Value> {
    let run = format!(
        r#"{script} "$1" live --headless --json --scenario shaft-steady --duration 6 --pace {pace} --controls - --log-dir "$2""#
    );
    let mut child = Command::new("sh")
        .args(["-c", &run, "sh", env!("CARGO_BIN_EXE_physid")])
        .arg(dir)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    writeln!(stdin, r#"{{"cmd":"record","file":"run.{ext}"}}"#).unwrap();
    drop(stdin);
    let o = child.wait_with_output().unwrap();
    assert!(
        o.status.success(),
        "{script}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout)
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect()
}

/// `physid args` under a file-size limit of `kib` KiB (the shell's `ulimit -f`), SIGXFSZ
/// ignored so that a write past it fails (EFBIG) instead of killing the process.
fn physid_limited(kib: u32, args: &[&std::ffi::OsStr]) -> std::process::Output {
    Command::new("sh")
        .args([
            "-c",
            &format!(r#"trap '' XFSZ; ulimit -f {kib}; exec "$0" "$@""#),
            env!("CARGO_BIN_EXE_physid"),
        ])
        .args(args)
        .output()
        .unwrap()
}

/// The log's stopping told: the `error` event's message (which must contain `says`) and the
/// last `log` event's samples (closed); the run went on to its end.
fn log_stopped(events: &[Value], says: &str, what: &str) -> usize {
    let error = events
        .iter()
        .find(|e| e["type"] == "error")
        .unwrap_or_else(|| panic!("{what}: no error event"));
    let message = error["message"].as_str().unwrap();
    assert!(message.contains(says), "{what}: {message}");
    let last = events.iter().rev().find(|e| e["type"] == "log").unwrap();
    assert_eq!(last["state"], "closed", "{what}: {last}");
    let end = events.last().unwrap();
    assert_eq!(end["type"], "end", "{what}: the run did not go on");
    assert_eq!(end["samples"], 60_001, "{what}: {end}");
    last["samples"].as_u64().unwrap() as usize
}

/// A live log on a full disk loses nothing it can keep. On a small file system (a 4 MB tmpfs
/// in a mount namespace of its own) the log is closed before the disk fills — every sample so
/// far, readable — where it used to write until the disk refused and leave a Parquet file no
/// reader opens (its footer unwritten) or an MDF4 file holding only its first commit. A write
/// refused anyway (here by the process's file-size limit, `ulimit -f`) leaves the file
/// readable up to its last commit. Either way the run goes on, and the log holds a stretch of
/// `physid simulate`'s samples, bit for bit.
#[test]
fn a_live_log_on_a_full_disk_keeps_what_it_can() {
    let s = physid_testkit::Scratch::new("physid-full-disk");
    let sim_path = s.file("sim.parquet");
    common::simulated(&sim_path, "shaft-steady", "6");
    let sim = physid_io::read_parquet(&sim_path, None).unwrap();
    for ext in ["parquet", "mf4"] {
        // The file-size limit: 6 MB (the shell's `ulimit -f` counts 1024-byte blocks), SIGXFSZ
        // ignored so that the write fails instead of killing the process; paced, so that
        // commits come each second.
        let dir = s.file(&format!("limit-{ext}"));
        std::fs::create_dir_all(&dir).unwrap();
        let events = live_through_shell("trap '' XFSZ; ulimit -f 6000;", &dir, ext, "2");
        let what = format!("{ext}, file-size limit");
        let kept = log_stopped(&events, "File too large (os error 27)", &what);
        let logged = physid_io::read(dir.join(format!("run.{ext}")), &Default::default())
            .unwrap_or_else(|e| panic!("{what}: {e}"));
        assert_eq!(logged.len(), kept, "{what}");
        // At least what the first commit held: the log's first chunk, committed at once and
        // reported by the first `log` event.
        let first = events
            .iter()
            .find(|e| e["type"] == "log" && e["state"] == "recording")
            .unwrap_or_else(|| panic!("{what}: no log event while recording"));
        let committed = first["samples"].as_u64().unwrap() as usize;
        assert!(
            kept >= committed && kept > 0,
            "{what}: {kept} < {committed}"
        );
        a_stretch_of(&logged, &sim, &what);
        // The small disk: mounted in a namespace of its own, the log copied out after.
        let out = s.file(&format!("small-{ext}"));
        std::fs::create_dir_all(&out).unwrap();
        let small = s.file(&format!("mnt-{ext}"));
        std::fs::create_dir_all(&small).unwrap();
        let probe = Command::new("unshare")
            .args(["--mount", "--map-root-user", "sh", "-c"])
            .arg("mount -t tmpfs -o size=4m tmpfs \"$0\"")
            .arg(&small)
            .output();
        if !probe.is_ok_and(|o| o.status.success()) {
            eprintln!(
                "a_live_log_on_a_full_disk_keeps_what_it_can: no mount namespace here (unshare --mount --map-root-user): the small-disk half is not run"
            );
            continue;
        }
        // The inner shell: `$0` is physid, `$@` its arguments (the paths are the scratch's,
        // without spaces or quotes).
        let script = format!(
            r#"exec unshare --mount --map-root-user sh -c 'mount -t tmpfs -o size=4m tmpfs {} && "$0" "$@"; cp {}/run.{ext} {}/' "#,
            small.display(),
            small.display(),
            out.display()
        );
        let events = live_through_shell(&script, &small, ext, "max");
        let what = format!("{ext}, a 4 MB disk");
        let kept = log_stopped(&events, "less than the log needs to go on and close", &what);
        let logged = physid_io::read(out.join(format!("run.{ext}")), &Default::default())
            .unwrap_or_else(|e| panic!("{what}: {e}"));
        assert_eq!(logged.len(), kept, "{what}");
        // The disk took at least a quarter of its size in samples (35 channels of 8 bytes).
        assert!(kept * 35 * 8 > 1_000_000, "{what}: {kept}");
        a_stretch_of(&logged, &sim, &what);
    }
}

/// A file verb whose output's disk refuses a write (here the file-size limit, 3 MB) leaves
/// the output readable with what reached the disk and says how much: MDF4 and CSV the samples
/// wholly written, the first of the input's; a Parquet file before its first row group (65 536
/// rows) can keep nothing and is removed. They used to be left torn: "Corrupt footer", or an
/// MDF4 file of 0 samples.
#[test]
fn a_conversion_on_a_full_disk_keeps_what_it_wrote() {
    let s = physid_testkit::Scratch::new("physid-full-convert");
    let input = s.file("sim.parquet");
    common::simulated(&input, "shaft-steady", "3");
    let sim = physid_io::read_parquet(&input, None).unwrap();
    for ext in ["mf4", "csv", "parquet"] {
        let out = s.file(&format!("out.{ext}"));
        let o = physid_limited(
            3000,
            &["convert".as_ref(), input.as_os_str(), out.as_os_str()],
        );
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{ext}: {e}");
        assert!(e.contains("File too large (os error 27)"), "{ext}: {e}");
        if ext == "parquet" {
            assert!(e.contains("had no complete row group yet"), "{e}");
            assert!(!out.exists(), "a Parquet file no reader opens is left");
            continue;
        }
        let logged = physid_io::read(&out, &Default::default()).unwrap();
        if ext == "mf4" {
            assert!(
                e.contains(&format!(
                    "keeps its first {} samples, readable",
                    logged.len()
                )),
                "{e}"
            );
        }
        // 3 MB of 35 float64 (MDF4) or text (CSV) columns.
        assert!(logged.len() > 2000, "{ext}: {}", logged.len());
        if ext == "mf4" {
            a_stretch_of(&logged, &sim, ext);
        }
        assert_eq!(logged.values("t").unwrap()[0], 0.0, "{ext}");
    }
}

/// A whole write (`filter --ba`, Python's `Recording.write`) that the disk refuses leaves the
/// file already at its path as it was and nothing beside it: it writes a staging file and
/// renames it. It used to truncate the old file first and leave a torn one.
#[test]
fn a_whole_write_refused_leaves_the_old_file() {
    let s = physid_testkit::Scratch::new("physid-whole-write");
    let input = s.file("sim.parquet");
    common::simulated(&input, "shaft-steady", "3");
    let out = s.file("out.parquet");
    let small = s.file("small.parquet");
    common::simulated(&small, "shaft-steady", "0.2");
    std::fs::copy(&small, &out).unwrap();
    let before = std::fs::read(&out).unwrap();
    let filter = ["--ba", "--lowpass", "500", "--channels", "torque_shaft"];
    let mut args = vec!["filter".as_ref(), input.as_os_str(), out.as_os_str()];
    args.extend(filter.iter().map(std::ffi::OsStr::new));
    let o = physid_limited(2000, &args);
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(
        e.contains(&format!("{}: File too large (os error 27)", out.display())),
        "the error names the file asked for: {e}"
    );
    assert!(
        std::fs::read(&out).unwrap() == before,
        "the old file changed"
    );
    let left: Vec<_> = std::fs::read_dir(s.file(""))
        .unwrap()
        .filter_map(|d| d.ok())
        .map(|d| d.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".partial"))
        .collect();
    assert!(left.is_empty(), "staging files left: {left:?}");
    // Within the limit the same command replaces it.
    let mut args = vec!["filter", small.to_str().unwrap(), out.to_str().unwrap()];
    args.extend(filter);
    let o = physid(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(std::fs::read(&out).unwrap() != before);
}

/// `physid live --headless` whose events' reader goes away (`| head`, a consumer that died)
/// ends as at a stop control: its log closed and readable as it is, with at least every sample
/// its last `log` event counted, the run's exit 0, and stderr saying what the log kept.
#[test]
fn a_live_log_outlives_its_events_reader() {
    let s = physid_testkit::Scratch::new("physid-reader-gone");
    for ext in ["parquet", "mf4"] {
        let dir = s.file(&format!("logs-{ext}"));
        let name = format!("run.{ext}");
        let (mut child, stdin) = live_logging(&dir, &name, "30", Stdio::piped());
        // Read until the log has reported twice, then close the events' pipe.
        let mut out = BufReader::new(child.stdout.take().unwrap());
        let mut counted = 0;
        let mut reports = 0;
        let mut line = String::new();
        while reports < 2 {
            line.clear();
            assert!(
                out.read_line(&mut line).unwrap() > 0,
                "{ext}: the run ended early"
            );
            let e: Value = serde_json::from_str(&line).unwrap();
            if e["type"] == "log" {
                counted = e["samples"].as_u64().unwrap() as usize;
                reports += 1;
            }
        }
        drop(out);
        let deadline = Instant::now() + Duration::from_secs(20);
        let status = loop {
            if let Some(st) = child.try_wait().unwrap() {
                break st;
            }
            assert!(
                Instant::now() < deadline,
                "{ext}: still running without its reader"
            );
            std::thread::sleep(Duration::from_millis(50));
        };
        drop(stdin);
        let mut err = String::new();
        std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
        assert!(status.success(), "{ext}: {status}; {err}");
        let file = dir.join(&name);
        let logged = physid_io::read(&file, &Default::default())
            .unwrap_or_else(|e| panic!("{ext}: the log is not readable as it is: {e}; {err}"));
        assert!(
            logged.len() >= counted,
            "{ext}: {} < {counted}",
            logged.len()
        );
        assert!(
            err.contains(&format!(
                "the log {} was closed: {} samples, readable",
                file.display(),
                logged.len()
            )) && err.contains("the events' reader has gone"),
            "{ext}: {err}"
        );
    }
}

/// A run started by `nohup` (SIGHUP ignored) goes on through a hangup to its end.
#[test]
fn a_nohup_run_goes_on_through_a_hangup() {
    if Command::new("nohup").arg("true").status().is_err() {
        eprintln!("skipped: no nohup here");
        return;
    }
    let mut child = Command::new("nohup")
        .args([
            env!("CARGO_BIN_EXE_physid"),
            "live",
            "--headless",
            "--json",
            "--scenario",
            "shaft-steady",
            "--duration",
            "6",
            "--pace",
            "2",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut out = BufReader::new(child.stdout.take().unwrap());
    let mut line = String::new();
    out.read_line(&mut line).unwrap();
    signal(child.id(), "HUP");
    let events: Vec<Value> = out
        .lines()
        .map_while(Result::ok)
        .filter_map(|l| serde_json::from_str(&l).ok())
        .collect();
    assert!(child.wait().unwrap().success());
    let end = events
        .iter()
        .find(|e| e["type"] == "end")
        .expect("an end event");
    assert!(end["t_s"].as_f64().unwrap() > 5.9, "{end}");
}

/// A live log being recorded is its writer's alone: while `physid live` writes it, `physid
/// inspect` says it is being written (not that its footer is corrupt), `physid recover` does
/// not cut it, and `simulate` and `convert` do not write over it — and the log the run closes
/// holds every sample its last `log` event counts, a stretch of the cell's own run. Before,
/// `inspect` called the log's footer corrupt, `recover` cut the log under its writer, and
/// `simulate --recording` emptied it and wrote into it beside the run: the closed log was
/// unreadable either way.
#[test]
fn a_log_being_recorded_is_left_to_its_writer() {
    let s = physid_testkit::Scratch::new("physid-left-to-its-writer");
    let sim_path = s.file("sim.parquet");
    common::simulated(&sim_path, "shaft-steady", "14");
    let sim = physid_io::read_parquet(&sim_path, None).unwrap();
    let small = s.file("small.parquet");
    common::simulated(&small, "shaft-steady", "0.1");
    for ext in ["parquet", "mf4"] {
        let dir = s.file(&format!("logs-{ext}"));
        let file = dir.join(format!("run.{ext}"));
        let f = file.to_str().unwrap();
        // Long enough to outlast the probes (14 s at 4× real time); stopped after them.
        let (mut child, mut stdin) = live_logging(&dir, &format!("run.{ext}"), "14", Stdio::null());
        let mut events = BufReader::new(child.stdout.take().unwrap()).lines();
        // The log has been committed once: its first `log` event.
        let first = events
            .by_ref()
            .map_while(Result::ok)
            .filter_map(|l| serde_json::from_str::<Value>(&l).ok())
            .find(|e| e["type"] == "log")
            .expect("a log event");
        assert_eq!(first["state"], "recording", "{ext}: {first}");

        let o = physid(&["inspect", f]);
        let said = String::from_utf8_lossy(&o.stderr);
        if ext == "parquet" {
            assert!(
                !o.status.success(),
                "{ext}: inspect read a log with no footer"
            );
            assert!(
                said.contains("is being written") && said.contains("not damaged"),
                "{ext}: {said}"
            );
        } else {
            // MDF4 is readable as it is committed.
            assert!(o.status.success(), "{ext}: {said}");
        }
        let o = physid(&["recover", f]);
        let said = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success(),
            "{ext}: recover mended a log being written"
        );
        assert!(said.contains("nothing to recover"), "{ext}: {said}");
        let o = physid(&[
            "simulate",
            "--scenario",
            "shaft-steady",
            "--duration",
            "0.2",
            "--recording",
            f,
        ]);
        let said = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{ext}: simulate wrote over a log");
        assert!(said.contains("not written over"), "{ext}: {said}");
        let o = physid(&["convert", small.to_str().unwrap(), f]);
        let said = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{ext}: convert wrote over a log");
        assert!(said.contains("being written"), "{ext}: {said}");

        // The run is stopped and closes the log: all of it is there.
        writeln!(stdin, r#"{{"cmd":"stop"}}"#).unwrap();
        let rest: Vec<Value> = events
            .map_while(Result::ok)
            .filter_map(|l| serde_json::from_str(&l).ok())
            .collect();
        assert!(child.wait().unwrap().success(), "{ext}");
        drop(stdin);
        let closed = rest
            .iter()
            .rev()
            .find(|e| e["type"] == "log" && e["state"] == "closed")
            .unwrap_or_else(|| panic!("{ext}: no closing log event"));
        // Closed by the stop: the probes ran while it was written.
        assert!(
            closed["t_s"].as_f64().unwrap() < 14.0,
            "{ext}: the run ended before the probes did: {closed}"
        );
        let logged = physid_io::read(&file, &Default::default()).unwrap();
        assert_eq!(
            closed["samples"].as_u64().unwrap() as usize,
            logged.len(),
            "{ext}"
        );
        assert!(logged.len() > 1000, "{ext}: {} samples", logged.len());
        a_stretch_of(&logged, &sim, ext);
    }
}

/// A command whose output is its own input is refused before it writes a byte, the recording
/// kept bit for bit — by the same name, another (`./`) or a link. Before, `convert a.parquet
/// a.parquet` and `monitor shaft --data a.parquet --tracks a.parquet` emptied the recording (4
/// bytes left) and then blamed it ("the file was damaged or changed after it was written"), and
/// `filter a.csv a.csv` deleted it (its cleanup removed "its" partial output).
#[test]
fn an_output_that_is_the_input_is_refused() {
    let s = physid_testkit::Scratch::new("physid-output-is-input");
    let pq = s.file("run.parquet");
    common::simulated(&pq, "shaft-steady", "2");
    let csv = s.file("run.csv");
    let o = physid(&["convert", pq.to_str().unwrap(), csv.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let link = s.file("link.parquet");
    std::os::unix::fs::symlink(&pq, &link).unwrap();
    let (p, c, l) = (
        pq.to_str().unwrap(),
        csv.to_str().unwrap(),
        link.to_str().unwrap(),
    );
    let dotted = format!("{}/./run.csv", s.file("").display());
    let cases: [&[&str]; 5] = [
        &["convert", p, p],
        &["convert", p, l],
        &[
            "filter",
            c,
            &dotted,
            "--lowpass",
            "500",
            "--channels",
            "torque_shaft",
        ],
        &["monitor", "shaft", "--data", p, "--tracks", p],
        &["convert", l, c, "--channels", "t"],
    ];
    for args in cases {
        let (before_p, before_c) = (std::fs::read(&pq).unwrap(), std::fs::read(&csv).unwrap());
        let o = physid(args);
        let said = String::from_utf8_lossy(&o.stderr);
        if args[1] == l && args[2] == c {
            // A link read, another file written: as any conversion.
            assert!(o.status.success(), "{args:?}: {said}");
            continue;
        }
        assert_eq!(o.status.code(), Some(1), "{args:?}: {said}");
        assert!(
            said.contains("is also what this command reads"),
            "{args:?}: {said}"
        );
        assert!(
            std::fs::read(&pq).unwrap() == before_p,
            "{args:?}: run.parquet changed"
        );
        assert!(
            std::fs::read(&csv).unwrap() == before_c,
            "{args:?}: run.csv changed"
        );
    }
}

/// A `simulate` refused before it writes (a recording too large for the disk) leaves the file
/// already at its output as it was. Before, its cleanup removed "its" output: the earlier
/// recording of that name was deleted.
#[test]
fn a_refused_simulation_leaves_the_file_at_its_output() {
    let s = physid_testkit::Scratch::new("physid-refused-simulation");
    let f = s.file("keep.parquet");
    common::simulated(&f, "shaft-steady", "0.5");
    let before = std::fs::read(&f).unwrap();
    let o = physid(&[
        "simulate",
        "--scenario",
        "shaft-steady",
        "--duration",
        "1e9",
        "--recording",
        f.to_str().unwrap(),
    ]);
    let said = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{said}");
    assert!(said.contains("record less"), "{said}");
    assert!(
        std::fs::read(&f).ok().is_some_and(|b| b == before),
        "the recording at --recording was changed or removed"
    );
}
