//! The pipeline files shipped in `pipelines/` run and meet their objectives against the
//! simulated truth; bad files and models are explained.
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_apps::pipeline::{load_data, run_pipeline, run_pipeline_data, Pipeline};
use std::path::{Path, PathBuf};

fn shipped(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../pipelines")
        .join(name)
}

fn value(r: &physid_apps::pipeline::PipelineResult, name: &str) -> (f64, f64) {
    let j = r.names.iter().position(|n| n == name).unwrap();
    (r.params[j], r.std_err[j].unwrap())
}

#[test]
fn torque_ramp_pipeline_finds_the_heavier_reciprocating_mass() {
    let p = Pipeline::load(&shipped("torque-ramp.toml")).unwrap();
    let rec = load_data(&p.data).unwrap();
    let r = run_pipeline(&p, &rec).unwrap();
    assert!(
        r.estimable.contains(&"M_rec".to_string()),
        "{:?}",
        r.estimable
    );
    assert!(
        r.objective.met && r.objective.value_pct < 1.0,
        "{:?}",
        r.objective
    );
    // The recording's engine has M_rec = 0.84 kg; the rest of the geometry is nominal.
    for (name, truth) in [("M_rec", 0.84), ("b", 0.054), ("L", 0.088)] {
        let (v, se) = value(&r, name);
        // Within 3σ of the truth, and σ itself small: an over-uncertain filter would pass the
        // first test alone (the run gives σ/value of 1e-4, 3e-5 and 2e-4).
        assert!(
            (v - truth).abs() < 3.0 * se && se < 1e-3 * truth,
            "{name}: {v} ± {se} vs {truth}"
        );
    }
}

#[test]
fn shaft_formula_pipeline_with_dsfc_recovers_the_red_spider() {
    let p = Pipeline::load(&shipped("shaft-expr.toml")).unwrap();
    let rec = load_data(&p.data).unwrap();
    let r = run_pipeline(&p, &rec).unwrap();
    assert_eq!(r.method.as_str(), "dsfc");
    assert!(r.objective.met, "{:?}", r.objective);
    let (k, _) = value(&r, "K");
    let (b, _) = value(&r, "B");
    assert!((k - 1340.0).abs() < 0.01 * 1340.0, "K {k}");
    assert!((b - 0.7).abs() < 0.05 * 0.7, "B {b}");
    // The other linear methods through the same model gradient: forgetting with one λ per
    // parameter, and the Kalman filter with R2 from the batch fit.
    for method in ["rlsvf", "kf", "rls", "rlsf"] {
        let mut q = p.clone();
        q.estimator.method = method.parse().unwrap();
        if method == "kf" || method == "rls" {
            q.estimator.lambda = None;
        }
        let r = run_pipeline(&q, &rec).unwrap();
        let (k, _) = value(&r, "K");
        let (b, _) = value(&r, "B");
        assert!((k - 1340.0).abs() < 0.01 * 1340.0, "{method}: K {k}");
        assert!((b - 0.7).abs() < 0.05 * 0.7, "{method}: B {b}");
    }
}

/// The error of a pipeline that must fail (without printing its result when it does not).
fn error_of(p: &Pipeline) -> String {
    match run_pipeline(p, &load_data(&p.data).unwrap()) {
        Ok(r) => panic!("expected an error, got estimable {:?}", r.estimable),
        Err(e) => e.to_string(),
    }
}

