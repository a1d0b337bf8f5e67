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
    /// The burn fractions whose crank angles are given [%] (mfbK_deg for each K).
    #[arg(long, value_delimiter = ',', default_values_t = physid_apps::combustion::MFB)]
    pub mfb: Vec<f64>,
    #[command(flatten)]
    pub knock: KnockArgs,
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
}

/// Knock's flags.
#[derive(clap::Args)]
pub struct KnockArgs {
    /// Knock per cycle: the pressure band-passed (zero phase), its maximum amplitude (MAPO) and
    /// integral of modulus (IMPO) in a window after TDC, a flag above a threshold (with the
    /// geometry not needed, the pressure in Pa, a step fine enough for the band).
    #[arg(long)]
    pub knock: bool,
    /// The knock band [Hz].
    #[arg(
        long,
        value_name = "LOW,HIGH",
        value_delimiter = ',',
        num_args = 2,
        requires = "knock"
    )]
    pub knock_band: Option<Vec<f64>>,
    /// The knock window [deg ATDC].
    #[arg(
        long,
        value_name = "FROM,TO",
        value_delimiter = ',',
        num_args = 2,
        requires = "knock",
        allow_hyphen_values = true
    )]
    pub knock_window: Option<Vec<f64>>,
    /// A cycle knocks when its MAPO exceeds this [Pa] (set it for the engine).
    #[arg(long, value_name = "PA", default_value_t = physid_apps::knock::DEFAULT_THRESHOLD_PA)]
    pub knock_threshold: f64,
}

impl KnockArgs {
    /// The knock settings asked for.
    pub fn knock(&self) -> Option<physid_apps::knock::Knock> {
        use physid_apps::knock::Knock;
        let d = Knock::default();
        let pair = |v: &Option<Vec<f64>>, d: (f64, f64)| v.as_ref().map_or(d, |v| (v[0], v[1]));
        self.knock.then(|| Knock {
            band_hz: pair(&self.knock_band, d.band_hz),
            window: pair(&self.knock_window, d.window),
            threshold_pa: self.knock_threshold,
        })
    }
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
    let peg = Pegging::parse(args.peg.as_deref()).map_err(|e| miette!("{e}"))?;
    let geometry = args.geometry.full()?;
    let mut input = crank_input(&args.input, &args.file, &args.angle, &args.geometry.crank)?;
    input.quiet = args.json;
    input.step_deg = args.step_deg;
    let knock = args.knock.knock();
    let (analyser, wheel) = input
        .read(
            Some(&[args.channel.as_str()]),
            |h| {
                let a = CycleAnalyser::new(h, &args.channel, geometry.as_ref(), peg)?
                    .with_heat_release(HeatRelease {
                        gamma: args.gamma,
                        mfb: args.mfb.clone(),
                        ..HeatRelease::default()
                    })?;
                match knock {
                    Some(k) => a.with_knock(k),
                    None => Ok(a),
                }
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
