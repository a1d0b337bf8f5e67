//! `physid friction`: the mean-value friction model (SPEC §2.5) — `eval` at an operating point,
//! `rank` of its design parameters over an operating grid (thesis §7.2, Table 7.1, Fig. 7.1),
//! `fit` of its regression coefficients to a motored recording (thesis §7.3, Application 2).

use super::crank_input::crank_input;
use super::inspect::AngleArgs;
use super::CrankArgs;
use crate::out::outln;
use crate::plot::{self, Panel, Series, PALETTE};
use crate::progress::Reading;
use crate::report::{self, Report};
use miette::{miette, Result};
use physid_apps::friction_fit::{
    self, friction_fit, friction_fit_stream, friction_preset, FrictionCycles, FrictionFit,
    FrictionFitConfig, TorqueSource, FRICTION_PRESETS, OBJECTIVE_PCT,
};
use physid_apps::friction_rank::{friction_rank, RankGrid, RankTable};
use physid_ident::Selection;
use physid_models::friction::{
    fmep, set_by_name, tau_nm, Design, OperatingPoint, Settings, REGRESSION_DESCRIPTIONS,
    REGRESSION_PARAMS, REGRESSION_UNITS,
};
use std::path::{Path, PathBuf};

/// Arguments of `physid friction`.
#[derive(clap::Args)]
pub struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(clap::Subcommand)]
enum Command {
    /// fmep by component [kPa] and the friction torque [N·m] at one operating point.
    ///
    /// Example: physid friction eval --n 1000 --p-int 100 --t-oil 35 --json
    Eval(EvalArgs),
    /// Rank the design parameters by the normalised sensitivity of the friction torque at each
    /// point of an operating grid (default: the thesis's 3³ design, 27 tests).
    ///
    /// Example: physid friction rank --out rank   (table, rank.svg heat map)
    Rank(RankArgs),
    /// Characterise the engine's friction from a motored recording (thesis §7.3): cycle-mean
    /// motoring torque, identifiability of the regression coefficients c1 … c20, DSFC on the
    /// estimable ones, prediction error over time.
    ///
    /// Example: physid friction fit --data sweep.parquet --preset cell --out fit
    Fit(FitArgs),
}

/// The model: preset and overrides.
#[derive(clap::Args)]
struct ModelArgs {
    /// Model preset: thesis (the thesis's code), sandoval2002 (the original model) or cell (the
    /// built-in virtual test cell's engine: its geometry with the thesis's oil and valvetrain).
    #[arg(long, default_value = "thesis")]
    preset: String,
    /// Override a design parameter (B, S, kappa, Di, De, Lv, Db, Lb, r — mm) or a setting
    /// (oil, valvetrain, ft_fto, cr, nc, nv, nb); repeatable, e.g. --set B=56 --set oil=SAE30.
    #[arg(long = "set", value_name = "NAME=VALUE")]
    set: Vec<String>,
}

impl ModelArgs {
    fn build(&self) -> Result<(Design<f64>, Settings)> {
        let (mut d, mut st) = friction_preset(&self.preset).ok_or_else(|| {
            miette!(
                "no friction preset '{}'; the presets are {}",
                self.preset,
                FRICTION_PRESETS.join(", ")
            )
        })?;
        for s in &self.set {
            let (name, value) = s
                .split_once('=')
                .ok_or_else(|| miette!("--set {s}: expected NAME=VALUE, e.g. --set B=56"))?;
            set_by_name(&mut d, &mut st, name.trim(), value).map_err(|e| miette!("--set {e}"))?;
        }
        Ok((d, st))
    }
}

#[derive(clap::Args)]
struct EvalArgs {
    /// Engine speed [rpm].
    #[arg(long, value_parser = super::range::rpm, allow_negative_numbers = true)]
    n: f64,
    /// Intake manifold pressure [kPa].
    #[arg(long, value_parser = super::range::kpa, allow_negative_numbers = true)]
    p_int: f64,
    /// Oil temperature [°C].
    #[arg(long, value_parser = super::range::celsius, allow_negative_numbers = true)]
    t_oil: f64,
    /// Ambient pressure [kPa] (the thesis code's 101 kPa).
    #[arg(long, value_name = "KPA", default_value_t = 101.0, value_parser = super::range::kpa, allow_negative_numbers = true)]
    p_atm: f64,
    #[command(flatten)]
    model: ModelArgs,
    /// Print JSON: {"fmep_kpa": {cfmep, rfmep, vfmep, afmep, pmep, total}, "tau_fri_nm"}.
    #[arg(long)]
    json: bool,
}

