//! `physid cycles`: cylinder-pressure figures per cycle — peak pressure and its angle (between
//! the samples), IMEP (net and gross), polytropic exponents, speed, CoV of IMEP; with the
//! geometry the apparent heat release, MFB10/50/90 and the steepest pressure rise — with
//! pegging (`physid_apps::pressure`, `physid_apps::combustion`). A time-basis recording is taken to one sample per crank degree
//! first (its engine angle from `theta_en`, an encoder, or a trigger wheel with `--wheel`).

use super::{GeometryArgs, InputArgs};
use crate::cmd::crank_input::{crank_input, read_error};
use crate::cmd::inspect::AngleArgs;
use crate::out::outln;
use miette::{miette, IntoDiagnostic, Result};
use physid_apps::combustion::HeatRelease;
use physid_apps::pressure::{CycleAnalyser, Pegging};
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
    /// Pressure referencing per cycle: `bdc=P` (P, in the channel's unit, at BDC of the intake
    /// stroke) or `polytropic=N` (the offset that makes p·V^N constant on compression).
    #[arg(long, value_name = "bdc=P|polytropic=N")]
    pub peg: Option<String>,
    /// The ratio of specific heats of the single-zone heat release (constant; with the
    /// geometry and the pressure in Pa).
    #[arg(long, default_value_t = physid_apps::combustion::DEFAULT_GAMMA)]
    pub gamma: f64,
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
}

/// The per-cycle table as a tracks file (crate::tracks).
fn write_tracks(path: &std::path::Path, a: &physid_apps::pressure::CycleAnalysis) -> Result<()> {
    let u = a.unit.as_str();
    let columns = [
        ("t", "s"),
        ("cycle", "-"),
        ("rpm", "rpm"),
        ("p_max", u),
        ("p_max_deg", "deg"),
        ("peg_offset", u),
        ("imep", "Pa"),
        ("imep_gross", "Pa"),
        ("n_compression", "-"),
        ("n_expansion", "-"),
        ("heat_release", "J"),
        ("fired", "-"),
        ("mfb10_deg", "deg"),
        ("mfb50_deg", "deg"),
        ("mfb90_deg", "deg"),
        ("dp_max", "Pa/deg"),
        ("dp_max_deg", "deg"),
    ]
    .iter()
    .map(|(n, u)| (n.to_string(), u.to_string()))
    .collect();
    let mut f = crate::tracks::TrackFile::create(path, columns)?;
    let nan = |v: Option<f64>| v.unwrap_or(f64::NAN);
    for c in &a.cycles {
        let b = c.burn.as_ref();
        let burn = |f: fn(&physid_apps::combustion::Burn) -> Option<f64>| nan(b.and_then(f));
        f.row([
            c.t_start_s,
            c.cycle as f64,
            c.rpm,
            c.p_max,
            c.p_max_deg,
            c.peg_offset,
            nan(c.imep_pa),
            nan(c.imep_gross_pa),
            nan(c.n_compression),
            nan(c.n_expansion),
            burn(|b| Some(b.heat_release_j)),
            burn(|b| Some(f64::from(u8::from(b.fired)))),
            burn(|b| b.mfb10_deg),
            burn(|b| b.mfb50_deg),
            burn(|b| b.mfb90_deg),
            burn(|b| Some(b.dp_max_pa_per_deg)),
            burn(|b| Some(b.dp_max_deg)),
        ])?;
    }
    f.close()
}

fn pegging(s: &Option<String>) -> Result<Pegging> {
    let Some(s) = s else {
        return Ok(Pegging::None);
    };
    let bad = || {
        miette!("--peg '{s}': expected bdc=PRESSURE or polytropic=EXPONENT, e.g. bdc=1e5, polytropic=1.32")
    };
    let (kind, value) = s.split_once('=').ok_or_else(bad)?;
    let v: f64 = value
        .trim()
        .parse()
        .ok()
        .filter(|v: &f64| v.is_finite())
        .ok_or_else(bad)?;
    match kind.trim() {
        "bdc" => Ok(Pegging::Bdc(v)),
        "polytropic" if v > 1.0 && v < 2.0 => Ok(Pegging::Polytropic(v)),
        "polytropic" => Err(miette!(
            "--peg polytropic={v}: expected an exponent between 1 and 2"
        )),
        _ => Err(bad()),
    }
}

/// Run `physid cycles`.
pub fn run(args: &Args) -> Result<()> {
    let peg = pegging(&args.peg)?;
    let geometry = args.geometry.full()?;
    let mut input = crank_input(&args.input, &args.file, &args.angle, &args.geometry.crank)?;
    input.quiet = args.json;
    let (analyser, wheel) = input
        .read(
            Some(&[args.channel.as_str()]),
            |h| {
                CycleAnalyser::new(h, &args.channel, geometry.as_ref(), peg)?.with_heat_release(
                    HeatRelease {
                        gamma: args.gamma,
                        ..HeatRelease::default()
                    },
                )
            },
            |a, chunk| a.push(chunk),
        )
        .map_err(read_error(&args.file))?;
    let a = analyser.finish().map_err(super::app_error(&args.file))?;
    if let Some(path) = &args.tracks {
        write_tracks(path, &a)?;
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
    outln!(
        "{:>6} {:>10} {:>8} {:>12} {:>9} {:>12} {:>12} {:>7} {:>7} {:>8} {:>7}",
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
        outln!(
            "{:>6} {:>10.4} {:>8.1} {:>12.5e} {:>9.2} {:>12} {:>12} {:>7} {:>7} {:>8} {:>7}",
            c.cycle,
            c.t_start_s,
            c.rpm,
            c.p_max,
            c.p_max_deg,
            opt(c.imep_pa, 1e-3, 2),
            opt(c.imep_gross_pa, 1e-3, 2),
            opt(c.n_compression, 1.0, 3),
            opt(c.n_expansion, 1.0, 3),
            opt(c.burn.map(|b| b.heat_release_j), 1.0, 1),
            opt(c.burn.and_then(|b| b.mfb50_deg), 1.0, 2)
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
