//! `physid twin`: the self-calibrated test cell (issue 44; thesis §9.2; docs/twin.md) — the
//! virtual cell calibrated from a recording (`calibrate`) and checked against one (`check`).

use super::simulate::SetArgs;
use crate::out::outln;
use crate::report::{self, Report};
use miette::{miette, IntoDiagnostic, Result};
use physid_apps::twin::calibrate::DEFAULT_PARAMS;
use physid_apps::twin::{calibrate, CalibrateConfig, Calibration, Demand, Replay};
use physid_sim::params::CellParams;
use serde_json::json;
use std::path::{Path, PathBuf};

/// Arguments of `physid twin`.
#[derive(clap::Args)]
pub struct Args {
    #[command(subcommand)]
    what: What,
}

#[derive(clap::Subcommand)]
enum What {
    /// Which of the cell's physical parameters a recording resolves, their values and 95 %
    /// intervals: the cell driven by the recording's speed demand and throttle, its outputs
    /// matched degree by degree; the rest held at nominal, and said so.
    ///
    /// Example: physid twin calibrate --data run.parquet --out twin
    Calibrate(CalibrateArgs),
    /// The calibrated cell driven by a recording's inputs against the recording, channel by
    /// channel: NRMSE with the nominal cell and with the calibrated one, the band the residual
    /// is predicted to stay in (the noise and the calibration's covariance, from
    /// calibration.json beside the cell file) and where it leaves it.
    ///
    /// Example: physid twin check --data run.parquet --twin twin/cell.toml
    Check(super::twin_check::CheckArgs),
}

/// What both verbs read.
#[derive(clap::Args)]
pub(super) struct DataArgs {
    /// The recording, on a crank-angle basis (one sample per degree; `physid convert
    /// --crank-angle` converts a time-basis one): t, theta, speed_demand, throttle and the
    /// channels matched.
    #[arg(long, value_name = "FILE")]
    pub(super) data: PathBuf,
    #[command(flatten)]
    pub(super) input: super::InputArgs,
    /// The channels matched [default: those of omega_en, omega_dy, torque_shaft, p_int, p_cyl
    /// the recording has].
    #[arg(long, value_name = "CHANNELS", value_delimiter = ',')]
    pub(super) channels: Vec<String>,
    /// What the recording's speed_demand holds: the dynamometer's speed demand [rad/s] (speed)
    /// or, on a torque demand, its torque [N·m] (torque), replayed open loop from the
    /// recording's start [default: its metadata param.dyno.torque_mode, which physid simulate
    /// writes, else speed].
    #[arg(long, value_name = "speed|torque")]
    pub(super) demand: Option<String>,
    /// The nominal cell: the built-in one with these settings.
    #[command(flatten)]
    pub(super) set: SetArgs,
    /// Print the result as JSON.
    #[arg(long)]
    pub(super) json: bool,
}

impl DataArgs {
    /// The recording's replay and the nominal cell.
    pub(super) fn replay(&self) -> Result<(Replay, CellParams)> {
        let rec = super::InputArgs::read(&self.input, &self.data, None)?;
        let channels = (!self.channels.is_empty()).then_some(&self.channels[..]);
        let demand = match &self.demand {
            Some(d) => Some(d.parse::<Demand>().map_err(|e| miette!("--demand: {e}"))?),
            None => None,
        };
        let cell = self.set.params()?;
        let replay = Replay::new(&rec, channels, demand, &cell)
            .map_err(|e| miette!("--data {}: {e}", self.data.display()))?;
        Ok((replay, cell))
    }
}

#[derive(clap::Args)]
struct CalibrateArgs {
    #[command(flatten)]
    data: DataArgs,
    /// The cell parameters tried, by their --list-params paths, each with an optional nominal
    /// (starting) value PATH=VALUE [default: shaft.k, shaft.b, engine.inertia, dyno.inertia,
    /// engine.friction_scale, engine.kappa, engine.v_int, engine.m_rec at the cell's values].
    #[arg(long, value_name = "NAME=VALUE,…", value_delimiter = ',')]
    params: Vec<String>,
    /// A parameter is estimable while its relative standard error stays at or below this.
    #[arg(long, value_name = "FRACTION", default_value_t = 0.05, value_parser = super::range::positive)]
    max_rel_se: f64,
    /// The report directory: `cell.toml` — the calibrated cell as a scenario file, the
    /// recording's inputs replayed and the calibrated values in its `set` (what `physid simulate
    /// --scenario`, `physid twin check --twin` and `physid live --twin` take), the intervals in
    /// its header —, `report.html` and `calibration.json`.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Worker threads for the replays (0: every core).
    #[arg(long, default_value_t = 0)]
    threads: usize,
}

