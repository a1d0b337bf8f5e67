//! Scenarios, profiles, faults and the recording a run produces.
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_core::standard_unit;
use physid_sim::params::CellParams;
use physid_sim::run::{parameter_truth, simulate, OutputBasis, RunOptions};
use physid_sim::scenario::{named, Fault, Profile, Scenario, Segment, Shape, NAMED};
use std::f64::consts::PI;

#[test]
fn every_named_scenario_is_valid() {
    for (name, _) in NAMED {
        let s = named(name).unwrap();
        s.validate().unwrap();
        assert!(s.duration > 0.0 && !s.description.is_empty(), "{name}");
        assert!(
            s.speed.value(0.0) > 0.0 && s.speed.value(s.duration) > 0.0,
            "{name}"
        );
    }
    assert!(named("nope").is_none());
    let e = Scenario::load("nope").unwrap_err().to_string();
    assert!(
        e.contains("shaft-steady") && e.contains("nor a file"),
        "{e}"
    );
}

#[test]
fn profile_shapes_in_closed_form() {
    let p = Profile::default()
        .then(2.0, Shape::Ramp { v0: 1.0, v1: 3.0 })
        .then(
            2.0,
            Shape::Sine {
                mean: 5.0,
                amplitude: 2.0,
                frequency: 0.25,
                phase: 0.0,
            },
        )
        .then(
            3.0,
            Shape::Steps {
                values: vec![7.0, 8.0, 9.0],
                every: 1.0,
            },
        )
        .then(
            2.0,
            Shape::Chirp {
                mean: 0.0,
                amplitude: 1.0,
                f0: 1.0,
                f1: 3.0,
            },
        );
    assert_eq!(p.value(1.0), 2.0);
    assert!((p.value(3.0) - (5.0 + 2.0 * (2.0 * PI * 0.25).sin())).abs() < 1e-12);
    assert_eq!(p.value(5.5), 8.0);
    // Chirp: phase 2π(f0τ + (f1−f0)τ²/(2T)); at τ = 0.25: 2π(0.25 + 2·0.0625/4).
    let want = (2.0 * PI * (0.25 + 0.5 * 1.0 * 0.0625)).sin();
    assert!((p.value(7.25) - want).abs() < 1e-12);
    assert_eq!(p.value(-1.0), 1.0);
    assert!((p.value(100.0) - p.value(9.0)).abs() < 1e-12);
}

/// A staircase of many segments (as a designed test has) with gaps between them: inside a
/// segment its own value, at a shared end the earlier segment's, in a gap the last end's held,
/// before the first its start — segment `k` spans `[2k, 2k + 1.5]` s at value `k`.
#[test]
fn many_segments_with_gaps() {
    let p = Profile {
        segments: (0..500)
            .map(|k| Segment {
                t0: 2.0 * k as f64,
                t1: 2.0 * k as f64 + 1.5,
                shape: Shape::Constant { value: k as f64 },
            })
            .collect(),
    };
    for i in 0..4000 {
        let t = -1.0 + 0.25 * i as f64;
        let k = (t / 2.0).floor().clamp(0.0, 499.0);
        // Within [2k, 2k + 1.5]: k; in the gap after it (and past the end): k held.
        assert_eq!(p.value(t), k, "t = {t}");
    }
    // Adjacent segments share their end: the earlier one's value there.
    let q = Profile::constant(1.0, 1.0).then(1.0, Shape::Constant { value: 2.0 });
    assert_eq!((q.value(1.0), q.value(1.0 + 1e-9)), (1.0, 2.0));
    // Overlapping segments are refused by name.
    let mut s = named("shaft-steady").unwrap();
    s.speed = Profile::constant(900.0, 2.0).then(1.0, Shape::Constant { value: 1000.0 });
    s.speed.segments[1].t0 = 1.5;
    let e = s.validate().unwrap_err().to_string();
    assert!(
        e.contains("speed segment 1.5–3 s starts before the previous one (0–2 s) ends"),
        "{e}"
    );
}

