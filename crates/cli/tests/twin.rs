//! `physid twin`: calibrate writes a scenario file the other verbs take, check reads it; what
//! it cannot use is refused by name.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{ok_json, physid};

/// A recording from a perturbed cell (K −10 %, friction ×1.15, compression ratio 9.0),
/// calibrated from the nominal cell: the JSON has each parameter under its path, the
/// perturbed ones within their intervals; the cell file runs with `physid simulate` and
/// `physid twin check` shows the NRMSE falling ≥ 10× on the speeds and the shaft torque.
#[test]
fn calibrate_then_check() {
    let d = physid_testkit::Scratch::new("twin-cli");
    let rec = d.file("run.parquet");
    let rec_s = rec.to_str().unwrap();
    let sim = physid(&[
        "simulate",
        "--scenario",
        "shaft-ramp",
        "--duration",
        "2",
        "--basis",
        "crank",
        "--set",
        "shaft.k=1125",
        "--set",
        "engine.friction_scale=1.15",
        "--set",
        "engine.kappa=9",
        "--set",
        "sensors.speed.noise=0.01",
        "--recording",
        rec_s,
    ]);
    assert!(
        sim.status.success(),
        "{}",
        String::from_utf8_lossy(&sim.stderr)
    );
    let cell = d.file("cell.toml");
    let cell_s = cell.to_str().unwrap();
    let j = ok_json(&[
        "twin",
        "calibrate",
        "--data",
        rec_s,
        "--params",
        "shaft.k,engine.friction_scale,engine.kappa,engine.inertia",
        "--out",
        cell_s,
        "--json",
    ]);
    for (p, truth) in [
        ("shaft.k", 1125.0),
        ("engine.friction_scale", 1.15),
        ("engine.kappa", 9.0),
        ("engine.inertia", 0.035),
    ] {
        let e = &j["params"][p];
        assert_eq!(e["estimable"], true, "{p}: {e}");
        let ci = e["ci95"].as_array().unwrap();
        let (lo, hi) = (ci[0].as_f64().unwrap(), ci[1].as_f64().unwrap());
        assert!(
            lo <= truth && truth <= hi,
            "{p}: {truth} not in {lo} … {hi}"
        );
    }
    let text = std::fs::read_to_string(&cell).unwrap();
    assert!(text.starts_with("# physid twin calibrate"), "{text}");
    assert!(
        text.contains("\"shaft.k\" = 1124.") || text.contains("\"shaft.k\" = 1125."),
        "{text}"
    );
    // The cell file is a scenario: the calibrated cell replays the recording's inputs.
    let out = d.file("twin.parquet");
    let sim = physid(&[
        "simulate",
        "--scenario",
        cell_s,
        "--basis",
        "crank",
        "--recording",
        out.to_str().unwrap(),
    ]);
    assert!(
        sim.status.success(),
        "{}",
        String::from_utf8_lossy(&sim.stderr)
    );
    let c = ok_json(&["twin", "check", "--data", rec_s, "--cell", cell_s, "--json"]);
    for ch in ["omega_en", "omega_dy", "torque_shaft"] {
        let e = &c["channels"][ch];
        let (b, a) = (
            e["nrmse_before"].as_f64().unwrap(),
            e["nrmse_after"].as_f64().unwrap(),
        );
        assert!(b >= 10.0 * a, "{ch}: {b} → {a}");
    }
    // The text output names the held parameters and the reason.
    let t = physid(&[
        "twin",
        "calibrate",
        "--data",
        rec_s,
        "--params",
        "shaft.k,sensors.temperature.lag",
    ]);
    let s = String::from_utf8_lossy(&t.stdout);
    assert!(
        t.status.success() && s.contains("held: no information"),
        "{s}"
    );
}

#[test]
fn twin_errors_name_the_problem() {
    let d = physid_testkit::Scratch::new("twin-cli-errors");
    let rec = d.file("run.parquet");
    let rec_s = rec.to_str().unwrap();
    common::simulated(&rec, "shaft-steady", "0.5");
    for (args, want) in [
        (vec!["twin", "calibrate", "--data", rec_s], "--crank-angle"),
        (
            vec!["twin", "calibrate", "--data", "/nonexistent.parquet"],
            "nonexistent",
        ),
    ] {
        let o = physid(&args);
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && e.contains(want), "{args:?}: {e}");
    }
    let crank = d.file("crank.parquet");
    let sim = physid(&[
        "simulate",
        "--scenario",
        "shaft-steady",
        "--duration",
        "0.3",
        "--basis",
        "crank",
        "--recording",
        crank.to_str().unwrap(),
    ]);
    assert!(sim.status.success());
    let o = physid(&[
        "twin",
        "calibrate",
        "--data",
        crank.to_str().unwrap(),
        "--params",
        "shaft.q",
    ]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && e.contains("shaft.q") && e.contains("list-params"),
        "{e}"
    );
    let o = physid(&[
        "twin",
        "calibrate",
        "--data",
        crank.to_str().unwrap(),
        "--channels",
        "T_oil",
    ]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("'T_oil'"), "{e}");
    let o = physid(&[
        "twin",
        "check",
        "--data",
        crank.to_str().unwrap(),
        "--cell",
        "/nonexistent.toml",
    ]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("nonexistent.toml"), "{e}");
}
