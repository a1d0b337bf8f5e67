//! `physid torque fit`: Application 3 — identifiability and EKF/UKF estimation of the cyclic
//! engine torque model (thesis ch. 8).

use super::crank_input::crank_input;
use super::inspect::AngleArgs;
use super::{named_values, CrankArgs};
use crate::out::outln;
use crate::plot::{self, Panel, Series, PALETTE};
use crate::report::{self, Report};
use miette::{miette, Result};
use physid_apps::angle_input::CrankFile;
use physid_apps::torque_fit::{
    cyclic_torque_nominal, torque_fit_degrees, Degrees, TorqueFit, TorqueFitConfig,
};
use physid_core::Basis;
use physid_estim::MethodName;
use physid_ident::Selection;
use physid_models::cyclic_torque::PARAMS;
use physid_sim::params::CellParams;
use std::path::{Path, PathBuf};

/// Arguments of `physid torque`.
#[derive(clap::Args)]
pub struct Args {
    #[command(subcommand)]
    what: What,
}

#[derive(clap::Subcommand)]
enum What {
    /// Which parameters of the cyclic-torque model (Eq. 8.2) a motored recording supports, and
    /// their estimates by EKF, UKF or SR-UKF with uncertainty.
    ///
    /// Example: physid torque fit --data t2.parquet --fix delta,r --out fit
    Fit(FitArgs),
}

#[derive(clap::Args)]
struct FitArgs {
    /// Motored recording, one sample per crank degree, or on a time basis (resampled to one
    /// sample per degree from its first TDC marker, on the stream as `physid live --torque`
    /// does; with only the encoder count, converted first): theta or theta_en, omega_en,
    /// alpha_en, p_cyl, p_crank, T_oil, torque_engine.
    #[arg(long, value_name = "FILE")]
    data: PathBuf,
    #[command(flatten)]
    input: super::InputArgs,
    /// Filter: ekf, ukf or srukf.
    #[arg(long, default_value = "ukf", value_parser = MethodName::parse_model_based)]
    method: MethodName,
    /// Parameters known by design, held: NAME at its nominal value, NAME=VALUE at that value
    /// (δ's nominal value is 0 and cannot be scaled), e.g. --fix delta,r=0.0457.
    #[arg(
        long,
        value_name = "NAME[=VALUE],…",
        value_delimiter = ',',
        default_value = "delta"
    )]
    fix: Vec<String>,
    /// How many ranked parameters to estimate: rel:FRACTION (default rel:1e-6), repeat, wu or
    /// an absolute residual.
    #[arg(long, default_value = "rel:1e-6")]
    cutoff: Selection,
    /// Estimate these parameters, chosen beforehand (a test designed by `physid design --app
    /// torque`: its --params and --alongside), instead of those the cut-off selects; the others
    /// are held at their nominal values and the ranking is still reported.
    #[arg(
        long,
        value_name = "NAME,…",
        value_delimiter = ',',
        conflicts_with = "cutoff"
    )]
    estimate: Vec<String>,
    /// The parameters' nominal (initial) values NAME=VALUE (SI: kg, m; c in kPa units) over
    /// the built-in test cell's engine, e.g. --params M_rec=0.82,b=0.0541.
    #[arg(long, value_name = "NAME=VALUE,…", value_delimiter = ',')]
    params: Vec<String>,
    /// Deprecated: --params.
    #[arg(
        long = "nominal",
        hide = true,
        value_delimiter = ',',
        conflicts_with = "params"
    )]
    nominal_old: Vec<String>,
    /// P0 = p0·I over the scaled coordinates x, ϑ = ϑ0·(1 + x).
    #[arg(long, value_name = "P0", default_value_t = 0.01, value_parser = super::range::positive, allow_negative_numbers = true)]
    p0: f64,
    /// Measurement-noise variance R2 [N²·m²] (default: the batch fit's residual variance).
    #[arg(long, value_name = "R2", value_parser = super::range::positive, allow_negative_numbers = true)]
    r2: Option<f64>,
    /// Let a parameter drift: NAME=VARIANCE per sample in scaled coordinates, e.g.
    /// --track M_rec=1e-6 to follow a reciprocating-mass change.
    #[arg(long, value_delimiter = ',')]
    track: Vec<String>,
    /// Print JSON: {"estimable", "params", "std_err", "nmse_before", "nmse_after", …}.
    #[arg(long)]
    json: bool,
    /// Directory for the report (report.html with its SVGs, torque_fit.json).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Write every cycle's worth (720 samples) through the filter — the estimates and their
    /// standard errors after it, the RMS one-step prediction error and the RMS measured torque —
    /// to this file (.csv, .parquet or .mf4), with units.
    #[arg(long, value_name = "FILE")]
    tracks: Option<PathBuf>,
}