#[derive(clap::Args)]
struct RankArgs {
    /// Engine speeds of the grid [rpm].
    #[arg(long, value_delimiter = ',', default_values_t = [1000.0, 3000.0, 5000.0], value_parser = super::range::rpm, allow_negative_numbers = true)]
    n: Vec<f64>,
    /// Intake manifold pressures of the grid [kPa].
    #[arg(long, value_delimiter = ',', default_values_t = [10.0, 55.0, 100.0], value_parser = super::range::kpa, allow_negative_numbers = true)]
    p_int: Vec<f64>,
    /// Oil temperatures of the grid [°C].
    #[arg(long, value_delimiter = ',', default_values_t = [20.0, 55.0, 90.0], value_parser = super::range::celsius, allow_negative_numbers = true)]
    t_oil: Vec<f64>,
    /// Ambient pressure [kPa].
    #[arg(long, value_name = "KPA", default_value_t = 101.0, value_parser = super::range::kpa, allow_negative_numbers = true)]
    p_atm: f64,
    /// The parameters to rank (the others held) [default: B,S,kappa,Di,De,Lv,Db,Lb,r].
    #[arg(long, value_name = "NAME,…", value_delimiter = ',')]
    free: Vec<String>,
    /// Deprecated: --free (--params gives parameter values in the other verbs).
    #[arg(
        long = "params",
        hide = true,
        value_delimiter = ',',
        conflicts_with = "free"
    )]
    params_old: Vec<String>,
    #[command(flatten)]
    model: ModelArgs,
    /// Print JSON: {"parameters": [...], "tests": [{n_rpm, p_int_kpa, t_oil_c, ranking}]}.
    #[arg(long)]
    json: bool,
    /// Directory for the report: report.html, the heat map rank.svg (like the thesis's Fig. 7.1), rank.json.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
}

#[derive(clap::Args)]
struct FitArgs {
    /// Motored recording: crank-angle basis with `cycle` (or a time basis with the engine
    /// encoder `count_en` and the TDC marker `tdc`), `omega_en`, `p_int`, `T_oil`, `p_atm` and
    /// the torque channel.
    #[arg(long, value_name = "FILE")]
    data: PathBuf,
    #[command(flatten)]
    input: super::InputArgs,
    #[command(flatten)]
    model: ModelArgs,
    /// Motoring torque from the engine load cell (−torque_engine) or the shaft transducer
    /// (+torque_shaft).
    #[arg(long, default_value = "engine")]
    source: String,
    /// How many ranked coefficients to estimate: repeat (the thesis's), wu, rel:FRACTION or an
    /// absolute residual.
    #[arg(long, default_value = "repeat")]
    cutoff: Selection,
    /// Estimate these coefficients (e.g. c4,c17, as a test from `physid design --app friction`
    /// was designed for) instead of the ranked estimable subset; the ranking is still reported.
    #[arg(
        long,
        value_name = "NAME,…",
        value_delimiter = ',',
        conflicts_with = "cutoff"
    )]
    estimate: Vec<String>,
    /// DSFC initial square-root covariance S0 = s0·I, in relative coordinates c = c0·(1 + x).
    #[arg(long, default_value_t = 10.0, value_parser = super::range::positive, allow_negative_numbers = true)]
    s0: f64,
    /// DSFC forgetting factor λ ∈ (0, 1].
    #[arg(long, value_name = "LAMBDA", default_value_t = 1.0, value_parser = super::range::forgetting, allow_negative_numbers = true)]
    lambda: f64,
    /// Start-up transient excluded from the maximum error [s].
    #[arg(long, default_value_t = 5.0, value_parser = super::range::nonnegative, allow_negative_numbers = true)]
    transient: f64,
    /// Ambient pressure [kPa] if the recording has no p_atm channel.
    #[arg(long, value_name = "KPA")]
    p_atm: Option<f64>,
    /// Print JSON: {"estimable", "params", "std_err", "prediction_error_pct": {"final",
    /// "max_after_transient"}, …}.
    #[arg(long)]
    json: bool,
    /// Directory for the report (report.html with its SVGs, friction_fit.json).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Write every steady cycle — its operating point, the measured, one-step predicted,
    /// nominal (and simulated) friction torque, the estimable coefficients and their standard
    /// errors — to this file (.csv, .parquet or .mf4), with units.
    #[arg(long, value_name = "FILE")]
    tracks: Option<PathBuf>,
}

