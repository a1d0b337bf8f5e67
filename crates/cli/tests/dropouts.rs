//! A sensor's dropout in a file — samples that are not a number — and the file verbs that take
//! a recording's cycles (`cycles`, `friction fit`, `torque fit`): each leaves out the cycle the
//! dropout cuts, tells it once (a warning on stderr naming the file, channel and sample; the
//! `--json` result's `dropouts`: channel, sample, time, value) and goes on. Before, each refused
//! the whole file at the first such sample.
//!
//! The evidence that only the cut cycles are left out is not the code's: on a crank-angle file,
//! the fits equal, to the last digit, those on the same file with the cut cycles' rows deleted
//! by the test, and every other cycle's combustion figures are the clean file's.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{physid, set_cells};
use physid_testkit::Scratch;
use serde_json::{json, Value};
use std::path::Path;

/// `physid ARGS --json`, which must succeed: the result without its provenance, and stderr.
fn run(args: &[&str]) -> (Value, String) {
    let mut all = args.to_vec();
    all.push("--json");
    let o = physid(&all);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{args:?}: {err}");
    let mut v: Value = serde_json::from_slice(&o.stdout).expect("JSON on stdout");
    if let Some(o) = v.as_object_mut() {
        o.remove("provenance");
    }
    (v, err)
}

/// Each estimated parameter of `got` within one of `clean`'s standard errors of `clean`'s.
fn within_a_std_err(got: &Value, clean: &Value) {
    assert_eq!(got["estimable"], clean["estimable"]);
    for p in clean["estimable"].as_array().unwrap() {
        let p = p.as_str().unwrap();
        let (v, w) = (got["params"][p].as_f64(), clean["params"][p].as_f64());
        let se = clean["std_err"][p].as_f64().unwrap();
        assert!(
            (v.unwrap() - w.unwrap()).abs() <= se,
            "{p}: {v:?} against {w:?} ± {se}"
        );
    }
}

/// The warning each dropout gives on stderr, once: the file, `what` (the channel, value and
/// sample), the time, what was done.
fn warned(err: &str, file: &Path, what: &str) {
    let head = format!("warning: {}: {what} (t = ", file.display());
    let told = err
        .lines()
        .filter(|l| {
            l.starts_with(&head)
                && l.ends_with(" s): the cycle it cuts is left out, the analysis goes on after it")
        })
        .count();
    assert_eq!(told, 1, "{err}");
}

