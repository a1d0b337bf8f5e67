//! Bad input at the command line gives a clear error — never a panic, an abort, a hang or a
//! silently wrong number: every case here was once one of those.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_testkit::Scratch;
mod common;
use common::{ok_json, on_a_terminal, physid};

fn fails_with(args: &[&str], want: &str) {
    let o = physid(args);
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{args:?}: {e}");
    assert!(e.contains(want), "{args:?}: {e}");
}

/// `simulate` writes as it goes (memory flat), so what bounds it is the disk: a recording
/// whose float64 size exceeds the free space is refused before it starts, naming the place,
/// and so is one a stream cannot count; no file is left behind. The live cell likewise.
#[test]
fn runs_that_cannot_fit_are_refused_before_they_start() {
    let s = Scratch::new("physid-rel");
    let out = s.file("x.parquet");
    let out_path = out.clone();
    let out = out.to_str().unwrap();
    fails_with(
        &[
            "simulate",
            "--scenario",
            "shaft-steady",
            "--duration",
            "1e6",
            "--recording",
            out,
        ],
        "the recording would take at least 3040.000 GB",
    );
    fails_with(
        &[
            "simulate",
            "--scenario",
            "shaft-steady",
            "--duration",
            "1e308",
            "--basis",
            "crank",
            "--recording",
            out,
        ],
        "more than a stream counts exactly",
    );
    assert!(!out_path.exists(), "no file is left behind");
    fails_with(
        &[
            "live",
            "--headless",
            "--json",
            "--scenario",
            "shaft-steady",
            "--duration",
            "1e308",
        ],
        "more than a stream counts exactly",
    );
}