/// Run `physid friction`.
pub fn run(args: &Args) -> Result<()> {
    match &args.command {
        Command::Eval(a) => eval(a),
        Command::Rank(a) => rank(a),
        Command::Fit(a) => fit(a),
    }
}

fn fit(a: &FitArgs) -> Result<()> {
    let (d, st) = a.model.build()?;
    let mut cfg = FrictionFitConfig::new(d, st);
    cfg.source = TorqueSource::parse(&a.source)
        .ok_or_else(|| miette!("--source '{}': expected engine or shaft", a.source))?;
    cfg.selection = a.cutoff;
    cfg.estimate = (!a.estimate.is_empty()).then(|| a.estimate.clone());
    cfg.s0 = a.s0;
    cfg.lambda = a.lambda;
    cfg.transient_s = a.transient;
    cfg.p_atm_kpa = a.p_atm;
    // A time-basis file streams through the stage, a crank-angle one (with `cycle`) through
    // the cycle means, each reading only the channels it takes; a time basis whose angle is an
    // encoder's counts is resampled to 1° as it is read (`CrankInput`), into the cycle means.
    let header = a.input.open_all(&a.data)?.header().clone();
    let r = if friction_fit::streams(&header) {
        let (needed, optional) = friction_fit::sample_channels(&cfg);
        let mut reader = a.input.open(&a.data, &needed, &optional)?;
        let r = friction_fit_stream(Reading::new(&mut reader, &a.data), &cfg);
        super::warn_read(&reader, &a.data);
        r
    } else if header.channel("cycle").is_ok() {
        let (needed, optional) = friction_fit::cycle_channels(&cfg);
        let mut reader = a.input.open(&a.data, &needed, &optional)?;
        let r = friction_fit::friction_fit_cycles(Reading::new(&mut reader, &a.data), &cfg);
        super::warn_read(&reader, &a.data);
        r
    } else if header.basis == physid_core::Basis::Time {
        // The engine angle from an encoder's counts: the crank-angle samples as they are made.
        let (angle, crank) = (AngleArgs::default(), CrankArgs::default());
        let input = crank_input(&a.input, &a.data, &angle, &crank)?;
        let (needed, optional) = friction_fit::cycle_channels(&cfg);
        let made = ["cycle"];
        input
            .require(
                &needed
                    .iter()
                    .filter(|n| !made.contains(n))
                    .copied()
                    .collect::<Vec<_>>(),
            )
            .map_err(super::app_error(&a.data))?;
        let channels: Vec<&str> = needed.into_iter().chain(optional).collect();
        let (cycles, _) = input
            .read(
                Some(&channels),
                |_| Ok(FrictionCycles::new(&cfg)),
                |s, chunk| s.push(chunk),
            )
            .map_err(super::app_error(&a.data))?;
        cycles.fit()
    } else {
        friction_fit(&a.input.read(&a.data, None)?, &cfg)
    }
    .map_err(super::app_error(&a.data))?;
    super::warn_dropouts(&r.dropouts, &a.data);
    if let Some(path) = &a.tracks {
        write_tracks(path, &r)?;
    }
    let j = r.summary();
    if let Some(dir) = &a.out {
        let title = "physid — friction fit";
        report::write(dir, title, &a.data, "friction_fit.json", &j, |rep, dir| {
            fit_report_section(rep, &r, &cfg, dir)
        })?;
    }
    if a.json {
        crate::provenance::print_json(&j)?;
        return Ok(());
    }
    outln!(
        "{}: {} steady cycles ({} skipped as not steady)",
        a.data.display(),
        r.data.len(),
        r.data.skipped_unsteady
    );
    outln!("  estimable: {}", r.estimable.join(", "));
    outln!("  coefficient      nominal        final    change   std error");
    for name in &r.estimable {
        let j = coefficient_index(name);
        outln!(
            "  {:<8} {:>12.4e} {:>12.4e} {:>8.1} % {:>11.3e}",
            name,
            r.nominal[j],
            r.params[j],
            100.0 * (r.params[j] - r.nominal[j]) / r.nominal[j],
            r.std_err[j].unwrap_or(f64::NAN)
        );
    }
    outln!(
        "  prediction error: final {:+.2} %, max after the {} s transient {:.2} %{}",
        r.final_error_pct,
        physid_core::Num(a.transient),
        r.max_error_after_transient_pct,
        r.max_truth_error_after_transient_pct
            .map_or(String::new(), |t| format!(
                " (against the simulated truth {t:.2} %)"
            ))
    );
    outln!(
        "  NMSE (Eq. 6.4): nominal model {:.3e}, fitted {:.3e}",
        r.nmse_nominal,
        r.nmse_final
    );
    if let Some(dir) = &a.out {
        outln!("wrote {}", dir.join("report.html").display());
    }
    Ok(())
}

