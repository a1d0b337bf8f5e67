//! Application 2 on the virtual test cell (issue 8): the `friction-sweep` scenario, whose engine
//! has 0.45 of the nominal model's mechanical friction, characterised from cycle means —
//! identifiability of c1 … c20 (thesis Table 7.3), DSFC on the estimable subset from the
//! nominal values, prediction within ±5 % of the simulated friction after the start-up
//! transient. The stage's friction model on a stream against sympy's (no simulator).
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_apps::friction_fit::{cycle_means, friction_fit, FrictionFitConfig};
use physid_core::Recording;
use physid_sim::engine::Engine;
use physid_sim::params::CellParams;
use physid_sim::run::{simulate, OutputBasis, RunOptions};
use physid_sim::scenario::named;

fn sweep(seconds: Option<f64>, basis: OutputBasis) -> Recording {
    let s = named("friction-sweep").unwrap();
    let opts = RunOptions {
        duration: seconds,
        basis,
        ..Default::default()
    };
    simulate(&s, &opts, |_| {}).unwrap()
}

fn config() -> FrictionFitConfig {
    let p = CellParams::default();
    let (d, st) = Engine::new(&p.engine, &p.ambient).friction_model();
    FrictionFitConfig::new(d, st)
}

/// The thesis's estimable set (Table 7.3), in every one of its four tests.
const THESIS_SET: [&str; 6] = ["c1", "c4", "c5", "c7", "c17", "c19"];

fn top_six(r: &physid_apps::friction_fit::FrictionFit) -> Vec<String> {
    let mut v: Vec<String> = r.ranking[..6].iter().map(|row| row.param.clone()).collect();
    v.sort_by_key(|p| p[1..].parse::<u32>().unwrap());
    v
}

/// The largest |error| [%] of the one-step predictions after `transient_s`, against the
/// simulated friction — each used cycle's mean of
/// `true_torque_friction − true_torque_indicated + true_torque_reciprocating`, averaged here
/// from the recording's samples — and against the measured cycle means.
fn errors_after_transient(
    rec: &Recording,
    r: &physid_apps::friction_fit::FrictionFit,
    transient_s: f64,
) -> (f64, f64) {
    let cycle = rec.values("cycle").unwrap();
    let [f, i, p] = [
        "true_torque_friction",
        "true_torque_indicated",
        "true_torque_reciprocating",
    ]
    .map(|c| rec.values(c).unwrap());
    let mut sum = std::collections::HashMap::<i64, (f64, usize)>::new();
    for k in 0..cycle.len() {
        let e = sum.entry(cycle[k] as i64).or_default();
        e.0 += f[k] - i[k] + p[k];
        e.1 += 1;
    }
    let t0 = r.data.t_s[0];
    let (mut truth, mut measured) = (0.0f64, 0.0f64);
    for k in 0..r.predicted.len() {
        if r.data.t_s[k] - t0 < transient_s {
            continue;
        }
        let (s, n) = sum[&r.data.cycle[k]];
        let tau = s / n as f64;
        truth = truth.max((100.0 * (r.predicted[k] - tau) / tau).abs());
        let m = r.data.tau_nm[k];
        measured = measured.max((100.0 * (r.predicted[k] - m) / m).abs());
    }
    (truth, measured)
}

