//! `physid cycles`: cylinder-pressure figures per cycle — peak pressure and its angle (between
//! the samples), IMEP (net and gross), polytropic exponents, speed, CoV of IMEP; with the
//! geometry the apparent heat release, MFB10/50/90 and the steepest pressure rise — with
//! pegging (`physid_apps::pressure`, `physid_apps::combustion`). A time-basis recording is taken to one sample per crank degree
//! first (its engine angle from `theta_en`, an encoder, or a trigger wheel with `--wheel`).

use super::combustion_args::CombustionArgs;
use super::{GeometryArgs, InputArgs};
use crate::cmd::crank_input::{crank_input, read_error};
use crate::cmd::inspect::AngleArgs;
use crate::out::outln;
use miette::{miette, IntoDiagnostic, Result};
use physid_apps::pressure::CycleAnalyser;
use std::path::PathBuf;

/// Arguments of `physid cycles`.
#[derive(clap::Args)]
pub struct Args {
    /// Recording (CSV, Parquet, MDF4, text): on a crank-angle basis, or on a time basis with
    /// the engine angle (theta_en, an encoder count, or --wheel).
    pub file: PathBuf,
    #[command(flatten)]
    pub input: InputArgs,
    /// The cylinder-pressure channel.
    #[arg(long, default_value = "p_cyl")]
    pub channel: String,
    /// The cylinder's geometry (all four: IMEP and polytropic exponents; --stroke and --rod
    /// alone serve --tdc-from).
    #[command(flatten)]
    pub geometry: GeometryArgs,
    /// Pegging, heat release, burn fractions, knock.
    #[command(flatten)]
    pub combustion: CombustionArgs,
    /// Crank-angle step of a time-basis recording's resampling [deg] (a divisor of 720; finer
    /// than the source's own samples is interpolation between them). Knock needs a step the
    /// band fits in: at most 6·rpm / (2.5·f_high).
    #[arg(long, default_value_t = 0.1)]
    pub step_deg: f64,
    #[command(flatten)]
    pub angle: AngleArgs,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
    /// Write a row per cycle — t, cycle, rpm, the peak pressure and its angle, the pegging
    /// offset, net and gross IMEP, the polytropic exponents, the heat released, fired (1/0),
    /// MFB10/50/90 and the steepest pressure rise and its angle (NaN where not computed) — to
    /// this file (.csv, .parquet or .mf4), with units.
    #[arg(long, value_name = "FILE")]
    pub tracks: Option<PathBuf>,
    /// Write a report to this directory: report.html (the summary; pressure, heat release rate
    /// and mass fraction burned of the ensemble mean cycle and of --report-cycle against crank
    /// angle; their p–V and log p–log V; IMEP, MFB50, p_max and MAPO per cycle), cycles.json,
    /// tracks.csv.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// The cycle the report draws beside the mean [default: the last].
    #[arg(long, value_name = "N", requires = "out")]
    pub report_cycle: Option<i64>,
}

/// The per-cycle table as a tracks file (crate::tracks).
fn write_tracks(path: &std::path::Path, a: &physid_apps::pressure::CycleAnalysis) -> Result<()> {
    let columns = a.columns();
    let mut f = crate::tracks::TrackFile::create(
        path,
        columns
            .iter()
            .map(|(n, u, _)| (n.clone(), u.clone()))
            .collect(),
    )?;
    for k in 0..a.cycles.len() {
        f.row(columns.iter().map(|(.., v)| v[k]))?;
    }
    f.close()
}