#[test]
fn an_unmet_objective_and_bad_pipelines_are_reported() {
    let base = Path::new(".");
    let text = |model: &str, method: &str, limit: f64| {
        format!(
            "[model]\n{model}\noutput = \"torque_shaft\"\n[data]\nscenario = \"shaft-steady\"\nduration = 2.0\nrate_hz = 2000.0\n[estimator]\nmethod = \"{method}\"\n[objective]\nprediction_within_pct = {limit}\n"
        )
    };
    let linear = "expr = \"K*(theta_dy - theta_en) + B*(omega_dy - omega_en)\"\nparams = { K = 1250.0, B = 0.95 }";
    // A limit no model meets.
    let p = Pipeline::parse(&text(linear, "rls", 1e-6), base).unwrap();
    let r = run_pipeline(&p, &load_data(&p.data).unwrap()).unwrap();
    assert!(!r.objective.met && r.objective.value_pct > 1e-6);
    // A linear method on a model that is not linear in its parameters.
    let nonlinear = "expr = \"K^2*(theta_dy - theta_en) + B*(omega_dy - omega_en)\"\nparams = { K = 35.0, B = 0.95 }";
    let p = Pipeline::parse(&text(nonlinear, "dsfc", 5.0), base).unwrap();
    let e = error_of(&p);
    assert!(e.contains("not linear in its parameters"), "{e}");
    // Units and meanings for the report name parameters of the model.
    let misnamed = "expr = \"K*(theta_dy - theta_en) + B*(omega_dy - omega_en)\"\nparams = { K = 1250.0, B = 0.95 }\nunits = { K = \"N·m/rad\", Q = \"m\" }";
    let p = Pipeline::parse(&text(misnamed, "dsfc", 5.0), base).unwrap();
    let e = error_of(&p);
    assert!(
        e.contains("model.units: 'Q' is not a parameter; the parameters are B, K"),
        "{e}"
    );
    // Unknown keys, methods, channels.
    let e = Pipeline::parse(
        "[model]\nbuiltin = \"shaft\"\noutput = \"y\"\nmodle = 1\n[data]\n",
        base,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("modle"), "{e}");
    // A misspelt method is refused when the file is read, before anything runs.
    let e = Pipeline::parse(&text(linear, "lms", 5.0), base)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("method = \"lms\"")
            && e.contains(
                "unknown variant `lms`, expected one of `rls`, `rlsf`, `rlsvf`, `kf`, `dsfc`, `ekf`, `ukf`, `srukf`"
            ),
        "{e}"
    );
    let p = Pipeline::parse(&text("builtin = \"cyclic-torque\"", "ukf", 5.0), base).unwrap();
    let e = error_of(&p);
    assert!(e.contains("model input 'theta'"), "{e}");
    let e = Pipeline::parse(
        "[model]\nbuiltin = \"shaft\"\noutput = \"y\"\n[data]\n",
        base,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("data: give file"), "{e}");
}

#[test]
fn settings_without_a_valid_value_or_a_use_are_refused_naming_the_key() {
    let base = Path::new(".");
    let model = "[model]\nexpr = \"K*(theta_dy - theta_en)\"\nparams = { K = 1250.0 }\noutput = \"torque_shaft\"\n";
    let cases = [
        (
            "[data]\nscenario = \"shaft-steady\"\nbasis = \"sideways\"\n",
            "",
            "unknown variant `sideways`, expected `crank` or `time`",
        ),
        (
            "[data]\nfile = \"x.csv\"\nrate_hz = 2000.0\n",
            "",
            "data.rate_hz applies to a simulated scenario",
        ),
        (
            "[data]\nfile = \"x.csv\"\nduration = 2.0\n",
            "",
            "data.duration applies to a simulated scenario",
        ),
        (
            "[data]\nscenario = \"shaft-steady\"\nbasis = \"crank\"\nrate_hz = 2000.0\n",
            "",
            "data.rate_hz: a crank-angle basis",
        ),
        (
            "[data]\nscenario = \"shaft-steady\"\nduration = -1.0\n",
            "",
            "data.duration = -1",
        ),
        (
            "[data]\nscenario = \"shaft-steady\"\nfile = \"x.csv\"\n",
            "",
            "both file and scenario",
        ),
        (
            "[data]\nscenario = \"shaft-steady\"\n",
            "[estimator]\nmethod = \"dsfc\"\nr2 = nan\n",
            "estimator.r2 is the Kalman filters' noise variance: dsfc does not use it",
        ),
        (
            "[data]\nscenario = \"shaft-steady\"\n",
            "[estimator]\nmethod = \"ukf\"\nr2 = nan\n",
            "estimator.r2 = NaN",
        ),
        (
            "[data]\nscenario = \"shaft-steady\"\n",
            "[estimator]\nmethod = \"rls\"\nlambda = 0.98\n",
            "estimator.lambda: rls does not forget",
        ),
        (
            "[data]\nscenario = \"shaft-steady\"\n",
            "[estimator]\nmethod = \"dsfc\"\nlambda = 1.5\n",
            "estimator.lambda = 1.5",
        ),
        (
            "[data]\nscenario = \"shaft-steady\"\n",
            "[objective]\nafter_s = -1.0\n",
            "objective.after_s = -1",
        ),
        (
            "[data]\nscenario = \"shaft-steady\"\n",
            "[objective]\nmetric = \"rms\"\n",
            "unknown variant `rms`, expected `nrmse` or `max_relative`",
        ),
        (
            "[data]\nscenario = \"shaft-steady\"\n",
            "[identifiability]\nscaling = \"log\"\n",
            "unknown variant `log`, expected one of `thesis`, `sigma`, `none`",
        ),
    ];
    let cases = cases.into_iter().chain([(
        "[data]\nscenario = \"shaft-steady\"\n",
        "[identifiability]\ncutoff = \"rel:-1\"\n",
        "cut-off 'rel:-1': expected repeat, wu, rel:FRACTION or an absolute residual ≥ 0",
    )]);
    for (data, rest, want) in cases {
        let e = Pipeline::parse(&format!("{model}{data}{rest}"), base)
            .unwrap_err()
            .to_string();
        assert!(e.contains(want), "{data}{rest}: {e}");
    }
    let both = "[model]\nbuiltin = \"shaft\"\nexpr = \"K*x\"\noutput = \"y\"\n[data]\nscenario = \"shaft-steady\"\n";
    assert!(Pipeline::parse(both, base)
        .unwrap_err()
        .to_string()
        .contains("both builtin and expr"));
    // Every parameter fixed: refused naming the key, not an index panic.
    let fixed = format!("{model}fixed = [\"K\"]\n[data]\nscenario = \"shaft-steady\"\nduration = 1.0\n[estimator]\nmethod = \"rls\"\n");
    let p = Pipeline::parse(&fixed, base).unwrap();
    let e = error_of(&p);
    assert!(e.contains("model.fixed fixes every parameter (K)"), "{e}");
    // An objective judged after the data's end is said to have nothing to judge (it was "not
    // met, nrmse NaN %").
    let late = format!("{model}[data]\nscenario = \"shaft-steady\"\nduration = 1.0\nrate_hz = 2000.0\n[estimator]\nmethod = \"rls\"\n[objective]\nafter_s = 100.0\n");
    let p = Pipeline::parse(&late, base).unwrap();
    let e = error_of(&p);
    assert!(
        e.contains("objective.after_s = 100 s: no prediction to judge after it — the data span 1"),
        "{e}"
    );
    // A recording that cannot fit is refused before the run.
    let huge = format!("{model}[data]\nscenario = \"shaft-steady\"\nduration = 1e308\n");
    let p = Pipeline::parse(&huge, base).unwrap();
    let e = load_data(&p.data).unwrap_err().to_string();
    assert!(e.contains("would not fit in any memory"), "{e}");
}