/// A time-basis file with a cylinder pressure's dropout of 10 samples at 1 s and a manifold
/// pressure's NaN at 2.5 s: `friction fit` (which reads p_int, not p_cyl) and `torque fit`
/// (p_cyl, not p_int) each leave out the one cycle their channel's dropout cuts and end within
/// one standard error of the clean file's estimates.
#[test]
fn a_dropout_in_a_time_basis_file_leaves_out_its_cycle_and_the_fits_go_on() {
    let s = Scratch::new("physid-dropouts-time");
    let (clean, file) = (s.file("clean.csv"), s.file("run.csv"));
    common::simulated(&clean, "torque-steady", "4");
    std::fs::copy(&clean, &file).unwrap();
    set_cells(&file, "p_cyl", 10_000..10_010, "nan");
    set_cells(&file, "p_int", 25_000..25_001, "nan");
    let (c, f) = (clean.to_str().unwrap(), file.to_str().unwrap());

    let (want, _) = run(&["friction", "fit", "--data", c]);
    let (got, err) = run(&["friction", "fit", "--data", f]);
    assert_eq!(want["dropouts"], json!([]));
    assert_eq!(
        got["dropouts"],
        json!([{"channel": "p_int", "sample": 25000, "t_s": 2.5, "value": "NaN"}])
    );
    warned(&err, &file, "'p_int' is NaN at sample 25000");
    assert_eq!(
        got["cycles"]["used"].as_u64().unwrap() + 1,
        want["cycles"]["used"].as_u64().unwrap()
    );
    within_a_std_err(&got, &want);

    let (want, _) = run(&["torque", "fit", "--data", c]);
    let (got, err) = run(&["torque", "fit", "--data", f]);
    assert_eq!(
        got["dropouts"],
        json!([{"channel": "p_cyl", "sample": 10000, "t_s": 1.0, "value": "NaN"}])
    );
    warned(&err, &file, "'p_cyl' is NaN at sample 10000");
    assert_eq!(
        got["samples"].as_u64().unwrap() + 720,
        want["samples"].as_u64().unwrap()
    );
    within_a_std_err(&got, &want);

    // The combustion figures, its crank-angle samples made as it is read: every cycle but the
    // one the pressure's dropout cuts is the clean file's; the sample counts the samples made
    // (one per 0.1°), the time is the dropout's.
    let (want, _) = run(&["cycles", c]);
    let (got, err) = run(&["cycles", f]);
    let (want, got) = (
        want["cycles"].as_array().unwrap(),
        got["cycles"].as_array().unwrap(),
    );
    assert!(want.len() >= 30, "{}", want.len());
    let cut = |c: &&Value| {
        let t = c["t_start_s"].as_f64().unwrap();
        (0.88..1.0).contains(&t)
    };
    let kept: Vec<&Value> = want.iter().filter(|c| !cut(c)).collect();
    assert_eq!(kept.len() + 1, want.len());
    assert_eq!(got.iter().collect::<Vec<_>>(), kept);
    let told: Vec<&str> = err.lines().filter(|l| l.starts_with("warning:")).collect();
    assert_eq!(told.len(), 1, "{err}");
    let head = format!(
        "warning: {} (its samples at each step of crank angle): 'p_cyl' is NaN at sample ",
        file.display()
    );
    assert!(
        told[0].starts_with(&head) && told[0].contains("(t = 0.99"),
        "{err}"
    );
}

/// The rows of a CSV recording written by physid (after its header and units row), and the
/// index of `column`.
fn rows(file: &Path, column: &str) -> (Vec<String>, usize) {
    let text = std::fs::read_to_string(file).unwrap();
    let lines: Vec<String> = text.lines().map(String::from).collect();
    let col = lines[0].split(',').position(|c| c == column).unwrap();
    (lines, col)
}

/// The first row (sample index) of block `cycle` at `deg` or later on its `crank_deg`.
fn row_at(file: &Path, cycle: i64, deg: f64) -> usize {
    let (lines, c) = rows(file, "cycle");
    let (_, d) = rows(file, "crank_deg");
    lines[2..]
        .iter()
        .position(|l| {
            let cells: Vec<&str> = l.split(',').collect();
            cells[c].parse::<f64>().unwrap() == cycle as f64
                && cells[d].parse::<f64>().unwrap() >= deg
        })
        .unwrap()
}

/// `from` with the rows (sample indices) `cut` says deleted, written to `to`.
fn without_rows(from: &Path, to: &Path, cut: impl Fn(usize, &[&str]) -> bool) {
    let (lines, _) = rows(from, "t");
    let mut out: Vec<&str> = lines[..2].iter().map(String::as_str).collect();
    for (i, l) in lines[2..].iter().enumerate() {
        if !cut(i, &l.split(',').collect::<Vec<_>>()) {
            out.push(l);
        }
    }
    std::fs::write(to, out.join("\n") + "\n").unwrap();
}

