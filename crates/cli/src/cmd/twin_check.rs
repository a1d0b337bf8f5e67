//! `physid twin check`: the calibrated cell driven by a recording's inputs against the
//! recording — each channel's NRMSE with the nominal and the calibrated cell, the residual's
//! band from the calibration beside the cell file and where the residual leaves it, and with
//! `--out DIR` the report with the overlays (docs/twin.md).

use crate::out::outln;
use crate::report::{self, Report};
use miette::{miette, IntoDiagnostic, Result};
use physid_apps::twin::check::ChannelCheck;
use physid_apps::twin::{check, Replay, Uncertainty};
use physid_sim::scenario::Scenario;
use serde_json::json;
use std::path::{Path, PathBuf};

/// Arguments of `physid twin check`.
#[derive(clap::Args)]
pub struct CheckArgs {
    #[command(flatten)]
    data: super::twin::DataArgs,
    /// The calibrated cell: a scenario file whose `set` holds the calibrated values (`physid
    /// twin calibrate --out DIR` writes DIR/cell.toml, and beside it calibration.json, whose
    /// covariance and channel noise give the residual's band).
    #[arg(long, value_name = "FILE")]
    twin: PathBuf,
    /// The report directory: `report.html` (each channel measured against the nominal and
    /// the calibrated cell, the residual in its band) and `check.json`.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
}

/// Run `physid twin check`.
pub(super) fn run(a: &CheckArgs) -> Result<()> {
    let (replay, nominal) = a.data.replay()?;
    let twin = Scenario::load(&a.twin.to_string_lossy())
        .map_err(|e| miette!("--twin {}: {e}", a.twin.display()))?;
    let mut calibrated = nominal.clone();
    for (k, v) in &twin.set {
        calibrated
            .set(k, *v)
            .map_err(|e| miette!("--twin {}: {e}", a.twin.display()))?;
    }
    let (uncertainty, no_band) = uncertainty_beside(&a.twin)?;
    let checks =
        check(&replay, &nominal, &calibrated, uncertainty.as_ref()).map_err(|e| miette!("{e}"))?;
    let channels: serde_json::Map<String, serde_json::Value> = checks
        .iter()
        .map(|c| Ok((c.name.clone(), serde_json::to_value(c).into_diagnostic()?)))
        .collect::<Result<_>>()?;
    let json = json!({"channels": channels, "samples": replay.n, "no_band": no_band});
    if let Some(dir) = &a.out {
        report::write(
            dir,
            "The self-calibrated cell: check",
            &a.data.data,
            "check.json",
            &json,
            |rep, dir| check_report(rep, dir, &replay, &checks, no_band.as_deref()),
        )?;
    }
    if a.data.json {
        outln!("{}", serde_json::to_string(&json).into_diagnostic()?);
        return Ok(());
    }
    outln!(
        "{:<16} {:>14} {:>14} {:>8} {:>16}  {:>10} {:>11}",
        "channel",
        "NRMSE nominal",
        "NRMSE twin",
        "gain",
        "RMS twin",
        "σ (fit)",
        "out of band"
    );
    for c in &checks {
        let band = c.band.as_ref().map_or_else(
            || format!("{:>10} {:>11}", "—", "—"),
            |b| format!("{:>10.3e} {:>10.1} %", b.sigma, 100.0 * b.outside),
        );
        outln!(
            "{:<16} {:>14.3e} {:>14.3e} {:>7.1}× {:>12.4e} {:<3} {band}",
            c.name,
            c.nrmse_before,
            c.nrmse_after,
            c.nrmse_before / c.nrmse_after,
            c.rms_after,
            c.unit
        );
    }
    outln!(
        "(NRMSE: the residual's RMS over the measured channel's range, {} samples; out of band: samples outside the 95 % band, 5 % expected)",
        replay.n
    );
    match &no_band {
        Some(why) => outln!("no band: {why}"),
        None => {
            for c in &checks {
                for e in c.band.iter().flat_map(|b| &b.excursions) {
                    outln!(
                        "{}: the residual leaves its band from {:.3} s to {:.3} s ({:.0} % of the samples outside, up to {:.1}× the band)",
                        c.name,
                        e.t_from_s,
                        e.t_to_s,
                        100.0 * e.outside,
                        e.peak
                    );
                }
            }
        }
    }
    Ok(())
}

/// The band's inputs from `calibration.json` beside the cell file, or why there is no band
/// (no such file: a cell written by hand or by an older calibration). A file that is there but
/// unreadable is an error.
fn uncertainty_beside(cell: &Path) -> Result<(Option<Uncertainty>, Option<String>)> {
    let path = cell
        .parent()
        .unwrap_or_else(|| Path::new("."))
        .join("calibration.json");
    let text = match std::fs::read_to_string(&path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Ok((
                None,
                Some(format!(
                    "{} not found (physid twin calibrate --out DIR writes it beside DIR/cell.toml)",
                    path.display()
                )),
            ))
        }
        Err(e) => return Err(miette!("reading {}: {e}", path.display())),
    };
    let v: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| miette!("{}: {e}", path.display()))?;
    let u = Uncertainty::from_json(&v).map_err(|e| miette!("{}: {e}", path.display()))?;
    Ok((Some(u), None))
}

