//! End-to-end tests of the `physid` command: run the binary, check its output and exit code.
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::PathBuf;
mod common;
use common::physid;
use std::process::{Command, Output};

/// A scratch directory removed when the test ends.
fn dir(name: &str) -> physid_testkit::Scratch {
    physid_testkit::Scratch::new(&format!("physid-cli-{name}"))
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).to_string()
}

/// A noise-free regression y = 2·a − 3·b + 0.5·c on 2000 exciting samples.
fn regression_csv(d: &std::path::Path, bad_line: Option<usize>) -> PathBuf {
    let mut s = String::from("t,a,b,c,y\n");
    for i in 0..2000 {
        let t = i as f64 * 1e-3;
        let (a, b, c) = (
            (37.0 * t).sin(),
            (11.0 * t).cos() + 0.3 * (91.0 * t).sin(),
            1.0,
        );
        let y = 2.0 * a - 3.0 * b + 0.5 * c;
        if bad_line == Some(i + 2) {
            s.push_str(&format!("{t},{a},NaN,{c},{y}\n"));
        } else {
            s.push_str(&format!("{t},{a},{b},{c},{y}\n"));
        }
    }
    let p = d.join("reg.csv");
    std::fs::write(&p, s).unwrap();
    p
}

/// Standard errors of the Kalman filter with R1 = 0 on `regression_csv`'s regressors: the
/// square roots of the diagonal of `(I/p0 + ΦᵀΦ/r2)⁻¹`, inverted here by cofactors.
fn kalman_std_errors(csv: &std::path::Path, p0: f64, r2: f64) -> [f64; 3] {
    let text = std::fs::read_to_string(csv).unwrap();
    let mut m = [[0.0; 3]; 3];
    for l in text.lines().skip(1) {
        let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
        let phi = [v[1], v[2], v[3]];
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] += phi[i] * phi[j] / r2;
            }
        }
    }
    for (i, row) in m.iter_mut().enumerate() {
        row[i] += 1.0 / p0;
    }
    let cof = |i: usize, j: usize| {
        let (r, c) = ([(i + 1) % 3, (i + 2) % 3], [(j + 1) % 3, (j + 2) % 3]);
        m[r[0]][c[0]] * m[r[1]][c[1]] - m[r[0]][c[1]] * m[r[1]][c[0]]
    };
    let det: f64 = (0..3).map(|j| m[0][j] * cof(0, j)).sum();
    [0, 1, 2].map(|i| (cof(i, i) / det).sqrt())
}

