//! Day-one data handling, end to end: the same recording in SI and in a test cell's units
//! (deg, rpm, °C, bar, kN·m, under its own column names) gives the same estimates in every
//! application; a crank-angle recording keeps its basis in every format and every verb takes
//! it; `inspect --strict` passes on every clean built-in scenario in both bases, and every
//! injected defect is found at its sample.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_core::{Basis, Channel, Recording};
use physid_io::{read, write, ReadOptions, WriteOptions};
use physid_testkit::Scratch;
use serde_json::Value;
use std::path::{Path, PathBuf};
mod common;
use common::{ok_json, physid};

fn simulate(dir: &Path, scenario: &str, basis: &str, duration: &str, ext: &str) -> PathBuf {
    let f = dir.join(format!("{scenario}-{basis}.{ext}"));
    let o = physid(&[
        "simulate",
        "--scenario",
        scenario,
        "--basis",
        basis,
        "--duration",
        duration,
        "--recording",
        f.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    f
}

/// A unit and the conversion into it from SI.
type LogUnit = (&'static str, fn(f64) -> f64);

/// How a test-cell log states each standard channel: `(unit, from SI)`.
fn test_cell_unit(name: &str) -> Option<LogUnit> {
    Some(match name {
        "theta_en" | "theta_dy" | "theta" => ("deg", |x: f64| x.to_degrees()),
        "omega_en" | "omega_dy" | "speed_demand" => {
            ("rpm", |x: f64| x * 30.0 / std::f64::consts::PI)
        }
        "T_oil" | "T_int" | "T_exh" => ("°C", |x: f64| x - 273.15),
        "p_cyl" | "p_int" | "p_exh" | "p_crank" | "p_atm" => ("bar", |x: f64| x / 1e5),
        "torque_shaft" | "torque_engine" => ("kNm", |x: f64| x / 1e3),
        _ => return None,
    })
}

/// The recording in the test cell's units, every channel renamed `Log_<name>`, written as a
/// CSV with a units row; returns the file and the `--map` items that read it back.
fn test_cell_log(rec: &Recording, path: &Path) -> Vec<String> {
    let mut out = Recording::new(rec.basis);
    let mut map = Vec::new();
    for ch in rec.channels() {
        let (unit, values) = match test_cell_unit(&ch.name) {
            Some((u, f)) => (u.to_string(), ch.values.iter().map(|&v| f(v)).collect()),
            None => (ch.unit.clone(), ch.values.clone()),
        };
        let name = format!("Log_{}", ch.name);
        map.push(format!("--map={}={name}", ch.name));
        out.push(Channel { name, unit, values }).unwrap();
    }
    write(path, &out, &WriteOptions::default()).unwrap();
    map
}

/// Relative agreement of two JSON numbers.
fn close(a: &Value, b: &Value, tol: f64, what: &str) {
    let (x, y) = (a.as_f64().unwrap(), b.as_f64().unwrap());
    assert!(
        (x - y).abs() <= tol * y.abs().max(1e-300),
        "{what}: {x} against {y}"
    );
}

#[test]
fn the_same_recording_in_test_cell_units_gives_the_same_estimates() {
    let s = Scratch::new("physid-data");
    // Shaft monitor (time basis).
    let si = simulate(&s, "shaft-steady", "time", "3", "csv");
    let log = s.file("shaft-log.csv");
    let map = test_cell_log(&read(&si, &ReadOptions::default()).unwrap(), &log);
    let a = ok_json(&["monitor", "shaft", "--data", si.to_str().unwrap(), "--json"]);
    let mut args = vec![
        "monitor",
        "shaft",
        "--data",
        log.to_str().unwrap(),
        "--json",
    ];
    args.extend(map.iter().map(String::as_str));
    let b = ok_json(&args);
    for p in ["K", "B"] {
        close(&b["final"][p], &a["final"][p], 1e-9, p);
        close(&b["std_err"][p], &a["std_err"][p], 1e-9, p);
    }
    // τ0 is zero within its standard error: compared on the scale of that error.
    let (x, y, se) = (
        b["final"]["tau0"].as_f64().unwrap(),
        a["final"]["tau0"].as_f64().unwrap(),
        a["std_err"]["tau0"].as_f64().unwrap(),
    );
    assert!((x - y).abs() <= 1e-9 * se, "tau0: {x} against {y} (σ {se})");
    assert!(a["alarms"].as_array().unwrap().is_empty());
    assert!(b["alarms"].as_array().unwrap().is_empty());

    // The qualitative identification pipeline on the same two files: the log's columns named
    // and converted by the pipeline's own CHANNEL:UNIT (inputs and output).
    let pipeline = |data: &Path, log: bool| {
        let c = |name: &str, unit: &str| {
            if log {
                format!("Log_{name}:{unit}")
            } else {
                name.to_string()
            }
        };
        let f = s.file(if log { "p-log.toml" } else { "p-si.toml" });
        std::fs::write(
            &f,
            format!(
                "[model]\nexpr = \"K*(theta_dy - theta_en) + B*(omega_dy - omega_en) + tau0\"\nparams = {{ K = 1250.0, B = 0.95, tau0 = 0.1 }}\noutput = \"{}\"\ninputs = {{ theta_dy = \"{}\", theta_en = \"{}\", omega_dy = \"{}\", omega_en = \"{}\" }}\n[data]\nfile = \"{}\"\n[estimator]\nmethod = \"dsfc\"\nlambda = 0.999\n",
                c("torque_shaft", "N*m"),
                c("theta_dy", "rad"),
                c("theta_en", "rad"),
                c("omega_dy", "rad/s"),
                c("omega_en", "rad/s"),
                data.display()
            ),
        )
        .unwrap();
        ok_json(&["run", f.to_str().unwrap(), "--json"])
    };
    let (a, b) = (pipeline(&si, false), pipeline(&log, true));
    assert_eq!(a["estimable"], b["estimable"]);
    for p in ["K", "B"] {
        close(&b["params"][p], &a["params"][p], 1e-9, p);
    }
    close(
        &b["objective"]["value_pct"],
        &a["objective"]["value_pct"],
        1e-9,
        "objective",
    );

    // Cyclic torque (crank-angle basis, UKF).
    let si = simulate(&s, "torque-ramp", "crank", "2", "parquet");
    let log = s.file("torque-log.csv");
    let map = test_cell_log(&read(&si, &ReadOptions::default()).unwrap(), &log);
    let a = ok_json(&["torque", "fit", "--data", si.to_str().unwrap(), "--json"]);
    let mut args = vec!["torque", "fit", "--data", log.to_str().unwrap(), "--json"];
    args.extend(map.iter().map(String::as_str));
    let b = ok_json(&args);
    assert_eq!(a["estimable"], b["estimable"]);
    for p in a["estimable"].as_array().unwrap() {
        let p = p.as_str().unwrap();
        close(&b["params"][p], &a["params"][p], 1e-9, p);
    }
    close(&b["nmse_after"], &a["nmse_after"], 1e-9, "nmse_after");

    // Friction characterisation (crank-angle basis, cycle means).
    let si = simulate(&s, "friction-sweep", "crank", "8", "parquet");
    let log = s.file("friction-log.csv");
    let map = test_cell_log(&read(&si, &ReadOptions::default()).unwrap(), &log);
    let a = ok_json(&[
        "friction",
        "fit",
        "--data",
        si.to_str().unwrap(),
        "--preset",
        "cell",
        "--json",
    ]);
    let mut args = vec![
        "friction",
        "fit",
        "--data",
        log.to_str().unwrap(),
        "--preset",
        "cell",
        "--json",
    ];
    args.extend(map.iter().map(String::as_str));
    let b = ok_json(&args);
    assert_eq!(a["estimable"], b["estimable"]);
    assert_eq!(a["cycles"], b["cycles"]);
    for p in a["estimable"].as_array().unwrap() {
        let p = p.as_str().unwrap();
        close(&b["params"][p], &a["params"][p], 1e-9, p);
        close(&b["std_err"][p], &a["std_err"][p], 1e-9, p);
    }
}

#[test]
fn a_unit_physid_cannot_convert_is_refused_naming_the_channel() {
    let s = Scratch::new("physid-data");
    let f = s.file("bad.csv");
    std::fs::write(&f, "t,torque_shaft\ns,lbf*ft\n0,1\n0.001,2\n").unwrap();
    let o = physid(&["inspect", f.to_str().unwrap()]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("'torque_shaft' is in 'lbf*ft'"), "{e}");
    // A unit stated on the command line where the file has none.
    let f = s.file("bare.csv");
    std::fs::write(&f, "t,EngSpeed\n0,1500\n0.001,1500\n").unwrap();
    let j = ok_json(&[
        "inspect",
        f.to_str().unwrap(),
        "--map",
        "omega_en=EngSpeed:rpm",
        "--json",
    ]);
    let ch = j["channels"].as_array().unwrap();
    assert!(
        ch.iter()
            .any(|c| c["name"] == "omega_en" && c["unit"] == "rad/s"),
        "{j}"
    );
}

#[test]
fn a_crank_angle_recording_keeps_its_basis_in_every_format_and_every_verb_takes_it() {
    let s = Scratch::new("physid-data");
    let mut fits = Vec::new();
    for ext in ["csv", "parquet", "mf4"] {
        let f = simulate(&s, "torque-ramp", "crank", "2", ext);
        let i = ok_json(&["inspect", f.to_str().unwrap(), "--json", "--strict"]);
        assert_eq!(i["basis"], "crank_angle", "{ext}");
        fits.push(ok_json(&[
            "torque",
            "fit",
            "--data",
            f.to_str().unwrap(),
            "--json",
        ]));
        // The shaft monitor on the crank-angle recording (taken back to time) finds the
        // scenario's shaft (shaft.k = 1250 N·m/rad, shaft.b = 0.95 N·m·s/rad) within 3σ.
        let m = ok_json(&["monitor", "shaft", "--data", f.to_str().unwrap(), "--json"]);
        for (p, truth) in [("K", 1250.0), ("B", 0.95)] {
            let (v, se) = (
                m["final"][p].as_f64().unwrap(),
                m["std_err"][p].as_f64().unwrap(),
            );
            assert!(
                (v - truth).abs() < 3.0 * se,
                "{ext}: {p} = {v} ± {se} against {truth}"
            );
        }
    }
    // The same samples in each format: the same fit to the last digit.
    assert_eq!(fits[0]["params"], fits[1]["params"]);
    assert_eq!(fits[0]["params"], fits[2]["params"]);
}

#[test]
fn inspect_strict_passes_on_every_clean_scenario_in_both_bases() {
    let s = Scratch::new("physid-data");
    let list = physid(&["simulate", "--list"]);
    let names: Vec<String> = String::from_utf8_lossy(&list.stdout)
        .lines()
        .filter_map(|l| l.split_whitespace().next().map(String::from))
        .collect();
    assert!(names.len() >= 8, "{names:?}");
    for name in &names {
        for basis in ["time", "crank"] {
            let f = simulate(&s, name, basis, "1.5", "parquet");
            let o = physid(&["inspect", f.to_str().unwrap(), "--strict", "--json"]);
            assert!(
                o.status.success(),
                "{name} {basis}: {}{}",
                String::from_utf8_lossy(&o.stdout),
                String::from_utf8_lossy(&o.stderr)
            );
        }
    }
}

fn findings(j: &Value, kind: &str) -> Vec<u64> {
    j["integrity"]["findings"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|f| f["kind"] == kind)
        .map(|f| f["index"].as_u64().unwrap())
        .collect()
}

#[test]
fn every_injected_defect_is_found_at_its_sample() {
    let s = Scratch::new("physid-data");
    let f = simulate(&s, "shaft-steady", "time", "1.5", "parquet");
    let rec = read(&f, &ReadOptions::default()).unwrap();
    let edit = |name: &str, fun: &dyn Fn(&mut Recording)| {
        let mut r = rec.clone();
        fun(&mut r);
        let p = s.file(name);
        write(&p, &r, &WriteOptions::default()).unwrap();
        let o = physid(&["inspect", p.to_str().unwrap(), "--json", "--strict"]);
        assert!(!o.status.success(), "{name}: --strict should fail");
        serde_json::from_slice::<Value>(&o.stdout).unwrap()
    };
    // A gap: samples 999..1009 dropped from every channel.
    let j = edit("gap.csv", &|r| {
        let mut out = Recording::new(Basis::Time);
        for c in r.channels() {
            let mut c = c.clone();
            c.values.drain(999..1009);
            out.push(c).unwrap();
        }
        *r = out;
    });
    assert_eq!(findings(&j, "lost_samples"), [999], "{j}");
    // A NaN, and time going back.
    let j = edit("nan.parquet", &|r| {
        let mut v = r.values("p_cyl").unwrap().to_vec();
        v[1234] = f64::NAN;
        r.replace_values("p_cyl", v).unwrap();
    });
    assert_eq!(findings(&j, "non_finite"), [1234], "{j}");
    let j = edit("back.parquet", &|r| {
        let mut t = r.values("t").unwrap().to_vec();
        t[2345] = t[2343];
        r.replace_values("t", t).unwrap();
    });
    assert_eq!(findings(&j, "non_monotonic_time"), [2345], "{j}");
    // MDF4 orders its records by their time master: such a recording is refused, not reordered.
    let mut back = rec.clone();
    let mut t = back.values("t").unwrap().to_vec();
    t[2345] = t[2343];
    back.replace_values("t", t).unwrap();
    let e = write(s.file("back.mf4"), &back, &WriteOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("'t' goes back at sample 2345"), "{e}");
    // Lost encoder pulses, from the simulator's own fault.
    let p = s.file("lost.parquet");
    let o = physid(&[
        "simulate",
        "--scenario",
        "shaft-steady",
        "--duration",
        "1.5",
        "--fault",
        "sensors.lost_pulses_en=0.01@1.0",
        "--recording",
        p.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = physid(&["inspect", p.to_str().unwrap(), "--json"]);
    let j: Value = serde_json::from_slice(&o.stdout).unwrap();
    let lost = findings(&j, "pulse_loss");
    assert!(!lost.is_empty(), "{j}");
    let t = read(&p, &ReadOptions::default()).unwrap();
    let t = t.values("t").unwrap();
    // The first interval found ends after the fault's time and starts at most a revolution
    // (at 1000 rpm, 60 ms) before it.
    let at = t[lost[0] as usize];
    assert!((1.0 - 0.061..1.0).contains(&at), "{at}");
}

#[test]
fn physically_impossible_inputs_are_refused_naming_the_flag_and_range() {
    let s = Scratch::new("physid-data");
    let st = simulate(&s, "shaft-steady", "time", "1", "parquet");
    let out = s.file("x.csv");
    let out = out.to_str().unwrap();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["simulate", "--scenario", "shaft-steady", "--set", "engine.m_rec=-1", "--recording", out],
            "engine.m_rec = -1: expected ≥ 0 (kg)",
        ),
        (
            vec!["simulate", "--scenario", "shaft-steady", "--duration", "1", "--fault", "shaft.k=1000@5", "--recording", out],
            "--fault shaft.k=1000@5: at 5 s, outside the recording (0 to 1 s)",
        ),
        (
            vec!["simulate", "--scenario", "torque-ramp", "--basis", "crank", "--duration", "0.05", "--recording", out],
            "--duration 0.05: the recording would hold no sample",
        ),
        (
            vec!["simulate", "--scenario", "shaft-steady", "--duration", "-5", "--recording", out],
            "invalid value '-5' for '--duration <S>': expected a number > 0",
        ),
        (
            vec!["friction", "eval", "--n", "1000", "--p-int", "100000", "--t-oil", "35"],
            "'--p-int <P_INT>': the pressure is in kPa (0 < p ≤ 500); 100000 looks like Pa: 100 kPa",
        ),
        (
            vec!["friction", "eval", "--n", "1000", "--p-int", "50", "--t-oil", "363"],
            "looks like K",
        ),
        (
            vec!["monitor", "shaft", "--data", st.to_str().unwrap(), "--update-rate", "0"],
            "invalid value '0' for '--update-rate <HZ>': expected a number > 0",
        ),
        (
            vec!["monitor", "shaft", "--data", st.to_str().unwrap(), "--lambda", "1.5"],
            "'--lambda <LAMBDA>': a forgetting factor is in (0, 1]",
        ),
    ];
    for (args, want) in cases {
        let o = physid(&args);
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} should fail");
        assert!(e.contains(want), "{args:?}: {e}");
    }
    // A scenario's own fault beyond a shortened run is not the user's: it simply does not
    // happen (shaft-steady has none; fig314's throttle steps lie beyond 1 s).
    simulate(&s, "fig314", "time", "1", "parquet");
}

/// A lab recording as it comes — a `.dat` file of space-aligned numbers in scientific
/// notation, no header row — opens in every verb with `--columns` (and `--scale` for the
/// pressure sensor's volts): `inspect` reports it, `convert` makes a Parquet file of it with the
/// calibrated pressure in Pa.
#[test]
fn a_lab_recording_of_bare_columns_opens_with_columns_and_scale() {
    let s = Scratch::new("physid-lab");
    let dat = s.file("run01.dat");
    let mut text = String::new();
    for i in 0..2000 {
        let t = i as f64 * 1e-5;
        let volts = 1.0 + 0.5 * (2.0 * std::f64::consts::PI * 50.0 * t).sin();
        text.push_str(&format!(
            "  {t:.6e}   {:.6e}   {volts:.6e}\n",
            (i % 7) as f64 - 0.8
        ));
    }
    std::fs::write(&dat, text).unwrap();
    let flags = ["--columns", "t,pickup,p_cyl", "--scale", "p_cyl=2e5,1e5"];
    let mut args = vec!["inspect", dat.to_str().unwrap(), "--json"];
    args.extend(flags);
    let j = ok_json(&args);
    assert_eq!(j["channels"].as_array().unwrap().len(), 3);
    assert_eq!(j["channels"][0]["samples"], 2000);
    assert!(
        (j["sample_rate_hz"].as_f64().unwrap() - 1e5).abs() < 1e-3,
        "{j}"
    );
    let pq = s.file("run01.parquet");
    let mut args = vec!["convert", dat.to_str().unwrap(), pq.to_str().unwrap()];
    args.extend(flags);
    let o = physid(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r = read(&pq, &ReadOptions::default()).unwrap();
    let p = r.values("p_cyl").unwrap();
    // 1 V (the first sample) → 2e5·1 + 1e5 = 3e5 Pa.
    assert!((p[0] - 3e5).abs() < 1e-6, "{}", p[0]);
    assert_eq!(r.channel("p_cyl").unwrap().unit, "Pa");
    // Without --columns, numbers where names should be: a clear error says what to do.
    let o = physid(&["inspect", dat.to_str().unwrap()]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("line 1 holds 3 numbers") && e.contains("--columns"),
        "{e}"
    );
}

/// The tempting shortcut: a 60−3 wheel's 57 real teeth counted and given as a 57-pulse
/// encoder. The crank angle taken from such counts is wrong by up to the gap (12.6°), so the
/// counts are found out: `inspect` reports them (`uneven_pulses`) and the crank-angle
/// conversion refuses them, saying why.
#[test]
fn a_toothed_wheel_counted_as_an_encoder_is_found_out() {
    let s = Scratch::new("physid-wheel-counts");
    let f = s.file("wheel.csv");
    let mut text = String::from("t,count_en\n");
    for i in 0..60_000 {
        let t = i as f64 / 100_000.0;
        let theta = 104.72 * t + 0.02 * (2.0 * std::f64::consts::PI * 8.0 * t).sin();
        let rev = (theta / std::f64::consts::TAU).floor();
        let k = ((theta / std::f64::consts::TAU - rev) * 60.0)
            .floor()
            .min(56.0);
        text.push_str(&format!("{t},{}\n", rev * 57.0 + k));
    }
    std::fs::write(&f, text).unwrap();
    let j = ok_json(&[
        "inspect",
        f.to_str().unwrap(),
        "--encoder",
        "count_en=57",
        "--json",
    ]);
    let found: Vec<&Value> = j["integrity"]["findings"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|f| f["kind"] == "uneven_pulses")
        .collect();
    assert_eq!(found.len(), 1, "{j}");
    assert!(found[0]["detail"].as_str().unwrap().contains("count_en"));
    let out = s.file("deg.parquet");
    let o = physid(&[
        "convert",
        f.to_str().unwrap(),
        out.to_str().unwrap(),
        "--crank-angle",
        "--encoder",
        "count_en=57",
    ]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("not equally spaced in angle"), "{e}");
}

/// A lab recording as it comes, decoded: the raw voltage of an inductive pickup over a 60−3
/// wheel and a pressure sensor's volts at 100 kHz (`physid-signal`'s golden file, generated by
/// numpy with the true crank angle), written as a tab-separated `.dat` without a header.
/// `inspect --wheel` reports the wheel; `convert --crank-angle --wheel --tdc-offset
/// --phase-from` gives one sample per degree whose every cycle starts at the same true angle
/// (within 0.05°), 117–120° after the reference tooth's centre (the TDC offset given is read
/// from the tooth's edge, a fraction of a pitch before its centre), in the revolution of the
/// compression (the true TDC at 120° + 720°·k, not 480°), where the pressure peaks.
#[test]
fn a_trigger_wheel_s_raw_signal_gives_the_crank_angle() {
    let s = Scratch::new("physid-raw-wheel");
    let dat = common::raw_wheel_dat(&s.file("raw.dat"), &[]);
    let flags = [
        "--columns",
        "t,enc,p_cyl,theta_true",
        "--scale",
        "p_cyl=1e6,0",
        "--wheel",
        "enc=60-3",
    ];
    let mut args = vec!["inspect", dat.to_str().unwrap(), "--json"];
    args.extend(flags);
    let j = ok_json(&args);
    let w = &j["wheel"];
    assert_eq!(
        (w["teeth"].as_u64(), w["missing"].as_u64()),
        (Some(57), Some(3))
    );
    assert_eq!(w["glitches"], 4, "{w}");
    assert!(w["rpm_min"].as_f64().unwrap() > 270.0 && w["rpm_max"].as_f64().unwrap() < 2650.0);
    assert_eq!(j["integrity"]["ok"], true, "{j}");
    let deg = s.file("deg.parquet");
    let mut args = vec!["convert", dat.to_str().unwrap(), deg.to_str().unwrap()];
    args.extend(flags);
    args.extend([
        "--crank-angle",
        "--tdc-offset",
        "117",
        "--phase-from",
        "p_cyl",
    ]);
    let o = physid(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("wheel 60-3 decoded") && e.contains("odd revolutions"),
        "{e}"
    );
    let r = read(&deg, &ReadOptions::default()).unwrap();
    assert_eq!(r.basis, Basis::CrankAngle);
    let (crank, theta, cycle, p) = (
        r.values("crank_deg").unwrap(),
        r.values("theta_true").unwrap(),
        r.values("cycle").unwrap(),
        r.values("p_cyl").unwrap(),
    );
    let starts: Vec<f64> = (0..r.len())
        .filter(|&i| crank[i] == 0.0)
        .map(|i| theta[i].to_degrees().rem_euclid(720.0))
        .collect();
    assert!(starts.len() >= 12, "{starts:?}");
    let (lo, hi) = starts
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), &x| (a.min(x), b.max(x)));
    assert!(hi - lo < 0.05, "{starts:?}");
    assert!(lo > 117.0 && hi <= 120.0, "{starts:?}");
    // The pressure peaks at the true TDC, 120° after the tooth's centre — up to 3° after the
    // edge-referenced one, give or take the noise on the flat top: within 3.5° in every cycle.
    let last = cycle[cycle.len() - 1];
    for c in 0..last as usize {
        let idx: Vec<usize> = (0..r.len()).filter(|&i| cycle[i] == c as f64).collect();
        let peak = idx
            .iter()
            .copied()
            .max_by(|&a, &b| p[a].total_cmp(&p[b]))
            .unwrap();
        let at = crank[peak];
        assert!(at <= 3.5 || at >= 719.0, "cycle {c}: peak at {at}°");
    }
    let o = physid(&[
        "inspect",
        dat.to_str().unwrap(),
        "--columns",
        "t,enc,p_cyl,theta_true",
        "--wheel",
        "pickup=60-3",
    ]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("--wheel names 'pickup'"), "{e}");
    // The wrong wheel, or none named right: what was found, and what to give.
    let mut args = vec!["convert", dat.to_str().unwrap(), deg.to_str().unwrap()];
    args.extend(["--columns", "t,enc,p_cyl,theta_true", "--crank-angle"]);
    for (wheel, says) in [
        (
            "enc=60-2",
            "57 teeth between gaps of 4 pitches, expected 58",
        ),
        ("enc=60", "expected N-M"),
        ("enc", "expected CHANNEL=N-M"),
        (
            "pickup=60-3",
            "the engine angle is to be decoded from 'pickup' (a trigger wheel's), which the recording does not have; its channels are t, enc, p_cyl, theta_true",
        ),
    ] {
        let mut a = args.clone();
        a.extend(["--wheel", wheel]);
        let o = physid(&a);
        assert!(!o.status.success(), "{wheel}");
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(e.contains(says), "{wheel}: {e}");
    }
}

/// `physid cycles` on the raw recording straight away (the wheel decoded on the way): per
/// cycle the speed, the peak pressure at TDC, IMEP with the geometry, and the wheel's report —
/// the JSON the issue names. The golden pressure is a pulse symmetric about the true TDC, so
/// with the TDC placed right (118.28° after the tooth's edge: 120° after its centre, which lies
/// 1.72° after the edge — measured by the test above) compression and expansion mirror each
/// other and the gross IMEP is ≈ 0; placed 1.28° early (`--tdc-offset 117`), the loop gains
/// area — the classic sensitivity of IMEP to the TDC.
#[test]
fn cycles_of_a_raw_recording() {
    let s = Scratch::new("physid-raw-cycles");
    let dat = common::raw_wheel_dat(&s.file("raw.dat"), &[]);
    let run = |tdc: &str| {
        ok_json(&[
            "cycles",
            dat.to_str().unwrap(),
            "--columns",
            "t,enc,p_cyl,theta_true",
            "--scale",
            "p_cyl=1e6,0",
            "--wheel",
            "enc=60-3",
            "--tdc-offset",
            tdc,
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
            "--json",
        ])
    };
    let early = run("117");
    for c in early["cycles"].as_array().unwrap() {
        let gross = c["imep_gross_pa"].as_f64().unwrap();
        assert!(gross > 2e4, "{c}");
    }
    let j = run("118.28");
    let cycles = j["cycles"].as_array().unwrap();
    assert!(cycles.len() >= 12, "{j}");
    assert_eq!(j["wheel"]["teeth"], 57);
    assert_eq!(j["unit"], "Pa");
    let mut last_rpm = 0.0;
    for c in cycles {
        let rpm = c["rpm"].as_f64().unwrap();
        assert!(rpm > last_rpm && rpm < 2600.0, "{c}");
        last_rpm = rpm;
        // At TDC, give or take the noise on the pulse's top: 3 noise σ (6 mV) against a 2 V
        // Gaussian of σ 35° is ±2.7°, where every source sample (0.1° steps) is a candidate.
        let at = c["p_max_deg"].as_f64().unwrap();
        assert!((-2.7..=2.7).contains(&at), "{c}");
        assert!(
            (c["p_max"].as_f64().unwrap() / 2.5e6 - 1.0).abs() < 0.01,
            "{c}"
        );
        let gross = c["imep_gross_pa"].as_f64().unwrap();
        assert!(gross.abs() < 3e3, "{c}");
        assert!(c["n_compression"].as_f64().is_some());
    }
    assert!(j["cov_imep"].as_f64().is_some());
    // Bad values name the flag.
    for (flags, says) in [
        (vec!["--peg", "polytropic=7"], "--peg polytropic=7"),
        (vec!["--peg", "tdc=1"], "expected bdc="),
    ] {
        let mut a = vec![
            "cycles",
            dat.to_str().unwrap(),
            "--columns",
            "t,enc,p_cyl,theta_true",
            "--wheel",
            "enc=60-3",
        ];
        a.extend(flags);
        let o = physid(&a);
        assert!(!o.status.success());
        assert!(
            String::from_utf8_lossy(&o.stderr).contains(says),
            "{}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
}

/// The same lab recording replayed live (`live --replay --wheel`): the angle decoded as
/// `convert --crank-angle` decodes it, then on a time basis at its mean rate, so the live cycle
/// statistics run on it — as many cycles as `convert` gives (every complete one, less the
/// last, which the time basis ends within), each starting at the same true angle as there, so
/// the cylinder pressure peaks within 3.5° of the firing TDC in every cycle. Without --replay
/// the flags are refused.
#[test]
fn a_trigger_wheel_s_raw_signal_replays_live() {
    let s = Scratch::new("physid-raw-wheel-live");
    let dat = common::raw_wheel_dat(&s.file("raw.dat"), &[]);
    let flags = [
        "--columns",
        "t,enc,p_cyl,theta_true",
        "--scale",
        "p_cyl=1e6,0",
        "--wheel",
        "enc=60-3",
        "--tdc-offset",
        "117",
        "--phase-from",
        "p_cyl",
    ];
    let deg = s.file("deg.parquet");
    let mut args = vec![
        "convert",
        dat.to_str().unwrap(),
        deg.to_str().unwrap(),
        "--crank-angle",
    ];
    args.extend(flags);
    let o = physid(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r = read(&deg, &ReadOptions::default()).unwrap();
    let complete = r.values("cycle").unwrap().last().copied().unwrap() as usize;
    let mut args = vec![
        "live",
        "--headless",
        "--json",
        "--replay",
        dat.to_str().unwrap(),
        "--pace",
        "max",
    ];
    args.extend(flags);
    let o = physid(&args);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{e}");
    assert!(e.contains("wheel 60-3 decoded"), "{e}");
    let cycles: Vec<Value> = String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| serde_json::from_str::<Value>(l).unwrap())
        .filter(|v| v["type"] == "cycle")
        .collect();
    assert!(
        cycles.len() + 1 >= complete && cycles.len() <= complete,
        "{} live cycles, {complete} complete in convert's",
        cycles.len()
    );
    assert!(cycles.len() >= 11, "{} cycles", cycles.len());
    for c in &cycles {
        let at = c["max_deg"]["p_cyl"].as_f64().unwrap();
        assert!(
            at <= 3.5 || at >= 716.5,
            "cycle {}: peak at {at}°",
            c["cycle"]
        );
    }
    let o = physid(&["live", "--headless", "--json", "--wheel", "enc=60-3"]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("of a --replay file"), "{e}");
}

/// A quadrature encoder's raw A/B/Z signals (`physid-signal`'s golden file: 500 lines,
/// digital, 200 kHz, turning back 40° before running up to 1200 rpm) converted to one sample
/// per degree with `--quadrature`: the angle is taken from after the shaft last turned back,
/// and every cycle starts at the true angle 90° (`--tdc-offset 90` from the index) within a
/// tenth of a degree. Without the index channel the TDC has no reference: refused.
#[test]
fn a_quadrature_encoder_s_raw_signals_give_the_crank_angle() {
    let golden = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../signal/tests/golden/quadrature_500.parquet");
    let s = Scratch::new("physid-raw-quadrature");
    let deg = s.file("deg.parquet");
    let o = physid(&[
        "convert",
        golden.to_str().unwrap(),
        deg.to_str().unwrap(),
        "--crank-angle",
        "--quadrature",
        "enc_a,enc_b,enc_z=500",
        "--tdc-offset",
        "90",
    ]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{e}");
    assert!(e.contains("quadrature encoder of 500 lines decoded"), "{e}");
    assert!(e.contains("after it last turned back"), "{e}");
    common::revolutions_start_at(&deg, 90.0, 0.1, 1);
    let o = physid(&[
        "convert",
        golden.to_str().unwrap(),
        deg.to_str().unwrap(),
        "--crank-angle",
        "--quadrature",
        "enc_a,enc_b=500",
    ]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("without an index channel (Z)"), "{e}");
    for (bad, says) in [
        ("enc_a=500", "expected A,B,Z=LINES"),
        ("enc_a,enc_b,enc_z=0", "expected A,B,Z=LINES"),
    ] {
        let o = physid(&[
            "convert",
            golden.to_str().unwrap(),
            deg.to_str().unwrap(),
            "--crank-angle",
            "--quadrature",
            bad,
        ]);
        assert!(!o.status.success());
        assert!(String::from_utf8_lossy(&o.stderr).contains(says), "{bad}");
    }
    let o = physid(&[
        "convert",
        golden.to_str().unwrap(),
        deg.to_str().unwrap(),
        "--crank-angle",
        "--quadrature",
        "enc_a,enc_b,enc_z=500",
        "--wheel",
        "enc_a=60-2",
    ]);
    assert!(!o.status.success(), "--wheel and --quadrature together");
}

/// A golden file of physid-apps (generated by its `tests/golden/gen_motored.py`).
fn apps_golden(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../apps/tests/golden")
        .join(name)
}

fn motored_truth() -> Value {
    serde_json::from_str(&std::fs::read_to_string(apps_golden("motored.json")).unwrap()).unwrap()
}

/// A raw motored recording (60−2 wheel, cam, pressure volts) taken to crank angle with the
/// TDC placed from the pressure: the offset within 0.1° of the truth, with its interval on
/// stderr, and every cycle of the output starting at the true firing TDC.
/// `convert --crank-angle --wheel … --tdc-from p_cyl` of the golden raw motored file into
/// `out`, with `extra` flags: the offset it found and the line that says it.
fn convert_tdc_from(out: &Path, extra: &[&str]) -> (f64, String) {
    let raw = apps_golden("motored_wheel.parquet");
    let mut args = vec![
        "convert",
        raw.to_str().unwrap(),
        out.to_str().unwrap(),
        "--crank-angle",
        "--wheel",
        "enc=60-2",
        "--phase-from",
        "cam",
        "--tdc-from",
        "p_cyl",
        "--stroke",
        "0.09",
        "--rod",
        "0.15",
        "--scale",
        "p_cyl=1e6,0",
    ];
    args.extend_from_slice(extra);
    let o = physid(&args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    // "TDC from 'p_cyl' (…): 73.509° after the sensor's reference (95 %: a … b°)"
    let line = err
        .lines()
        .find(|l| l.contains("TDC from 'p_cyl'"))
        .unwrap()
        .to_string();
    let found: f64 = line
        .split("): ")
        .nth(1)
        .and_then(|r| r.split('°').next())
        .unwrap()
        .parse()
        .unwrap();
    (found, line)
}

#[test]
fn convert_places_the_tdc_from_a_motored_pressure_trace() {
    let s = Scratch::new("physid-data");
    let out = s.file("deg.parquet");
    let raw = apps_golden("motored_wheel.parquet");
    let (found, line) = convert_tdc_from(&out, &[]);
    let t = motored_truth();
    let truth = t["wheel"]["tdc_offset_deg"].as_f64().unwrap();
    assert!((found - truth).abs() < 0.1, "{line}");
    assert!(
        line.contains("95 %") && line.contains("loss angle"),
        "{line}"
    );
    // Every cycle starts at the true firing TDC (theta_true carried onto the grid).
    let rec = read(&out, &ReadOptions::default()).unwrap();
    let (c, th) = (
        rec.values("crank_deg").unwrap(),
        rec.values("theta_true").unwrap(),
    );
    let tdc = (0.25 * 6.0 + truth).to_radians();
    let four_pi = 4.0 * std::f64::consts::PI;
    let starts: Vec<usize> = (0..c.len()).filter(|&i| c[i].abs() < 1e-6).collect();
    assert!(starts.len() >= 11);
    for i in starts {
        let d = (th[i] * 1e-6 - tdc).rem_euclid(four_pi);
        assert!(d.min(four_pi - d).to_degrees() < 0.1, "sample {i}: {d}");
    }
    // A known compression ratio is held by the motored model (it used to be refused here while
    // `compression fit` took it): the TDC the same within 0.1°.
    let eps = t["wheel"]["eps"].to_string();
    let (with_ratio, line) = convert_tdc_from(
        &s.file("held.parquet"),
        &["--compression-ratio", eps.as_str()],
    );
    assert!((with_ratio - truth).abs() < 0.1, "{line}");
    // The flags that go with it.
    for (flags, says) in [
        (vec!["--tdc-from", "p_cyl"], "--stroke and --rod"),
        (
            vec![
                "--tdc-from",
                "p_cyl",
                "--tdc-offset",
                "70",
                "--stroke",
                "0.09",
                "--rod",
                "0.15",
            ],
            "cannot be used with",
        ),
    ] {
        let mut a = vec![
            "convert",
            raw.to_str().unwrap(),
            out.to_str().unwrap(),
            "--crank-angle",
            "--wheel",
            "enc=60-2",
            "--scale",
            "p_cyl=1e6,0",
        ];
        a.extend(flags);
        let o = physid(&a);
        assert!(!o.status.success());
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(e.contains(says), "{e}");
    }
    let o = physid(&[
        "inspect",
        raw.to_str().unwrap(),
        "--wheel",
        "enc=60-2",
        "--tdc-from",
        "p_cyl",
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("inspect --tdc-from"));
    // Without --wheel, inspect recognises the wheel (and not the cam or the pressure).
    let j = ok_json(&[
        "inspect",
        raw.to_str().unwrap(),
        "--scale",
        "p_cyl=1e6,0",
        "--json",
    ]);
    let r = j["recognised"].as_array().unwrap();
    assert_eq!(r.len(), 1, "{j}");
    assert_eq!(
        (r[0]["channel"].as_str(), r[0]["wheel"].as_str()),
        (Some("enc"), Some("60-2"))
    );
}

/// `physid compression fit` on the numpy motored trace: every parameter's 95 % interval
/// holds the truth, the JSON and the report directory say so, and the tracks file has a row
/// per TDC with units.
#[test]
fn compression_fit_recovers_the_motored_trace_s_parameters() {
    let s = Scratch::new("physid-data");
    let dir = s.file("comp");
    let data = apps_golden("motored_deg.parquet");
    let j = ok_json(&[
        "compression",
        "fit",
        "--data",
        data.to_str().unwrap(),
        "--stroke",
        "0.09",
        "--rod",
        "0.15",
        "--bore",
        "0.08",
        "--json",
        "--out",
        dir.to_str().unwrap(),
    ]);
    let t = motored_truth();
    for e in j["estimates"].as_array().unwrap() {
        let name = e["name"].as_str().unwrap();
        let truth = t["deg"][name].as_f64().unwrap();
        let (lo, hi) = (
            e["ci95"][0].as_f64().unwrap(),
            e["ci95"][1].as_f64().unwrap(),
        );
        assert!(lo <= truth && truth <= hi, "{name}: {e}");
        assert_eq!(e["status"], "fitted");
    }
    assert_eq!(j["ranking"].as_array().unwrap().len(), 6);
    assert!(
        j["motored_imep_pa"].as_f64().unwrap() < 0.0,
        "{}",
        j["motored_imep_pa"]
    );
    for f in ["report.html", "compression_fit.json", "tracks.csv"] {
        assert!(dir.join(f).exists(), "{f}");
    }
    let tracks = read(dir.join("tracks.csv"), &ReadOptions::default()).unwrap();
    assert_eq!(tracks.len(), 11);
    assert_eq!(tracks.channel("tdc_shift").unwrap().unit, "deg");
    let html = std::fs::read_to_string(dir.join("report.html")).unwrap();
    assert!(html.contains("compression ratio") && html.contains("loss angle"));
    // A known compression ratio is held, not fitted.
    let held = ok_json(&[
        "compression",
        "fit",
        "--data",
        data.to_str().unwrap(),
        "--stroke",
        "0.09",
        "--rod",
        "0.15",
        "--compression-ratio",
        "10.5",
        "--json",
    ]);
    let eps = held["estimates"]
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["name"] == "eps")
        .unwrap();
    assert_eq!(
        (eps["status"].as_str(), eps["value"].as_f64()),
        (Some("held"), Some(10.5))
    );
    // Geometry missing; a parameter that is not the model's.
    let o = physid(&["compression", "fit", "--data", data.to_str().unwrap()]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("--stroke and --rod"));
    let o = physid(&[
        "compression",
        "fit",
        "--data",
        data.to_str().unwrap(),
        "--stroke",
        "0.09",
        "--rod",
        "0.15",
        "--set",
        "kappa=10",
    ]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && e.contains("eps, tdc_shift, p_offset"),
        "{e}"
    );
    // A pressure in bar labelled Pa where IMEP needs Pa: named with its sample.
    let csv = s.file("bar.csv");
    let rec = read(&data, &ReadOptions::default()).unwrap();
    let mut text = String::from("t,cycle,crank_deg,p_cyl\ns,-,deg,Pa\n");
    let (tt, cy, cd, p) = (
        rec.values("t").unwrap(),
        rec.values("cycle").unwrap(),
        rec.values("crank_deg").unwrap(),
        rec.values("p_cyl").unwrap(),
    );
    for i in 0..rec.len() {
        text.push_str(&format!("{},{},{},{}\n", tt[i], cy[i], cd[i], p[i] / 1e5));
    }
    std::fs::write(&csv, text).unwrap();
    let o = physid(&[
        "cycles",
        csv.to_str().unwrap(),
        "--bore",
        "0.08",
        "--stroke",
        "0.09",
        "--rod",
        "0.15",
        "--compression-ratio",
        "10.5",
    ]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && e.contains("'p_cyl' peaks at") && e.contains("sample"),
        "{e}"
    );
}

/// A 360-pulse analog encoder and its analog index (`physid-signal`'s golden file, numpy: 600 →
/// 3000 rpm at 200 kHz, a missing pulse, glitches on both channels) decoded by `convert
/// --crank-angle --encoder-raw enc=360 --index-raw idx`: one sample per degree whose every
/// revolution starts at the same true angle (within 0.05°) — 1° after the wheel's 0, where the
/// first rising edge after the index lies, plus the `--tdc-offset` given — the missing pulse an
/// integrity finding; a wrong pulse count, or the index missing, said with what was found.
/// `inspect --encoder-raw` reports the decoding: edges, revolutions, speeds, the glitches
/// rejected, the missing pulse among the integrity findings.
#[test]
fn a_pulse_encoder_s_raw_channels_give_the_crank_angle() {
    let s = Scratch::new("physid-raw-pulses");
    let golden = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../signal/tests/golden/pulse_encoder_360.parquet");
    let g = golden.to_str().unwrap();
    let j = ok_json(&[
        "inspect",
        g,
        "--json",
        "--encoder-raw",
        "enc=360",
        "--index-raw",
        "idx",
    ]);
    let w = &j["wheel"];
    assert_eq!(
        (
            w["teeth"].as_u64(),
            w["missing"].as_u64(),
            w["index"].as_str()
        ),
        (Some(360), Some(0), Some("idx")),
        "{w}"
    );
    assert_eq!(w["glitches"], 4, "{w}");
    let revs = w["revolutions"].as_u64().unwrap();
    assert!((20..=23).contains(&revs), "{w}");
    assert!(w["rpm_min"].as_f64().unwrap() > 540.0 && w["rpm_max"].as_f64().unwrap() < 3300.0);
    assert_eq!(j["integrity"]["ok"], false, "{j}");
    let o = physid(&[
        "inspect",
        g,
        "--encoder-raw",
        "enc=360",
        "--index-raw",
        "idx",
    ]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("encoder 'enc' (360 pulses, index 'idx')"));
    let o = physid(&["inspect", g, "--encoder-raw", "enc=360", "--index-raw", "z"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("name 'enc' and 'z'"));
    let deg = s.file("deg.parquet");
    let d = deg.to_str().unwrap();
    let o = physid(&[
        "convert",
        g,
        d,
        "--crank-angle",
        "--encoder-raw",
        "enc=360",
        "--index-raw",
        "idx",
        "--tdc-offset",
        "30",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("encoder of 360 pulses with the index 'idx' decoded"),
        "{e}"
    );
    assert!(e.contains("tooth edge(s) missing"), "{e}");
    common::revolutions_start_at(&deg, 31.0, 0.05, 14);
    for (args, says) in [
        (
            ["--encoder-raw", "enc=500", "--index-raw", "idx"],
            "360 edges between the index pulses of 'idx'",
        ),
        (
            ["--encoder-raw", "enc=360", "--index-raw", "enc"],
            "expected two different channels",
        ),
        (
            ["--encoder-raw", "enc=0", "--index-raw", "idx"],
            "expected CHANNEL=PULSES",
        ),
    ] {
        let mut a = vec!["convert", g, d, "--crank-angle"];
        a.extend(args);
        let o = physid(&a);
        assert!(!o.status.success(), "{args:?}");
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(e.contains(says), "{args:?}: {e}");
    }
    let o = physid(&["convert", g, d, "--crank-angle", "--encoder-raw", "enc=360"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--index-raw"));
}