/// Run `physid twin`.
pub fn run(a: &Args) -> Result<()> {
    match &a.what {
        What::Calibrate(c) => run_calibrate(c),
        What::Check(c) => super::twin_check::run(c),
    }
}

fn run_calibrate(a: &CalibrateArgs) -> Result<()> {
    let (replay, mut cell) = a.data.replay()?;
    // PATH=VALUE: the nominal value set on the cell.
    let mut params = Vec::new();
    let mut nominal = Vec::new();
    for item in &a.params {
        match item.split_once('=') {
            Some((path, v)) => {
                let v: f64 = v
                    .trim()
                    .parse()
                    .map_err(|_| miette!("--params {item}: '{v}' is not a number"))?;
                cell.set(path.trim(), v)
                    .map_err(|e| miette!("--params {item}: {e}"))?;
                nominal.push((path.trim().to_string(), v));
                params.push(path.trim().to_string());
            }
            None => params.push(item.trim().to_string()),
        }
    }
    let cfg = CalibrateConfig {
        cell: cell.clone(),
        params: if params.is_empty() {
            DEFAULT_PARAMS.iter().map(|s| s.to_string()).collect()
        } else {
            params
        },
        max_rel_se: a.max_rel_se,
        threads: a.threads,
        ..CalibrateConfig::default()
    };
    let started = std::time::Instant::now();
    let cal = calibrate(&replay, &cfg).map_err(|e| miette!("{e}"))?;
    let seconds = started.elapsed().as_secs_f64();
    let json = calibration_json(&cal, seconds);
    if let Some(dir) = &a.out {
        report::create_dir(dir)?;
        write_cell(
            &dir.join("cell.toml"),
            &replay,
            &cell,
            &a.data.set,
            &nominal,
            &cal,
        )?;
        let mut rep = Report::new(
            "The self-calibrated cell: calibration",
            &a.data.data.display().to_string(),
        );
        report_body(&mut rep, &cal);
        report::finish(dir, rep, "calibration.json", &json)?;
    }
    if a.data.json {
        outln!("{}", serde_json::to_string(&json).into_diagnostic()?);
        return Ok(());
    }
    outln!(
        "{} samples per channel of {}; {} replays of the cell, {} Gauss–Newton iterations, {seconds:.1} s",
        cal.samples,
        cal.channels
            .iter()
            .map(|c| c.name.as_str())
            .collect::<Vec<_>>()
            .join(", "),
        cal.replays,
        cal.iterations
    );
    outln!(
        "{:<24} {:>5} {:>13} {:>13} {:>28}  ",
        "parameter",
        "rank",
        "nominal",
        "calibrated",
        "95 % interval"
    );
    for p in &cal.params {
        match p.ci95 {
            Some([lo, hi]) => outln!(
                "{:<24} {:>5} {:>13.6} {:>13.6} {:>13.6} … {:<13.6}",
                p.path,
                p.rank,
                p.nominal,
                p.value,
                lo,
                hi
            ),
            None => outln!(
                "{:<24} {:>5} {:>13.6} {:>13} {:>28}  held: {}",
                p.path,
                p.rank,
                p.nominal,
                "(nominal)",
                "",
                p.held.as_deref().unwrap_or("not estimable")
            ),
        }
    }
    outln!(
        "{:<16} {:>12} {:>14} {:>14}",
        "channel",
        "σ (fit)",
        "RMS nominal",
        "RMS calibrated"
    );
    for c in &cal.channels {
        outln!(
            "{:<16} {:>12.4e} {:>14.4e} {:>14.4e}",
            c.name,
            c.sigma,
            c.rms_nominal,
            c.rms_calibrated
        );
    }
    for (x, y, rho) in &cal.collinear {
        outln!("nearly collinear: {x} and {y} (correlation {rho:+.3})");
    }
    if let Some(dir) = &a.out {
        outln!("wrote {}", dir.join("cell.toml").display());
    }
    Ok(())
}