/// A pipeline over a file reads only the channels the run takes — the model's inputs (through
/// `model.inputs`), its output and the time — and answers as on the whole recording.
#[test]
fn a_pipeline_over_a_file_reads_only_its_channels() {
    let dir = physid_testkit::Scratch::new("physid-pipeline-file");
    let file = dir.file("t01.parquet");
    let mut scenario = Pipeline::load(&shipped("shaft-expr.toml")).unwrap();
    // Longer than a reader's chunk, several times.
    scenario.data.rate_hz = Some(20_000.0);
    let rec = load_data(&scenario.data).unwrap();
    assert!(rec.channels().len() > 30);
    assert!(rec.len() > 3 * physid_io::CHUNK_ROWS);
    physid_io::write(&file, &rec, &Default::default()).unwrap();
    let text = std::fs::read_to_string(shipped("shaft-expr.toml"))
        .unwrap()
        .replace(
            "scenario = \"shaft-steady\"",
            &format!("file = {:?}", file.to_str().unwrap()),
        )
        .lines()
        .filter(|l| {
            !["duration", "basis", "rate_hz", "set"]
                .iter()
                .any(|k| l.starts_with(k))
        })
        .collect::<Vec<_>>()
        .join("\n");
    let p = Pipeline::parse(&text, Path::new(".")).unwrap();
    // Only the run's channels are read; the file is gone over in passes, held or read again
    // on each, and the result is the one on the whole recording in memory.
    let whole = run_pipeline(&p, &physid_io::read(&file, &Default::default()).unwrap()).unwrap();
    for hold in [usize::MAX, 0] {
        let (r, read) = run_pipeline_data(&p, hold).unwrap();
        assert_eq!(
            read.names(),
            [
                "theta_dy",
                "theta_en",
                "omega_dy",
                "omega_en",
                "torque_shaft",
                "t"
            ],
            "hold {hold}"
        );
        assert_eq!(r.params, whole.params, "hold {hold}");
        assert_eq!(r.std_err, whole.std_err, "hold {hold}");
        assert_eq!(r.ranking, whole.ranking, "hold {hold}");
        assert_eq!(r.t, whole.t, "hold {hold}");
        assert_eq!(r.predicted, whole.predicted, "hold {hold}");
        assert_eq!(r.tracks, whole.tracks, "hold {hold}");
        assert_eq!(
            r.objective.value_pct.to_bits(),
            whole.objective.value_pct.to_bits(),
            "hold {hold}"
        );
    }
}