#[test]
fn estimate_json_recovers_the_parameters() {
    let d = dir("est");
    let csv = regression_csv(&d, None);
    let out_csv = d.join("track.csv");
    for method in ["rls", "rlsf", "rlsvf", "kf", "dsfc"] {
        let o = physid(&[
            "estimate",
            "--data",
            csv.to_str().unwrap(),
            "--y",
            "y",
            "--phi",
            "a,b,c",
            "--method",
            method,
            "--p0",
            "1e6",
            "--json",
            "--tracks",
            out_csv.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{method}: {}", stderr(&o));
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(v["method"], method);
        assert_eq!(v["samples"], 2000);
        // Noise-free data: the truth is the least-squares solution.
        let kf_se = kalman_std_errors(&csv, 1e6, 1.0);
        for (j, (k, truth)) in [("a", 2.0), ("b", -3.0), ("c", 0.5)]
            .into_iter()
            .enumerate()
        {
            let est = v["params"][k].as_f64().unwrap();
            assert!((est - truth).abs() < 1e-4, "{method} {k}: {est}");
            let se = v["std_err"][k].as_f64().unwrap();
            if method == "kf" {
                // R1 = 0, R2 = 1: P = (P0⁻¹ + ΦᵀΦ/R2)⁻¹ in closed form.
                assert!(
                    (se / kf_se[j] - 1.0).abs() < 1e-6,
                    "kf {k}: {se} vs {}",
                    kf_se[j]
                );
            } else {
                // σ̂² holds only the start-up transient of exactly fitting data.
                assert!((0.0..1e-5).contains(&se), "{method} {k}: {se}");
            }
        }
        let track = std::fs::read_to_string(&out_csv).unwrap();
        // The time, then the tracks; a units row (t in s).
        assert!(
            track.starts_with(
                "t,y_predicted,prediction_error,a,b,c,a_std_err,b_std_err,c_std_err\ns,"
            ),
            "{}",
            &track[..100]
        );
        assert_eq!(track.lines().count(), 2002);
        // NMSE (Eq. 6.4) of the one-step predictions in the track, computed here.
        let data = std::fs::read_to_string(&csv).unwrap();
        let y: Vec<f64> = data
            .lines()
            .skip(1)
            .map(|l| l.split(',').nth(4).unwrap().parse().unwrap())
            .collect();
        let yp: Vec<f64> = track
            .lines()
            .skip(2)
            .map(|l| l.split(',').nth(1).unwrap().parse().unwrap())
            .collect();
        let n = y.len() as f64;
        let mse = y
            .iter()
            .zip(&yp)
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f64>()
            / n;
        let nmse = mse / (y.iter().sum::<f64>() / n * yp.iter().sum::<f64>() / n);
        let got = v["nmse"].as_f64().unwrap();
        assert!(
            (got / nmse - 1.0).abs() < 1e-9,
            "{method}: nmse {got} vs {nmse}"
        );
    }
    // A fixed subset: c held at its nominal 0.5, a and b estimated.
    let o = physid(&[
        "estimate",
        "--data",
        csv.to_str().unwrap(),
        "--y",
        "y",
        "--phi",
        "a,b,c",
        "--method",
        "rls",
        "--params",
        "c=0.5",
        "--free",
        "a,b",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["params"]["c"], 0.5);
    assert!(v["std_err"].get("c").is_none());
    assert!((v["params"]["a"].as_f64().unwrap() - 2.0).abs() < 1e-4);
    // The tracks in Parquet and MDF4 (as asammdf and MATLAB users take them): the CSV's
    // values; the old spelling --out still writes them, with a deprecation warning.
    let csv_track = physid_io::read(&out_csv, &Default::default()).unwrap();
    for ext in ["parquet", "mf4"] {
        let f = d.join(format!("track.{ext}"));
        let args = |flag: &'static str| {
            vec![
                "estimate".to_string(),
                "--data".into(),
                csv.to_str().unwrap().into(),
                "--y".into(),
                "y".into(),
                "--phi".into(),
                "a,b,c".into(),
                "--method".into(),
                "dsfc".into(),
                "--p0".into(),
                "1e6".into(),
                flag.into(),
                f.to_str().unwrap().into(),
            ]
        };
        let a = args("--tracks");
        let o = physid(&a.iter().map(String::as_str).collect::<Vec<_>>());
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(o.stderr.is_empty(), "{}", stderr(&o));
        let t = physid_io::read(&f, &Default::default()).unwrap();
        assert_eq!(t.names(), csv_track.names(), "{ext}");
        assert_eq!(t.channel("t").unwrap().unit, "s");
        assert_eq!(
            t.values("a").unwrap(),
            csv_track.values("a").unwrap(),
            "{ext}"
        );
        let a = args("--out");
        let o = physid(&a.iter().map(String::as_str).collect::<Vec<_>>());
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(stderr(&o).contains("--tracks"), "{}", stderr(&o));
    }
}

#[test]
fn estimate_errors_name_the_problem() {
    let d = dir("err");
    let csv = regression_csv(&d, Some(17));
    let c = csv.to_str().unwrap();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["--y", "torque", "--phi", "a,b"],
            "no channel 'torque'; the channels are: t, a, b, c, y",
        ),
        (
            vec!["--y", "y", "--phi", "a,b,c"],
            "line 17 (sample 15): phi[1] (b) is not finite (NaN)",
        ),
        (
            vec!["--y", "y", "--phi", "a", "--lambda", "1.5"],
            "'--lambda <LAMBDA>': a forgetting factor is in (0, 1], got 1.5",
        ),
        (
            vec!["--y", "y", "--phi", "a", "--method", "lms"],
            "unknown method 'lms'",
        ),
        (
            vec![
                "--y",
                "y",
                "--phi",
                "a,b",
                "--method",
                "rlsvf",
                "--lambdas",
                "0.9",
            ],
            "expected 2, got 1",
        ),
        (
            vec!["--y", "y", "--phi", "a", "--free", "q"],
            "unknown parameter 'q'",
        ),
    ];
    for (extra, expect) in cases {
        let mut args = vec!["estimate", "--data", c];
        args.extend(extra);
        let o = physid(&args);
        assert!(!o.status.success());
        assert!(
            stderr(&o).contains(expect),
            "expected '{expect}' in:\n{}",
            stderr(&o)
        );
        assert!(!stderr(&o).contains("panicked"));
    }
    // Skipping the bad sample instead.
    let o = physid(&[
        "estimate", "--data", c, "--y", "y", "--phi", "a,b,c", "--on-bad", "skip", "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(
        (v["samples"].as_u64(), v["skipped"].as_u64()),
        (Some(1999), Some(1))
    );
    // Not a number, empty file.
    let bad = d.join("text.csv");
    std::fs::write(&bad, "a,y\n1,2\n3,abc\n").unwrap();
    let o = physid(&[
        "estimate",
        "--data",
        bad.to_str().unwrap(),
        "--y",
        "y",
        "--phi",
        "a",
    ]);
    assert!(
        stderr(&o).contains("line 3, column 'y': 'abc' is not a number"),
        "{}",
        stderr(&o)
    );
    let empty = d.join("empty.csv");
    std::fs::write(&empty, "").unwrap();
    let o = physid(&[
        "estimate",
        "--data",
        empty.to_str().unwrap(),
        "--y",
        "y",
        "--phi",
        "a",
    ]);
    assert!(
        !o.status.success() && stderr(&o).contains("no header row"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn example_5_2_writes_csv_and_svg() {
    let d = dir("ex");
    let o = physid(&["example", "5.2", "--out", d.to_str().unwrap(), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    // At t = 10 s: RLS has not tracked the step (A between the regimes), vector forgetting has.
    let last = |m: &str| {
        v["estimates"][m]
            .as_array()
            .unwrap()
            .last()
            .unwrap()
            .clone()
    };
    assert!(last("rls")["A"].as_f64().unwrap() > 4.8);
    assert!((last("rlsvf")["A"].as_f64().unwrap() - 4.0).abs() < 0.08);
    let svg = std::fs::read_to_string(d.join("example-5.2.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("vector forgetting"));
    let csv = std::fs::read_to_string(d.join("example-5.2.csv")).unwrap();
    assert_eq!(csv.lines().count(), 2 + 10_001);
    let html = std::fs::read_to_string(d.join("report.html")).unwrap();
    assert!(html.contains("<svg") && html.contains("truth"));
    let o = physid(&["example", "9.9"]);
    assert!(!o.status.success() && stderr(&o).contains("no example '9.9'"));
}

#[test]
fn bench_json_has_the_documented_shape() {
    let o = physid(&["bench", "--json", "--seconds", "0.02"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(v["machine"].as_str().unwrap().contains("cores"));
    let r = v["results"].as_array().unwrap();
    // 15 linear, 2 × 2 RLS over arrays (tracks, p = 2 and 20), 3 filters and the EKF and UKF
    // over a formula, 4 model evaluations, 1 gradient, 3 identifiability, 3 + 2 test cell, 3
    // combustion, the live twin.
    assert_eq!(r.len(), 15 + 4 + 3 + 2 + 4 + 1 + 3 + 3 + 2 + 3 + 1);
    // The live twin: simulated seconds per second with its four copies at 10 kHz.
    let tw = r.iter().find(|e| e["name"] == "twin_live").unwrap();
    assert!(
        tw["realtime_factor"].as_f64().unwrap() > 0.0 && tw["copies"] == 4,
        "{tw}"
    );
    for name in ["ekf_expr", "ukf_expr"] {
        let e = r.iter().find(|e| e["name"] == name).unwrap();
        assert!(
            e["updates_per_s"].as_f64().unwrap() > 0.0 && e["p"] == 10,
            "{name}"
        );
    }
    // The combustion stage: cycles per second, and that against 4 cylinders at 6000 rpm.
    for name in ["combustion_figures", "combustion", "combustion_knock"] {
        let e = r.iter().find(|e| e["name"] == name).unwrap();
        let (rate, realtime) = (
            e["cycles_per_s"].as_f64().unwrap(),
            e["realtime_factor"].as_f64().unwrap(),
        );
        assert!(rate > 0.0 && (rate / (4.0 * 6000.0 / 120.0) / realtime - 1.0).abs() < 1e-12);
        assert_eq!(e["step_deg"], 0.1);
    }
    // `bench combustion`: those three alone.
    let o = physid(&["bench", "--json", "--seconds", "0.02", "combustion"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let names: Vec<&str> = v["results"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["name"].as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        ["combustion_figures", "combustion", "combustion_knock"]
    );
    for name in ["rls_tracks", "rls_tracks_se"] {
        for p in [2, 20] {
            let e = r.iter().find(|e| e["name"] == name && e["p"] == p).unwrap();
            assert!(e["updates_per_s"].as_f64().unwrap() > 0.0, "{name} p = {p}");
        }
    }
    for (name, order) in [
        ("testcell", 2.0),
        ("testcell_rk4", 4.0),
        ("testcell_step2", 2.0),
        ("testcell_dynamics", 2.0),
        ("testcell_dynamics_rk4", 4.0),
    ] {
        let tc = r.iter().find(|e| e["name"] == name).unwrap();
        let (realtime, steps) = (
            tc["realtime_factor"].as_f64().unwrap(),
            tc["steps_per_s"].as_f64().unwrap(),
        );
        assert!(realtime.is_finite() && realtime > 0.0, "{name}");
        // One step per crank degree at 1000 rpm: 6000 steps per simulated second.
        assert!(
            (steps / (6000.0 * realtime) - 1.0).abs() < 1e-12,
            "{name}: {steps} steps/s at {realtime}× real time"
        );
        assert_eq!(tc["solver_order"].as_f64(), Some(order));
        // The dynamics alone: Heun takes one sub-step per step, RK4 at least one.
        if let Some(sub) = tc["substeps_per_step"].as_f64() {
            assert!(
                if order == 2.0 { sub == 1.0 } else { sub >= 1.0 },
                "{name}: {sub} sub-steps per step"
            );
        }
    }
    for name in ["ident_batch", "ident_cyclic_torque", "ident_online"] {
        let e = r
            .iter()
            .find(|e| e["name"] == name && e["p"] == 15)
            .unwrap();
        assert!(e["rows_per_s"].as_f64().unwrap() > 0.0, "{name}");
    }
    let ct = r
        .iter()
        .find(|e| e["name"] == "cyclic_torque_grad")
        .unwrap();
    assert!(ct["evals_per_s"].as_f64().unwrap() > 0.0);
    for name in ["ekf", "ukf", "srukf"] {
        let e = r
            .iter()
            .find(|e| e["name"] == name && e["p"] == 10)
            .unwrap();
        assert!(e["updates_per_s"].as_f64().unwrap() > 0.0);
    }
    for name in ["native", "expr"] {
        for what in ["value", "gradient"] {
            let e = r
                .iter()
                .find(|e| e["name"] == name && e["what"] == what)
                .unwrap();
            assert!(e["evals_per_s"].as_f64().unwrap() > 0.0);
        }
    }
    for name in ["rls", "rlsf", "rlsvf", "kf", "dsfc"] {
        for p in [2, 6, 20] {
            let e = r.iter().find(|e| e["name"] == name && e["p"] == p).unwrap();
            assert!(e["updates_per_s"].as_f64().unwrap() > 0.0);
        }
    }
}

#[test]
fn closed_pipe_ends_the_run_without_a_panic() {
    use std::io::{BufRead, BufReader};
    use std::process::Stdio;
    let mut child = Command::new(env!("CARGO_BIN_EXE_physid"))
        .args(["bench", "--seconds", "0.05"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    assert!(first.starts_with("machine:"));
    // The reader is gone now (like `| head -1`).
    let o = child.wait_with_output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("panicked"));
}

/// y = A·exp(−B·x) + C·x on 3000 noise-free samples: EKF, UKF and SR-UKF from a model given
/// as an expression recover A, B, C; the JSON carries repairs and timing.
#[test]
fn estimate_nonlinear_expression_models() {
    let d = dir("nl");
    let mut s = String::from("x,y\n");
    for i in 0..3000 {
        let x = 3.0 * ((i as f64 * 0.618).fract());
        s.push_str(&format!("{x},{}\n", 2.0 * (-0.7 * x).exp() + 0.5 * x));
    }
    let csv = d.join("nl.csv");
    std::fs::write(&csv, s).unwrap();
    for method in ["ekf", "ukf", "srukf"] {
        let o = physid(&[
            "estimate",
            "--data",
            csv.to_str().unwrap(),
            "--y",
            "y",
            "--method",
            method,
            "--expr",
            "A*exp(-B*x) + C*x",
            "--params",
            "A=1.5,B=0.5,C=0.3",
            "--p0",
            "1",
            "--r2",
            "1e-6",
            "--json",
        ]);
        assert!(o.status.success(), "{method}: {}", stderr(&o));
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(v["method"], method);
        for (k, truth) in [("A", 2.0), ("B", 0.7), ("C", 0.5)] {
            let est = v["params"][k].as_f64().unwrap();
            assert!((est - truth).abs() < 1e-3, "{method} {k}: {est}");
        }
        assert_eq!(v["repairs"], 0);
        assert_eq!(v["projections"], 0);
        assert!(v["timing"]["updates_per_s"].as_f64().unwrap() > 0.0);
    }
    // Only B free, A and C fixed at their (true) values; scaled coordinates.
    let o = physid(&[
        "estimate",
        "--data",
        csv.to_str().unwrap(),
        "--y",
        "y",
        "--method",
        "ekf",
        "--expr",
        "A*exp(-B*x) + C*x",
        "--params",
        "A=2,B=0.5,C=0.5",
        "--free",
        "B",
        "--scaled",
        "--p0",
        "0.5",
        "--r2",
        "1e-6",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let (b, se) = (
        v["params"]["B"].as_f64().unwrap(),
        v["std_err"]["B"].as_f64().unwrap(),
    );
    assert!((b - 0.7).abs() < 3.0 * se && se < 1e-4, "B = {b} ± {se}");
    assert_eq!(v["params"]["A"], 2.0);
    assert!(v["std_err"].get("A").is_none());
    // Bounds that the sigma points cross (truth inside, wide prior): every filter converges;
    // a bound that excludes the truth holds the estimate at it and is reported.
    for method in ["ekf", "ukf", "srukf"] {
        let o = physid(&[
            "estimate",
            "--data",
            csv.to_str().unwrap(),
            "--y",
            "y",
            "--method",
            method,
            "--expr",
            "A*exp(-B*x) + C*x",
            "--params",
            "A=1.95,B=0.5,C=0.3",
            "--p0",
            "1",
            "--r2",
            "1e-6",
            "--limits",
            "A=1.9:2.5",
            "--limits",
            "B=0.01:5",
            "--json",
        ]);
        assert!(o.status.success(), "{method}: {}", stderr(&o));
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        for (k, truth) in [("A", 2.0), ("B", 0.7), ("C", 0.5)] {
            let est = v["params"][k].as_f64().unwrap();
            assert!((est - truth).abs() < 1e-3, "{method} {k}: {est}");
        }
        let o = physid(&[
            "estimate",
            "--data",
            csv.to_str().unwrap(),
            "--y",
            "y",
            "--method",
            method,
            "--expr",
            "A*exp(-B*x) + C*x",
            "--params",
            "A=1.5,B=0.5,C=0.3",
            "--p0",
            "1",
            "--r2",
            "1e-6",
            "--limits",
            "A=0:1.8",
            "--json",
        ]);
        assert!(o.status.success(), "{method}: {}", stderr(&o));
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        let a = v["params"]["A"].as_f64().unwrap();
        assert!((1.8 - 1e-3..=1.8).contains(&a), "{method}: A = {a}");
        assert!(v["projections"].as_u64().unwrap() > 0);
    }
    // Errors point at the problem.
    let c = csv.to_str().unwrap();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["--method", "ekf", "--expr", "A*sine(x)", "--params", "A=1"], "unknown function 'sine' at column 3"),
        (vec!["--method", "ekf", "--expr", "A*z", "--params", "A=1"], "name 'z' at column 3 is neither a parameter nor a data column (parameters: A; columns: x, y)"),
        (vec!["--method", "ekf", "--expr", "A*x", "--params", "A"], "--params 'A': expected NAME=VALUE"),
        (vec!["--method", "ukf", "--params", "A=1"], "needs a model: --expr"),
        (vec!["--method", "rls", "--expr", "A*x", "--phi", "x"], "--expr needs --method ekf, ukf or srukf"),
        (vec!["--method", "rls"], "needs the regressor columns: --phi"),
        (vec!["--method", "ekf", "--expr", "A*x", "--params", "A=1", "--limits", "A=3"], "expected NAME=LOW:HIGH"),
    ];
    for (extra, expect) in cases {
        let mut args = vec!["estimate", "--data", c, "--y", "y"];
        args.extend(extra);
        let o = physid(&args);
        assert!(!o.status.success());
        assert!(
            stderr(&o).contains(expect),
            "expected '{expect}' in:\n{}",
            stderr(&o)
        );
    }
}

/// `friction eval --json` has the documented shape; components add up; the torque is
/// fmep·V_d/(4π) (four-stroke) and equals sympy's value at the thesis grid's test 25
/// (1000 rpm, 100 kPa, 90 °C; crates/apps/tests/golden/friction_rank.json).
#[test]
fn friction_eval_json() {
    let o = physid(&[
        "friction", "eval", "--n", "1000", "--p-int", "100", "--t-oil", "90", "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let f = &j["fmep_kpa"];
    let parts: f64 = ["cfmep", "rfmep", "vfmep", "afmep", "pmep"]
        .iter()
        .map(|k| f[k].as_f64().unwrap())
        .sum();
    let total = f["total"].as_f64().unwrap();
    assert!((parts - total).abs() < 1e-9 * total);
    let tau = j["tau_fri_nm"].as_f64().unwrap();
    let vd = std::f64::consts::PI / 4.0 * 0.054f64.powi(2) * 2.0 * 0.0257;
    assert!((tau - total * 1e3 * vd / (4.0 * std::f64::consts::PI)).abs() < 1e-12 * tau);
    let golden: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../apps/tests/golden/friction_rank.json"
        ))
        .unwrap(),
    )
    .unwrap();
    let t25 = &golden["tests"][24];
    assert_eq!(t25["n_rpm"], 1000);
    assert_eq!(t25["t_oil_c"], 90);
    assert_eq!(t25["p_int_kpa"], 100);
    assert!((tau - t25["tau_nm"].as_f64().unwrap()).abs() < 1e-12 * tau);

    // --set changes the design; the other preset changes the model.
    let o2 = physid(&[
        "friction",
        "eval",
        "--n",
        "1000",
        "--p-int",
        "100",
        "--t-oil",
        "90",
        "--set",
        "B=60",
        "--preset",
        "sandoval2002",
        "--json",
    ]);
    assert!(o2.status.success(), "{}", stderr(&o2));
    let j2: serde_json::Value = serde_json::from_slice(&o2.stdout).unwrap();
    assert_ne!(j2["tau_fri_nm"], j["tau_fri_nm"]);
}

#[test]
fn friction_rank_json_table_and_heatmap() {
    let d = dir("rank");
    let o = physid(&["friction", "rank", "--json", "--out", d.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let params = j["parameters"].as_array().unwrap();
    assert_eq!(params.len(), 9);
    let tests = j["tests"].as_array().unwrap();
    assert_eq!(tests.len(), 27);
    for t in tests {
        assert!(t["n_rpm"].is_number() && t["p_int_kpa"].is_number() && t["t_oil_c"].is_number());
        let mut r: Vec<&str> = t["ranking"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_str().unwrap())
            .collect();
        r.sort();
        let mut p: Vec<&str> = params.iter().map(|v| v.as_str().unwrap()).collect();
        p.sort();
        assert_eq!(r, p, "each test ranks every parameter once");
    }
    let svg = std::fs::read_to_string(d.join("rank.svg")).unwrap();
    assert!(svg.contains("<svg") && svg.contains("kappa"));
    let html = std::fs::read_to_string(d.join("report.html")).unwrap();
    assert!(html.contains("<svg") && html.contains("<table>"));
    assert!(d.join("rank.json").exists());

    // The human table: a header and 27 rows; a chosen grid and parameter list.
    let o = physid(&[
        "friction", "rank", "--n", "2000", "--p-int", "40,80", "--t-oil", "60", "--free", "B,r,Lv",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8(o.stdout).unwrap();
    assert_eq!(
        text.lines().filter(|l| l.contains(" 2000 ")).count(),
        2,
        "{text}"
    );
    assert!(text.contains("Lv") && !text.contains("kappa"));
}

#[test]
fn friction_errors_name_the_problem() {
    let cases: [(&[&str], &str); 5] = [
        (
            &[
                "friction", "eval", "--n", "0", "--p-int", "50", "--t-oil", "90",
            ],
            "'--n <N>': an engine speed in rpm is in (0, 20000], got 0",
        ),
        (
            &[
                "friction", "eval", "--n", "1000", "--p-int", "50", "--t-oil", "90", "--preset",
                "x",
            ],
            "presets are thesis, sandoval2002",
        ),
        (
            &[
                "friction", "eval", "--n", "1000", "--p-int", "50", "--t-oil", "90", "--set", "B",
            ],
            "expected NAME=VALUE",
        ),
        (
            &[
                "friction", "eval", "--n", "1000", "--p-int", "50", "--t-oil", "90", "--set",
                "oil=5W31",
            ],
            "the grades are",
        ),
        (
            &["friction", "rank", "--free", "B,bore"],
            "'bore' is not a design parameter",
        ),
    ];
    for (args, want) in cases {
        let o = physid(args);
        assert!(!o.status.success(), "{args:?}");
        assert!(stderr(&o).contains(want), "{args:?}: {}", stderr(&o));
    }
}

const EX51: &str = "sin(A)*x + B^2*y*cos(x) + sqrt(C)*x^2 + D*y^2 + E*x/y + F*2*x/y";

fn names_of(v: &serde_json::Value, key: &str) -> Vec<String> {
    v[key]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| {
            s.get("param")
                .and_then(|p| p.as_str())
                .or_else(|| s.as_str())
                .unwrap()
                .to_string()
        })
        .collect()
}

/// Issue 4, verification 1: `physid example 5.1 --json` prints estimable [D, C, B, A, F] and
/// unidentifiable [E]; the same through `physid identify --expr` on the CSV it wrote.
#[test]
fn example_5_1_and_identify_agree() {
    let d = dir("ex51");
    let o = physid(&["example", "5.1", "--json", "--out", d.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(names_of(&j, "ranking"), ["D", "C", "B", "A", "F"]);
    assert_eq!(names_of(&j, "unidentifiable"), ["E"]);
    assert_eq!(j["scaling"], "thesis");
    for key in ["fim", "std_err", "ci95", "collinearity", "design"] {
        assert!(!j[key].is_null(), "{key}");
    }
    assert_eq!(j["design"]["d"], j["d_criterion"]);
    let html = std::fs::read_to_string(d.join("report.html")).unwrap();
    assert!(html.contains("Not identifiable: E"), "{html}");
    let csv = d.join("example-5.1.csv");
    let o = physid(&[
        "identify",
        "--data",
        csv.to_str().unwrap(),
        "--units-row",
        "--expr",
        EX51,
        "--params",
        "A=1,B=2,C=3,D=4,E=5,F=6",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let k: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(names_of(&k, "ranking"), ["D", "C", "B", "A", "F"]);
    assert_eq!(names_of(&k, "unidentifiable"), ["E"]);
    // The formula and the Rust model give the same residuals.
    for (a, b) in j["ranking"]
        .as_array()
        .unwrap()
        .iter()
        .zip(k["ranking"].as_array().unwrap())
    {
        let (x, y) = (
            a["residual_ss"].as_f64().unwrap(),
            b["residual_ss"].as_f64().unwrap(),
        );
        assert!((x - y).abs() <= 1e-9 * x, "{x} vs {y}");
    }

    // Two recordings: the comparison; Wu's criterion with the measured output.
    let o = physid(&[
        "identify",
        "--data",
        csv.to_str().unwrap(),
        "--data",
        csv.to_str().unwrap(),
        "--units-row",
        "--model",
        "example-5.1",
        "--y",
        "z",
        "--cutoff",
        "wu",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let c: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let ex = c["experiments"].as_array().unwrap();
    assert_eq!(ex.len(), 2);
    assert_eq!(ex[0]["cutoff"]["kind"], "wu");
    let k_star = ex[0]["cutoff"]["k_star"].as_u64().unwrap();
    assert!((1..=6).contains(&k_star));
    assert_eq!(ex[0]["sigma2_source"], "fit");
    // The human table of a comparison ends with one line per recording.
    let o = physid(&[
        "identify",
        "--data",
        csv.to_str().unwrap(),
        "--data",
        csv.to_str().unwrap(),
        "--units-row",
        "--model",
        "example-5.1",
    ]);
    let text = String::from_utf8(o.stdout).unwrap();
    assert!(text.contains("experiment comparison"), "{text}");
}

#[test]
fn identify_errors_name_the_problem() {
    let d = dir("identerr");
    let csv = regression_csv(&d, None);
    let c = csv.to_str().unwrap();
    let cases: [(&[&str], &str); 6] = [
        (
            &["identify", "--data", c, "--expr", "A*q", "--params", "A=1"],
            "name 'q' at column 3 is neither a parameter nor a data column",
        ),
        (
            &["identify", "--data", c, "--model", "shaft"],
            "the model needs column 'theta_dy'",
        ),
        (
            &["identify", "--data", c, "--model", "warp"],
            "no built-in model 'warp'",
        ),
        (
            &[
                "identify", "--data", c, "--expr", "A*a", "--params", "A=1", "--cutoff", "wu",
            ],
            "needs the measured output",
        ),
        (
            &[
                "identify",
                "--data",
                c,
                "--expr",
                "A*a",
                "--params",
                "A=1",
                "--scaling",
                "log",
            ],
            "expected thesis, sigma or none",
        ),
        (
            &[
                "identify", "--data", c, "--expr", "A*a", "--params", "A=1", "--free", "Z",
            ],
            "--free Z: the parameters are A",
        ),
    ];
    for (args, want) in cases {
        let o = physid(args);
        assert!(!o.status.success(), "{args:?}");
        assert!(stderr(&o).contains(want), "{args:?}: {}", stderr(&o));
    }
}

/// A time-basis recording like a test cell's: 2 s at 20 kHz, engine encoder counts (360/rev),
/// a TDC marker, a pressure that depends on the angle, a noisy torque.
fn engine_csv(d: &std::path::Path) -> PathBuf {
    let mut s = String::from("t,count_en,tdc,p_int,torque_shaft\ns,-,-,Pa,N*m\n");
    let q = std::f64::consts::TAU / 360.0;
    let mut prev_rev = f64::NEG_INFINITY;
    for i in 0..40_000 {
        let t = i as f64 / 20_000.0;
        let th = 105.0 * t - 0.2;
        let rev = (th / std::f64::consts::TAU).floor();
        let marker = u8::from(i > 0 && rev > prev_rev);
        prev_rev = rev;
        let p = 1e5 + 1e4 * (th / 2.0).cos();
        let tq = 12.0 + 3.0 * (th * 2.0).sin() + 0.5 * ((i * 7919 % 1000) as f64 / 1000.0 - 0.5);
        s.push_str(&format!("{t},{},{marker},{p},{tq}\n", (th / q).floor()));
    }
    let path = d.join("engine.csv");
    std::fs::write(&path, s).unwrap();
    path
}

#[test]
fn inspect_convert_filter_chain() {
    let d = dir("chain");
    let csv = engine_csv(&d);
    let c = csv.to_str().unwrap();
    let o = physid(&["inspect", c, "--units-row", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["basis"], "time");
    assert_eq!(j["cycles"], 16);
    assert!((j["sample_rate_hz"].as_f64().unwrap() - 20_000.0).abs() < 1e-6);
    assert_eq!(j["channels"].as_array().unwrap().len(), 5);
    assert_eq!(j["channels"][3]["unit"], "Pa");
    // Starting mid-revolution is a note, not a finding: --strict passes.
    assert_eq!(j["integrity"]["ok"], true);
    assert_eq!(j["integrity"]["notes"][0]["kind"], "note");
    assert!(j["integrity"]["notes"][0]["detail"]
        .as_str()
        .unwrap()
        .contains("starts mid-revolution"));
    let o = physid(&["inspect", c, "--strict"]);
    assert!(o.status.success(), "{}", stderr(&o));

    // To one sample per degree, as Parquet; then inspect it and draw a surface.
    let pq = d.join("deg.parquet");
    let o = physid(&[
        "convert",
        c,
        pq.to_str().unwrap(),
        "--units-row",
        "--crank-angle",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = physid(&[
        "inspect",
        pq.to_str().unwrap(),
        "--json",
        "--out",
        d.to_str().unwrap(),
        "--surface",
        "p_int",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["basis"], "crank_angle");
    assert_eq!(j["cycles"], 16);
    let svg = std::fs::read_to_string(d.join("surface-p_int.svg")).unwrap();
    assert!(svg.contains("<svg") && svg.contains("crank angle"));
    let html = std::fs::read_to_string(d.join("report.html")).unwrap();
    assert!(html.contains("Integrity") && html.contains("<svg"));

    // Filter the torque (zero phase) into MDF4 and read it back.
    let mf = d.join("f.mf4");
    let o = physid(&[
        "filter",
        c,
        mf.to_str().unwrap(),
        "--units-row",
        "--lowpass",
        "200",
        "--order",
        "4",
        "--channels",
        "torque_shaft",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = physid(&["inspect", mf.to_str().unwrap(), "--json"]);
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["channels"][0]["name"], "t");
    assert_eq!(j["channels"].as_array().unwrap().len(), 5);
    // Errors: no filter chosen; a channel that is not there.
    let o = physid(&[
        "filter",
        c,
        mf.to_str().unwrap(),
        "--units-row",
        "--channels",
        "torque_shaft",
    ]);
    assert!(!o.status.success() && stderr(&o).contains("choose a filter"));
    // A cut-off of 1e300 Hz is refused as 1e300, not as its 301 digits.
    let o = physid(&[
        "filter",
        c,
        mf.to_str().unwrap(),
        "--units-row",
        "--lowpass",
        "1e300",
        "--channels",
        "torque_shaft",
    ]);
    let e = stderr(&o);
    assert!(
        !o.status.success() && e.contains("cut-off 1e300 Hz") && e.len() < 400,
        "{e}"
    );
    let o = physid(&[
        "filter",
        c,
        mf.to_str().unwrap(),
        "--units-row",
        "--lowpass",
        "100",
        "--channels",
        "x",
    ]);
    assert!(stderr(&o).contains("no channel 'x'"), "{}", stderr(&o));
    // A surface of time-basis data asks for conversion first.
    let o = physid(&[
        "inspect",
        c,
        "--units-row",
        "--out",
        d.to_str().unwrap(),
        "--surface",
        "p_int",
    ]);
    assert!(stderr(&o).contains("convert first"), "{}", stderr(&o));
}

#[test]
fn simulate_runs_and_studies() {
    let d = dir("sim");
    let o = physid(&["simulate", "--list"]);
    assert!(o.status.success());
    let text = String::from_utf8(o.stdout).unwrap();
    for name in [
        "fig314",
        "shaft-steady",
        "friction-sweep",
        "torque-ramp",
        "transient-10min",
    ] {
        assert!(text.contains(name), "{name}");
    }
    let o = physid(&["simulate", "--list-params", "--set", "shaft.k=1340"]);
    let text = String::from_utf8(o.stdout).unwrap();
    assert!(text.contains("shaft.k") && text.contains("1340") && text.contains("Table 6.1"));
    // A short run with a fault, on a crank-angle basis, to Parquet; inspect reads it back.
    let out = d.join("t01.parquet");
    let o = physid(&[
        "simulate",
        "--scenario",
        "shaft-steady",
        "--duration",
        "0.5",
        "--fault",
        "shaft.k=1200@0.2",
        "--basis",
        "crank",
        "--recording",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = physid(&["inspect", out.to_str().unwrap(), "--json"]);
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["basis"], "crank_angle");
    assert!(j["cycles"].as_u64().unwrap() >= 3);
    // --set wins over a scenario's own setting (friction-sweep sets friction_scale 0.45).
    let out = d.join("sweep.parquet");
    let o = physid(&[
        "simulate",
        "--scenario",
        "friction-sweep",
        "--duration",
        "0.2",
        "--set",
        "engine.friction_scale=0.3",
        "--recording",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rec = physid_io::read(&out, &Default::default()).unwrap();
    assert_eq!(rec.meta["param.engine.friction_scale"], "0.3");
    // The studies' JSON shapes.
    let o = physid(&[
        "simulate",
        "dyno-curve",
        "--speeds",
        "1400,1465,1490",
        "--json",
    ]);
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let pts = j["points"].as_array().unwrap();
    assert_eq!(pts.len(), 3);
    for key in [
        "speed_rpm",
        "slip",
        "torque_nm",
        "current_a_rms",
        "power_factor",
    ] {
        assert!(pts[1][key].is_number(), "{key}");
    }
    let o = physid(&[
        "simulate",
        "motored-cycle",
        "--rpm",
        "1000",
        "--throttle",
        "90",
        "--json",
    ]);
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for key in [
        "p_max_pa",
        "theta_p_max_deg",
        "imep_pa",
        "pmep_pa",
        "trapped_mass_kg",
        "vol_eff",
    ] {
        assert!(j[key].is_number(), "{key}");
    }
    for key in ["indicated", "reciprocating", "friction"] {
        assert!(j["torque_mean_nm"][key].is_number(), "{key}");
    }
    let o = physid(&[
        "simulate",
        "compression",
        "--p-bdc",
        "100000",
        "--t-bdc",
        "300",
        "--rpm",
        "1000",
        "--no-heat-transfer",
        "--json",
    ]);
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    // Cantera: 22.606 bar, 713.9 K (crates/sim/tests/golden/cantera_compression.json).
    assert!((j["p_max_pa"].as_f64().unwrap() / 22.606e5 - 1.0).abs() < 0.01);
    assert!((j["t_max_k"].as_f64().unwrap() / 713.88 - 1.0).abs() < 0.01);
    // Errors.
    for (args, want) in [
        (
            vec!["simulate", "--scenario", "warp", "--recording", "x.csv"],
            "neither a built-in scenario",
        ),
        (
            vec!["simulate", "--scenario", "shaft-steady"],
            "--recording FILE",
        ),
        (
            vec![
                "simulate",
                "--scenario",
                "shaft-steady",
                "--recording",
                "x.txt",
            ],
            "the extension picks the format",
        ),
        (
            vec![
                "simulate",
                "--scenario",
                "shaft-steady",
                "--recording",
                "x.csv",
                "--fault",
                "shaft.k=1@x",
            ],
            "expected PATH=VALUE@T",
        ),
        (
            vec![
                "simulate",
                "--scenario",
                "shaft-steady",
                "--recording",
                "x.csv",
                "--set",
                "shaft.q=1",
            ],
            "no parameter 'shaft.q'",
        ),
        (
            vec![
                "simulate",
                "--scenario",
                "shaft-steady",
                "--recording",
                "x.csv",
                "--set",
                "engine.kappa=0.5",
            ],
            "engine.kappa",
        ),
    ] {
        let o = physid(&args);
        assert!(!o.status.success(), "{args:?}");
        assert!(stderr(&o).contains(want), "{args:?}: {}", stderr(&o));
    }
}

/// `physid demo --out DIR` exits 0 and leaves DIR/report.html and DIR/summary.json; the shaft
/// fault is found and named.
#[test]
fn demo_writes_report_and_summary() {
    let d = dir("demo");
    let o = physid(&["demo", "--out", d.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let html = std::fs::read_to_string(d.join("report.html")).unwrap();
    assert!(html.contains("<svg") && html.contains("ALARM: K moved"));
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s["solver_order"].as_f64(), Some(2.0));
    let alarms = s["shaft"]["alarms"].as_array().unwrap();
    assert!(!alarms.is_empty() && alarms.iter().all(|a| a["param"] == "K"));
    assert!((s["shaft"]["final"]["K"].as_f64().unwrap() / 1100.0 - 1.0).abs() < 0.02);
    let t = s["torque_identifiability"].as_array().unwrap();
    assert!(
        t[1]["estimable"].as_array().unwrap().len() > t[0]["estimable"].as_array().unwrap().len()
    );
    // Application 2: within ±5 % of the simulated friction after the start-up.
    let f = &s["friction_fit"];
    assert!(
        f["prediction_error_pct"]["max_after_transient_vs_truth"]
            .as_f64()
            .unwrap()
            < 5.0
    );
    assert!(names_of(f, "estimable").contains(&"c1".to_string()));
    // Application 3: the heavier reciprocating mass (0.84 kg) found within 3σ.
    let tf = &s["torque_fit"];
    let m = tf["params"]["M_rec"].as_f64().unwrap();
    let se = tf["std_err"]["M_rec"].as_f64().unwrap();
    // σ bounded too (the run gives 9e-5 kg): an over-uncertain filter must not pass.
    assert!((m - 0.84).abs() < 3.0 * se && se < 1e-3, "M_rec {m} ± {se}");
    assert!(
        html.contains("Engine friction characterisation") && html.contains("Cyclic engine torque")
    );
    // A solver the test cell does not have is refused, naming the parameter.
    let o = physid(&["demo", "--out", d.to_str().unwrap(), "--solver-order", "3"]);
    assert!(
        !o.status.success() && stderr(&o).contains("solver.order = 3"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn monitor_shaft_json_and_errors() {
    let d = dir("monitor");
    let f = d.join("t01.parquet");
    let o = physid(&[
        "simulate",
        "--scenario",
        "shaft-steady",
        "--duration",
        "3",
        "--fault",
        "shaft.b=1.4@1.5",
        "--recording",
        f.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = physid(&[
        "monitor",
        "shaft",
        "--data",
        f.to_str().unwrap(),
        "--method",
        "dsfc",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["method"], "dsfc");
    for key in ["K", "B"] {
        assert!(
            j["final"][key].is_number()
                && j["std_err"][key].is_number()
                && j["nmse"][key].is_number()
        );
    }
    let alarms = j["alarms"].as_array().unwrap();
    assert!(alarms.iter().any(|a| a["param"] == "B"), "{alarms:?}");
    for a in alarms {
        assert!(a["t_start_s"].is_number() && a["relative_error"].is_number());
    }
    let o = physid(&[
        "monitor",
        "shaft",
        "--data",
        f.to_str().unwrap(),
        "--method",
        "kf",
    ]);
    assert!(stderr(&o).contains("expected rlsf, rlsvf or dsfc"));
    let o = physid(&[
        "monitor",
        "shaft",
        "--data",
        f.to_str().unwrap(),
        "--healthy",
        "Q=1",
    ]);
    assert!(stderr(&o).contains("the parameters are K and B"));
}

#[test]
fn friction_fit_json_report_and_errors() {
    let d = dir("friction-fit");
    let f = d.join("sweep.parquet");
    let o = physid(&[
        "simulate",
        "--scenario",
        "friction-sweep",
        "--duration",
        "20",
        "--basis",
        "crank",
        "--recording",
        f.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = d.join("report");
    let o = physid(&[
        "friction",
        "fit",
        "--data",
        f.to_str().unwrap(),
        "--preset",
        "cell",
        "--json",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let estimable = names_of(&j, "estimable");
    assert!(estimable.contains(&"c1".to_string()), "{estimable:?}");
    for c in &estimable {
        assert!(
            j["params"][c].is_number() && j["std_err"][c].is_number(),
            "{c}"
        );
    }
    assert_eq!(j["params"].as_object().unwrap().len(), 20);
    let pe = &j["prediction_error_pct"];
    assert!(pe["final"].as_f64().unwrap().abs() < 5.0, "{pe}");
    assert!(pe["max_after_transient"].as_f64().unwrap() < 5.0, "{pe}");
    assert!(out.join("report.html").exists() && out.join("friction_fit.json").exists());
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(html.contains("<svg") && html.contains("Engine friction characterisation"));
    // Errors name the problem.
    let o = physid(&[
        "friction",
        "fit",
        "--data",
        f.to_str().unwrap(),
        "--source",
        "dyno",
    ]);
    assert!(
        stderr(&o).contains("expected engine or shaft"),
        "{}",
        stderr(&o)
    );
    let o = physid(&[
        "friction",
        "fit",
        "--data",
        f.to_str().unwrap(),
        "--cutoff",
        "most",
    ]);
    assert!(stderr(&o).contains("expected repeat, wu"), "{}", stderr(&o));
    let csv = regression_csv(&d, None);
    let o = physid(&["friction", "fit", "--data", csv.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("no engine angle"), "{}", stderr(&o));
}

#[test]
fn run_pipeline_json_report_and_exit_code() {
    let d = dir("run");
    let shipped = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../pipelines");
    let out = d.join("report");
    let tracks = d.join("tracks.mf4");
    let o = physid(&[
        "run",
        shipped.join("shaft-expr.toml").to_str().unwrap(),
        "--json",
        "--out",
        out.to_str().unwrap(),
        "--tracks",
        tracks.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["objective"]["met"], true);
    assert!(j["objective"]["value_pct"].as_f64().unwrap() < 5.0);
    let k = j["params"]["K"].as_f64().unwrap();
    assert!((k - 1340.0).abs() < 13.4, "K {k}");
    // The tracks (MDF4): time, measured, predicted and K, its last point the final K.
    let tr = physid_io::read(&tracks, &Default::default()).unwrap();
    assert_eq!(&tr.names()[..3], ["t", "measured", "predicted"]);
    let kt = tr.values("K").unwrap();
    assert!(kt.len() > 100);
    assert!(
        (kt[kt.len() - 1] - k).abs() <= 1e-9 * k.abs(),
        "{} vs {k}",
        kt[kt.len() - 1]
    );
    assert!(j["std_err"]["K"].is_number());
    assert!(out.join("report.html").exists() && out.join("pipeline.json").exists());
    // An objective no model meets: the run says so and exits non-zero.
    let text = std::fs::read_to_string(shipped.join("shaft-expr.toml"))
        .unwrap()
        .replace(
            "prediction_within_pct = 5.0",
            "prediction_within_pct = 0.0001",
        )
        .replace("duration = 10.0", "duration = 2.0");
    let f = d.join("strict.toml");
    std::fs::write(&f, text).unwrap();
    let o = physid(&["run", f.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stdout).contains("NOT met"));
    assert!(
        stderr(&o).contains("the objective was not met"),
        "{}",
        stderr(&o)
    );
    // A bad file names the problem and the file.
    std::fs::write(&f, "[model]\nbuiltin = \"shaft\"\n").unwrap();
    let o = physid(&["run", f.to_str().unwrap()]);
    assert!(
        stderr(&o).contains("strict.toml") && stderr(&o).contains("output"),
        "{}",
        stderr(&o)
    );
}