/// Run `physid torque`.
pub fn run(args: &Args) -> Result<()> {
    match &args.what {
        What::Fit(a) => fit(a),
    }
}

fn config(a: &FitArgs) -> Result<TorqueFitConfig> {
    let mut nominal = cyclic_torque_nominal(&CellParams::default()).map_err(|e| miette!("{e}"))?;
    let (flag, given) = if a.nominal_old.is_empty() {
        ("--params", &a.params)
    } else {
        super::deprecated("--nominal is now --params");
        ("--nominal", &a.nominal_old)
    };
    // `--fix NAME=VALUE` sets the value it holds.
    let held: Vec<String> = a.fix.iter().filter(|s| s.contains('=')).cloned().collect();
    let (names, values) = named_values(given, flag)?;
    let (held_names, held_values) = named_values(&held, "--fix")?;
    let flags = std::iter::repeat_n(flag, names.len())
        .chain(std::iter::repeat_n("--fix", held_names.len()));
    let pairs = names
        .iter()
        .chain(&held_names)
        .zip(values.into_iter().chain(held_values));
    for ((n, v), flag) in pairs.zip(flags) {
        let j = PARAMS
            .iter()
            .position(|p| p == n)
            .ok_or_else(|| miette!("{flag} {n}: the parameters are {}", PARAMS.join(", ")))?;
        nominal[j] = v;
    }
    let mut cfg = TorqueFitConfig::new(nominal);
    cfg.method = a.method;
    cfg.fixed = a
        .fix
        .iter()
        .map(|s| s.split('=').next().unwrap_or_default().trim().to_string())
        .collect();
    cfg.selection = a.cutoff;
    cfg.estimate = (!a.estimate.is_empty()).then(|| a.estimate.clone());
    cfg.chosen().map_err(|e| miette!("--estimate: {e}"))?;
    cfg.p0 = a.p0;
    if let Some(r2) = a.r2 {
        if !(r2.is_finite() && r2 > 0.0) {
            return Err(miette!(
                "--r2 {r2}: expected a variance > 0",
                r2 = physid_core::Num(r2)
            ));
        }
        cfg.r2 = Some(r2);
    }
    let (names, values) = named_values(&a.track, "--track")?;
    cfg.track = names.into_iter().zip(values).collect();
    Ok(cfg)
}

