//! `physid compression fit`: the chain on a motored pressure trace
//! (`physid_apps::compression`) — which of the motored model's physical parameters (compression
//! ratio, TDC, sensor offset, polytropic exponent, BDC pressure, loss rate) the trace resolves,
//! those fitted to all the TDCs with 95 % intervals, per TDC and recursively, the loss angle.

use super::{GeometryArgs, InputArgs};
use crate::cmd::crank_input::crank_input;
use crate::cmd::inspect::AngleArgs;
use crate::out::outln;
use crate::plot::{self, Panel, Series, PALETTE};
use crate::report::{self, Report};
use miette::{miette, Result};
use physid_apps::angle_input::{AngleInput, CrankFile};
use physid_apps::compression::{
    compression_fit_events, CompressionConfig, CompressionFit, TdcEvents,
};
use physid_apps::pressure::{CycleAnalyser, Geometry, Pegging};
use physid_ident::Selection;
use physid_models::motored::PARAMS;
use std::path::{Path, PathBuf};

/// Arguments of `physid compression`.
#[derive(clap::Args)]
pub struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(clap::Subcommand)]
enum Command {
    /// Fit the motored-pressure model around every firing TDC of a motored recording: the
    /// identifiability ranking of its six physical parameters, the estimable ones per TDC with
    /// 95 % intervals (all the TDCs at once, per TDC, recursively), the thermodynamic loss
    /// angle.
    ///
    /// Example: physid compression fit --data deg.parquet --stroke 0.09 --rod 0.15 --out comp
    Fit(FitArgs),
}

#[derive(clap::Args)]
struct FitArgs {
    /// Motored recording: on a crank-angle basis (`cycle`, `crank_deg`), or on a time basis with
    /// the engine angle (theta_en, an encoder count, or --wheel / --quadrature).
    #[arg(long, value_name = "FILE")]
    data: PathBuf,
    #[command(flatten)]
    input: InputArgs,
    /// The cylinder-pressure channel.
    #[arg(long, default_value = "p_cyl")]
    channel: String,
    /// The crank's lengths (needed); with the bore, the motored cycles' net IMEP (the pressure
    /// in Pa); a compression ratio given is held (as --fix eps=R), not fitted.
    #[command(flatten)]
    geometry: GeometryArgs,
    /// The fitting window [deg ATDC], inside IVC … EVO.
    #[arg(
        long,
        value_name = "FROM,TO",
        default_value = "-120,120",
        allow_hyphen_values = true
    )]
    window: String,
    /// Hold parameters at values instead of fitting them: eps, tdc_shift [deg], p_offset, n,
    /// p_bdc [the channel's unit], k_loss [1/rad]; e.g. --fix eps=10.5,tdc_shift=-0.4.
    #[arg(
        long,
        value_name = "NAME=VALUE,…",
        value_delimiter = ',',
        allow_hyphen_values = true
    )]
    fix: Vec<String>,
    /// Widen (or narrow) where a fitted parameter is physical — by default eps 4 … 25 and n 1.0 …
    /// 1.45; a fit outside is flagged with the reason (and --tdc-from refuses it); e.g.
    /// --plausible eps=4,30.
    #[arg(long, value_name = "NAME=LO,HI")]
    plausible: Vec<String>,
    /// Deprecated: --fix (--set configures a model or the virtual cell in the other verbs).
    #[arg(long = "set", hide = true, allow_hyphen_values = true)]
    set_old: Vec<String>,
    /// How many ranked parameters to fit: wu (Wu et al.), repeat, rel:FRACTION or an absolute
    /// residual.
    #[arg(long, default_value = "wu")]
    cutoff: Selection,
    #[command(flatten)]
    angle: AngleArgs,
    /// Print JSON: {"ranking", "fitted", "estimates": [{"name", "unit", "status", "value",
    /// "std_err", "ci95"}, …], "events": […], "peak_deg", …}.
    #[arg(long)]
    json: bool,
    /// Directory for the report (report.html with its SVGs, compression_fit.json,
    /// tracks.csv: per TDC the estimates, their standard errors and the recursive track).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Write per TDC its time, cycle, speed, residual, each fitted parameter, its standard
    /// error and the recursive track to this file (.csv, .parquet or .mf4), with units.
    #[arg(long, value_name = "FILE")]
    tracks: Option<PathBuf>,
}