/// A number out of its range is said as it was given — `1e300`, not its 301 digits (each of
/// these printed every digit, found by driving the Python package's functions with ±10³⁰⁰).
/// A negative value is taken after a space as after `=` (`--knock-threshold -1e300` was an
/// unknown flag `-1`).
#[test]
fn a_number_out_of_range_is_said_in_exponent_form() {
    let s = Scratch::new("physid-num");
    let time = s.file("t.csv");
    let crank = s.file("c.csv");
    for (file, basis) in [(&time, "time"), (&crank, "crank")] {
        let o = physid(&[
            "simulate",
            "--scenario",
            "fired-steady",
            "--duration",
            "0.3",
            "--basis",
            basis,
            "--recording",
            file.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let (t, c) = (time.to_str().unwrap(), crank.to_str().unwrap());
    let cases: [&[&str]; 14] = [
        &["monitor", "shaft", "--data", t, "--lambda", "1e300"],
        &["monitor", "shaft", "--data", t, "--bound=-1e300"],
        &["friction", "fit", "--data", t, "--s0=-1e300"],
        &["friction", "fit", "--data", t, "--lambda=-1e300"],
        &["torque", "fit", "--data", c, "--r2=-1e300"],
        &["torque", "fit", "--data", c, "--p0=-1e300"],
        &["cycles", c, "--knock", "--knock-threshold", "-1e300"],
        &["cycles", c, "--knock", "--knock-band", "1e300,-1e300"],
        &["cycles", c, "--pressure-lowpass=-1e300"],
        &[
            "simulate",
            "--scenario",
            "shaft-steady",
            "--duration",
            "-1e300",
            "--recording",
            t,
        ],
        &[
            "simulate",
            "--scenario",
            "shaft-steady",
            "--sample-rate",
            "-1e300",
            "--recording",
            t,
        ],
        &["design", "--target-rel-se=-1e300"],
        &["design", "--duration", "1e-300"],
        &["design", "--band", "1e300:-1e300"],
    ];
    for args in cases {
        let o = physid(args);
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?}: accepted");
        assert!(e.contains("e300") || e.contains("e-300"), "{args:?}: {e}");
        let longest = e
            .split(|c: char| !c.is_ascii_digit())
            .map(str::len)
            .max()
            .unwrap_or(0);
        assert!(longest < 20, "{args:?}: a run of {longest} digits: {e}");
    }
}

/// An engine angle scaled by 10³⁰⁰ by mistake (`--scale theta_en=1e300,0`): telling the
/// firing revolution from `p_cyl` hung (its TDCs at 10²⁹⁸ rad, where a revolution added
/// changes nothing), and the resampler's refusal advised a coarser grid; it now names the jump.
#[test]
fn an_angle_scaled_by_1e300_is_refused_naming_its_jump() {
    let s = Scratch::new("physid-jump");
    let time = s.file("t.parquet");
    let t = time.to_str().unwrap();
    let o = physid(&[
        "simulate",
        "--scenario",
        "fired-steady",
        "--duration",
        "0.3",
        "--recording",
        t,
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = s.file("c.parquet");
    for scale in ["1e300", "1e12"] {
        fails_with(
            &[
                "convert",
                "--crank-angle",
                "--scale",
                &format!("theta_en={scale},0"),
                t,
                out.to_str().unwrap(),
            ],
            "is it in radians, and of the right scale?",
        );
    }
}

/// Numbers a typo makes huge do not take the machine's memory (each used to end in the
/// allocator's abort or the kernel's OOM kill): a resampling grid whose points cannot fit is
/// refused naming them; a dwell of 10¹² samples is only a long dwell; a design of 10⁹ seconds
/// is refused by its range; so is a live curve step of 10⁻⁹°.
#[test]
fn a_typo_of_an_exponent_does_not_take_the_memory() {
    let s = Scratch::new("physid-rel");
    let rec = s.file("r.parquet");
    let rec = rec.to_str().unwrap();
    let o = physid(&[
        "simulate",
        "--scenario",
        "shaft-steady",
        "--duration",
        "0.3",
        "--quiet",
        "--recording",
        rec,
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = s.file("c.parquet");
    let out = out.to_str().unwrap();
    fails_with(
        &["convert", rec, out, "--crank-angle", "--step-deg", "1e-9"],
        "points of the 1e-9° crank-angle grid in the data from sample 0 on would take about",
    );
    // A step of 1e-300°: the step and the count of points in exponent form, not 300 digits.
    let o = physid(&["convert", rec, out, "--crank-angle", "--step-deg", "1e-300"]);
    let e = String::from_utf8_lossy(&o.stderr);
    let longest = e
        .split(|c: char| !c.is_ascii_digit())
        .map(str::len)
        .max()
        .unwrap_or(0);
    assert!(
        o.status.code() == Some(1)
            && e.contains("e30")
            && e.contains(" points of the 1e-300° crank-angle grid")
            && longest < 20,
        "{e}"
    );
    fails_with(
        &["convert", rec, out, "--time-basis", "1e12"],
        "points of the 1000000000000 Hz time basis in the data from sample 0 on would take about",
    );
    let o = physid(&[
        "monitor",
        "shaft",
        "--data",
        rec,
        "--dwell",
        "1000000000000",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    fails_with(
        &["design", "--duration", "1e9"],
        "duration 1000000000 s: expected 1–3600 s",
    );
    // The live combustion stage's curve of 7·10¹¹ points per cycle (5.8 TB): refused at the
    // start, not the allocator's abort of the service.
    fails_with(
        &[
            "live",
            "--headless",
            "--json",
            "--replay",
            rec,
            "--pace",
            "max",
            "--combustion",
            "--step-deg",
            "1e-9",
        ],
        "curve step 1e-9°: expected a divisor of 720° giving at least 2 points, at least 0.01°",
    );
}

#[test]
fn a_formula_of_forty_thousand_terms_is_refused_not_a_stack_overflow() {
    let s = Scratch::new("physid-rel");
    let data = s.file("d.csv");
    std::fs::write(&data, "t,x,y\n0,1,2\n0.1,2,4\n0.2,3,6\n").unwrap();
    let expr = format!("A*x{}", "+A*x".repeat(39_999));
    let pipeline = s.file("deep.toml");
    std::fs::write(
        &pipeline,
        format!(
            "[model]\nexpr = \"{expr}\"\nparams = {{ A = 1.0 }}\noutput = \"y\"\n[data]\nfile = \"{}\"\n[estimator]\nmethod = \"rls\"\n",
            data.display()
        ),
    )
    .unwrap();
    fails_with(
        &[
            "run",
            pipeline.to_str().unwrap(),
            "--out",
            s.file("o").to_str().unwrap(),
        ],
        "a chain of more than 1000 operations at column 4000",
    );
}

#[test]
fn bad_samples_are_placed_by_file_line_and_empty_cells_are_missing_samples() {
    let s = Scratch::new("physid-rel");
    let f = s.file("nan.csv");
    std::fs::write(&f, "t,a,y\ns,,\n0,1,2\n0.1,nan,4\n0.2,3,6\n").unwrap();
    // identify places the bad value by its line (4) like every other verb.
    fails_with(
        &[
            "identify",
            "--expr",
            "A*a",
            "--params",
            "A=1",
            "--data",
            f.to_str().unwrap(),
            "--y",
            "y",
        ],
        "line 4 (sample 1): 'a' is NaN",
    );
    // An empty cell is a missing sample: refused by default, skipped with --on-bad skip.
    let f = s.file("empty.csv");
    let mut text = String::from("t,a,y\n");
    for i in 0..50 {
        let a = 1.0 + (i % 7) as f64;
        if i == 10 {
            text.push_str(&format!("{},,{}\n", i as f64 * 0.1, 2.0 * a));
        } else {
            text.push_str(&format!("{},{a},{}\n", i as f64 * 0.1, 2.0 * a));
        }
    }
    std::fs::write(&f, text).unwrap();
    let out = s.file("e.csv");
    let base = [
        "estimate",
        "--data",
        f.to_str().unwrap(),
        "--y",
        "y",
        "--phi",
        "a",
        "--method",
        "rls",
        "--out",
        out.to_str().unwrap(),
    ];
    fails_with(&base, "line 12 (sample 10)");
    let mut skip = base.to_vec();
    skip.extend(["--on-bad", "skip", "--json"]);
    let o = physid(&skip);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["skipped"], 1, "{j}");
    // y = 2·a exactly: the estimate is 2.
    let a = j["estimates"]["a"]
        .as_f64()
        .unwrap_or_else(|| j["params"]["a"].as_f64().unwrap());
    assert!((a - 2.0).abs() < 1e-3, "{j}");
}

#[test]
fn an_overflowing_output_is_named_as_such() {
    let s = Scratch::new("physid-rel");
    let f = s.file("big.csv");
    std::fs::write(
        &f,
        "t,a,y\n0,1e300,2e300\n0.1,2e300,4e300\n0.2,3e300,6e300\n",
    )
    .unwrap();
    fails_with(
        &[
            "identify",
            "--expr",
            "A*a",
            "--params",
            "A=1",
            "--data",
            f.to_str().unwrap(),
            "--y",
            "y",
        ],
        "the data overflow 64-bit floating point in their squares",
    );
}

/// Twenty parameters entering the model the same way (`p0*x + … + p19*x`) are named as
/// collinear, not as an overflow (issue 41, item 7: "use --scaling" when scaling was already
/// `thesis` and the sums were ≈ 4e8).
#[test]
fn identical_sensitivities_are_named_collinear_not_an_overflow() {
    let s = Scratch::new("physid-rel");
    let f = s.file("same.csv");
    let mut text = String::from("x,y\n");
    for i in 0..3001 {
        let x = (0.37 * i as f64).sin() + 0.1;
        text += &format!("{x},{}\n", 3.0 * x + 0.01 * (1.7 * i as f64).cos());
    }
    std::fs::write(&f, text).unwrap();
    let expr: Vec<String> = (0..20).map(|k| format!("p{k}*x")).collect();
    let params: Vec<String> = (0..20).map(|k| format!("p{k}=1")).collect();
    fails_with(
        &[
            "identify",
            "--expr",
            &expr.join(" + "),
            "--params",
            &params.join(","),
            "--data",
            f.to_str().unwrap(),
            "--y",
            "y",
        ],
        "the parameters' sensitivities are exactly collinear",
    );
}

/// Two regressors and `y = 2·x1 − 3·x2` (+ a small known disturbance when `noise`), written
/// with `scale` on every column.
fn regression(path: &std::path::Path, scale: f64, collinear: bool, noise: bool) {
    let mut s = String::from("t,x1,x2,y\n");
    for i in 0..500 {
        let t = i as f64 * 0.01;
        let a = (3.0 * t).sin() + 0.5;
        let b = if collinear { a } else { (5.0 * t).cos() };
        let e = if noise { 0.01 * (91.0 * t).sin() } else { 0.0 };
        s.push_str(&format!(
            "{t},{},{},{}\n",
            a * scale,
            b * scale,
            (2.0 * a - 3.0 * b + e) * scale
        ));
    }
    std::fs::write(path, s).unwrap();
}

#[test]
fn parameters_the_data_cannot_resolve_are_flagged_never_given_a_standard_error() {
    let s = Scratch::new("physid-rel");
    let (tiny, coll, good) = (s.file("tiny.csv"), s.file("coll.csv"), s.file("good.csv"));
    regression(&tiny, 1e-300, false, false);
    regression(&coll, 1.0, true, false);
    regression(&good, 1.0, false, true);
    for method in ["rls", "rlsf", "rlsvf", "kf", "dsfc"] {
        for (f, what) in [(&tiny, "scaled by 1e-300"), (&coll, "collinear")] {
            let j = ok_json(&[
                "estimate",
                "--data",
                f.to_str().unwrap(),
                "--y",
                "y",
                "--phi",
                "x1,x2",
                "--method",
                method,
                "--json",
            ]);
            assert_eq!(
                j["unresolved"],
                serde_json::json!(["x1", "x2"]),
                "{method} {what}: {j}"
            );
            assert!(
                j["std_err"]["x1"].is_null() && j["std_err"]["x2"].is_null(),
                "{method} {what}: {j}"
            );
            assert_eq!(j["resolution"]["x1"]["resolved"], false);
        }
        // Well-posed data: nothing flagged, the estimates within 5σ of the truth and σ small.
        let j = ok_json(&[
            "estimate",
            "--data",
            good.to_str().unwrap(),
            "--y",
            "y",
            "--phi",
            "x1,x2",
            "--method",
            method,
            "--json",
        ]);
        assert_eq!(j["unresolved"], serde_json::json!([]), "{method}: {j}");
        for (p, truth) in [("x1", 2.0), ("x2", -3.0)] {
            let (v, se) = (
                j["params"][p].as_f64().unwrap(),
                j["std_err"][p].as_f64().unwrap(),
            );
            // (kf takes its noise variance as given, R2 = 1 by default: a wider σ.)
            assert!(se > 0.0 && se < 0.1, "{method} {p}: σ {se}");
            assert!(
                (v - truth).abs() < 5.0 * se + 1e-3,
                "{method} {p}: {v} ± {se}"
            );
        }
    }
    // A model whose parameters only appear as a product: A and B cannot be told apart.
    let j = ok_json(&[
        "estimate",
        "--data",
        good.to_str().unwrap(),
        "--y",
        "y",
        "--expr",
        "A*B*x1 - 3*x2",
        "--params",
        "A=1,B=1",
        "--method",
        "ukf",
        "--json",
    ]);
    assert_eq!(j["unresolved"], serde_json::json!(["A", "B"]), "{j}");
    // Separately: both resolved, near the truth.
    let j = ok_json(&[
        "estimate",
        "--data",
        good.to_str().unwrap(),
        "--y",
        "y",
        "--expr",
        "A*x1 + B*x2",
        "--params",
        "A=1,B=1",
        "--method",
        "ukf",
        "--json",
    ]);
    assert_eq!(j["unresolved"], serde_json::json!([]), "{j}");
    assert!(
        (j["params"]["A"].as_f64().unwrap() - 2.0).abs() < 0.01,
        "{j}"
    );
}

#[test]
fn a_csv_cut_off_in_its_last_number_is_read_with_a_warning() {
    let s = Scratch::new("physid-rel");
    let f = s.file("cut.csv");
    std::fs::write(&f, "t,x\n0,1\n0.001,2\n0.002,3.1").unwrap();
    let o = physid(&["inspect", f.to_str().unwrap(), "--json"]);
    assert!(o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("the last line (line 4) has no line end: the file may have been cut short"),
        "{e}"
    );
}

/// `simulate` writes its recording as it goes, and the file is the whole recording's: CSV and
/// MDF4 byte for byte what writing the recording `physid_sim::simulate` returns gives, Parquet
/// the same channels, units, metadata and values (its row groups are smaller).
#[test]
fn simulate_writes_as_it_goes_the_whole_recordings_file() {
    use physid_sim::run::{simulate, OutputBasis, RunOptions};
    let s = Scratch::new("physid-sim-stream");
    let scenario = physid_sim::scenario::named("shaft-steady").unwrap();
    for basis in ["time", "crank"] {
        let opts = RunOptions {
            duration: Some(2.5),
            basis: match basis {
                "time" => OutputBasis::Time(10_000.0),
                _ => OutputBasis::Crank(1.0),
            },
            ..Default::default()
        };
        let whole = simulate(&scenario, &opts, |_| {}).unwrap();
        for ext in ["csv", "mf4", "parquet"] {
            let streamed = s.file(&format!("{basis}.{ext}"));
            let o = physid(&[
                "simulate",
                "--scenario",
                "shaft-steady",
                "--duration",
                "2.5",
                "--basis",
                basis,
                "--recording",
                streamed.to_str().unwrap(),
            ]);
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
            let reference = s.file(&format!("{basis}-whole.{ext}"));
            physid_io::write(&reference, &whole, &Default::default()).unwrap();
            if ext == "parquet" {
                let (mut a, mut b) = (
                    physid_io::read_parquet(&streamed, None).unwrap(),
                    physid_io::read_parquet(&reference, None).unwrap(),
                );
                // `source` is the file read.
                a.meta.remove("source");
                b.meta.remove("source");
                assert_eq!(a.meta, b.meta, "{basis}");
                assert_eq!(a.channels(), b.channels(), "{basis}");
            } else if ext == "mf4" {
                // The MDF4 header carries the file's creation time: compare from the blocks on.
                let (a, b) = (
                    std::fs::read(&streamed).unwrap(),
                    std::fs::read(&reference).unwrap(),
                );
                assert_eq!(a.len(), b.len(), "{basis}.{ext}");
                let back = physid_io::read_mdf(&streamed, None).unwrap();
                assert_eq!(back.channels().len(), whole.channels().len());
                for c in whole.channels() {
                    assert!(
                        back.values(&c.name).unwrap() == c.values.as_slice(),
                        "{}",
                        c.name
                    );
                }
            } else {
                assert!(
                    std::fs::read(&streamed).unwrap() == std::fs::read(&reference).unwrap(),
                    "{basis}.{ext}"
                );
            }
        }
    }
}

/// The verbs that read recordings read them a chunk at a time, only the channels they take,
/// and answer as on the whole recording: `inspect` (findings in the second chunk: a NaN, lost
/// samples, a count going back) and `monitor shaft` against the library run on the recording
/// read whole, in CSV, Parquet and MDF4; `friction fit` and `torque fit` the same in all three
/// formats, and with the file's columns renamed through `--map`; `convert` between formats
/// (MDF4 compressed too).
/// A result's own answer, its provenance (the command line, the date, the input's checksum)
/// taken off after checking it names one input with a SHA-256.
fn without_provenance(mut v: serde_json::Value) -> serde_json::Value {
    let p = v.as_object_mut().unwrap().remove("provenance").unwrap();
    let sha = p["inputs"][0]["sha256"].as_str().unwrap();
    assert!(
        sha.len() == 64 && sha.chars().all(|c| c.is_ascii_hexdigit()),
        "{p}"
    );
    v
}

#[test]
fn the_file_verbs_read_as_they_go_and_answer_as_on_the_whole() {
    use physid_apps::acquisition::{inspect, AcquisitionOptions};
    use physid_apps::shaft_monitor::{monitor_shaft, MonitorConfig};
    use physid_sim::run::{simulate, OutputBasis, RunOptions};
    let s = Scratch::new("physid-read-stream");
    let sim = |name: &str, faults: Vec<&str>, seconds: f64| {
        let opts = RunOptions {
            duration: Some(seconds),
            basis: OutputBasis::Time(10_000.0),
            faults: faults
                .iter()
                .map(|f| physid_sim::scenario::Fault::parse(f).unwrap())
                .collect(),
            ..Default::default()
        };
        simulate(&physid_sim::scenario::named(name).unwrap(), &opts, |_| {}).unwrap()
    };
    // 8 s at 10 kHz: two chunks of the reader; a stiffness fault at 4 s.
    let shaft = sim("shaft-steady", vec!["shaft.k=1000@4"], 8.0);
    let mut defective = shaft.clone();
    let n = defective.len();
    let mut t = defective.values("t").unwrap().to_vec();
    for v in &mut t[70_010..] {
        *v += 3e-4;
    }
    defective.replace_values("t", t).unwrap();
    let mut p = defective.values("p_cyl").unwrap().to_vec();
    p[70_500] = f64::NAN;
    defective.replace_values("p_cyl", p).unwrap();
    let mut c = defective.values("count_dy").unwrap().to_vec();
    c[75_000] -= 5.0;
    defective.replace_values("count_dy", c).unwrap();
    assert!(n > physid_io::CHUNK_ROWS);
    for ext in ["csv", "parquet", "mf4"] {
        let f = s.file(&format!("defective.{ext}"));
        physid_io::write(&f, &defective, &Default::default()).unwrap();
        let got = without_provenance(ok_json(&["inspect", f.to_str().unwrap(), "--json"]));
        let whole = physid_io::read(&f, &Default::default()).unwrap();
        let mut want =
            serde_json::to_value(inspect(&whole, &AcquisitionOptions::default())).unwrap();
        want["surfaces"] = serde_json::json!([]);
        assert_eq!(got, want, "{ext}");
        let kinds: Vec<&str> = got["integrity"]["findings"]
            .as_array()
            .unwrap()
            .iter()
            .map(|f| f["kind"].as_str().unwrap())
            .collect();
        for k in ["lost_samples", "non_finite", "count_backwards"] {
            assert!(kinds.contains(&k), "{ext}: {kinds:?}");
        }

        let f = s.file(&format!("shaft.{ext}"));
        physid_io::write(&f, &shaft, &Default::default()).unwrap();
        let got = without_provenance(ok_json(&[
            "monitor",
            "shaft",
            "--data",
            f.to_str().unwrap(),
            "--json",
        ]));
        let whole = physid_io::read(&f, &Default::default()).unwrap();
        let want = serde_json::to_value(
            monitor_shaft(&whole, &MonitorConfig::default())
                .unwrap()
                .summary(),
        )
        .unwrap();
        assert_eq!(got, want, "{ext}");
        assert_eq!(got["alarms"][0]["param"], "K", "{ext}: {got}");

        // The tracks, every estimator sample, in the same format: K's last sample is the final
        // estimate, and alarm_K turns 1 when the alarm was raised.
        let tracks = s.file(&format!("shaft-tracks.{ext}"));
        let o = physid(&[
            "monitor",
            "shaft",
            "--data",
            f.to_str().unwrap(),
            "--tracks",
            tracks.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let tr = physid_io::read(&tracks, &Default::default()).unwrap();
        let (t, k, alarm) = (
            tr.values("t").unwrap(),
            tr.values("K").unwrap(),
            tr.values("alarm_K").unwrap(),
        );
        assert_eq!(tr.channel("K").unwrap().unit, "N*m/rad");
        assert!(
            (t.len() as f64 - 8.0 * 2000.0).abs() < 50.0,
            "{ext}: {}",
            t.len()
        );
        assert_eq!(k[k.len() - 1], got["final"]["K"].as_f64().unwrap(), "{ext}");
        let raised = got["alarms"][0]["t_raised_s"].as_f64().unwrap();
        let first = t[alarm.iter().position(|&a| a == 1.0).unwrap()];
        assert_eq!(first, raised, "{ext}");
        assert!(alarm[t.iter().position(|&x| x >= raised).unwrap()..]
            .iter()
            .all(|&a| a == 1.0));
    }

    // Motored and fired runs through the cycle-indexed stages.
    let motored = sim("friction-sweep", vec![], 8.0);
    let fired = sim("torque-steady", vec![], 3.0);
    let mut friction: Option<serde_json::Value> = None;
    let mut torque: Option<serde_json::Value> = None;
    for ext in ["csv", "parquet", "mf4"] {
        let f = s.file(&format!("motored.{ext}"));
        physid_io::write(&f, &motored, &Default::default()).unwrap();
        let got = without_provenance(ok_json(&[
            "friction",
            "fit",
            "--data",
            f.to_str().unwrap(),
            "--json",
        ]));
        assert!(got["cycles"]["used"].as_u64().unwrap() > 30, "{got}");
        assert_eq!(friction.get_or_insert(got.clone()), &got, "{ext}");
        let f = s.file(&format!("fired.{ext}"));
        physid_io::write(&f, &fired, &Default::default()).unwrap();
        let got = without_provenance(ok_json(&[
            "torque",
            "fit",
            "--data",
            f.to_str().unwrap(),
            "--json",
        ]));
        assert_eq!(torque.get_or_insert(got.clone()), &got, "{ext}");
    }
    // The tracks: a row per steady cycle (friction), per cycle's worth of samples (torque),
    // ending at the final estimates.
    let (fj, tj) = (friction.clone().unwrap(), torque.clone().unwrap());
    for (verb, data, json) in [("friction", "motored", &fj), ("torque", "fired", &tj)] {
        let tracks = s.file(&format!("{verb}-tracks.parquet"));
        let data = s.file(&format!("{data}.parquet"));
        let o = physid(&[
            verb,
            "fit",
            "--data",
            data.to_str().unwrap(),
            "--tracks",
            tracks.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let tr = physid_io::read(&tracks, &Default::default()).unwrap();
        let rows = tr.len();
        if verb == "friction" {
            assert_eq!(rows as u64, json["cycles"]["used"].as_u64().unwrap());
        } else {
            assert_eq!(rows as u64, json["samples"].as_u64().unwrap() / 720);
        }
        for p in json["estimable"].as_array().unwrap() {
            let p = p.as_str().unwrap();
            let last = tr.values(p).unwrap()[rows - 1];
            assert_eq!(last, json["params"][p].as_f64().unwrap(), "{verb} {p}");
        }
    }
    // The columns renamed in the file, mapped back on reading.
    let mut renamed = physid_core::Recording::new(motored.basis);
    for ch in motored.channels() {
        renamed
            .push(physid_core::Channel {
                name: format!("Log_{}", ch.name),
                unit: ch.unit.clone(),
                values: ch.values.clone(),
            })
            .unwrap();
    }
    let f = s.file("renamed.parquet");
    physid_io::write(&f, &renamed, &Default::default()).unwrap();
    let mut args = vec![
        "friction".to_string(),
        "fit".into(),
        "--data".into(),
        f.to_str().unwrap().into(),
        "--json".into(),
    ];
    args.extend(
        motored
            .channels()
            .iter()
            .map(|c| format!("--map={0}=Log_{0}", c.name)),
    );
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    assert_eq!(Some(without_provenance(ok_json(&args))), friction);

    // `convert` between formats goes a chunk at a time: every channel, or a selection with the
    // time channel brought along, the values as they were (units converted on reading).
    let src = s.file("motored.parquet");
    for ext in ["csv", "mf4", "parquet"] {
        let out = s.file(&format!("converted.{ext}"));
        let o = physid(&["convert", src.to_str().unwrap(), out.to_str().unwrap()]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let (a, b) = (
            physid_io::read(&src, &Default::default()).unwrap(),
            physid_io::read(&out, &Default::default()).unwrap(),
        );
        assert_eq!(a.channels(), b.channels(), "{ext}");
        let o = physid(&[
            "convert",
            src.to_str().unwrap(),
            out.to_str().unwrap(),
            "--channels",
            "p_int,omega_en",
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let b = physid_io::read(&out, &Default::default()).unwrap();
        assert_eq!(b.names(), ["t", "p_int", "omega_en"], "{ext}");
        assert_eq!(b.values("p_int").unwrap(), a.values("p_int").unwrap());
    }
    // MDF4 written compressed goes a chunk at a time too: 80 000 records of 35 channels, a
    // deflated block per 4 MiB of them; the values read back as they were.
    let a = physid_io::read(&src, &Default::default()).unwrap();
    for comp in ["deflate", "transposed"] {
        let out = s.file(&format!("converted-{comp}.mf4"));
        let o = physid(&[
            "convert",
            src.to_str().unwrap(),
            out.to_str().unwrap(),
            "--compression",
            comp,
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let bytes = std::fs::read(&out).unwrap();
        let raw = a.len() * 8 * a.channels().len();
        assert!(
            bytes.windows(4).filter(|w| w == b"##DZ").count() >= raw / physid_io::MDF_BLOCK_BYTES,
            "{comp}"
        );
        assert!(bytes.len() < raw, "{comp}: {} bytes", bytes.len());
        let b = physid_io::read(&out, &Default::default()).unwrap();
        assert_eq!(a.channels(), b.channels(), "{comp}");
    }
}

/// `estimate` feeds a file through the estimator a chunk at a time, writing its tracks as they
/// come: RLS over 150 000 rows of a CSV file (three chunks of the reader) ends at the least
/// squares solution of the normal equations (solved here, independently; RLS from ϑ0 = 0 and
/// P0 = 1000·I is exactly the solution regularised by I/1000), and `--out` holds a row per
/// sample ending at the final estimate.
#[test]
fn estimate_streams_a_long_file_as_one_run() {
    let s = Scratch::new("physid-estimate-stream");
    let f = s.file("long.csv");
    let n = 150_000;
    let mut text = String::from("x1,x2,y\n");
    let (mut xtx, mut xty) = ([[0.0f64; 2]; 2], [0.0f64; 2]);
    for i in 0..n {
        let t = i as f64 * 1e-3;
        let x = [(7.0 * t).sin() + 1.5, (3.1 * t).cos() * (0.5 + t / 150.0)];
        // A deterministic disturbance, so the least squares solution is not the generator's.
        let y = 2.0 * x[0] - 0.5 * x[1] + 0.01 * (91.0 * t).sin();
        text.push_str(&format!("{},{},{}\n", x[0], x[1], y));
        // The numbers as the file holds them (shortest round trip).
        let x: [f64; 2] = [
            format!("{}", x[0]).parse().unwrap(),
            format!("{}", x[1]).parse().unwrap(),
        ];
        let y: f64 = format!("{y}").parse().unwrap();
        for a in 0..2 {
            xty[a] += x[a] * y;
            for b in 0..2 {
                xtx[a][b] += x[a] * x[b];
            }
        }
    }
    std::fs::write(&f, text).unwrap();
    for (a, row) in xtx.iter_mut().enumerate() {
        row[a] += 1e-3;
    }
    let det = xtx[0][0] * xtx[1][1] - xtx[0][1] * xtx[1][0];
    let ls = [
        (xtx[1][1] * xty[0] - xtx[0][1] * xty[1]) / det,
        (xtx[0][0] * xty[1] - xtx[1][0] * xty[0]) / det,
    ];
    let out = s.file("tracks.csv");
    let j = ok_json(&[
        "estimate",
        "--data",
        f.to_str().unwrap(),
        "--y",
        "y",
        "--phi",
        "x1,x2",
        "--method",
        "rls",
        "--json",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(j["samples"], n);
    for (k, name) in ["x1", "x2"].iter().enumerate() {
        let got = j["params"][name].as_f64().unwrap();
        assert!(
            (got / ls[k] - 1.0).abs() < 1e-8,
            "{name}: {got} vs {}",
            ls[k]
        );
    }
    let tracks = physid_io::read(&out, &Default::default()).unwrap();
    assert_eq!(tracks.len(), n);
    assert_eq!(
        tracks.values("x1").unwrap()[n - 1],
        j["params"]["x1"].as_f64().unwrap()
    );
}

/// Progress goes to stderr only on a terminal (here a pseudo-terminal made by `script`), for
/// work past a delay (set to 0 here), and never with `--quiet` or when stderr is a pipe.
#[test]
fn progress_shows_on_a_terminal_only() {
    let s = Scratch::new("physid-progress");
    let f = s.file("run.parquet");
    let o = physid(&[
        "simulate",
        "--scenario",
        "shaft-steady",
        "--duration",
        "2",
        "--recording",
        f.to_str().unwrap(),
    ]);
    assert!(o.status.success());
    // Piped: nothing on stderr.
    assert!(
        o.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let on_a_terminal = |extra: &str| on_a_terminal(&format!("inspect {} {extra}", f.display()));
    let shown = on_a_terminal("");
    assert!(
        shown.contains("reading") && shown.contains("run.parquet"),
        "{shown}"
    );
    assert!(shown.contains("integrity: ok"), "{shown}");
    let quiet = on_a_terminal("--quiet");
    assert!(!quiet.contains("reading"), "{quiet}");
    assert!(quiet.contains("integrity: ok"), "{quiet}");
}

/// `estimate --phi` takes formulas over columns as regressors (the shaft's twist and twist
/// rate from the two angles and speeds): the same estimates as with the differences written
/// into the file as columns; a formula over a column that is not there names it.
#[test]
fn estimate_takes_formulas_over_columns_as_regressors() {
    let s = Scratch::new("physid-estimate-derived");
    let (raw, pre) = (s.file("raw.csv"), s.file("pre.csv"));
    let mut a = String::from("theta_dy,theta_en,omega_dy,omega_en,tau\n");
    let mut b = String::from("dth,dw,tau\n");
    for i in 0..3000 {
        let t = i as f64 * 1e-3;
        let (te, td) = (100.0 * t, 100.0 * t + 0.01 * (7.0 * t).sin());
        let (we, wd) = (
            100.0,
            100.0 + 0.07 * (7.0 * t).cos() + 0.02 * (31.0 * t).sin(),
        );
        let tau = 1200.0 * (td - te) + 0.9 * (wd - we);
        a.push_str(&format!("{td},{te},{wd},{we},{tau}\n"));
        // The differences of the numbers as the first file holds them.
        let p = |v: f64| -> f64 { format!("{v}").parse().unwrap() };
        b.push_str(&format!("{},{},{tau}\n", p(td) - p(te), p(wd) - p(we)));
    }
    std::fs::write(&raw, a).unwrap();
    std::fs::write(&pre, b).unwrap();
    let est = |file: &std::path::Path, phi: &str| {
        ok_json(&[
            "estimate",
            "--data",
            file.to_str().unwrap(),
            "--y",
            "tau",
            "--phi",
            phi,
            "--method",
            "rls",
            "--json",
        ])
    };
    let derived = est(&raw, "theta_dy-theta_en,omega_dy-omega_en");
    let columns = est(&pre, "dth,dw");
    // `1` is an offset regressor: zero within its ±3σ here, the torque has none.
    let with_offset = est(&raw, "theta_dy-theta_en,omega_dy-omega_en,1");
    let (offset, se) = (
        with_offset["params"]["1"].as_f64().unwrap(),
        with_offset["std_err"]["1"].as_f64().unwrap(),
    );
    assert!(offset.abs() < 3.0 * se, "{with_offset}");
    assert_eq!(
        derived["params"]["theta_dy-theta_en"],
        columns["params"]["dth"]
    );
    assert_eq!(
        derived["params"]["omega_dy-omega_en"],
        columns["params"]["dw"]
    );
    let k = derived["params"]["theta_dy-theta_en"].as_f64().unwrap();
    // Near the truth (the prior P0 = 1000·I still weighs against Σ(Δθ)² ≈ 0.15 here).
    assert!((k / 1200.0 - 1.0).abs() < 1e-2, "{derived}");
    fails_with(
        &[
            "estimate",
            "--data",
            raw.to_str().unwrap(),
            "--y",
            "tau",
            "--phi",
            "theta_dy-theta_xx",
            "--method",
            "rls",
        ],
        "theta_xx",
    );
}

/// Work of unknown length (a pipeline run) shows a spinner on a terminal past the delay, and
/// nothing with `--quiet`.
#[test]
fn a_long_analysis_shows_a_spinner_on_a_terminal() {
    let shipped = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../pipelines");
    let run = |extra: &str| {
        on_a_terminal(&format!(
            "run {} --json {extra}",
            shipped.join("shaft-expr.toml").display()
        ))
    };
    let shown = run("");
    assert!(
        shown.contains("running") && shown.contains("shaft-expr.toml"),
        "{shown}"
    );
    assert!(shown.contains("\"objective\""), "{shown}");
    let quiet = run("--quiet");
    assert!(!quiet.contains("running"), "{quiet}");
}

/// `compression fit --json` on `f` with `PHYSID_HOLD_MB=hold`: its exit code, stderr and
/// stdout.
fn compression_fit_holding(f: &str, hold: &str, extra: &[&str]) -> (Option<i32>, String, Vec<u8>) {
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_physid"))
        .env("PHYSID_HOLD_MB", hold)
        .args([
            "compression",
            "fit",
            "--data",
            f,
            "--stroke",
            "0.0514",
            "--rod",
            "0.088",
            "--json",
        ])
        .args(extra)
        .output()
        .unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stderr).to_string(),
        o.stdout,
    )
}

/// The verbs on a crank-angle basis read as they go too, and answer as on the whole recording
/// (the library on the file read whole, put on a crank-angle basis with `to_crank_angle`):
/// `cycles` (with the geometry: IMEP, polytropic exponents) and `compression fit` on a
/// time-basis file with `theta_en` (resampled as it is read; the fit's windows held, or
/// gathered again on every pass), `convert --crank-angle` bit for
/// bit, in CSV, Parquet and MDF4; on a crank-angle file `torque fit`, `convert --time-basis`
/// bit for bit and `monitor shaft` (put on a time basis as it is read, at the whole
/// recording's mean rate).
/// Every file is longer than one chunk of the reader.
#[test]
fn the_crank_angle_verbs_read_as_they_go_and_answer_as_on_the_whole() {
    use physid_apps::acquisition::{to_crank_angle, to_time_basis, AcquisitionOptions};
    use physid_apps::compression::{compression_fit, CompressionConfig};
    use physid_apps::pressure::{analyse, Geometry, Pegging};
    use physid_apps::shaft_monitor::{monitor_shaft, MonitorConfig};
    use physid_core::Recording;
    use physid_sim::run::{simulate, OutputBasis, RunOptions};
    let s = Scratch::new("physid-crank-stream");
    let sim = |name: &str, seconds: f64, basis: OutputBasis| {
        let opts = RunOptions {
            duration: Some(seconds),
            basis,
            ..Default::default()
        };
        simulate(&physid_sim::scenario::named(name).unwrap(), &opts, |_| {}).unwrap()
    };
    let opts = AcquisitionOptions::default();
    let motored = sim("friction-sweep", 8.0, OutputBasis::Time(10_000.0));
    assert!(motored.len() > physid_io::CHUNK_ROWS);
    // Without `theta_en`: the angle from the encoder's counts, the file read three times over
    // (a few channels: the compression fit not held reads it three times on every pass).
    let mut counts_only = Recording::new(motored.basis);
    for name in ["t", "count_en", "count_dy", "tdc", "p_cyl", "omega_en"] {
        counts_only
            .push(motored.channel(name).unwrap().clone())
            .unwrap();
    }
    let geometry = Geometry {
        bore: 0.054,
        stroke: 0.0514,
        rod: 0.088,
        compression_ratio: 9.5,
    };
    let mut deg = Recording::new(motored.basis);
    for (angle, motored) in [("theta_en", &motored), ("counts", &counts_only)] {
        deg = to_crank_angle(motored, &opts, 1.0).unwrap();
        // `cycles` resamples at 0.1° unless told otherwise; `compression fit` at 1°.
        let fine = to_crank_angle(motored, &opts, 0.1).unwrap();
        let want_cycles = serde_json::to_value(
            analyse(&fine, "p_cyl", Some(&geometry), Pegging::Bdc(1e5)).unwrap(),
        )
        .unwrap();
        assert!(want_cycles["cycles"].as_array().unwrap().len() > 40);
        assert!(want_cycles["cycles"][3]["imep_pa"].is_number());
        let want_fit = {
            let r = compression_fit(&deg, &CompressionConfig::new("p_cyl", 0.0514, 0.088)).unwrap();
            serde_json::to_value(&r).unwrap()
        };
        for ext in ["csv", "parquet", "mf4"] {
            let f = s.file(&format!("motored-{angle}.{ext}"));
            physid_io::write(&f, motored, &Default::default()).unwrap();
            let f = f.to_str().unwrap();
            let got = without_provenance(ok_json(&[
                "cycles",
                f,
                "--bore",
                "0.054",
                "--stroke",
                "0.0514",
                "--rod",
                "0.088",
                "--compression-ratio",
                "9.5",
                "--peg",
                "bdc=1e5",
                "--json",
            ]));
            assert_eq!(got, want_cycles, "{angle} {ext}");
            // The windows held, and not: gathered again from the file on every pass of the fit.
            for hold in ["256", "0"] {
                let (code, err, out) = compression_fit_holding(f, hold, &[]);
                assert_eq!(code, Some(0), "{angle} {ext}: {err}");
                let mut got = without_provenance(serde_json::from_slice(&out).unwrap());
                got.as_object_mut().unwrap().remove("motored_imep_pa");
                assert_eq!(got, want_fit, "{angle} {ext}, PHYSID_HOLD_MB={hold}");
            }
            let out = s.file(&format!("deg-{angle}-{ext}.{ext}"));
            let o = physid(&["convert", f, out.to_str().unwrap(), "--crank-angle"]);
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
            let back = physid_io::read(&out, &Default::default()).unwrap();
            assert_eq!(back.names(), deg.names(), "{angle} {ext}");
            for ch in deg.channels() {
                assert_eq!(
                    back.values(&ch.name).unwrap(),
                    &ch.values[..],
                    "{angle} {ext} {}",
                    ch.name
                );
            }
        }
    }
    // `friction fit` and `torque fit` on the counts of every channel (without `theta_en`) answer
    // as on the crank-angle file the library makes of them whole.
    let fired = sim("torque-steady", 3.0, OutputBasis::Time(10_000.0));
    for (verb, rec) in [("friction", &motored), ("torque", &fired)] {
        let mut counts = Recording::new(rec.basis);
        for c in rec.channels().iter().filter(|c| c.name != "theta_en") {
            counts.push(c.clone()).unwrap();
        }
        let (f, g) = (
            s.file(&format!("{verb}-counts.parquet")),
            s.file(&format!("{verb}-deg.parquet")),
        );
        physid_io::write(&f, &counts, &Default::default()).unwrap();
        let whole = to_crank_angle(&counts, &opts, 1.0).unwrap();
        physid_io::write(&g, &whole, &Default::default()).unwrap();
        let fit = |f: &std::path::Path| {
            without_provenance(ok_json(&[
                verb,
                "fit",
                "--data",
                f.to_str().unwrap(),
                "--json",
            ]))
        };
        let got = fit(&f);
        assert_eq!(got, fit(&g), "{verb}");
        assert!(got["params"].is_object(), "{verb}: {got}");
    }

    // From here on, the crank-angle recording of the counts (which the fit's wants match).
    let want_fit = {
        let r = compression_fit(&deg, &CompressionConfig::new("p_cyl", 0.0514, 0.088)).unwrap();
        serde_json::to_value(&r).unwrap()
    };

    // A crank-angle file, its windows gathered again on every pass; a cut-short last line is
    // said once, not on every pass.
    let f = s.file("motored-deg.csv");
    physid_io::write(&f, &deg, &Default::default()).unwrap();
    let text = std::fs::read_to_string(&f).unwrap();
    std::fs::write(&f, text.trim_end()).unwrap();
    let (code, err, out) = compression_fit_holding(f.to_str().unwrap(), "0", &[]);
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(err.matches("warning:").count(), 1, "{err}");
    let mut got = without_provenance(serde_json::from_slice(&out).unwrap());
    got.as_object_mut().unwrap().remove("motored_imep_pa");
    assert_eq!(got, want_fit, "crank-angle CSV, PHYSID_HOLD_MB=0");

    // A fired crank-angle file: the torque fit reads its 1° samples as they come (the library
    // cuts the recording in chunks of its own).
    let fired = sim("torque-steady", 3.0, OutputBasis::Crank(1.0));
    let f = s.file("fired-deg.parquet");
    physid_io::write(&f, &fired, &Default::default()).unwrap();
    let got = without_provenance(ok_json(&[
        "torque",
        "fit",
        "--data",
        f.to_str().unwrap(),
        "--json",
    ]));
    let cfg = physid_apps::torque_fit::TorqueFitConfig::new(
        physid_apps::torque_fit::cyclic_torque_nominal(&Default::default()).unwrap(),
    );
    let want = physid_apps::torque_fit::torque_fit(&fired, &cfg).unwrap();
    assert_eq!(got, serde_json::to_value(want.summary()).unwrap());

    // A crank-angle file back to a time basis, and the shaft monitored on it.
    let shaft = sim("shaft-steady", 12.0, OutputBasis::Crank(1.0));
    assert!(shaft.len() > physid_io::CHUNK_ROWS, "{}", shaft.len());
    let f = s.file("shaft-deg.parquet");
    physid_io::write(&f, &shaft, &Default::default()).unwrap();
    let out = s.file("shaft-time.parquet");
    let o = physid(&[
        "convert",
        f.to_str().unwrap(),
        out.to_str().unwrap(),
        "--time-basis",
        "7000",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let want = to_time_basis(&shaft, 7000.0).unwrap();
    let back = physid_io::read(&out, &Default::default()).unwrap();
    assert_eq!(back.names(), want.names());
    for ch in want.channels() {
        assert_eq!(
            back.values(&ch.name).unwrap(),
            &ch.values[..],
            "{}",
            ch.name
        );
    }
    let got = without_provenance(ok_json(&[
        "monitor",
        "shaft",
        "--data",
        f.to_str().unwrap(),
        "--json",
    ]));
    let want = serde_json::to_value(
        monitor_shaft(&shaft, &MonitorConfig::default())
            .unwrap()
            .summary(),
    )
    .unwrap();
    assert_eq!(got, want);
}

/// `identify` goes over its file in passes (the output's level, the ranking's factors, each
/// Gauss–Newton iteration of the fit and of Wu's criterion): held after the first when the
/// columns fit `PHYSID_HOLD_MB`, else read again on every pass. Either way the result is the
/// library's on the whole recording, for CSV, Parquet and MDF4 files longer than a reader's
/// chunk; a bad value met on a pass read again is placed by its line; a bad limit is refused.
#[test]
fn identify_goes_over_its_file_in_passes_and_answers_as_on_the_whole() {
    use physid_core::{Basis, Channel, Recording};
    use physid_ident::{identify, Data, IdentConfig, Selection};
    let s = Scratch::new("physid-ident-passes");
    let n = physid_io::CHUNK_ROWS * 2 + 777;
    let t: Vec<f64> = (0..n).map(|i| i as f64 * 1e-4).collect();
    let x: Vec<f64> = (0..n)
        .map(|i| 0.5 + ((i * 7919 % 10_007) as f64 / 10_007.0))
        .collect();
    let y: Vec<f64> = x
        .iter()
        .enumerate()
        .map(|(i, x)| {
            2.0 * (-0.8 * x).exp() + 0.3 * x + 1e-3 * ((i * 104_729 % 1000) as f64 / 1000.0 - 0.5)
        })
        .collect();
    let mut rec = Recording::new(Basis::Time);
    for (name, unit, values) in [("t", "s", &t), ("x", "", &x), ("y", "", &y), ("z", "", &x)] {
        rec.push(Channel {
            name: name.into(),
            unit: unit.into(),
            values: values.clone(),
        })
        .unwrap();
    }
    let (expr, params) = ("A*exp(-B*x) + C*x + D*x^2", "A=2,B=0.8,C=0.3,D=0.01");
    let model = physid_expr::ExprModel::parse(expr, &["A", "B", "C", "D"]).unwrap();
    let whole = Data {
        inputs: vec![&x],
        y: Some(&y),
    };
    let id = identify(
        &model,
        &whole,
        &[2.0, 0.8, 0.3, 0.01],
        &[],
        IdentConfig::default(),
        Selection::Wu { sigma2: None },
        None,
    )
    .unwrap();
    let want = serde_json::to_value(id.report()).unwrap();
    assert_eq!(want["rows"], n);
    let run = |f: &str, hold: &str| {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_physid"))
            .env("PHYSID_HOLD_MB", hold)
            .args([
                "identify", "--data", f, "--expr", expr, "--params", params, "--y", "y",
                "--cutoff", "wu", "--json",
            ])
            .output()
            .unwrap();
        (
            o.status.code(),
            String::from_utf8_lossy(&o.stderr).to_string(),
            o.stdout,
        )
    };
    for ext in ["csv", "parquet", "mf4"] {
        let f = s.file(&format!("xy.{ext}"));
        physid_io::write(&f, &rec, &Default::default()).unwrap();
        let f = f.to_str().unwrap();
        for hold in ["256", "0"] {
            let (code, err, out) = run(f, hold);
            assert_eq!(code, Some(0), "{ext}, hold {hold}: {err}");
            let mut got = without_provenance(serde_json::from_slice(&out).unwrap());
            assert_eq!(got.as_object_mut().unwrap().remove("data").unwrap(), f);
            assert_eq!(got, want, "{ext}, hold {hold}");
        }
    }
    // A value that is not finite, in a chunk after the first: its line, counted from the file's
    // start.
    let mut bad = rec.clone();
    let mut v = y.clone();
    v[physid_io::CHUNK_ROWS + 5] = f64::INFINITY;
    bad.replace_values("y", v).unwrap();
    let f = s.file("bad.csv");
    physid_io::write(&f, &bad, &Default::default()).unwrap();
    let (code, err, _) = run(f.to_str().unwrap(), "0");
    assert_eq!(code, Some(1), "{err}");
    let sample = physid_io::CHUNK_ROWS + 5;
    assert!(
        err.contains(&format!(
            "line {} (sample {sample}): 'output' is inf",
            sample + 3
        )),
        "{err}"
    );
    let (code, err, _) = run(f.to_str().unwrap(), "lots");
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("PHYSID_HOLD_MB=lots: expected a whole number of MiB"),
        "{err}"
    );
}

/// A time-basis file whose angle is a raw sensor's signal, made from the simulator's angle (no
/// `theta_en`, no counts) — a Hall sensor over a 36−1 wheel; a 36-line quadrature encoder with
/// its index — is read as it goes (what must be known before any angle, then what the decoding
/// found and where the firing TDC lies, with the pressure, then the channels with the sensor
/// read ahead of them), and `cycles`, `compression fit` (the windows held and not) and `convert
/// --crank-angle` answer as the library on the whole recording does — the wheel in CSV, Parquet
/// and MDF4; with `--tdc-from`, the TDC is placed from the pressure as the library places it.
#[test]
fn a_raw_sensor_file_is_read_as_it_goes_and_answers_as_on_the_whole() {
    use physid_apps::acquisition::{AngleSensor, AngleSpec, PhaseFrom};
    use physid_core::Channel;
    use physid_sim::run::{simulate, OutputBasis, RunOptions};
    use std::f64::consts::TAU;
    let opts = RunOptions {
        duration: Some(6.0),
        basis: OutputBasis::Time(20_000.0),
        ..Default::default()
    };
    let sim = simulate(
        &physid_sim::scenario::named("friction-sweep").unwrap(),
        &opts,
        |_| {},
    )
    .unwrap();
    assert!(sim.len() > physid_io::CHUNK_ROWS);
    let theta = sim.values("theta_en").unwrap();
    let channel = |name: &str, f: &dyn Fn(f64) -> bool| Channel {
        name: name.into(),
        unit: "V".into(),
        values: theta.iter().map(|&th| f64::from(f(th))).collect(),
    };
    let pitch = TAU / 36.0;
    let wheel = channel("enc", &|th| {
        let tooth = (th / pitch).floor();
        tooth.rem_euclid(36.0) < 35.0 && th / pitch - tooth < 0.5
    });
    let line = |th: f64| (th / pitch).rem_euclid(1.0);
    let quadrature = [
        channel("qa", &|th| line(th) < 0.5),
        channel("qb", &|th| (line(th) - 0.25).rem_euclid(1.0) < 0.5),
        channel("qz", &|th| (th / TAU).rem_euclid(1.0) < 0.02),
    ];
    let spec = |sensor| AngleSpec {
        sensor,
        tdc_offset_deg: 0.0,
        phase_from: PhaseFrom::channel("p_cyl"),
    };
    sensor_file_answers_as_the_whole(
        &sim,
        &[wheel],
        &["--wheel", "enc=36-1"],
        spec(AngleSensor::Wheel {
            channel: "enc".into(),
            wheel: "36-1".parse().unwrap(),
            edges: Default::default(),
        }),
        &["csv", "parquet", "mf4"],
    );
    sensor_file_answers_as_the_whole(
        &sim,
        &quadrature,
        &["--quadrature", "qa,qb,qz=36"],
        spec(AngleSensor::Quadrature {
            a: "qa".into(),
            b: "qb".into(),
            z: Some("qz".into()),
            lines: 36,
        }),
        &["parquet"],
    );
}

/// The raw sensor's channels `sensor` with `sim`'s `t`, `p_cyl` and `omega_en`, written as
/// `exts`: the verbs with `flags` (and `--phase-from p_cyl`) answer as the library with `spec`.
fn sensor_file_answers_as_the_whole(
    sim: &physid_core::Recording,
    sensor: &[physid_core::Channel],
    flags: &[&str],
    spec: physid_apps::acquisition::AngleSpec,
    exts: &[&str],
) {
    use physid_apps::acquisition::{to_crank_angle_decoded, AcquisitionOptions};
    use physid_apps::compression::{compression_fit, CompressionConfig};
    use physid_apps::pressure::{analyse, Geometry, Pegging};
    use physid_core::Recording;
    let s = Scratch::new("physid-sensor-stream");
    let mut rec = Recording::new(sim.basis);
    for name in ["t", "p_cyl", "omega_en"] {
        rec.push(sim.channel(name).unwrap().clone()).unwrap();
    }
    for c in sensor {
        rec.push(c.clone()).unwrap();
    }
    let mut wheel: Vec<&str> = flags.to_vec();
    wheel.extend(["--tdc-offset", "0", "--phase-from", "p_cyl"]);
    let sensor_flags = &wheel[..flags.len()];
    let aopts = AcquisitionOptions {
        sensor: Some(spec),
        ..Default::default()
    };
    let (deg, decoded) = to_crank_angle_decoded(&rec, &aopts, 1.0).unwrap();
    let decoded = decoded.unwrap();
    assert!(
        decoded.summary.contains(" decoded: "),
        "{}",
        decoded.summary
    );
    let geometry = Geometry {
        bore: 0.054,
        stroke: 0.0514,
        rod: 0.088,
        compression_ratio: 9.5,
    };
    // `cycles` resamples at 0.1° unless told otherwise; `compression fit` at 1°.
    let (fine, _) = to_crank_angle_decoded(&rec, &aopts, 0.1).unwrap();
    let want_cycles =
        serde_json::to_value(analyse(&fine, "p_cyl", Some(&geometry), Pegging::Bdc(1e5)).unwrap())
            .unwrap();
    assert!(want_cycles["cycles"].as_array().unwrap().len() > 30);
    let want_fit = serde_json::to_value(
        compression_fit(&deg, &CompressionConfig::new("p_cyl", 0.0514, 0.088)).unwrap(),
    )
    .unwrap();
    for &ext in exts {
        let f = s.file(&format!("sensor.{ext}"));
        physid_io::write(&f, &rec, &Default::default()).unwrap();
        let f = f.to_str().unwrap();
        let mut args = vec![
            "cycles",
            f,
            "--bore",
            "0.054",
            "--stroke",
            "0.0514",
            "--rod",
            "0.088",
            "--compression-ratio",
            "9.5",
            "--peg",
            "bdc=1e5",
            "--json",
        ];
        args.extend(&wheel);
        let mut got = without_provenance(ok_json(&args));
        let o = got.as_object_mut().unwrap();
        assert_eq!(o.remove("phase").unwrap(), decoded.phase.as_str(), "{ext}");
        match (o.remove("wheel"), o.remove("encoder"), &decoded.wheel) {
            (Some(w), None, Some(d)) => assert_eq!(w["revolutions"], d.revolutions, "{ext}"),
            (None, Some(e), None) => {
                assert_eq!(e, serde_json::to_value(&decoded.encoder).unwrap(), "{ext}")
            }
            other => panic!("{ext}: {other:?}"),
        }
        assert_eq!(
            o.remove("findings").unwrap(),
            serde_json::to_value(&decoded.findings).unwrap(),
            "{ext}"
        );
        assert_eq!(got, want_cycles, "{ext}");
        for hold in ["256", "0"] {
            let (code, err, out) = compression_fit_holding(f, hold, &wheel);
            assert_eq!(code, Some(0), "{ext}: {err}");
            assert!(err.matches(" decoded: ").count() < 2, "{ext}: {err}");
            let mut got = without_provenance(serde_json::from_slice(&out).unwrap());
            got.as_object_mut().unwrap().remove("motored_imep_pa");
            assert_eq!(got, want_fit, "{ext}, PHYSID_HOLD_MB={hold}");
        }
        let out = s.file(&format!("deg-{ext}.{ext}"));
        let mut args = vec!["convert", f, out.to_str().unwrap(), "--crank-angle"];
        args.extend(&wheel);
        let o = physid(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let back = physid_io::read(&out, &Default::default()).unwrap();
        assert_eq!(back.names(), deg.names(), "{ext}");
        for ch in deg.channels() {
            assert_eq!(
                back.values(&ch.name).unwrap(),
                &ch.values[..],
                "{ext} {}",
                ch.name
            );
        }
    }
    // `--tdc-from`: the TDC placed from the motored pressure as the file is read (the fit's
    // windows held, and gathered again on every pass), as the library places it on the whole.
    let found = physid_apps::compression::tdc_from_pressure(
        &rec,
        &aopts,
        &CompressionConfig::new("p_cyl", 0.0514, 0.088),
        1.0,
    )
    .unwrap();
    let mut placed = aopts.clone();
    if let Some(spec) = placed.sensor.as_mut() {
        spec.tdc_offset_deg = found.tdc_offset_deg;
    }
    let (deg, _) = to_crank_angle_decoded(&rec, &placed, 1.0).unwrap();
    let f = s.file("sensor.parquet");
    for hold in ["256", "0"] {
        let out = s.file(&format!("tdc-from-{hold}.parquet"));
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_physid"))
            .env("PHYSID_HOLD_MB", hold)
            .args(["convert", f.to_str().unwrap(), out.to_str().unwrap()])
            .args([
                "--crank-angle",
                "--phase-from",
                "p_cyl",
                "--tdc-from",
                "p_cyl",
            ])
            .args(["--stroke", "0.0514", "--rod", "0.088"])
            .args(sensor_flags)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{err}");
        let said = format!("{:.3}° after the sensor's reference", found.tdc_offset_deg);
        assert!(err.contains(&said), "{err}");
        let back = physid_io::read(&out, &Default::default()).unwrap();
        assert_eq!(back.names(), deg.names());
        for ch in deg.channels() {
            assert_eq!(
                back.values(&ch.name).unwrap(),
                &ch.values[..],
                "{hold} {}",
                ch.name
            );
        }
    }
}

/// `identify` and `estimate` take rows in the file's order; a time that goes back or repeats
/// is said, with where it first does (issue 41, item 7: it was accepted without a word).
#[test]
fn a_time_that_goes_back_is_said_by_identify_and_estimate() {
    let s = Scratch::new("physid-rel");
    let f = s.file("back.csv");
    let mut text = String::from("t,x,y\n");
    for i in 0..1000 {
        let t = match i {
            100 => 0.5,
            200 => 1.99,
            _ => i as f64 * 0.01,
        };
        let x = (0.37 * i as f64).sin() + 0.1;
        text += &format!("{t},{x},{}\n", 3.0 * x + 0.01 * (1.7 * i as f64).cos());
    }
    std::fs::write(&f, text).unwrap();
    let path = f.to_str().unwrap();
    let said = "the time goes back at 1 sample(s) and repeats at 1 (the first at sample 100)";
    for args in [
        vec![
            "identify", "--data", path, "--expr", "K*x", "--params", "K=1", "--y", "y",
        ],
        vec!["estimate", "--data", path, "--y", "y", "--phi", "x"],
    ] {
        let o = physid(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{args:?}: {err}");
        assert!(err.contains(said), "{args:?}: {err}");
    }
}

/// Issue 41, item 5: the output alone scaled by 1e-300, 1e-150 or 1e150 — the estimates and
/// their standard errors scale with it (y is linear in them), never a standard error of
/// exactly 0 (the squared residuals underflowed) or ∞.
#[test]
fn an_output_at_the_edge_of_double_precision_keeps_its_standard_errors() {
    let s = Scratch::new("physid-rel");
    let write = |name: &str, scale: f64| {
        let f = s.file(name);
        let mut text = String::from("t,x1,x2,y\n");
        for i in 0..500 {
            let t = i as f64 * 0.01;
            let (a, b) = ((3.0 * t).sin() + 0.5, (5.0 * t).cos());
            let y = 2.0 * a - 3.0 * b + 0.01 * (91.0 * t).sin();
            text.push_str(&format!("{t},{a},{b},{}\n", y * scale));
        }
        std::fs::write(&f, text).unwrap();
        f
    };
    let run = |f: &std::path::Path, method: &str| {
        let j = ok_json(&[
            "estimate",
            "--data",
            f.to_str().unwrap(),
            "--y",
            "y",
            "--phi",
            "x1,x2",
            "--method",
            method,
            "--p0",
            "1e6",
            "--json",
        ]);
        let get = |k: &str, p: &str| j[k][p].as_f64().unwrap_or(f64::NAN);
        (
            [get("params", "x1"), get("params", "x2")],
            [get("std_err", "x1"), get("std_err", "x2")],
        )
    };
    let one = write("one.csv", 1.0);
    for method in ["rls", "rlsf", "dsfc"] {
        let (theta, se) = run(&one, method);
        for scale in [1e-300, 1e-150, 1e150] {
            let (theta_s, se_s) = run(&write(&format!("{scale:e}.csv"), scale), method);
            for j in 0..2 {
                let rel = |a: f64, b: f64| ((a / scale - b) / b).abs();
                assert!(
                    rel(theta_s[j], theta[j]) < 1e-9,
                    "{method} × {scale:e}: {theta_s:?} against {theta:?}"
                );
                assert!(
                    se_s[j] > 0.0 && rel(se_s[j], se[j]) < 1e-9,
                    "{method} × {scale:e}: standard errors {se_s:?} against {se:?}"
                );
            }
        }
    }
}

/// Issue 41, item 5, on the shaft monitor: torque scaled by 1e-300 scales K, B and their
/// standard errors with it (never a standard error of 0); every shaft channel scaled by
/// 1e-300 (K and B unchanged, but φφᵀ underflows: the data carry no information) leaves K and
/// B unresolved, said so, with no standard error and no alarm.
#[test]
fn the_shaft_monitor_at_the_edge_of_double_precision() {
    let s = Scratch::new("physid-rel");
    let run = s.file("run.parquet");
    common::simulated(&run, "shaft-steady", "3");
    let monitor = |f: &std::path::Path| {
        ok_json(&["monitor", "shaft", "--data", f.to_str().unwrap(), "--json"])
    };
    let scaled = |name: &str, channels: &[&str]| {
        let f = s.file(name);
        let mut args = vec![
            "convert".to_string(),
            run.to_str().unwrap().into(),
            f.to_str().unwrap().into(),
        ];
        for c in channels {
            args.extend(["--scale".into(), format!("{c}=1e-300,0")]);
        }
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = physid(&a);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        f
    };
    let base = monitor(&run);
    assert!(base.get("unresolved").is_none(), "{base}");
    let torque = monitor(&scaled("torque.parquet", &["torque_shaft"]));
    for p in ["K", "B"] {
        let (v, v1) = (
            torque["final"][p].as_f64().unwrap(),
            base["final"][p].as_f64().unwrap(),
        );
        let (se, se1) = (
            torque["std_err"][p].as_f64().unwrap(),
            base["std_err"][p].as_f64().unwrap(),
        );
        assert!(
            ((v / 1e-300 - v1) / v1).abs() < 1e-6,
            "{p}: {v} against {v1}"
        );
        assert!(
            se > 0.0 && ((se / 1e-300 - se1) / se1).abs() < 1e-6,
            "{p}: standard error {se} against {se1}"
        );
    }
    let all = monitor(&scaled(
        "all.parquet",
        &[
            "theta_en",
            "theta_dy",
            "omega_en",
            "omega_dy",
            "torque_shaft",
        ],
    ));
    let unresolved = all["unresolved"].as_array().unwrap();
    assert!(
        unresolved.contains(&"K".into()) && unresolved.contains(&"B".into()),
        "{all}"
    );
    assert!(
        all["std_err"]["K"].is_null() && all["std_err"]["B"].is_null(),
        "{all}"
    );
    assert_eq!(all["alarms"], serde_json::json!([]), "{all}");
}

/// Issue 41, item 5, on `identify`: an output scaled by 1e-300 is not "identically zero" — the
/// ranking is the unscaled one's; σ² (its squared residuals underflow) is null with the reason,
/// never 0. At 1e-150 and 1e150 the standard errors scale with the output.
#[test]
fn identify_at_the_edge_of_double_precision() {
    let s = Scratch::new("physid-rel");
    let write = |scale: f64| {
        let f = s.file(&format!("{scale:e}.csv"));
        let mut text = String::from("t,a,b,y\n");
        for i in 0..500 {
            let t = i as f64 * 0.01;
            let (a, b) = ((3.0 * t).sin() + 0.5, (5.0 * t).cos());
            let y = 2.0 * a - 3.0 * b + 0.01 * (91.0 * t).sin();
            text.push_str(&format!("{t},{a},{b},{}\n", y * scale));
        }
        std::fs::write(&f, text).unwrap();
        f
    };
    let identify = |scale: f64| {
        let params = format!("A={:e},B={:e}", 2.0 * scale, -3.0 * scale);
        ok_json(&[
            "identify",
            "--expr",
            "A*a+B*b",
            "--params",
            &params,
            "--data",
            write(scale).to_str().unwrap(),
            "--y",
            "y",
            "--json",
        ])
    };
    let one = identify(1.0);
    let tiny = identify(1e-300);
    for (a, b) in tiny["ranking"]
        .as_array()
        .unwrap()
        .iter()
        .zip(one["ranking"].as_array().unwrap())
    {
        let rel = |k: &str| (a[k].as_f64().unwrap() / b[k].as_f64().unwrap() - 1.0).abs();
        assert!(
            a["param"] == b["param"] && rel("relative") < 1e-9 && rel("residual_ss") < 1e-9,
            "{tiny} against {one}"
        );
    }
    assert!(tiny["sigma2"].is_null(), "{tiny}");
    assert!(
        tiny["sigma2_note"]
            .as_str()
            .unwrap()
            .contains("outside double precision"),
        "{tiny}"
    );
    for scale in [1e-150, 1e150] {
        let j = identify(scale);
        for p in ["A", "B"] {
            let (se, se1) = (
                j["std_err"][p].as_f64().unwrap(),
                one["std_err"][p].as_f64().unwrap(),
            );
            assert!(
                ((se / scale - se1) / se1).abs() < 1e-6,
                "× {scale:e} {p}: {se} against {se1}"
            );
        }
    }
}

/// Issue 41, item 6: units rows that lie. A speed in rpm read as rad/s (B = 0.0994 for a true
/// 0.95) and one in rad/s read as deg/s are found by `inspect` — the angle travelled against
/// the speed integrated — with the likely mislabel named; `monitor shaft` warns the same way.
/// The recording as simulated passes.
#[test]
fn a_speed_whose_units_row_lies_is_found_against_its_angle() {
    let s = Scratch::new("physid-rel");
    let run = s.file("run.parquet");
    common::simulated(&run, "shaft-steady", "2");
    let r = run.to_str().unwrap();
    let j = ok_json(&["inspect", r, "--json"]);
    assert_eq!(j["integrity"]["ok"], true, "{j}");
    for (gain, named) in [
        // rpm numbers under a rad/s label; rad/s numbers under deg/s (read as × π/180).
        (
            60.0 / std::f64::consts::TAU,
            "'omega_en' looks like rpm labelled rad/s",
        ),
        (
            std::f64::consts::PI / 180.0,
            "'omega_en' looks like rad/s labelled deg/s",
        ),
    ] {
        let f = s.file(&format!("lie-{gain}.parquet"));
        let o = physid(&[
            "convert",
            r,
            f.to_str().unwrap(),
            "--scale",
            &format!("omega_en={gain},0"),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let j = ok_json(&["inspect", f.to_str().unwrap(), "--json"]);
        let findings = j["integrity"]["findings"].as_array().unwrap();
        assert!(
            findings.iter().any(|x| x["kind"] == "speed_angle_mismatch"
                && x["detail"].as_str().unwrap().contains(named)),
            "{gain}: {j}"
        );
        fails_with(
            &["inspect", f.to_str().unwrap(), "--strict"],
            "the integrity check found",
        );
        let m = ok_json(&["monitor", "shaft", "--data", f.to_str().unwrap(), "--json"]);
        assert!(
            m["warnings"].as_array().unwrap()[0]
                .as_str()
                .unwrap()
                .contains(named),
            "{m}"
        );
    }
}

/// A flag that only shapes a reading on a crank-angle basis is refused where none is made,
/// naming the flag — `convert --step-deg 2` without `--crank-angle` wrote a time-basis file
/// and said nothing, `live --marker` without `--replay` was ignored, and `live --replay
/// --encoder-raw` replayed the file undecoded. A raw sensor whose channel the file lacks is
/// named: `convert --crank-angle --wheel enc=60-2` of a file with `theta_en` and no `enc`
/// took `theta_en` without a word. A conversion that gives no sample is an error.
#[test]
fn a_crank_angle_flag_without_a_crank_angle_reading_is_refused() {
    let s = Scratch::new("physid-rel");
    let rec = s.file("r.parquet");
    let rec = rec.to_str().unwrap();
    common::simulated(std::path::Path::new(rec), "shaft-steady", "0.5");
    let out = s.file("o.csv");
    let out = out.to_str().unwrap();
    for (flag, value) in [
        ("--step-deg", "2"),
        ("--phase-from", "p_cyl"),
        ("--marker", "tdc"),
        ("--encoder", "count_en=360"),
        ("--stroke", "0.09"),
    ] {
        fails_with(
            &["convert", rec, out, flag, value],
            &format!("{flag} is for a reading on a crank-angle basis: add --crank-angle"),
        );
        assert!(!std::path::Path::new(out).exists(), "{flag}: {out} written");
    }
    // With --crank-angle the same flags are taken; the crank's lengths only with --tdc-from.
    let o = physid(&["convert", rec, out, "--crank-angle", "--step-deg", "2"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    fails_with(
        &["convert", rec, out, "--crank-angle", "--rod", "0.15"],
        "--rod is for placing the TDC from a motored pressure (--tdc-from CHANNEL)",
    );
    // A recording shorter than its first cycle gave an empty file and exit 0: now an error,
    // and no file.
    let short = s.file("short.parquet");
    common::simulated(&short, "shaft-steady", "0.05");
    let empty = s.file("empty.csv");
    fails_with(
        &[
            "convert",
            short.to_str().unwrap(),
            empty.to_str().unwrap(),
            "--crank-angle",
        ],
        "no sample on a crank-angle basis, so",
    );
    assert!(!empty.exists());
    for (flag, value) in [("--marker", "tdc"), ("--phase-from", "p_cyl")] {
        fails_with(
            &[
                "live",
                "--headless",
                "--json",
                "--duration",
                "0.1",
                flag,
                value,
            ],
            &format!("{flag} is for the engine angle of a --replay file"),
        );
    }
    // A raw sensor named is decoded (here its channel is missing, and said), on a replay and
    // in a conversion, not passed over for the file's `theta_en`.
    let missing = "the engine angle is to be decoded from 'enc' (a pulse encoder's), which the recording does not have; its channels are t, theta_en,";
    let raw = ["--encoder-raw", "enc=360", "--index-raw", "idx"];
    for verb in [
        &["convert", rec, out, "--crank-angle"][..],
        &["live", "--headless", "--json", "--replay", rec][..],
    ] {
        fails_with(&[verb, &raw[..]].concat(), missing);
    }
}