#[test]
fn toml_files_with_a_recorded_profile() {
    let d = physid_testkit::Scratch::new("physid-scn");
    std::fs::write(d.join("speed.csv"), "t,value\n0,900\n1,1100\n2,1000\n").unwrap();
    let toml = r#"
name = "custom"
duration = 3.0
settle = 0.5
faults = ["shaft.b=1.2@1+1"]
[[speed]]
t0 = 0.0
t1 = 2.0
kind = "recorded"
file = "speed.csv"
[[speed]]
t0 = 2.0
t1 = 3.0
kind = "constant"
value = 1000.0
[[throttle]]
t0 = 0.0
t1 = 3.0
kind = "ramp"
v0 = 90.0
v1 = 10.0
[set]
"shaft.k" = 1340.0
"#;
    let f = d.join("custom.toml");
    std::fs::write(&f, toml).unwrap();
    let s = Scenario::load(f.to_str().unwrap()).unwrap();
    assert_eq!(s.speed.value(0.5), 1000.0);
    assert_eq!(s.speed.value(2.5), 1000.0);
    assert_eq!(s.throttle.value(1.5), 50.0);
    // Mistakes are named.
    std::fs::write(&f, toml.replace("\"shaft.k\"", "\"shaft.q\"")).unwrap();
    let e = Scenario::load(f.to_str().unwrap()).unwrap_err().to_string();
    assert!(
        e.contains("no parameter 'shaft.q'") && e.contains("shaft.k"),
        "{e}"
    );
    std::fs::write(&f, toml.replace("kind = \"ramp\"", "kind = \"zigzag\"")).unwrap();
    let e = Scenario::load(f.to_str().unwrap()).unwrap_err().to_string();
    assert!(e.contains("zigzag"), "{e}");
}

#[test]
fn fault_syntax_and_schedule() {
    let f = Fault::parse("shaft.k=1200@5").unwrap();
    assert_eq!((f.value, f.at, f.ramp), (1200.0, 5.0, 0.0));
    let g = Fault::parse("shaft.b=1.2@5+2").unwrap();
    let base = CellParams::default();
    let mut p = base.clone();
    Fault::apply_all(&[f.clone(), g.clone()], &base, &mut p, 4.9);
    assert_eq!((p.shaft.k, p.shaft.b), (1250.0, 0.95));
    Fault::apply_all(&[f.clone(), g.clone()], &base, &mut p, 6.0);
    assert_eq!(p.shaft.k, 1200.0);
    assert!((p.shaft.b - (0.95 + 0.5 * 0.25)).abs() < 1e-12);
    for (spec, want) in [
        ("shaft.k=1200", "expected PATH=VALUE@T"),
        ("shaft.k=x@5", "expected PATH=VALUE@T"),
        ("engine.bore=0.05@1", "cannot change during a run"),
        ("shaft.x=1@1", "no parameter 'shaft.x'"),
        // The value within the parameter's range, as `--set` has it.
        ("shaft.k=-1@0.5", "shaft.k = -1: expected > 0"),
        ("shaft.k=0@0.5", "shaft.k = 0: expected > 0"),
        (
            "engine.friction_scale=-5@1",
            "engine.friction_scale = -5: expected ≥ 0",
        ),
        (
            "sensors.lost_pulses_en=2@1",
            "a probability per pulse is in [0, 1]",
        ),
    ] {
        let e = Fault::parse(spec).unwrap_err().to_string();
        assert!(e.contains(want), "{spec}: {e}");
    }
}