#[test]
fn friction_sweep_is_characterised_within_5_percent() {
    let rec = sweep(None, OutputBasis::Crank(1.0));
    let r = friction_fit(&rec, &config()).unwrap();
    // 160 s at 750–1500 rpm: ≈ 1500 cycles, a few skipped at the speed and throttle steps.
    assert!(r.data.len() > 1400, "{} cycles", r.data.len());
    // The cycles skipped as unsteady are exactly the complete cycles of the recording the fit
    // did not use (22 of ≈ 1500), and each starts within 0.7 s of one of the scenario's steps —
    // speed and wide-open throttle at 0, 40, 80, 120 s, the throttle to the ramp's 15° at 5, 45,
    // 85, 125 s: after it while speed and manifold settle, before it where the throttle ramp
    // ends nearly closed and the manifold pressure falls fastest (and a cycle is judged against
    // its neighbours' pressure too). No steady cycle far from a step is lost. (The reference
    // solver, RK4, skips the cycle at 39.36 s, 0.64 s before the step at 40 s, as does ROS2
    // since its crank-angle column; ROS2 without it kept that cycle.)
    let (t, cycle) = (rec.values("t").unwrap(), rec.values("cycle").unwrap());
    let mut starts = std::collections::BTreeMap::<i64, f64>::new();
    for k in 0..t.len() {
        starts.entry(cycle[k] as i64).or_insert(t[k]);
    }
    // The first and the last cycle of the recording may be partial.
    let complete: Vec<(i64, f64)> = starts.iter().map(|(&c, &t)| (c, t)).collect();
    let complete = &complete[1..complete.len() - 1];
    let skipped: Vec<(i64, f64)> = complete
        .iter()
        .copied()
        .filter(|(c, _)| !r.data.cycle.contains(c))
        .collect();
    assert_eq!(skipped.len(), r.data.skipped_unsteady, "{skipped:?}");
    assert!(!skipped.is_empty());
    let steps = [0.0, 5.0, 40.0, 45.0, 80.0, 85.0, 120.0, 125.0];
    for (c, t0) in &skipped {
        assert!(
            steps.iter().any(|s| (t0 - s).abs() < 0.7),
            "cycle {c} at {t0:.2} s skipped, away from every step"
        );
    }
    // Table 7.3: the six most estimable coefficients are the thesis's.
    assert_eq!(top_six(&r), THESIS_SET);
    for p in THESIS_SET {
        assert!(r.estimable.iter().any(|e| e == p), "{p} not estimable");
    }
    // The uncalibrated model over-predicts: the engine has 0.45 of its *mechanical* friction,
    // and pumping is not scaled, so nominal / measured = (M + P) / (0.45·M + P′) — not 1/0.45 —
    // with M, P the nominal model's mechanical and pumping torque at the first cycle's
    // operating point (its fmep components, Eq. 3.44–3.50, evaluated here) and P′ the pumping
    // the cell's gas exchange simulated (the cycle mean of −true_torque_indicated).
    let (m, pumping) = {
        let c = config();
        let op = physid_models::friction::OperatingPoint {
            n_rpm: r.data.n_rpm[0],
            p_int_kpa: r.data.p_int_kpa[0],
            p_atm_kpa: r.data.p_atm_kpa[0],
            t_oil_c: r.data.t_oil_c[0],
        };
        let f = physid_models::friction::fmep(&c.design, &c.settings, &op);
        let tau = |kpa| physid_models::friction::tau_nm(kpa, &c.design);
        (tau(f.mechanical()), tau(f.pmep))
    };
    let (cycle0, indicated) = (
        rec.values("cycle").unwrap(),
        rec.values("true_torque_indicated").unwrap(),
    );
    let at0: Vec<usize> = (0..cycle0.len())
        .filter(|&k| cycle0[k] as i64 == r.data.cycle[0])
        .collect();
    let simulated_pumping = -at0.iter().map(|&k| indicated[k]).sum::<f64>() / at0.len() as f64;
    let expected = (m + pumping) / (0.45 * m + simulated_pumping);
    let over = r.predicted_nominal[0] / r.data.tau_nm[0];
    assert!(
        (over / expected - 1.0).abs() < 0.01,
        "nominal / measured = {over}, expected (M + P)/(0.45·M + P′) = {expected} (M {m}, P {pumping}, P′ {simulated_pumping} N·m)"
    );
    // After the 5 s start-up transient, the prediction is within ±5 % of the simulated
    // friction and of the measured cycle means — computed here from the predictions and the
    // recording's own truth channels, and equal to what the application reports.
    let (truth, measured) = errors_after_transient(&rec, &r, config().transient_s);
    assert!(truth < 5.0, "max error against the truth {truth:.2} %");
    assert!(
        measured < 5.0,
        "max error against the cycle means {measured:.2} %"
    );
    assert!((r.max_truth_error_after_transient_pct.unwrap() - truth).abs() < 1e-9);
    assert!((r.max_error_after_transient_pct - measured).abs() < 1e-9);
    let last = r.predicted.len() - 1;
    let final_error = 100.0 * (r.predicted[last] / r.data.tau_nm[last] - 1.0);
    assert!(final_error.abs() < 2.0, "{final_error}");
    // NMSE (Eq. 6.4) of the final coefficients' predictions, computed here: a hundred times
    // smaller than the nominal model's.
    let nmse = |pred: &[f64]| {
        let y = &r.data.tau_nm;
        let n = y.len() as f64;
        let mse = y
            .iter()
            .zip(pred)
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f64>()
            / n;
        mse / (y.iter().sum::<f64>() / n * (pred.iter().sum::<f64>() / n))
    };
    assert!(nmse(&r.predicted_final) < nmse(&r.predicted_nominal) / 100.0);
    // Standard errors for the estimated coefficients only.
    for (j, se) in r.std_err.iter().enumerate() {
        let name = format!("c{}", j + 1);
        assert_eq!(se.is_some(), r.estimable.contains(&name), "{name}");
        if se.is_none() {
            assert_eq!(r.params[j], r.nominal[j]);
        }
    }
}