/// The report: the parameters (estimable with their intervals, held with the reason), the
/// channels' noise and residuals, the collinear pairs.
fn report_body(rep: &mut Report, cal: &Calibration) {
    rep.para(
        &format!(
            "{} samples per channel; {} replays of the cell, {} Gauss–Newton iterations (docs/twin.md).",
            cal.samples, cal.replays, cal.iterations
        ),
        None,
    );
    rep.section("Parameters");
    let rows: Vec<Vec<String>> = cal
        .params
        .iter()
        .map(|p| {
            vec![
                p.path.clone(),
                p.rank.to_string(),
                format!("{}", p.nominal),
                match p.ci95 {
                    Some([lo, hi]) => format!("{:.6} ({lo:.6} … {hi:.6})", p.value),
                    None => "held".into(),
                },
                p.held.clone().unwrap_or_default(),
            ]
        })
        .collect();
    rep.table(
        &[
            "parameter",
            "rank",
            "nominal",
            "calibrated (95 %)",
            "held because",
        ],
        &rows,
    );
    rep.section("Channels");
    let rows: Vec<Vec<String>> = cal
        .channels
        .iter()
        .map(|c| {
            vec![
                c.name.clone(),
                format!("{:.4e}", c.sigma),
                format!("{:.4e}", c.rms_nominal),
                format!("{:.4e}", c.rms_calibrated),
            ]
        })
        .collect();
    rep.table(
        &["channel", "σ (fit)", "RMS nominal", "RMS calibrated"],
        &rows,
    );
    for (x, y, rho) in &cal.collinear {
        rep.para(
            &format!("nearly collinear: {x} and {y} (correlation {rho:+.3})"),
            None,
        );
    }
}

/// The calibration as JSON: each parameter under its path.
fn calibration_json(cal: &Calibration, seconds: f64) -> serde_json::Value {
    let params: serde_json::Map<String, serde_json::Value> = cal
        .params
        .iter()
        .map(|p| {
            (
                p.path.clone(),
                json!({"value": p.value, "nominal": p.nominal, "std_err": p.std_err,
                       "ci95": p.ci95, "estimable": p.estimable, "rank": p.rank, "held": p.held}),
            )
        })
        .collect();
    json!({
        "params": params,
        "covariance": cal.covariance,
        "channels": cal.channels,
        "collinear": cal.collinear.iter().map(|(a, b, r)| json!({"a": a, "b": b, "correlation": r})).collect::<Vec<_>>(),
        "iterations": cal.iterations,
        "samples": cal.samples,
        "replays": cal.replays,
        "seconds": seconds,
    })
}

/// The calibrated cell as a scenario file: the replayed inputs, `set` the nominal settings and
/// the calibrated values, the calibration in its header. Written whole to a temporary file
/// first, then renamed: an interrupted write leaves the old file.
fn write_cell(
    path: &Path,
    replay: &Replay,
    cell: &CellParams,
    set: &SetArgs,
    nominal: &[(String, f64)],
    cal: &Calibration,
) -> Result<()> {
    let mut scenario = replay.scenario.clone();
    scenario.name = "twin".into();
    for (k, v) in set.pairs()?.into_iter().chain(nominal.iter().cloned()) {
        scenario.set.insert(k, v);
    }
    for p in cal.params.iter().filter(|p| p.estimable) {
        scenario.set.insert(p.path.clone(), p.value);
    }
    // The file is read back as it will be: a wrong value is found here, not by its reader.
    scenario.validate().map_err(|e| miette!("{e}"))?;
    cal.cell(cell).map_err(|e| miette!("{e}"))?;
    let mut head = String::from(
        "# physid twin calibrate: the virtual cell calibrated from a recording (docs/twin.md).\n\
         # The recording's inputs are replayed below; `set` holds the calibrated values.\n",
    );
    for p in &cal.params {
        head.push_str(&match p.ci95 {
            Some([lo, hi]) => format!(
                "# {} = {} (95 %: {lo} … {hi}; nominal {})\n",
                p.path, p.value, p.nominal
            ),
            None => format!(
                "# {} held at nominal {}: {}\n",
                p.path,
                p.nominal,
                p.held.as_deref().unwrap_or("not estimable")
            ),
        });
    }
    let text = scenario.to_toml().map_err(|e| miette!("{e}"))?;
    let tmp = path.with_extension("toml.partial");
    std::fs::write(&tmp, format!("{head}{text}"))
        .and_then(|_| std::fs::rename(&tmp, path))
        .map_err(|e| miette!("writing {}: {e}", path.display()))
}