/// A short run: the channel table's names and units, the faults in the truth channels, the
/// sensors' noise at its configured level, the crank-angle basis.
#[test]
fn a_run_produces_the_recording() {
    let mut s = named("shaft-steady").unwrap();
    s.settle = 0.5;
    s.faults.push("shaft.k=1100@0.5".into());
    let mut opts = RunOptions {
        duration: Some(1.0),
        ..Default::default()
    };
    opts.params.set("sensors.torque_shaft.noise", 0.2).unwrap();
    let rec = simulate(&s, &opts, |_| {}).unwrap();
    for ch in rec.channels() {
        if let Some(u) = standard_unit(&ch.name) {
            assert_eq!(ch.unit, u, "{}", ch.name);
        }
        assert!(ch.values.iter().all(|v| v.is_finite()), "{}", ch.name);
    }
    assert_eq!(rec.len(), 10_001);
    let k = rec.values("true_shaft_k").unwrap();
    assert_eq!((k[0], k[10_000]), (1250.0, 1100.0));
    // The truth rebuilt from the metadata equals the parameter the cell ran with.
    let t = rec.values("t").unwrap();
    // The recorded channel holds the value the step containing the sample ran with (never one
    // between the two levels); the metadata gives the schedule. They differ only for samples
    // inside the step that spans the fault's time (a step lasts at most 1° at 500 rpm).
    let pt = parameter_truth(&rec, "shaft.k", t).unwrap();
    let mut late = 0;
    for i in 0..k.len() {
        assert!(k[i] == 1250.0 || k[i] == 1100.0, "sample {i}: {}", k[i]);
        if pt[i] != k[i] {
            assert!(
                t[i] >= 0.5 && t[i] < 0.5 + 1.0 / 3000.0,
                "sample {i} at {}",
                t[i]
            );
            assert_eq!((k[i], pt[i]), (1250.0, 1100.0));
            late += 1;
        }
    }
    assert!(late <= 2, "{late} samples");
    assert!(parameter_truth(&rec, "shaft.b", t)
        .unwrap()
        .iter()
        .all(|&b| b == 0.95));
    let mut measured = rec.clone();
    measured.meta.clear();
    assert!(parameter_truth(&measured, "shaft.k", t).is_none());
    // Noise: the measured minus the noise-free torque (K·twist + B·Δω from the truth).
    let (tq, th_dy, th_en, w_dy, w_en) = (
        rec.values("torque_shaft").unwrap(),
        rec.values("theta_dy").unwrap(),
        rec.values("theta_en").unwrap(),
        rec.values("omega_dy").unwrap(),
        rec.values("omega_en").unwrap(),
    );
    let resid: Vec<f64> = (0..rec.len())
        .map(|i| tq[i] - (k[i] * (th_dy[i] - th_en[i]) + 0.95 * (w_dy[i] - w_en[i])))
        .collect();
    let sd = (resid.iter().map(|r| r * r).sum::<f64>() / resid.len() as f64).sqrt();
    assert!((sd / 0.2 - 1.0).abs() < 0.05, "{sd}");
    // Encoders: 360 pulses per revolution on the engine.
    let c = rec.values("count_en").unwrap();
    let revs = (th_en[rec.len() - 1] - th_en[0]) / (2.0 * PI);
    assert!(((c[rec.len() - 1] - c[0]) / 360.0 - revs).abs() < 0.01);
    let markers = rec
        .values("tdc")
        .unwrap()
        .iter()
        .filter(|&&m| m == 1.0)
        .count();
    assert!((markers as f64 - revs).abs() <= 1.0);
    // The crank-angle basis: one sample per degree from firing TDC.
    let crank = simulate(
        &s,
        &RunOptions {
            duration: Some(0.5),
            basis: OutputBasis::Crank(1.0),
            ..Default::default()
        },
        |_| {},
    )
    .unwrap();
    let (cyc, deg) = (
        crank.values("cycle").unwrap(),
        crank.values("crank_deg").unwrap(),
    );
    assert_eq!((cyc[0], deg[0]), (0.0, 0.0));
    assert_eq!((cyc[720], deg[720]), (1.0, 0.0));
    assert!((deg[100] - 100.0).abs() < 1e-6);
}

/// A speed-sensor fault makes the drive run at the wrong speed (it holds the reading at the
/// demand), and leaves the shaft untouched.
#[test]
fn speed_sensor_fault_moves_the_drive_not_the_shaft() {
    let mut s = named("shaft-steady").unwrap();
    s.settle = 0.5;
    s.faults.push("dyno.speed_sensor.offset=5@0.5".into());
    let rec = simulate(
        &s,
        &RunOptions {
            duration: Some(3.0),
            ..Default::default()
        },
        |_| {},
    )
    .unwrap();
    let w = rec.values("omega_dy").unwrap();
    let n = w.len();
    let before = w[..4000].iter().sum::<f64>() / 4000.0;
    let after = w[n - 10000..].iter().sum::<f64>() / 10000.0;
    assert!((before - after - 5.0).abs() < 0.2, "{before} → {after}");
    let k = rec.values("true_shaft_k").unwrap();
    assert!(k.iter().all(|&v| v == 1250.0));
}