#[test]
fn each_test_alone_ranks_the_thesis_six_first() {
    // Test 1 (750 rpm) alone, as the thesis analysed each test.
    let rec = sweep(Some(40.0), OutputBasis::Crank(1.0));
    let r = friction_fit(&rec, &config()).unwrap();
    assert_eq!(top_six(&r), THESIS_SET);
    let (truth, _) = errors_after_transient(&rec, &r, config().transient_s);
    assert!(truth < 5.0, "{truth}");
}

#[test]
fn time_basis_recordings_give_the_same_cycle_means() {
    // The encoder/TDC conversion path against the simulator's own crank-angle output.
    let cfg = config();
    let crank = cycle_means(&sweep(Some(4.0), OutputBasis::Crank(1.0)), &cfg).unwrap();
    let time = cycle_means(&sweep(Some(4.0), OutputBasis::Time(10_000.0)), &cfg).unwrap();
    assert!(crank.len() > 20 && time.len() + 2 >= crank.len());
    let off = crank
        .cycle
        .iter()
        .position(|&c| c == time.cycle[0])
        .unwrap();
    for k in 0..time.len().min(crank.len() - off) {
        let (a, b) = (time.tau_nm[k], crank.tau_nm[k + off]);
        assert!((a - b).abs() < 0.02 * b.abs(), "cycle {k}: {a} vs {b}");
        assert!((time.n_rpm[k] - crank.n_rpm[k + off]).abs() < 1.0);
    }
}

#[test]
fn bad_recordings_are_explained() {
    let mut rec = sweep(Some(1.0), OutputBasis::Crank(1.0));
    let e = friction_fit(&rec, &config()).unwrap_err().to_string();
    assert!(
        e.contains("steady cycles") && e.contains("at least 20"),
        "{e}"
    );
    let mut cfg = config();
    cfg.source = physid_apps::friction_fit::TorqueSource::parse("shaft").unwrap();
    // A NaN (a sensor's dropout) leaves out the cycle it cuts; the others are as before.
    let clean = cycle_means(&rec, &cfg).unwrap();
    let n = rec.len();
    let cut = rec.values("cycle").unwrap()[n / 2] as i64;
    let mut v = rec.values("p_int").unwrap().to_vec();
    v[n / 2] = f64::NAN;
    rec.replace_values("p_int", v).unwrap();
    let got = cycle_means(&rec, &cfg).unwrap();
    let k = clean.cycle.iter().position(|&c| c == cut).unwrap();
    assert_eq!(got.len() + 1, clean.len());
    assert!(!got.cycle.contains(&cut));
    for (j, c) in got.cycle.iter().enumerate() {
        let i = if j < k { j } else { j + 1 };
        assert_eq!(*c, clean.cycle[i]);
        assert_eq!(got.inputs(j), clean.inputs(i));
        assert_eq!(got.tau_nm[j], clean.tau_nm[i]);
    }
}