/// A crank-angle file (`convert --crank-angle`, one sample per degree) with three dropouts:
/// p_cyl NaN for 3 samples 100° into block 10 (its expansion: cycle 10's), p_cyl infinite 500°
/// into block 20 (its second half: cycle 21's compression), p_int NaN 100° into block 15.
/// `cycles` leaves out cycles 10 and 21, and every other cycle's figures are the clean file's;
/// `torque fit` (720-sample cycles from the first) gives exactly the fit on the file without
/// the two cycles' rows, `friction fit` exactly the fit on the file without block 15.
#[test]
fn a_dropout_in_a_crank_angle_file_leaves_out_the_cycles_it_cuts() {
    let s = Scratch::new("physid-dropouts-crank");
    let (time, clean, file) = (s.file("t.csv"), s.file("clean.csv"), s.file("run.csv"));
    common::simulated(&time, "torque-steady", "4");
    let o = physid(&[
        "convert",
        time.to_str().unwrap(),
        clean.to_str().unwrap(),
        "--crank-angle",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::copy(&clean, &file).unwrap();
    let (a, b, q) = (
        row_at(&clean, 10, 100.0),
        row_at(&clean, 20, 500.0),
        row_at(&clean, 15, 100.0),
    );
    set_cells(&file, "p_cyl", a..a + 3, "nan");
    set_cells(&file, "p_cyl", b..b + 1, "inf");
    set_cells(&file, "p_int", q..q + 1, "nan");
    let (c, f) = (clean.to_str().unwrap(), file.to_str().unwrap());

    // The combustion figures: all but the two cut cycles, each the clean file's.
    let (want, _) = run(&["cycles", c]);
    let (got, err) = run(&["cycles", f]);
    let by_number = |v: &Value| -> Vec<(i64, Value)> {
        v["cycles"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| (c["cycle"].as_i64().unwrap(), c.clone()))
            .collect()
    };
    let (want_cycles, got_cycles) = (by_number(&want), by_number(&got));
    assert!(want_cycles.len() >= 30, "{}", want_cycles.len());
    let kept: Vec<(i64, Value)> = want_cycles
        .iter()
        .filter(|(n, _)| *n != 10 && *n != 21)
        .cloned()
        .collect();
    assert_eq!(kept.len() + 2, want_cycles.len());
    assert_eq!(got_cycles, kept);
    assert_eq!(got["dropouts"].as_array().unwrap().len(), 2);
    assert_eq!(got["dropouts"][0]["sample"], a);
    assert_eq!(got["dropouts"][1]["value"], "inf");
    assert!(got["notes"].as_array().unwrap().contains(&json!(
        "2 cycle(s) cut by 2 dropout(s) left out (a sample that is not a number)"
    )));
    warned(&err, &file, &format!("'p_cyl' is NaN at sample {a}"));
    warned(&err, &file, &format!("'p_cyl' is inf at sample {b}"));

    // The cyclic torque: the fit on the file without the 720-sample cycles the dropouts cut.
    let cut = s.file("torque-cut.csv");
    without_rows(&clean, &cut, |i, _| {
        i / 720 == a / 720 || i / 720 == b / 720
    });
    let (mut got, err) = run(&["torque", "fit", "--data", f]);
    let (mut want, _) = run(&["torque", "fit", "--data", cut.to_str().unwrap()]);
    let told = got.as_object_mut().unwrap().remove("dropouts").unwrap();
    assert_eq!(
        want.as_object_mut().unwrap().remove("dropouts"),
        Some(json!([]))
    );
    assert_eq!(got, want);
    assert_eq!(told.as_array().unwrap().len(), 2, "{told}");
    warned(&err, &file, &format!("'p_cyl' is inf at sample {b}"));

    // The friction characterisation: the fit on the file without block 15.
    let cut = s.file("friction-cut.csv");
    let (_, col) = rows(&clean, "cycle");
    without_rows(&clean, &cut, |_, cells| cells[col] == "15");
    let (mut got, err) = run(&["friction", "fit", "--data", f]);
    let (mut want, _) = run(&["friction", "fit", "--data", cut.to_str().unwrap()]);
    let told = got.as_object_mut().unwrap().remove("dropouts").unwrap();
    want.as_object_mut().unwrap().remove("dropouts");
    assert_eq!(got, want);
    assert_eq!(told[0]["channel"], "p_int");
    assert_eq!(told[0]["sample"], q);
    warned(&err, &file, &format!("'p_int' is NaN at sample {q}"));
}

/// A trigger wheel's raw signal with dropouts — the pickup's samples NaN for 5 samples at
/// sample 30 000 and for 60 samples (0.6 ms, over a tooth's edge at the recording's 2400 rpm)
/// at sample 100 000: `cycles` decodes the angle past them — before, it refused the file at the
/// first — tells each run (its sample, on stderr and in the `--json` findings, on stderr with
/// `--json` too, as the cycles a dropout cuts are) and the edge the
/// longer one hid, counted as a missing tooth; and every cycle still passes the checks the
/// clean recording's pass against the generator's truth (`data_handling.rs`,
/// `cycles_of_a_raw_recording`): the pressure's peak within ±2.7° of TDC, the gross IMEP of the
/// symmetric pulse within ±3 kPa of 0, as many cycles as the clean file's.
#[test]
fn a_dropout_in_a_trigger_wheel_s_signal_is_decoded_past() {
    let s = Scratch::new("physid-dropouts-wheel");
    let clean = common::raw_wheel_dat(&s.file("clean.dat"), &[]);
    let dat = common::raw_wheel_dat(&s.file("raw.dat"), &[30_000..30_005, 100_000..100_060]);
    let flags = [
        "--columns",
        "t,enc,p_cyl,theta_true",
        "--scale",
        "p_cyl=1e6,0",
        "--wheel",
        "enc=60-3",
        "--tdc-offset",
        "118.28",
        "--phase-from",
        "p_cyl",
        "--bore",
        "0.084",
        "--stroke",
        "0.09",
        "--rod",
        "0.15",
        "--compression-ratio",
        "10",
    ];
    let (c, d) = (clean.to_str().unwrap(), dat.to_str().unwrap());
    let args = |file| [&["cycles", file][..], &flags].concat();
    let (want, _) = run(&args(c));
    let (got, json_err) = run(&args(d));
    let found = |kind: &str| -> Vec<u64> {
        got["findings"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|f| f["kind"] == kind)
            .map(|f| f["index"].as_u64().unwrap())
            .collect()
    };
    assert_eq!(
        found("non_finite"),
        [30_000, 100_000],
        "{}",
        got["findings"]
    );
    let lost = found("pulse_loss");
    assert!(
        lost.len() == 1 && (100_060..100_200).contains(&lost[0]),
        "{}",
        got["findings"]
    );
    // Told on stderr too, each run at its sample, with --json (the decoding's summary left
    // out) as without.
    let o = physid(&args(d));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    for (at, n) in [(30_000, 5), (100_000, 60)] {
        let said = format!(
            "{}: sample {at}: 'enc': {n} sample(s) from sample {at} (t = ",
            dat.display()
        );
        assert!(err.contains(&said), "{said}\n{err}");
        assert!(json_err.contains(&said), "{said}\n{json_err}");
    }
    assert!(
        err.contains("decoded") && !json_err.contains("decoded"),
        "{json_err}"
    );
    let (a, b) = (
        want["cycles"].as_array().unwrap(),
        got["cycles"].as_array().unwrap(),
    );
    assert_eq!(a.len(), b.len());
    for c in b {
        let at = c["p_max_deg"].as_f64().unwrap();
        assert!((-2.7..=2.7).contains(&at), "{c}");
        let gross = c["imep_gross_pa"].as_f64().unwrap();
        assert!(gross.abs() < 3e3, "{c}");
    }
}

/// `physid-signal`'s golden file `golden` with the runs `dropouts` gives from its recording (a
/// channel, its samples) set to NaN, converted to one sample per degree (`convert
/// --crank-angle` with `flags`), which must succeed: the file converted, and stderr.
fn converted_with_dropouts(
    s: &Scratch,
    golden: &str,
    dropouts: impl FnOnce(&physid_core::Recording) -> Vec<(&'static str, std::ops::Range<usize>)>,
    flags: &[&str],
) -> (std::path::PathBuf, String) {
    let golden = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../signal/tests/golden")
        .join(golden);
    let mut rec = physid_io::read(&golden, &physid_io::ReadOptions::default()).unwrap();
    for (name, at) in dropouts(&rec) {
        let mut v = rec.values(name).unwrap().to_vec();
        v[at].fill(f64::NAN);
        rec.replace_values(name, v).unwrap();
    }
    let (file, deg) = (s.file("raw.parquet"), s.file("deg.parquet"));
    physid_io::write(&file, &rec, &physid_io::WriteOptions::default()).unwrap();
    let mut args = vec![
        "convert",
        file.to_str().unwrap(),
        deg.to_str().unwrap(),
        "--crank-angle",
    ];
    args.extend_from_slice(flags);
    let o = physid(&args);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{err}");
    (deg, err)
}

/// A pulse encoder's raw channels with dropouts (`physid-signal`'s golden 360-pulse encoder and
/// its index, numpy): the pulses NaN for 40 samples (over a pulse's edge) and the index for 200
/// samples away from its pulses. `convert --crank-angle --encoder-raw --index-raw` decodes past
/// both, names each with its channel and sample, and every revolution still starts at the true
/// angle the clean file's start at (31°, within 0.05°: `data_handling.rs`).
#[test]
fn a_dropout_in_a_pulse_encoder_s_channels_is_decoded_past() {
    let s = Scratch::new("physid-dropouts-pulses");
    let mut quiet = 0;
    let (deg, err) = converted_with_dropouts(
        &s,
        "pulse_encoder_360.parquet",
        |rec| {
            // The index is high a few samples a revolution: 200 samples just after one of its
            // pulses are clear of the next.
            let idx = rec.values("idx").unwrap();
            let (lo, hi) = idx
                .iter()
                .fold((f64::MAX, f64::MIN), |(a, b), &x| (a.min(x), b.max(x)));
            let high = (100_000..).find(|&i| idx[i] > 0.5 * (lo + hi)).unwrap();
            quiet = (high..).find(|&i| idx[i] < lo + 0.1 * (hi - lo)).unwrap() + 10;
            vec![("enc", 150_000..150_040), ("idx", quiet..quiet + 200)]
        },
        &[
            "--encoder-raw",
            "enc=360",
            "--index-raw",
            "idx",
            "--tdc-offset",
            "30",
        ],
    );
    for said in [
        "sample 150000: 'enc': 40 sample(s) from sample 150000 (t = ".to_string(),
        format!("sample {quiet}: 'idx': 200 sample(s) from sample {quiet} (t = "),
    ] {
        assert!(err.contains(&said), "{said}\n{err}");
    }
    common::revolutions_start_at(&deg, 31.0, 0.05, 14);
}

/// A quadrature encoder's raw channels with dropouts (`physid-signal`'s golden 500-line
/// encoder, numpy; its own tests check the decoding sample by sample): B NaN for 13 samples
/// and A and B for 40 at ≈ 1100 rpm (3 and 8 transitions hidden), Z over an index pulse.
/// Before, `convert --crank-angle --quadrature` refused the file at the first; now it tells
/// each run with its channel and sample, and the counts taken across them, and every
/// revolution still starts at the true 90° within the clean file's 0.1° (`data_handling.rs`).
#[test]
fn a_dropout_in_a_quadrature_encoder_s_channels_is_decoded_past() {
    let s = Scratch::new("physid-dropouts-quadrature");
    let (deg, err) = converted_with_dropouts(
        &s,
        "quadrature_500.parquet",
        |_| {
            vec![
                ("enc_b", 95_000..95_013),
                ("enc_a", 105_000..105_040),
                ("enc_b", 105_000..105_040),
                ("enc_z", 100_440..100_500),
            ]
        },
        &[
            "--quadrature",
            "enc_a,enc_b,enc_z=500",
            "--tdc-offset",
            "90",
        ],
    );
    for said in [
        "sample 95000: 'enc_b': 13 sample(s) from sample 95000 (t = ",
        "sample 95013: 'enc_a', 'enc_b': the dropout from sample 95000 to 95012 hides its transitions: taken as 3 count(s)",
        "sample 100440: 'enc_z': 60 sample(s) from sample 100440 (t = ",
        "sample 105000: 'enc_a': 40 sample(s) from sample 105000 (t = ",
        "sample 105000: 'enc_b': 40 sample(s) from sample 105000 (t = ",
        "sample 105040: 'enc_a', 'enc_b': the dropout from sample 105000 to 105039 hides its transitions: taken as 8 count(s)",
    ] {
        assert!(err.contains(said), "{said}\n{err}");
    }
    assert!(!err.contains("out of place"), "{err}");
    common::revolutions_start_at(&deg, 90.0, 0.1, 1);
}