/// Sensor faults act on the recording alone, from their time on: an offset on the shaft
/// torque transducer adds exactly its value to the reading and nothing to anything else (each
/// sensor draws its own noise, so the two runs' noise is the same sample for sample); lost
/// encoder pulses make the engine's count fall behind `floor(θ/q)` from the fault on, by about
/// the probability times the pulses since.
#[test]
fn sensor_faults_change_the_readings_from_their_time() {
    let mut s = named("shaft-steady").unwrap();
    s.settle = 0.2;
    let opts = RunOptions {
        duration: Some(1.0),
        ..Default::default()
    };
    let clean = simulate(&s, &opts, |_| {}).unwrap();
    s.faults.push("sensors.torque_shaft.offset=5@0.5".into());
    s.faults.push("sensors.lost_pulses_en=0.01@0.5".into());
    // A different noise level on another sensor leaves the shaft torque's noise as it was.
    let mut quieter = opts.clone();
    quieter.params.set("sensors.p_cyl.noise", 0.0).unwrap();
    let faulty = simulate(&s, &quieter, |_| {}).unwrap();
    let t = clean.values("t").unwrap();
    let (a, b) = (
        clean.values("torque_shaft").unwrap(),
        faulty.values("torque_shaft").unwrap(),
    );
    for i in 0..t.len() {
        let want = if t[i] >= 0.5 { 5.0 } else { 0.0 };
        assert!((b[i] - a[i] - want).abs() < 1e-9, "sample {i} at {}", t[i]);
    }
    assert_eq!(clean.values("omega_en"), faulty.values("omega_en"));
    // The lost pulses.
    let (th, count) = (
        faulty.values("theta_en").unwrap(),
        faulty.values("count_en").unwrap(),
    );
    let q = 2.0 * PI / 360.0;
    let mut pulses_since = 0.0;
    for i in 0..t.len() {
        let lost = (th[i] / q).floor() - count[i];
        if t[i] < 0.5 {
            assert_eq!(lost, 0.0, "sample {i}");
        } else if pulses_since == 0.0 {
            pulses_since = (th[i] / q).floor();
        }
    }
    let n = t.len() - 1;
    let since = (th[n] / q).floor() - pulses_since;
    let lost = (th[n] / q).floor() - count[n];
    // Binomial(since, 0.01): within 5 standard deviations.
    let (mean, sd) = (0.01 * since, (0.01 * 0.99 * since).sqrt());
    assert!(
        since > 2000.0 && (lost - mean).abs() < 5.0 * sd,
        "{lost} of {since}"
    );
}

/// A torque demand holds no speed: a torque-mode scenario's `speed_range` starts the engine in
/// its middle and stops the run, with the time and the speed, once the engine leaves it (a
/// cell's speed trips); a bad range is refused.
#[test]
fn torque_mode_keeps_to_its_speed_range() {
    let text = |torque: f64, range: &str| {
        format!(
            "name = \"tq\"\nduration = 4.0\nsettle = 0.0\ntorque_mode = true\nspeed_range = {range}\n[[speed]]\nt0 = 0.0\nt1 = 4.0\nkind = \"constant\"\nvalue = {torque}\n[[throttle]]\nt0 = 0.0\nt1 = 4.0\nkind = \"constant\"\nvalue = 90.0\n"
        )
    };
    let opts = RunOptions {
        basis: OutputBasis::Time(1000.0),
        ..Default::default()
    };
    // 1 N·m against the motored engine's drag: the speed stays near its start, 1200 rpm.
    let s: Scenario = toml::from_str(&text(1.0, "[800.0, 1600.0]")).unwrap();
    s.validate().unwrap();
    let rec = simulate(&s, &opts, |_| {}).unwrap();
    let w = rec.values("omega_en").unwrap();
    let rpm = |v: f64| v * 30.0 / PI;
    assert!((rpm(w[0]) - 1200.0).abs() < 30.0, "{}", rpm(w[0]));
    assert!(w.iter().all(|&v| (800.0..=1600.0).contains(&rpm(v))));
    // Braking at 5 N·m: the engine leaves 800 rpm and the run says when.
    let s: Scenario = toml::from_str(&text(-5.0, "[800.0, 1600.0]")).unwrap();
    let e = simulate(&s, &opts, |_| {}).unwrap_err().to_string();
    assert!(
        e.contains("left the scenario's speed range 800–1600 rpm at t = "),
        "{e}"
    );
    for bad in ["[1600.0, 800.0]", "[0.0, 800.0]"] {
        let s: Scenario = toml::from_str(&text(1.0, bad)).unwrap();
        let e = s.validate().unwrap_err().to_string();
        assert!(e.contains("expected 0 < low < high"), "{bad}: {e}");
    }
}

/// The solver's step is held to 0.01–5°: a step of 1e-9° (a typo) would make a run last for
/// ever, one of 6° would leave the valve events unresolved; the error names the range.
#[test]
fn the_solver_step_is_held_to_its_range() {
    for (step, ok) in [
        (1e-9, false),
        (0.001, false),
        (0.01, true),
        (1.0, true),
        (5.0, true),
        (6.0, false),
    ] {
        let mut p = CellParams::default();
        p.set("solver.step_deg", step).unwrap();
        match p.validate() {
            Ok(()) => assert!(ok, "{step}"),
            Err(e) => {
                assert!(!ok, "{step}: {e}");
                assert!(e.to_string().contains("expected 0.01–5°"), "{e}");
            }
        }
    }
}