/// The file verb is the stage over the file: streaming a time-basis recording through a
/// [`FrictionStage`] in chunks of 1, 17, 4096 samples or whole gives the file verb's result
/// bit for bit, its per-cycle outputs are the result's predictions, and a stage that chooses
/// its coefficients live — once it has seen as many steady cycles as the file holds — chooses
/// the same ones and predicts the same.
#[test]
fn the_stage_on_a_stream_is_the_file_verb() {
    use physid_apps::acquisition::{marker_tdc_angle, AcquisitionOptions};
    use physid_apps::friction_fit::{FrictionOutput, FrictionStage};
    use physid_apps::stage::Stage;
    let rec = sweep(Some(8.0), OutputBasis::Time(10_000.0));
    let cfg = config();
    let file = friction_fit(&rec, &cfg).unwrap();
    assert!(file.data.len() >= 40, "{} cycles", file.data.len());
    let run = |chunk: usize, select_after: Option<usize>| {
        let mut stage = FrictionStage::new(cfg.clone(), select_after).unwrap();
        // Cycles from the first TDC marker, as the file verb takes them.
        let tdc = marker_tdc_angle(&rec, &AcquisitionOptions::default()).unwrap();
        stage.set_theta_tdc(tdc).unwrap();
        let mut out = Vec::new();
        let n = rec.len();
        for start in (0..n).step_by(chunk) {
            stage
                .push(&rec.slice(start..(start + chunk).min(n)), &mut out)
                .unwrap();
        }
        let fit = stage.fit(&mut out).unwrap();
        (fit, out)
    };
    for chunk in [1, 17, 4096, rec.len()] {
        let (fit, out) = run(chunk, None);
        assert_eq!(fit.data.cycle, file.data.cycle, "chunk {chunk}");
        assert_eq!(fit.data.tau_nm, file.data.tau_nm, "chunk {chunk}");
        assert_eq!(fit.estimable, file.estimable, "chunk {chunk}");
        assert_eq!(fit.params, file.params, "chunk {chunk}");
        assert_eq!(fit.predicted, file.predicted, "chunk {chunk}");
        let predicted: Vec<f64> = out
            .iter()
            .filter_map(|o| match o {
                FrictionOutput::Cycle(s) => Some(s.predicted_nm),
                FrictionOutput::Selected { .. } | FrictionOutput::Dropout(_) => None,
            })
            .collect();
        assert_eq!(predicted, file.predicted);
        // The choice comes first, once, over all the steady cycles.
        assert!(
            matches!(&out[0], FrictionOutput::Selected { cycles, .. } if *cycles == file.data.len())
        );
    }
    let (live, out) = run(4096, Some(file.data.len()));
    assert_eq!(live.estimable, file.estimable);
    assert_eq!(live.predicted, file.predicted);
    assert_eq!(
        out.iter()
            .filter(|o| matches!(o, FrictionOutput::Selected { .. }))
            .count(),
        1
    );
    // Chosen early, on the first 20 steady cycles: every later cycle is predicted as it comes.
    let (early, out) = run(4096, Some(20));
    assert!(matches!(
        &out[0],
        FrictionOutput::Selected { cycles: 20, .. }
    ));
    assert_eq!(early.predicted.len(), file.data.len());
    assert_eq!(early.data.tau_nm, file.data.tau_nm);
}

/// A crank-angle recording read a chunk at a time (friction_fit_cycles, `physid friction fit`
/// on such a file) gives the whole recording's fit for every chunking; its cycle means are the
/// plain means over each complete cycle, computed here on their own.
#[test]
fn a_crank_angle_recording_in_chunks_is_the_whole_one() {
    use physid_apps::friction_fit::friction_fit_cycles;
    let rec = sweep(Some(6.0), OutputBasis::Crank(1.0));
    let cfg = config();
    let whole = friction_fit(&rec, &cfg).unwrap();
    assert!(whole.data.len() >= 30, "{} cycles", whole.data.len());
    for chunk in [1, 17, 1000, rec.len()] {
        let n = rec.len();
        let chunks = (0..n)
            .step_by(chunk)
            .map(|s| Ok::<_, physid_apps::error::AppError>(rec.slice(s..(s + chunk).min(n))));
        let fit = friction_fit_cycles(chunks, &cfg).unwrap();
        assert_eq!(fit.data.cycle, whole.data.cycle, "chunk {chunk}");
        assert_eq!(fit.data.tau_nm, whole.data.tau_nm, "chunk {chunk}");
        assert_eq!(fit.data.n_rpm, whole.data.n_rpm, "chunk {chunk}");
        assert_eq!(fit.data.truth_nm, whole.data.truth_nm, "chunk {chunk}");
        assert_eq!(fit.params, whole.params, "chunk {chunk}");
        assert_eq!(fit.predicted, whole.predicted, "chunk {chunk}");
    }
    // The means, independently: each cycle's samples (720 at 1°), the engine's load cell
    // torque negated.
    let (cycle, tau) = (
        rec.values("cycle").unwrap(),
        rec.values("torque_engine").unwrap(),
    );
    for (k, &c) in whole.data.cycle.iter().enumerate() {
        let samples: Vec<f64> = cycle
            .iter()
            .zip(tau)
            .filter(|(cc, _)| **cc == c as f64)
            .map(|(_, t)| *t)
            .collect();
        assert_eq!(samples.len(), 720);
        let mean = -samples.iter().sum::<f64>() / 720.0;
        assert!(
            (mean - whole.data.tau_nm[k]).abs() <= 1e-12 * mean.abs(),
            "cycle {c}: {mean} against {}",
            whole.data.tau_nm[k]
        );
    }
}