/// Run `physid cycles`.
pub fn run(args: &Args) -> Result<()> {
    let geometry = args.geometry.full()?;
    let settings = args.combustion.settings(geometry)?;
    let mut input = crank_input(&args.input, &args.file, &args.angle, &args.geometry.crank)?;
    input.quiet = args.json;
    input.step_deg = args.step_deg;
    let mut channels = vec![args.channel.as_str()];
    channels.extend(settings.brake.as_ref().map(|b| b.channel.as_str()));
    let (analyser, wheel) = input
        .read(
            Some(&channels),
            |h| {
                let mut a = CycleAnalyser::new(h, &args.channel, geometry.as_ref(), settings.peg)?
                    .with_heat_release(settings.heat.clone())?
                    .with_chosen_cycle(args.report_cycle);
                if let Some(b) = &settings.brake {
                    a = a.with_brake(h, b.clone())?;
                }
                if let Some(lp) = settings.lowpass {
                    a = a.with_lowpass(lp)?;
                }
                if let Some(m) = &settings.friction {
                    a = a.with_friction_model(m.clone())?;
                }
                match settings.knock {
                    Some(k) => a.with_knock(k),
                    None => Ok(a),
                }
            },
            |a, chunk| a.push(chunk),
        )
        .map_err(read_error(&args.file))?;
    let a = analyser.finish().map_err(super::app_error(&args.file))?;
    if !a.dropouts.is_empty() {
        if args.input.open_all(&args.file)?.header().basis == physid_core::Basis::Time {
            // Its crank-angle samples were made as it was read: a dropout's sample counts those.
            for d in &a.dropouts {
                eprintln!(
                    "warning: {} (its samples at each step of crank angle): {}",
                    args.file.display(),
                    d.message()
                );
            }
        } else {
            super::warn_dropouts(&a.dropouts, &args.file);
        }
    }
    if let Some(path) = &args.tracks {
        write_tracks(path, &a)?;
    }
    if let Some(dir) = &args.out {
        if let Some(n) = args.report_cycle {
            if !a.cycles.iter().any(|c| c.cycle == n) {
                return Err(miette!(
                    "--report-cycle {n}: no such complete cycle (the cycles are {} … {})",
                    a.cycles.first().map_or(0, |c| c.cycle),
                    a.cycles.last().map_or(0, |c| c.cycle)
                ));
            }
        }
        let threshold = settings.knock.map(|k| k.threshold_pa);
        crate::report::write(
            dir,
            "physid — combustion analysis",
            &args.file,
            "cycles.json",
            &a,
            |rep, dir| super::cycles_report::report(rep, &a, dir, threshold),
        )?;
        write_tracks(&dir.join("tracks.csv"), &a)?;
    }
    if args.json {
        let mut v = serde_json::to_value(&a).into_diagnostic()?;
        if let (Some(o), Some(d)) = (v.as_object_mut(), &wheel) {
            if let Some(a) = &d.wheel {
                o.insert(
                    "wheel".into(),
                    serde_json::json!({
                        "wheel": a.wheel.to_string(),
                        "teeth": a.wheel.present(),
                        "missing": a.wheel.missing,
                        "revolutions": a.revolutions,
                        "rpm_min": a.rpm.0,
                        "rpm_max": a.rpm.1,
                    }),
                );
            }
            if let Some(e) = &d.encoder {
                o.insert("encoder".into(), serde_json::to_value(e).into_diagnostic()?);
            }
            o.insert("phase".into(), d.phase.clone().into());
            o.insert(
                "findings".into(),
                serde_json::to_value(&d.findings).into_diagnostic()?,
            );
        }
        crate::provenance::print_json_value(v)?;
        return Ok(());
    }
    let u = &a.unit;
    outln!(
        "{}: {} complete cycle(s) of '{}' [{u}]",
        args.file.display(),
        a.cycles.len(),
        a.channel
    );
    // BMEP and FMEP with the brake torque, the friction model's FMEP with a model.
    let mut extra: Vec<&str> = Vec::new();
    if a.brake {
        extra.extend(["BMEP [kPa]", "FMEP [kPa]"]);
    }
    if a.friction {
        extra.push("model [kPa]");
    }
    let extra_head: String = extra.iter().map(|h| format!(" {h:>12}")).collect();
    outln!(
        "{:>6} {:>10} {:>8} {:>12} {:>9} {:>12} {:>12} {:>7} {:>7} {:>8} {:>7}{extra_head}",
        "cycle",
        "t [s]",
        "rpm",
        "p_max",
        "at [°]",
        "IMEP [kPa]",
        "gross [kPa]",
        "n_comp",
        "n_exp",
        "Q_n [J]",
        "MFB50"
    );
    let opt = |v: Option<f64>, scale: f64, prec: usize| {
        v.map_or("-".to_string(), |v| format!("{:.*}", prec, v * scale))
    };
    for c in &a.cycles {
        let mut more = Vec::new();
        if a.brake {
            more.extend([c.bmep_pa, c.fmep_pa]);
        }
        if a.friction {
            more.push(c.fmep_model_pa);
        }
        let more: String = more
            .into_iter()
            .map(|v| format!(" {:>12}", opt(v, 1e-3, 2)))
            .collect();
        outln!(
            "{:>6} {:>10.4} {:>8.1} {:>12.5e} {:>9.2} {:>12} {:>12} {:>7} {:>7} {:>8} {:>7}{more}",
            c.cycle,
            c.t_start_s,
            c.rpm,
            c.p_max,
            c.p_max_deg,
            opt(c.imep_pa, 1e-3, 2),
            opt(c.imep_gross_pa, 1e-3, 2),
            opt(c.n_compression, 1.0, 3),
            opt(c.n_expansion, 1.0, 3),
            opt(c.burn.as_ref().map(|b| b.heat_release_j), 1.0, 1),
            opt(c.burn.as_ref().and_then(|b| b.mfb(50.0)), 1.0, 2)
        );
    }
    if let Some(cov) = a.cov_imep {
        outln!("CoV of IMEP: {:.2} %", cov * 100.0);
    }
    if let Some(lnv) = a.lnv_imep {
        outln!("LNV of IMEP: {:.2} %", lnv * 100.0);
    }
    for n in &a.notes {
        outln!("note: {n}");
    }
    Ok(())
}