fn coefficient_index(name: &str) -> usize {
    REGRESSION_PARAMS
        .iter()
        .position(|p| *p == name)
        .unwrap_or(0)
}

/// The friction model's design parameters `names` with their units and meanings, as a table.
pub fn design_table(rep: &mut Report, names: &[String]) {
    let g = report::Glossary {
        names: &physid_models::friction::DESIGN_PARAMS,
        units: &physid_models::friction::DESIGN_UNITS,
        descriptions: &physid_models::friction::DESIGN_DESCRIPTIONS,
    };
    let rows: Vec<Vec<String>> = names
        .iter()
        .map(|n| {
            let (unit, meaning) = g.of(n);
            vec![n.clone(), unit, meaning]
        })
        .collect();
    rep.table(&["parameter", "unit", "meaning"], &rows);
}

/// Write the friction-fit section of a report (and its SVG into `dir`).
pub fn fit_report_section(
    rep: &mut Report,
    r: &FrictionFit,
    cfg: &FrictionFitConfig,
    dir: &Path,
) -> Result<()> {
    rep.section("Engine friction characterisation (thesis §7.3)");
    rep.para(
        &format!(
            "{} steady motored cycles ({} skipped at speed or throttle steps); motoring torque from {}. \
             Identifiability of the regression coefficients c1 … c20 (Alg. 5.1, thesis scaling), then \
             DSFC (λ = {}, S0 = {}·I in relative coordinates) on the estimable ones, the rest fixed at \
             their nominal values.",
            r.data.len(),
            r.data.skipped_unsteady,
            match cfg.source {
                TorqueSource::Engine => "the engine load cell (−torque_engine)",
                TorqueSource::Shaft => "the shaft transducer",
            },
            cfg.lambda,
            cfg.s0
        ),
        None,
    );
    for d in &r.dropouts {
        rep.para(&d.message(), Some("note"));
    }
    let glossary = report::Glossary {
        names: &REGRESSION_PARAMS,
        units: &REGRESSION_UNITS,
        descriptions: &REGRESSION_DESCRIPTIONS,
    };
    rep.ranking(
        &r.ranking,
        glossary,
        "Identifiability of c1 … c20: residual profile (Alg. 5.1)",
        &dir.join("friction_fit_residuals.svg"),
    )?;
    rep.table(
        &[
            "coefficient",
            "unit",
            "meaning",
            "nominal",
            "final",
            "change",
            "std error",
        ],
        &r.estimable
            .iter()
            .map(|n| {
                let j = coefficient_index(n);
                let (unit, meaning) = glossary.of(n);
                vec![
                    n.clone(),
                    unit,
                    meaning,
                    format!("{:.4e}", r.nominal[j]),
                    format!("{:.4e}", r.params[j]),
                    format!(
                        "{:+.1} %",
                        100.0 * (r.params[j] - r.nominal[j]) / r.nominal[j]
                    ),
                    r.std_err[j].map_or("—".into(), |s| format!("{s:.3e}")),
                ]
            })
            .collect::<Vec<_>>(),
    );
    // The headline is what a user has: the error against the measured cycle means; the
    // simulated truth, when the recording carries it, comes second.
    let truth = r.max_truth_error_after_transient_pct.map_or(String::new(), |t| {
        format!(
            " Against the simulated friction (known here, not in a real test): at most {t:.2} %; the ±{} % objective is judged on it, since the measured means carry the sensors' noise.",
            physid_apps::friction_fit::OBJECTIVE_PCT
        )
    });
    rep.para(
        &format!(
            "Prediction error against the measured cycle means after the {} s start-up transient: at most {:.2} % (final {:+.2} %); NMSE {:.3e} (nominal) → {:.3e} (fitted).{truth}",
            cfg.transient_s,
            r.max_error_after_transient_pct,
            r.final_error_pct,
            r.nmse_nominal,
            r.nmse_final
        ),
        Some(if r.objective_met() { "ok" } else { "alarm" }),
    );
    let svg = dir.join("friction_fit.svg");
    let mut torque = vec![
        Series {
            name: "measured".into(),
            x: &r.data.t_s,
            y: &r.data.tau_nm,
            color: PALETTE[1],
            reference: true,
        },
        Series {
            name: "nominal model".into(),
            x: &r.data.t_s,
            y: &r.predicted_nominal,
            color: PALETTE[4],
            reference: false,
        },
        Series {
            name: "predicted (DSFC)".into(),
            x: &r.data.t_s,
            y: &r.predicted,
            color: PALETTE[0],
            reference: false,
        },
    ];
    if let Some(tr) = &r.data.truth_nm {
        torque.push(Series {
            name: "simulated truth".into(),
            x: &r.data.t_s,
            y: tr,
            color: PALETTE[2],
            reference: true,
        });
    }
    let errors = vec![Series {
        name: "prediction error vs measured".into(),
        x: &r.data.t_s,
        y: &r.error_pct,
        color: PALETTE[0],
        reference: false,
    }];
    // The error axis is set by the error after the start-up transient (the estimator's first
    // cycles, from the nominal coefficients, are clipped at the frame) and the objective.
    let t0 = r.data.t_s.first().copied().unwrap_or(0.0);
    let after: Vec<f64> = r
        .data
        .t_s
        .iter()
        .zip(&r.error_pct)
        .filter(|(t, e)| **t - t0 >= cfg.transient_s && e.is_finite())
        .map(|(_, e)| *e)
        .collect();
    let objective = format!("objective ±{OBJECTIVE_PCT} %");
    let error_marks = vec![
        plot::Mark::value(objective.as_str(), OBJECTIVE_PCT, PALETTE[3]),
        plot::Mark::value(objective.as_str(), -OBJECTIVE_PCT, PALETTE[3]),
        plot::Mark::instant(
            "end of start-up transient",
            t0 + cfg.transient_s,
            plot::REFERENCE,
        ),
    ];
    let error_range = (
        after.iter().copied().fold(-OBJECTIVE_PCT, f64::min) * 1.2,
        after.iter().copied().fold(OBJECTIVE_PCT, f64::max) * 1.2,
    );
    let inputs = vec![Series {
        name: "speed [rpm]".into(),
        x: &r.data.t_s,
        y: &r.data.n_rpm,
        color: PALETTE[2],
        reference: false,
    }];
    let p_int = vec![Series {
        name: "manifold pressure [kPa]".into(),
        x: &r.data.t_s,
        y: &r.data.p_int_kpa,
        color: PALETTE[4],
        reference: false,
    }];
    plot::panels(
        &svg,
        "Cycle-mean friction torque: measured and predicted",
        "time [s]",
        &[
            Panel {
                ylabel: "friction torque [N·m]".into(),
                series: torque,
                ..Default::default()
            },
            Panel {
                ylabel: "error [%]".into(),
                series: errors,
                marks: error_marks,
                y_range: Some(error_range),
            },
            Panel {
                ylabel: "N [rpm]".into(),
                series: inputs,
                ..Default::default()
            },
            Panel {
                ylabel: "p_int [kPa]".into(),
                series: p_int,
                ..Default::default()
            },
        ],
    )?;
    rep.svg(&svg)
}