/// The stage's friction model against sympy's, on a stream (independent of physid: SPEC §2.5
/// written out and evaluated to 30 digits by `golden/gen_friction_rank.py`, the thesis preset):
/// 12 motored cycles at each of the golden file's 27 operating points (1000–5000 rpm, manifold
/// 10–100 kPa, oil 20–90 °C), the motoring torque −τ_sympy, in chunks of one operating point.
/// Every steady cycle's nominal prediction is sympy's τ to 1e-12 (measured: 1.2e-14); the data
/// are the nominal model, so the estimates stay at the nominal values and the one-step
/// prediction is sympy's τ to 1e-10 (measured: 4e-14). Of each point's 12 cycles, the one next
/// to a change of manifold pressure is not steady: 10 or 11 are judged.
#[test]
fn the_stage_s_friction_model_is_sympy_s() {
    use physid_apps::friction_fit::{FrictionOutput, FrictionStage};
    use physid_apps::stage::Stage;
    use physid_core::{Basis, Channel};
    use physid_models::friction::thesis_preset;
    use std::f64::consts::PI;
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/golden/friction_rank.json"
    ))
    .unwrap();
    let golden: serde_json::Value = serde_json::from_str(&text).unwrap();
    let p_atm_kpa = golden["p_atm_kpa"].as_f64().unwrap();
    let (d, st) = thesis_preset();
    let mut stage = FrictionStage::new(FrictionFitConfig::new(d, st), Some(20)).unwrap();
    let mut out = Vec::new();
    // Each operating point: its start time [s] and sympy's torque [N·m].
    let mut spans: Vec<(f64, f64)> = Vec::new();
    let (cycles, per_cycle) = (12, 180);
    let step = 4.0 * PI / per_cycle as f64;
    let (mut t0, mut theta0) = (0.0, 0.0);
    for point in golden["tests"].as_array().unwrap() {
        let at = |k: &str| point[k].as_f64().unwrap();
        let (n_rpm, tau) = (at("n_rpm"), at("tau_nm"));
        let w = n_rpm * PI / 30.0;
        let n = cycles * per_cycle;
        let t: Vec<f64> = (0..n).map(|k| t0 + k as f64 * step / w).collect();
        let theta: Vec<f64> = (0..n).map(|k| theta0 + k as f64 * step).collect();
        let mut r = Recording::new(Basis::Time);
        for (name, unit, values) in [
            ("t", "s", t),
            ("theta_en", "rad", theta),
            ("omega_en", "rad/s", vec![w; n]),
            ("p_int", "Pa", vec![at("p_int_kpa") * 1e3; n]),
            ("p_atm", "Pa", vec![p_atm_kpa * 1e3; n]),
            ("T_oil", "K", vec![at("t_oil_c") + 273.15; n]),
            ("torque_engine", "N*m", vec![-tau; n]),
        ] {
            r.push(Channel {
                name: name.into(),
                unit: unit.into(),
                values,
            })
            .unwrap();
        }
        stage.push(&r, &mut out).unwrap();
        spans.push((t0, tau));
        t0 += n as f64 * step / w;
        theta0 += n as f64 * step;
    }
    stage.finish(&mut out).unwrap();
    let mut seen = vec![0; spans.len()];
    for o in &out {
        let FrictionOutput::Cycle(s) = o else {
            continue;
        };
        let j = spans
            .iter()
            .rposition(|(start, _)| *start <= s.t_s + 1e-9)
            .unwrap();
        let tau = spans[j].1;
        seen[j] += 1;
        assert!(
            (s.nominal_nm / tau - 1.0).abs() < 1e-12,
            "cycle {} (point {j}): nominal {} N·m, sympy's {tau}",
            s.cycle,
            s.nominal_nm
        );
        assert!(
            (s.measured_nm / tau - 1.0).abs() < 1e-12,
            "cycle {}: measured {}",
            s.cycle,
            s.measured_nm
        );
        assert!(
            (s.predicted_nm / tau - 1.0).abs() < 1e-10,
            "cycle {} (point {j}): predicted {} N·m, sympy's {tau}",
            s.cycle,
            s.predicted_nm
        );
    }
    assert!(
        seen.iter().all(|&k| k >= 10),
        "steady cycles per operating point: {seen:?}"
    );
}