/// Run `physid compression`.
pub fn run(args: &Args) -> Result<()> {
    match &args.command {
        Command::Fit(a) => fit(a),
    }
}

fn window(s: &str) -> Result<(f64, f64)> {
    let bad = || miette!("--window '{s}': expected FROM,TO in degrees ATDC, e.g. -120,120");
    let (a, b) = s.split_once(',').ok_or_else(bad)?;
    let a: f64 = a.trim().parse().map_err(|_| bad())?;
    let b: f64 = b.trim().parse().map_err(|_| bad())?;
    Ok((a, b))
}

fn held(items: &[String]) -> Result<Vec<(String, f64)>> {
    items
        .iter()
        .map(|s| {
            let bad = || {
                miette!(
                    "--fix '{s}': expected NAME=VALUE with NAME one of {}",
                    PARAMS.join(", ")
                )
            };
            let (n, v) = s.split_once('=').ok_or_else(bad)?;
            let v: f64 = v.trim().parse().map_err(|_| bad())?;
            Ok((n.trim().to_string(), v))
        })
        .collect()
}

fn fit(a: &FitArgs) -> Result<()> {
    let (stroke, rod) = a.geometry.crank.lengths("compression fit")?;
    let mut cfg = CompressionConfig::new(&a.channel, stroke, rod);
    cfg.window_deg = window(&a.window)?;
    if !a.set_old.is_empty() {
        super::deprecated("--set NAME=VALUE in compression fit is now --fix NAME=VALUE");
    }
    cfg.held = held(&[a.fix.as_slice(), a.set_old.as_slice()].concat())?;
    // A known compression ratio is held, as `--fix eps=R` would.
    if let Some(r) = a.geometry.crank.compression_ratio {
        if !cfg.held.iter().any(|(n, _)| n == "eps") {
            cfg.held.push(("eps".into(), r));
        }
    }
    cfg.selection = a.cutoff;
    for item in &a.plausible {
        let bad =
            || miette!("--plausible '{item}': expected NAME=LO,HI with numbers, e.g. eps=4,30");
        let (name, range) = item.split_once('=').ok_or_else(bad)?;
        let (lo, hi) = range.split_once(',').ok_or_else(bad)?;
        let (lo, hi): (f64, f64) = (
            lo.trim().parse().map_err(|_| bad())?,
            hi.trim().parse().map_err(|_| bad())?,
        );
        let name = name.trim();
        cfg.plausible.retain(|(n, ..)| n != name);
        cfg.plausible.push((name.to_string(), lo, hi));
    }
    let mut input = crank_input(&a.input, &a.data, &a.angle, &a.geometry.crank)?;
    input.quiet = a.json;
    let file = CrankFile::new(input.clone(), vec![a.channel.as_str()]);
    let events = TdcEvents::new(&file, &a.channel, cfg.window_deg, super::hold_bytes()?);
    let r = compression_fit_events(&events, &cfg).map_err(super::app_error(&a.data))?;
    let imep = motored_imep(&input, &r, &a.geometry)?;
    // Made JSON only where it is written (the events' list grows with the recording).
    let json = FitOutput {
        fit: &r,
        motored_imep_pa: imep,
    };
    if let Some(dir) = &a.out {
        let title = "physid — compression fit";
        report::write(
            dir,
            title,
            &a.data,
            "compression_fit.json",
            &json,
            |rep, dir| {
                report_section(rep, &r, &cfg, dir)?;
                if let Some(v) = imep {
                    rep.para(&imep_text(v), None);
                }
                Ok(())
            },
        )?;
        write_tracks(&dir.join("tracks.csv"), &r)?;
    }
    if let Some(path) = &a.tracks {
        write_tracks(path, &r)?;
    }
    if a.json {
        crate::provenance::print_json(&json)?;
        return Ok(());
    }
    outln!(
        "{}: {} TDC(s) of '{}' [{}] fitted over {}° … {}° ATDC; RMS residual {:.4e}",
        a.data.display(),
        r.events.len(),
        r.channel,
        r.unit,
        r.window_deg.0,
        r.window_deg.1,
        r.rms_residual
    );
    outln!(
        "  identifiability (Alg. 5.1 at the starting values): {}",
        r.ranking
            .iter()
            .map(|p| format!("{} {:.1e}", p.param, p.relative_residual))
            .collect::<Vec<_>>()
            .join(" > ")
    );
    if let Some(pairs) = &r.confounded {
        if !pairs.is_empty() {
            outln!(
                "  trade off (|correlation| > 0.95 fitting all): {}",
                pairs
                    .iter()
                    .map(|c| format!("{}–{} {:+.3}", c.a, c.b, c.correlation))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
    }
    outln!(
        "  {:<9} {:>14} {:>10} {:>29} {:>11}  {}",
        "parameter",
        "value",
        "unit",
        "95 % interval",
        "status",
        "meaning"
    );
    for e in &r.estimates {
        outln!(
            "  {:<9} {:>14.6} {:>10} {:>29} {:>11}  {}",
            e.name,
            e.value,
            e.unit,
            e.ci95
                .map_or("—".into(), |(lo, hi)| format!("{lo:.6} … {hi:.6}")),
            e.status,
            e.description
        );
    }
    if let Some(p) = r.peak_deg {
        outln!(
            "  the fitted trace peaks {:.3}° before TDC (the loss angle)",
            -p
        );
    }
    if let Some(v) = imep {
        outln!("  {}", imep_text(v));
    }
    for n in &r.notes {
        outln!("note: {n}");
    }
    if let Some(dir) = &a.out {
        outln!("wrote {}", dir.join("report.html").display());
    }
    Ok(())
}

/// The JSON of `compression fit`: the fit, and the motored IMEP when it was worked out.
#[derive(serde::Serialize)]
struct FitOutput<'a> {
    #[serde(flatten)]
    fit: &'a CompressionFit,
    #[serde(skip_serializing_if = "Option::is_none")]
    motored_imep_pa: Option<f64>,
}

/// The mean net IMEP of the motored cycles [Pa] (`physid_apps::pressure`, the volume with the
/// fitted compression ratio): the work the motored loop loses, heat and gas exchange — with
/// --bore and the pressure in Pa. A constant sensor offset does not change a closed loop's work.
fn motored_imep(input: &AngleInput, r: &CompressionFit, g: &GeometryArgs) -> Result<Option<f64>> {
    let (Some(bore), Some(stroke), Some(rod)) = (g.bore, g.crank.stroke, g.crank.rod) else {
        return Ok(None);
    };
    if r.unit != "Pa" {
        return Ok(None);
    }
    let eps = r.get("eps").map_or(f64::NAN, |e| e.value);
    let geometry = Geometry {
        bore,
        stroke,
        rod,
        compression_ratio: eps,
    };
    // A second pass over the recording, the cycles with the fitted compression ratio.
    let (cycles, _) = input
        .read_again(
            Some(&[r.channel.as_str()]),
            |h| CycleAnalyser::new(h, &r.channel, Some(&geometry), Pegging::None),
            |c, chunk| c.push(chunk),
        )
        .map_err(super::app_error(&input.path))?;
    let a = cycles.finish().map_err(|e| miette!("{e}"))?;
    let v: Vec<f64> = a.cycles.iter().filter_map(|c| c.imep_pa).collect();
    Ok((!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64))
}

fn imep_text(v: f64) -> String {
    format!(
        "Net IMEP of the motored cycles: {:.2} kPa (the loop's loss: heat and gas exchange; with the fitted compression ratio).",
        v * 1e-3
    )
}

/// The report: the ranking, the estimates with units and meanings, the per-TDC tracks with the
/// recursive estimate and its interval, the last TDC measured and fitted.
fn report_section(
    rep: &mut Report,
    r: &CompressionFit,
    cfg: &CompressionConfig,
    dir: &Path,
) -> Result<()> {
    rep.section("The motored-pressure model");
    rep.para(
        &format!(
            "p(θ) = p_bdc·(V(−180°)/V(θ − tdc_shift))ⁿ·exp(−k_loss·(θ − tdc_shift + 180°)) + p_offset over {}° … {}° ATDC of '{}' [{}], \
             the volume of the slider crank (stroke {} m, rod {} m) with compression ratio eps. {} TDC(s); RMS residual {:.4e} {}.",
            r.window_deg.0, r.window_deg.1, r.channel, r.unit, cfg.stroke, cfg.rod, r.events.len(), r.rms_residual, r.unit
        ),
        None,
    );
    rep.section("Which parameters the trace resolves");
    // `P` in the model's units is the pressure channel's.
    let units: Vec<&str> = physid_models::motored::UNITS
        .iter()
        .map(|u| if *u == "P" { r.unit.as_str() } else { u })
        .collect();
    rep.ranking(
        &r.ranking,
        report::Glossary {
            names: &PARAMS,
            units: &units,
            descriptions: &physid_models::motored::DESCRIPTIONS,
        },
        "Motored model: residual profile (Alg. 5.1)",
        &dir.join("compression_residuals.svg"),
    )?;
    if let Some(pairs) = &r.confounded {
        rep.para(
            &if pairs.is_empty() {
                "No pair of parameters correlates beyond 0.95 in the fit of all of them.".into()
            } else {
                format!(
                    "Trade off in the fit of all of them (|correlation| > 0.95): {}.",
                    pairs
                        .iter()
                        .map(|c| format!("{} and {} ({:+.3})", c.a, c.b, c.correlation))
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            },
            Some("note"),
        );
    }
    rep.section("Estimates (fitted to all the TDCs at once)");
    rep.table(
        &[
            "parameter",
            "meaning",
            "unit",
            "status",
            "value",
            "95 % interval",
            "spread over TDCs (s.e.)",
        ],
        &r.estimates
            .iter()
            .map(|e| {
                vec![
                    e.name.clone(),
                    e.description.clone(),
                    e.unit.clone(),
                    e.status.into(),
                    format!("{:.6}", e.value),
                    e.ci95
                        .map_or("—".into(), |(lo, hi)| format!("{lo:.6} … {hi:.6}")),
                    e.between_events_std_err
                        .map_or("—".into(), |s| format!("{s:.3e}")),
                ]
            })
            .collect::<Vec<_>>(),
    );
    if let Some(p) = r.peak_deg {
        rep.para(
            &format!(
                "The fitted trace peaks {:.3}° before TDC: the thermodynamic loss angle.",
                -p
            ),
            None,
        );
    }
    for n in &r.notes {
        rep.para(n, Some("note"));
    }
    // Per-TDC estimates and the recursive track with its interval.
    let x: Vec<f64> = r.events.iter().map(|e| e.t_s).collect();
    // Per parameter: [per TDC, recursive, its ± 1.96σ].
    let columns: Vec<[Vec<f64>; 4]> = (0..r.fitted.len())
        .map(|i| {
            let track = |f: &dyn Fn(&physid_apps::compression::EventFit) -> f64| {
                r.events.iter().map(f).collect::<Vec<f64>>()
            };
            [
                track(&|e| e.values[i]),
                track(&|e| e.recursive[i]),
                track(&|e| e.recursive[i] + 1.96 * e.recursive_std_err[i]),
                track(&|e| e.recursive[i] - 1.96 * e.recursive_std_err[i]),
            ]
        })
        .collect();
    let panels: Vec<Panel> = r
        .fitted
        .iter()
        .zip(&columns)
        .map(|(name, [per, fused, hi, lo])| {
            let unit = r.get(name).map_or(String::new(), |e| e.unit.clone());
            Panel {
                ylabel: format!("{name} [{unit}]"),
                series: vec![
                    Series {
                        name: "per TDC".into(),
                        x: &x,
                        y: per,
                        color: PALETTE[1],
                        reference: false,
                    },
                    Series {
                        name: "recursive".into(),
                        x: &x,
                        y: fused,
                        color: PALETTE[0],
                        reference: false,
                    },
                    Series {
                        name: "recursive ± 95 %".into(),
                        x: &x,
                        y: hi,
                        color: PALETTE[2],
                        reference: true,
                    },
                    Series {
                        name: String::new(),
                        x: &x,
                        y: lo,
                        color: PALETTE[2],
                        reference: true,
                    },
                ],
                ..Default::default()
            }
        })
        .collect();
    let svg = dir.join("compression_tracks.svg");
    plot::panels(
        &svg,
        "Estimates per TDC and recursively over the TDCs",
        "time at TDC [s]",
        &panels,
    )?;
    rep.svg(&svg)?;
    let t = &r.trace;
    let residual: Vec<f64> = t
        .measured
        .iter()
        .zip(&t.fitted)
        .map(|(m, f)| m - f)
        .collect();
    let svg = dir.join("compression_trace.svg");
    plot::panels(
        &svg,
        &format!("The last TDC (cycle {}): measured and fitted", t.cycle),
        "crank angle [deg ATDC]",
        &[
            Panel {
                ylabel: format!("{} [{}]", r.channel, r.unit),
                series: vec![
                    Series {
                        name: "measured".into(),
                        x: &t.atdc,
                        y: &t.measured,
                        color: PALETTE[1],
                        reference: true,
                    },
                    Series {
                        name: "fitted".into(),
                        x: &t.atdc,
                        y: &t.fitted,
                        color: PALETTE[0],
                        reference: false,
                    },
                ],
                ..Default::default()
            },
            Panel {
                ylabel: format!("residual [{}]", r.unit),
                series: vec![Series {
                    name: "measured − fitted".into(),
                    x: &t.atdc,
                    y: &residual,
                    color: PALETTE[0],
                    reference: false,
                }],
                ..Default::default()
            },
        ],
    )?;
    rep.svg(&svg)
}

/// `tracks.csv`: per TDC its time, cycle, speed, residual, each fitted parameter, its standard
/// error and the recursive estimate, with units.
fn write_tracks(path: &Path, r: &CompressionFit) -> Result<()> {
    let mut columns: Vec<(String, String)> = vec![
        ("t".into(), "s".into()),
        ("cycle".into(), "-".into()),
        ("rpm".into(), "rpm".into()),
        ("rms_residual".into(), r.unit.clone()),
    ];
    for name in &r.fitted {
        let unit = r
            .get(name)
            .map(|e| e.unit.clone())
            .ok_or_else(|| miette!("{name} has no estimate"))?;
        columns.push((name.clone(), unit.clone()));
        columns.push((format!("{name}_std_err"), unit.clone()));
        columns.push((format!("{name}_recursive"), unit));
    }
    let mut f = crate::tracks::TrackFile::create(path, columns)?;
    for e in &r.events {
        let mut row = vec![e.t_s, e.cycle as f64, e.rpm, e.rms_residual];
        for i in 0..r.fitted.len() {
            row.extend([e.values[i], e.std_err[i], e.recursive[i]]);
        }
        f.row(row)?;
    }
    f.close()
}