fn eval(a: &EvalArgs) -> Result<()> {
    let (d, st) = a.model.build()?;
    let op = OperatingPoint {
        n_rpm: a.n,
        p_int_kpa: a.p_int,
        p_atm_kpa: a.p_atm,
        t_oil_c: a.t_oil,
    };
    op.validate().map_err(|e| miette!("{e}"))?;
    let f = fmep(&d, &st, &op);
    let tau = tau_nm(f.total(), &d);
    if a.json {
        let j = serde_json::json!({
            "fmep_kpa": {
                "cfmep": f.cfmep, "rfmep": f.rfmep, "vfmep": f.vfmep,
                "afmep": f.afmep, "pmep": f.pmep, "total": f.total(),
            },
            "tau_fri_nm": tau,
        });
        crate::provenance::print_json(&j)?;
        return Ok(());
    }
    outln!(
        "friction ({} preset) at {} rpm, p_int {} kPa, p_atm {} kPa, oil {} °C",
        a.model.preset,
        a.n,
        a.p_int,
        a.p_atm,
        a.t_oil
    );
    outln!("  component          fmep [kPa]");
    for (name, v) in [
        ("crankshaft (cfmep)", f.cfmep),
        ("reciprocating (rfmep)", f.rfmep),
        ("valvetrain (vfmep)", f.vfmep),
        ("auxiliaries (afmep)", f.afmep),
        ("pumping (pmep)", f.pmep),
    ] {
        outln!("  {name:<22}{v:>10.3}");
    }
    outln!("  {:<22}{:>10.3}", "total", f.total());
    outln!(
        "  friction torque      {tau:>10.4} N·m   (without pumping {:.4} N·m)",
        tau_nm(f.mechanical(), &d)
    );
    Ok(())
}