/// The check's report: the table, then per channel the measured values against the nominal
/// and the calibrated cell, and the calibrated cell's residual in its band.
fn check_report(
    rep: &mut Report,
    dir: &Path,
    replay: &Replay,
    checks: &[ChannelCheck],
    no_band: Option<&str>,
) -> Result<()> {
    use crate::plot::{self, Panel, Series, PALETTE};
    rep.para(
        &format!(
            "The calibrated cell driven by the recording's speed demand and throttle, {} samples per channel against the recording; the residual's 95 % band is the channel's noise at the calibration and the calibrated parameters' covariance carried through the cell (docs/twin.md).",
            replay.n
        ),
        None,
    );
    if let Some(why) = no_band {
        rep.para(&format!("No band: {why}."), None);
    }
    let rows: Vec<Vec<String>> = checks
        .iter()
        .map(|c| {
            let mut row = vec![
                c.name.clone(),
                c.unit.clone(),
                format!("{:.3e}", c.nrmse_before),
                format!("{:.3e}", c.nrmse_after),
                format!("{:.1}", c.nrmse_before / c.nrmse_after),
            ];
            match &c.band {
                Some(b) => row.extend([
                    format!("{:.3e}", b.sigma),
                    format!("{:.3e}", b.param_sd),
                    format!("{:.1}", 100.0 * b.outside),
                    b.excursions
                        .iter()
                        .map(|e| format!("{:.3}–{:.3} s", e.t_from_s, e.t_to_s))
                        .collect::<Vec<_>>()
                        .join(", "),
                ]),
                None => row.extend(["—".into(), "—".into(), "—".into(), String::new()]),
            }
            row
        })
        .collect();
    rep.table(
        &[
            "channel",
            "unit",
            "NRMSE nominal",
            "NRMSE twin",
            "gain ×",
            "σ (fit)",
            "parameters' σ (RMS)",
            "outside the band [%]",
            "leaves the band",
        ],
        &rows,
    );
    for (c, ch) in checks.iter().enumerate() {
        rep.section(&format!("{} [{}]", ch.name, ch.unit));
        let measured = &replay.measured[c];
        let residual: Vec<f64> = measured.iter().zip(&ch.after).map(|(m, y)| m - y).collect();
        let mut panels = vec![Panel {
            ylabel: format!("{} [{}]", ch.name, ch.unit),
            series: vec![
                Series {
                    name: "measured".into(),
                    x: &replay.t,
                    y: measured,
                    color: plot::REFERENCE,
                    reference: true,
                },
                Series {
                    name: "nominal cell".into(),
                    x: &replay.t,
                    y: &ch.before,
                    color: PALETTE[1],
                    reference: false,
                },
                Series {
                    name: "calibrated cell".into(),
                    x: &replay.t,
                    y: &ch.after,
                    color: PALETTE[0],
                    reference: false,
                },
            ],
            ..Default::default()
        }];
        let (hi, lo): (Vec<f64>, Vec<f64>) = match &ch.band {
            Some(b) => (
                b.half_width.clone(),
                b.half_width.iter().map(|h| -h).collect(),
            ),
            None => (Vec::new(), Vec::new()),
        };
        // The band over the residual, in a colour apart from it.
        let mut series = vec![Series {
            name: "residual".into(),
            x: &replay.t,
            y: &residual,
            color: PALETTE[0],
            reference: false,
        }];
        if !hi.is_empty() {
            series.push(Series {
                name: "95 % band".into(),
                x: &replay.t,
                y: &hi,
                color: PALETTE[4],
                reference: false,
            });
            series.push(Series {
                name: String::new(),
                x: &replay.t,
                y: &lo,
                color: PALETTE[4],
                reference: false,
            });
        }
        let marks = ch
            .band
            .iter()
            .flat_map(|b| &b.excursions)
            .flat_map(|e| {
                [
                    plot::Mark::instant("leaves the band", e.t_from_s, plot::ALARM),
                    plot::Mark::instant("leaves the band", e.t_to_s, plot::ALARM),
                ]
            })
            .collect();
        panels.push(Panel {
            ylabel: format!("residual [{}]", ch.unit),
            series,
            marks,
            ..Default::default()
        });
        let svg = dir.join(format!("check-{}.svg", ch.name));
        plot::panels(
            &svg,
            &format!("{}: the recording against the cell", ch.name),
            "time [s]",
            &panels,
        )?;
        rep.svg(&svg)?;
    }
    Ok(())
}