/// Write the cyclic-torque section of a report (and its SVGs into `dir`). `truth` holds the
/// true value of each track over time, where known.
pub fn report_section(
    rep: &mut Report,
    r: &TorqueFit,
    cfg: &TorqueFitConfig,
    truth: &[Option<Vec<f64>>],
    dir: &Path,
) -> Result<()> {
    rep.section("Cyclic engine torque (thesis ch. 8)");
    rep.para(
        &format!(
            "Eq. 8.2 over {} samples (one per crank degree). Held at nominal by design: {}. Ranking by the orthogonal method (Alg. 5.1, thesis scaling); the estimable ones estimated by the {} in scaled coordinates ϑ = ϑ0·(1 + x), P0 = {}·I, R2 = {:.3e} N²·m² ({}); {} covariance repairs.",
            r.samples,
            if cfg.fixed.is_empty() { "none".to_string() } else { cfg.fixed.join(", ") },
            r.method.to_uppercase(),
            cfg.p0,
            r.r2,
            if cfg.r2.is_some() { "given" } else { "the batch fit's residual variance" },
            r.repairs
        ),
        None,
    );
    for d in &r.dropouts {
        rep.para(&d.message(), Some("note"));
    }
    let glossary = report::Glossary {
        names: &PARAMS,
        units: &physid_models::cyclic_torque::UNITS,
        descriptions: &physid_models::cyclic_torque::DESCRIPTIONS,
    };
    rep.ranking(
        &r.ranking,
        glossary,
        "Identifiability of Eq. 8.2: residual profile (Alg. 5.1)",
        &dir.join("torque_residuals.svg"),
    )?;
    let mut rows = Vec::new();
    for (k, tr) in r.tracks.iter().enumerate() {
        let j = PARAMS.iter().position(|p| *p == tr.param).unwrap_or(0);
        let se = r.std_err[j].unwrap_or(f64::NAN);
        let t_end = truth
            .get(k)
            .and_then(|t| t.as_ref())
            .and_then(|t| t.last().copied());
        let (unit, meaning) = glossary.of(&tr.param);
        rows.push(vec![
            tr.param.clone(),
            unit,
            meaning,
            format!("{:.6e}", r.nominal[j]),
            format!("{:.6e}", r.params[j]),
            format!("{se:.2e}"),
            t_end.map_or("—".into(), |v| {
                format!("{v:.6e} ({:+.1}σ)", (r.params[j] - v) / se)
            }),
        ]);
    }
    rep.table(
        &[
            "parameter",
            "unit",
            "meaning",
            "nominal",
            "final",
            "σ",
            "truth",
        ],
        &rows,
    );
    rep.para(
        &format!(
            "NMSE (Eq. 6.4) {:.3e} before → {:.3e} after; NRMSE {:.3e} → {:.3e}. (Eq. 6.4 divides by the product of the means, which is near zero for a cyclic torque: NRMSE is the robust measure.)",
            r.nmse_before, r.nmse_after, r.nrmse_before, r.nrmse_after
        ),
        Some(if r.nrmse_after < r.nrmse_before { "ok" } else { "alarm" }),
    );
    // Tracks with ±3σ, truth where known.
    let bands: Vec<(Vec<f64>, Vec<f64>)> = r
        .tracks
        .iter()
        .map(|tr| {
            (
                tr.value
                    .iter()
                    .zip(&tr.std_err)
                    .map(|(v, s)| v + 3.0 * s)
                    .collect(),
                tr.value
                    .iter()
                    .zip(&tr.std_err)
                    .map(|(v, s)| v - 3.0 * s)
                    .collect(),
            )
        })
        .collect();
    let mut panels = Vec::new();
    for (k, tr) in r.tracks.iter().enumerate() {
        let mut series = vec![
            Series {
                name: "estimate".into(),
                x: &r.t,
                y: &tr.value,
                color: PALETTE[0],
                reference: false,
            },
            Series {
                name: "±3σ".into(),
                x: &r.t,
                y: &bands[k].0,
                color: plot::BAND,
                reference: false,
            },
            Series {
                name: "".into(),
                x: &r.t,
                y: &bands[k].1,
                color: plot::BAND,
                reference: false,
            },
        ];
        if let Some(Some(t)) = truth.get(k) {
            series.insert(
                0,
                Series {
                    name: "truth (simulated)".into(),
                    x: &r.t,
                    y: t,
                    color: PALETTE[1],
                    reference: true,
                },
            );
        }
        let (unit, _) = glossary.of(&tr.param);
        panels.push(Panel {
            ylabel: format!("{} [{unit}]", tr.param),
            series,
            ..Default::default()
        });
    }
    let svg = dir.join("torque_tracks.svg");
    plot::panels(
        &svg,
        "Cyclic-torque parameters, tracked",
        "time [s]",
        &panels,
    )?;
    rep.svg(&svg)?;
    let [t, y, before, after] = &r.last_cycles;
    let svg = dir.join("torque_prediction.svg");
    plot::panels(
        &svg,
        "Engine torque over the last two cycles: measured and predicted",
        "time [s]",
        &[Panel {
            ylabel: "torque [N·m]".into(),
            series: vec![
                Series {
                    name: "measured".into(),
                    x: t,
                    y,
                    color: PALETTE[1],
                    reference: true,
                },
                Series {
                    name: "nominal model".into(),
                    x: t,
                    y: before,
                    color: PALETTE[4],
                    reference: false,
                },
                Series {
                    name: "fitted model".into(),
                    x: t,
                    y: after,
                    color: PALETTE[0],
                    reference: false,
                },
            ],
            ..Default::default()
        }],
    )?;
    rep.svg(&svg)
}