fn rank(a: &RankArgs) -> Result<()> {
    let (d, st) = a.model.build()?;
    let grid = RankGrid {
        n_rpm: a.n.clone(),
        p_int_kpa: a.p_int.clone(),
        t_oil_c: a.t_oil.clone(),
        p_atm_kpa: a.p_atm,
    };
    let working = crate::progress::Working::new("ranking the design parameters over the grid");
    let free = if a.params_old.is_empty() {
        &a.free
    } else {
        super::deprecated("--params NAME,… in friction rank is now --free NAME,…");
        &a.params_old
    };
    let t = friction_rank(&d, &st, &grid, free).map_err(|e| miette!("{e}"))?;
    drop(working);
    if let Some(dir) = &a.out {
        report::create_dir(dir)?;
        let svg = dir.join("rank.svg");
        heatmap(&t, &a.model.preset, &svg)?;
        let mut rep = Report::new(
            "physid — friction design-parameter ranking",
            &format!(
                "Mean-value friction model ({} preset), p_atm {} kPa (thesis §7.2, Table 7.1, Fig. 7.1)",
                a.model.preset, a.p_atm
            ),
        );
        rep.section("Rank of each design parameter (1 = most sensitive)");
        rep.para("By |normalised sensitivity| (ϑ/τ)·∂τ/∂ϑ of the friction torque, exact derivatives, at each operating point.", None);
        let mut header = vec![
            "test",
            "N [rpm]",
            "p_int [kPa]",
            "T_oil [°C]",
            "τ_fri [N·m]",
        ];
        header.extend(t.parameters.iter().map(String::as_str));
        let rows: Vec<Vec<String>> = t
            .tests
            .iter()
            .enumerate()
            .map(|(i, x)| {
                let mut row = vec![
                    (i + 1).to_string(),
                    x.op.n_rpm.to_string(),
                    x.op.p_int_kpa.to_string(),
                    x.op.t_oil_c.to_string(),
                    format!("{:.4}", x.tau_nm),
                ];
                row.extend(x.rank.iter().map(|r| r.to_string()));
                row
            })
            .collect();
        rep.table(&header, &rows);
        rep.svg(&svg)?;
        design_table(&mut rep, &t.parameters);
        report::finish(dir, rep, "rank.json", &t.summary())?;
        if !a.json {
            outln!(
                "wrote {} and {}",
                svg.display(),
                dir.join("report.html").display()
            );
        }
    }
    if a.json {
        crate::provenance::print_json(&t.summary())?;
        return Ok(());
    }
    outln!(
        "Rank of each design parameter by |normalised sensitivity| of the friction torque (1 = most sensitive; {} preset, p_atm {} kPa)",
        a.model.preset,
        a.p_atm
    );
    let mut head = format!(
        "{:>4} {:>6} {:>6} {:>6} {:>8} ",
        "test", "N", "p_int", "T_oil", "τ_fri"
    );
    for p in &t.parameters {
        head.push_str(&format!("{p:>6}"));
    }
    outln!("{head}");
    outln!(
        "{:>4} {:>6} {:>6} {:>6} {:>8}",
        "",
        "rpm",
        "kPa",
        "°C",
        "N·m"
    );
    for (i, x) in t.tests.iter().enumerate() {
        let mut line = format!(
            "{:>4} {:>6} {:>6} {:>6} {:>8.4} ",
            i + 1,
            x.op.n_rpm,
            x.op.p_int_kpa,
            x.op.t_oil_c,
            x.tau_nm
        );
        for r in &x.rank {
            line.push_str(&format!("{r:>6}"));
        }
        outln!("{line}");
    }
    Ok(())
}

