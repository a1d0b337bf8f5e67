//! `physid design`: the designed test as a scenario file the cell runs, its predicted errors
//! in the JSON, and requests it cannot serve refused with what was expected.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{ok_json, physid};

/// Design, write the scenario, run it with `physid simulate` and monitor it: the file is a
/// scenario the other verbs take, on the cell it was designed for (`--set` carried in it).
#[test]
fn designed_test_runs_on_the_cell() {
    let d = physid_testkit::Scratch::new("design-cli");
    let out = d.file("shaft-test");
    let toml = out.join("scenario.toml");
    let toml_s = toml.to_str().unwrap();
    let j = ok_json(&[
        "design",
        "--app",
        "shaft",
        "--params",
        "K,B",
        "--target-rel-se",
        "0.01",
        "--limits",
        "speed=800:2000,throttle=0:60,dspeed=400",
        "--duration",
        "4",
        "--candidates",
        "5",
        "--set",
        "sensors.torque_shaft.noise=0.2",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]);
    let se = &j["predicted_std_err"];
    for p in ["K", "B"] {
        let v = se[p].as_f64().unwrap();
        assert!(v.is_finite() && v > 0.0, "{p}: {v}");
    }
    assert_eq!(j["chosen"]["curve"]["std_err"].as_array().unwrap().len(), 2);
    // The ranking along the test: every tenth of it and its end, each parameter once, the
    // first with all its information.
    let id = j["chosen"]["identifiability"].as_array().unwrap();
    assert!((10..=11).contains(&id.len()), "{}", id.len());
    let last_t = j["chosen"]["curve"]["t"]
        .as_array()
        .unwrap()
        .last()
        .unwrap()
        .clone();
    assert_eq!(id.last().unwrap()["t_s"], last_t);
    for x in id {
        let ranked = x["ranked"].as_array().unwrap();
        let mut names: Vec<&str> = ranked.iter().map(|e| e[0].as_str().unwrap()).collect();
        names.sort_unstable();
        assert_eq!(names, ["B", "K", "tau0"]);
        assert_eq!(ranked[0][1].as_f64().unwrap(), 1.0);
    }
    assert!(j["chosen"]["within_limits"].as_bool().unwrap());
    assert_eq!(j["baselines"][0]["name"], "shaft-steady");
    assert_eq!(
        j["baselines"][0]["within_limits"], false,
        "90° throttle is outside 0–60°"
    );
    let saved: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("design.json")).unwrap()).unwrap();
    assert_eq!(saved["predicted_std_err"], j["predicted_std_err"]);
    let text = std::fs::read_to_string(&toml).unwrap();
    assert!(text.contains("# predicted standard error of K"), "{text}");
    assert!(
        text.contains("\"sensors.torque_shaft.noise\" = 0.2"),
        "{text}"
    );
    let rec = d.file("run.csv");
    let o = physid(&[
        "simulate",
        "--scenario",
        toml_s,
        "--recording",
        rec.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let m = ok_json(&[
        "monitor",
        "shaft",
        "--data",
        rec.to_str().unwrap(),
        "--json",
    ]);
    let k = m["final"]["K"].as_f64().unwrap();
    assert!((k / 1250.0 - 1.0).abs() < 0.05, "K {k}");
}

/// What design refuses, and says why.
#[test]
fn design_errors_name_the_problem() {
    for (args, want) in [
        (
            vec!["--params", "K,X"],
            "the shaft monitor's parameters are K, B, tau0",
        ),
        (vec!["--limits", "speed=2000:800"], "2000 > 800"),
        (vec!["--criterion", "time"], "needs --target-rel-se"),
        (vec!["--method", "rlsvf"], "vector forgetting"),
        (vec!["--set", "sensors.torque_shaft.noise=0"], "noise is 0"),
        (
            vec!["--app", "engine"],
            "possible values: shaft, friction, torque",
        ),
        (vec!["--app", "torque"], "needs --params"),
        (vec!["--band", "2:1"], "expected LOW:HIGH in Hz"),
        (
            vec!["--candidates", "18446744073709551615"],
            "--candidates 18446744073709551615: expected 1–100000",
        ),
        (
            vec!["--sample-rate", "1e300"],
            "recording rate 1e300 Hz: expected > 0 and at most 1.08e6 Hz",
        ),
        (
            vec![
                "--app",
                "friction",
                "--params",
                "c4",
                "--sample-rate",
                "2e6",
            ],
            "recording rate 2e6 Hz",
        ),
        (
            vec!["--limits", "dtorque=0"],
            "dtorque 0: expected > 0 N·m/s",
        ),
        (
            vec!["--app", "torque", "--params", "M_rec,X"],
            "parameter 'X': expected one of M_rec",
        ),
        (
            vec!["--app", "torque", "--params", "M_rec=0.9"],
            "the cell engine's",
        ),
        (
            vec!["--app", "torque", "--params", "delta"],
            "'delta' has nominal value 0",
        ),
        (
            vec!["--app", "torque", "--params", "M_rec", "--lambda", "0.99"],
            "the cyclic-torque filter does not forget",
        ),
        (
            vec!["--app", "torque", "--params", "M_rec", "--s0", "3"],
            "--s0 is the friction fit's setting",
        ),
        (
            vec!["--app", "friction", "--params", "c4", "--alongside", "c1"],
            "--alongside is the cyclic-torque fit's setting",
        ),
        (
            vec![
                "--app",
                "torque",
                "--params",
                "M_rec,b,L,r",
                "--limits",
                "speed=800:1400",
            ],
            "structurally unidentifiable",
        ),
        (vec!["--app", "friction"], "needs --params"),
        (
            vec!["--app", "friction", "--params", "c4,c99"],
            "coefficient 'c99': expected one of c1",
        ),
        (
            vec!["--app", "friction", "--params", "c4=3"],
            "the engine model's",
        ),
        (
            vec!["--app", "friction", "--params", "c4", "--lowpass", "200"],
            "--lowpass is the shaft monitor's setting",
        ),
        (vec!["--s0", "3"], "--s0 is the friction fit's setting"),
        // A typo of an exponent does not take the machine's memory (it did: killed by the
        // kernel at 23 GB).
        (
            vec!["--duration", "1e9"],
            "duration 1000000000 s: expected 1–3600 s",
        ),
        (
            vec!["--params", "K=1000,B,K=1200"],
            "K is already given the value 1000",
        ),
        (vec!["--params", "K=-5"], "shaft.k = -5: expected > 0"),
    ] {
        let mut a = vec!["design"];
        if !args.contains(&"--candidates") {
            a.extend(["--candidates", "2"]);
        }
        if !args.contains(&"--duration") {
            a.extend(["--duration", "2"]);
        }
        a.extend(args.iter().copied());
        let o = physid(&a);
        assert!(!o.status.success(), "{a:?}");
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(e.contains(want), "{a:?}: {e}");
    }
}

/// A friction test designed, run on the cell and fitted with the coefficients it was designed
/// for (`physid friction fit --estimate`): the fit estimates those, with the standard errors
/// the design's JSON predicts the order of.
#[test]
fn designed_friction_test_runs_and_fits() {
    let d = physid_testkit::Scratch::new("design-friction-cli");
    let out = d.file("friction-test");
    let j = ok_json(&[
        "design",
        "--app",
        "friction",
        "--params",
        "c4,c17",
        "--limits",
        "speed=750:1500,throttle=1:90",
        "--duration",
        "40",
        "--candidates",
        "5",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(j["params"], serde_json::json!(["c4", "c17"]));
    assert_eq!(j["baselines"][0]["name"], "friction-sweep");
    let se: Vec<f64> = ["c4", "c17"]
        .iter()
        .map(|p| j["predicted_std_err"][p].as_f64().unwrap())
        .collect();
    assert!(se.iter().all(|v| v.is_finite() && *v > 0.0), "{se:?}");
    assert!(out.join("report.html").exists());
    let rec = d.file("run.parquet");
    let o = physid(&[
        "simulate",
        "--scenario",
        out.join("scenario.toml").to_str().unwrap(),
        "--recording",
        rec.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let f = ok_json(&[
        "friction",
        "fit",
        "--data",
        rec.to_str().unwrap(),
        "--estimate",
        "c4,c17",
        "--json",
    ]);
    assert_eq!(f["estimable"], serde_json::json!(["c4", "c17"]), "{f}");
}

/// A cyclic-torque test designed (M_rec, b, L with the friction level c1 alongside), run on
/// the cell one sample per crank degree and fitted with the parameters it was designed for
/// (`physid torque fit --estimate`): the filter's own standard errors agree with the design's
/// prediction (both the sandwich of the same sensitivities and noise: within 20 %).
#[test]
fn designed_torque_test_runs_and_fits() {
    let d = physid_testkit::Scratch::new("design-torque-cli");
    let out = d.file("torque-test");
    let j = ok_json(&[
        "design",
        "--app",
        "torque",
        "--params",
        "M_rec,b,L",
        "--limits",
        "speed=800:1400",
        "--candidates",
        "5",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(j["params"], serde_json::json!(["M_rec", "b", "L"]));
    let base: Vec<&str> = j["baselines"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| b["name"].as_str().unwrap())
        .collect();
    assert_eq!(base, ["torque-steady", "torque-ramp"]);
    assert_eq!(j["scenario"]["duration"], 5.0);
    assert!(out.join("report.html").exists());
    let rec = d.file("run.parquet");
    let o = physid(&[
        "simulate",
        "--scenario",
        out.join("scenario.toml").to_str().unwrap(),
        "--basis",
        "crank",
        "--recording",
        rec.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let f = ok_json(&[
        "torque",
        "fit",
        "--data",
        rec.to_str().unwrap(),
        "--estimate",
        "M_rec,b,L,c1",
        "--json",
    ]);
    assert_eq!(
        f["estimable"],
        serde_json::json!(["M_rec", "b", "L", "c1"]),
        "{f}"
    );
    for p in ["M_rec", "b", "L"] {
        let predicted = j["predicted_std_err"][p].as_f64().unwrap();
        let filter = f["std_err"][p].as_f64().unwrap();
        assert!(
            (filter / predicted - 1.0).abs() < 0.2,
            "{p}: the filter's σ {filter} against the design's {predicted}"
        );
    }
}

/// Candidates as the dynamometer's torque demands (`--limits torque=…`): the designed test is a
/// torque-mode scenario with the engine's speed range, which `simulate` runs (and stops where
/// the engine would leave it); its multisines within `--band`.
#[test]
fn a_torque_demand_test_is_designed_and_runs() {
    let d = physid_testkit::Scratch::new("design-torque-mode-cli");
    let out = d.file("tm");
    let j = ok_json(&[
        "design",
        "--params",
        "K,B",
        "--limits",
        "speed=800:1600,torque=-2:3,dtorque=20",
        "--band",
        "0.2:5",
        "--duration",
        "3",
        "--candidates",
        "10",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(j["scenario"]["torque_mode"], true, "{}", j["scenario"]);
    assert_eq!(
        j["scenario"]["speed_range"],
        serde_json::json!([800.0, 1600.0])
    );
    let rec = d.file("tm.parquet");
    let o = physid(&[
        "simulate",
        "--scenario",
        out.join("scenario.toml").to_str().unwrap(),
        "--recording",
        rec.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}