fn fit(a: &FitArgs) -> Result<()> {
    let cfg = config(a)?;
    // A crank-angle file, or a time-basis one with the engine angle, is gone over in passes
    // (its 1° samples made again on each, the channels held within PHYSID_HOLD_MB): memory
    // independent of its length. A time basis with an encoder's counts likewise, its 1° samples
    // made again from the file on each pass (`CrankFile`).
    let header = a.input.open_all(&a.data)?.header().clone();
    let r = if header.basis == Basis::CrankAngle || header.channel("theta_en").is_ok() {
        let src = Degrees::file(&a.data, &a.input.options(None)?, super::hold_bytes()?)
            .map_err(super::app_error(&a.data))?;
        let working =
            crate::progress::Working::new("choosing the parameters and filtering every degree");
        let r = torque_fit_degrees(&src, &cfg);
        drop(working);
        if let Some(w) = src.warning() {
            eprintln!("warning: {}: {w}", a.data.display());
        }
        r
    } else {
        // The engine angle from an encoder's counts: the 1° samples made as the file is read,
        // again on every pass.
        let (angle, crank) = (AngleArgs::default(), CrankArgs::default());
        let input = crank_input(&a.input, &a.data, &angle, &crank)?;
        let mut channels = physid_apps::torque_fit::crank_channels(&header);
        channels.retain(|n| *n != "theta_en");
        input
            .require(&channels)
            .map_err(super::app_error(&a.data))?;
        let file = CrankFile::new(input, channels);
        let working =
            crate::progress::Working::new("choosing the parameters and filtering every degree");
        let r = torque_fit_degrees(&Degrees::crank(&file), &cfg);
        drop(working);
        r
    }
    .map_err(super::app_error(&a.data))?;
    super::warn_dropouts(&r.dropouts, &a.data);
    if let Some(path) = &a.tracks {
        let mut columns: Vec<(String, String)> = vec![
            ("t".into(), "s".into()),
            ("rms_error".into(), "N*m".into()),
            ("rms_measured".into(), "N*m".into()),
        ];
        columns.extend(r.estimable.iter().map(|p| (p.clone(), String::new())));
        columns.extend(
            r.estimable
                .iter()
                .map(|p| (format!("{p}_std_err"), String::new())),
        );
        let mut f = crate::tracks::TrackFile::create(path, columns)?;
        for c in &r.cycles {
            f.row(
                [c.t_s, c.rms_error_nm, c.rms_measured_nm]
                    .into_iter()
                    .chain(c.params.iter().copied())
                    .chain(c.std_err.iter().copied()),
            )?;
        }
        f.close()?;
    }
    let j = r.summary();
    if let Some(dir) = &a.out {
        let title = "physid — cyclic torque fit";
        report::write(dir, title, &a.data, "torque_fit.json", &j, |rep, dir| {
            report_section(rep, &r, &cfg, &r.truths(&header), dir)
        })?;
    }
    if a.json {
        crate::provenance::print_json(&j)?;
        return Ok(());
    }
    outln!(
        "{}: {} samples, {} on {}",
        a.data.display(),
        r.samples,
        r.method,
        r.estimable.join(", ")
    );
    outln!("  parameter        nominal          final        σ");
    for tr in &r.tracks {
        let j = PARAMS.iter().position(|p| *p == tr.param).unwrap_or(0);
        outln!(
            "  {:<8} {:>14.6e} {:>14.6e} {:>10.2e}",
            tr.param,
            r.nominal[j],
            r.params[j],
            r.std_err[j].unwrap_or(f64::NAN)
        );
    }
    outln!(
        "  NMSE {:.3e} → {:.3e}, NRMSE {:.3e} → {:.3e}; R2 {:.3e}; {} repairs",
        r.nmse_before,
        r.nmse_after,
        r.nrmse_before,
        r.nrmse_after,
        r.r2,
        r.repairs
    );
    if let Some(dir) = &a.out {
        outln!("wrote {}", dir.join("report.html").display());
    }
    Ok(())
}