/// The heat map of a ranking table (thesis Fig. 7.1) as SVG.
pub fn heatmap(t: &RankTable, preset: &str, path: &std::path::Path) -> Result<()> {
    let rows: Vec<String> = t
        .tests
        .iter()
        .enumerate()
        .map(|(i, x)| {
            format!(
                "{:>2}: {} rpm, {} kPa, {} °C",
                i + 1,
                x.op.n_rpm,
                x.op.p_int_kpa,
                x.op.t_oil_c
            )
        })
        .collect();
    let ranks: Vec<Vec<usize>> = t.tests.iter().map(|x| x.rank.clone()).collect();
    plot::rank_heatmap(
        path,
        &format!("Friction design-parameter ranks ({preset}; 1 = most sensitive)"),
        &rows,
        &t.parameters,
        &ranks,
    )
}

/// `--tracks`: a row per steady cycle (see the flag).
fn write_tracks(path: &Path, r: &FrictionFit) -> Result<()> {
    let d = &r.data;
    let truth = d.truth_nm.is_some();
    let mut columns: Vec<(String, String)> = [
        ("t", "s"),
        ("cycle", "-"),
        ("n", "rpm"),
        ("p_int", "kPa"),
        ("p_atm", "kPa"),
        ("T_oil", "degC"),
        ("measured", "N*m"),
        ("predicted", "N*m"),
        ("nominal", "N*m"),
    ]
    .iter()
    .map(|(n, u)| (n.to_string(), u.to_string()))
    .collect();
    if truth {
        columns.push(("truth".into(), "N*m".into()));
    }
    columns.extend(r.estimable.iter().map(|c| (c.clone(), String::new())));
    columns.extend(
        r.estimable
            .iter()
            .map(|c| (format!("{c}_std_err"), String::new())),
    );
    let mut f = crate::tracks::TrackFile::create(path, columns)?;
    for c in &r.cycles {
        let k = d
            .cycle
            .iter()
            .position(|&x| x == c.cycle)
            .ok_or_else(|| miette!("cycle {} is not among the cycle means", c.cycle))?;
        let mut row = vec![
            c.t_s,
            c.cycle as f64,
            d.n_rpm[k],
            d.p_int_kpa[k],
            d.p_atm_kpa[k],
            d.t_oil_c[k],
            c.measured_nm,
            c.predicted_nm,
            c.nominal_nm,
        ];
        if truth {
            row.push(c.truth_nm.unwrap_or(f64::NAN));
        }
        row.extend(&c.params);
        row.extend(&c.std_err);
        f.row(row)?;
    }
    f.close()
}
