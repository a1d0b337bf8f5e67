//! `physid monitor shaft`: coupling-shaft health monitoring (thesis ch. 6).

use super::InputArgs;
use crate::out::outln;
use crate::plot::{self, Mark, Panel, Series, PALETTE};
use crate::progress::Reading;
use crate::report::{self, Report};
use crate::tracks::TrackFile;
use miette::{miette, Result};
use physid_apps::acquisition::file_time_basis_chunks;
use physid_apps::shaft_monitor::{
    monitor_shaft_tracked, MonitorConfig, MonitorMethod, ShaftAlarm, ShaftMonitor, ShaftParams,
    ShaftSample, SHAFT_CHANNELS, SHAFT_TRUTH,
};
use physid_core::Basis;
use std::path::{Path, PathBuf};

/// Arguments of `physid monitor`.
#[derive(clap::Args)]
pub struct Args {
    #[command(subcommand)]
    what: What,
}

#[derive(clap::Subcommand)]
enum What {
    /// Track the coupling shaft's stiffness K and damping B and raise alarms when they move.
    ///
    /// Example: physid monitor shaft --data t01.parquet --healthy K=1250,B=0.95 --out report
    Shaft(ShaftArgs),
}

#[derive(clap::Args)]
struct ShaftArgs {
    /// Recording with theta_dy, theta_en, omega_dy, omega_en, torque_shaft on a uniform time
    /// basis (CSV, Parquet or MDF4).
    #[arg(long, value_name = "FILE")]
    data: PathBuf,
    #[command(flatten)]
    input: InputArgs,
    #[command(flatten)]
    monitor: MonitorFlags,
    /// Print JSON.
    #[arg(long)]
    json: bool,
    /// Directory for the report (report.html, shaft.svg, shaft.json).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Write every estimator sample — t, K, B and their standard errors, τ0, the alarms (1 once
    /// raised) and with --supervise the frozen flags — to this file (.csv, .parquet or .mf4),
    /// with units, as they come.
    #[arg(long, value_name = "FILE")]
    tracks: Option<PathBuf>,
}

/// The tracks file's columns (name, unit).
fn track_columns(cfg: &MonitorConfig) -> Vec<(String, String)> {
    let mut c: Vec<(String, String)> = [
        ("t", "s"),
        ("K", "N*m/rad"),
        ("K_std_err", "N*m/rad"),
        ("B", "N*m*s/rad"),
        ("B_std_err", "N*m*s/rad"),
        ("tau0", "N*m"),
        ("alarm_K", "-"),
        ("alarm_B", "-"),
    ]
    .iter()
    .map(|(n, u)| (n.to_string(), u.to_string()))
    .collect();
    if cfg.supervise {
        for p in ["K", "B", "tau0"] {
            c.push((format!("frozen_{p}"), "-".into()));
        }
    }
    c
}

/// The shaft monitor's settings, shared by `monitor shaft` and `live`.
#[derive(clap::Args, Clone)]
pub struct MonitorFlags {
    /// Estimator: rlsf (RLS with forgetting λ), rlsvf (vector forgetting) or dsfc — the names
    /// `physid estimate` gives them ('rls', the old name of rlsf here, is taken for this
    /// release with a warning).
    #[arg(long, default_value = "rlsf")]
    method: String,
    /// Forgetting factor, 0 < λ ≤ 1.
    #[arg(long, value_name = "LAMBDA", default_value_t = 0.98, value_parser = super::range::forgetting, allow_negative_numbers = true)]
    lambda: f64,
    /// Healthy values K=…,B=… (the alarms' reference) [default: Table 6.1, 1250 and 0.95].
    #[arg(long, value_name = "K=…,B=…", value_delimiter = ',')]
    healthy: Vec<String>,
    /// Start the estimator at the healthy values instead of 0.
    #[arg(long)]
    start_healthy: bool,
    /// Relative-error bound (Eq. 6.3), > 0.
    #[arg(long, value_name = "FRACTION", default_value_t = 0.1, value_parser = super::range::positive, allow_negative_numbers = true)]
    bound: f64,
    /// Estimator samples beyond the bound before an alarm.
    #[arg(long, value_name = "N", default_value_t = 200)]
    dwell: u64,
    /// Zero-phase low-pass cut-off before estimation [Hz].
    #[arg(long, value_name = "HZ", default_value_t = 500.0, value_parser = super::range::positive, allow_negative_numbers = true)]
    lowpass: f64,
    /// Deprecated: --lowpass.
    #[arg(long = "cutoff", hide = true, conflicts_with = "lowpass", value_parser = super::range::positive, allow_negative_numbers = true)]
    cutoff_old: Option<f64>,
    /// Estimator updates per second [Hz], > 0 (the low-passed signals are taken at this rate;
    /// at most the recording's sample rate: every sample).
    #[arg(long, value_name = "HZ", default_value_t = 2000.0, value_parser = super::range::positive, allow_negative_numbers = true)]
    update_rate: f64,
    /// Deprecated: --update-rate.
    #[arg(long = "rate", hide = true, conflicts_with = "update_rate", value_parser = super::range::positive, allow_negative_numbers = true)]
    rate_old: Option<f64>,
    /// Freeze K or B while the data no longer resolve them, release them when they do again
    /// (the excitation supervisor: on-line identifiability over the last 0.1 s, thesis §9.2).
    #[arg(long)]
    supervise: bool,
}

/// Run `physid monitor`.
pub fn run(args: &Args) -> Result<()> {
    match &args.what {
        What::Shaft(a) => shaft(a),
    }
}

/// The monitor's configuration from the flags.
pub fn config(a: &MonitorFlags) -> Result<MonitorConfig> {
    let method = a
        .method
        .parse::<MonitorMethod>()
        .map_err(|e| miette!("--method {e}"))?;
    if MonitorMethod::is_old_name(&a.method) {
        super::deprecated(
            "--method rls is RLS with forgetting in the shaft monitor, now called rlsf as in physid estimate (where rls has no forgetting)",
        );
    }
    let mut cfg = MonitorConfig {
        method,
        lambda: a.lambda,
        bound: a.bound,
        dwell: a.dwell,
        cutoff_hz: super::renamed(a.cutoff_old, "--cutoff", "--lowpass").unwrap_or(a.lowpass),
        rate_hz: super::renamed(a.rate_old, "--rate", "--update-rate").unwrap_or(a.update_rate),
        supervise: a.supervise,
        ..Default::default()
    };
    let (names, values) = super::named_values(&a.healthy, "--healthy")?;
    for (n, v) in names.iter().zip(values) {
        match n.as_str() {
            "K" => cfg.healthy.k = v,
            "B" => cfg.healthy.b = v,
            other => return Err(miette!("--healthy {other}: the parameters are K and B")),
        }
    }
    if a.start_healthy {
        cfg.theta0 = ShaftParams {
            k: cfg.healthy.k,
            b: cfg.healthy.b,
            tau0: 0.0,
        };
    }
    Ok(cfg)
}

/// Write the shaft section of a report (and its SVG into `dir`).
pub fn report_section(
    rep: &mut Report,
    r: &ShaftMonitor,
    cfg: &MonitorConfig,
    dir: &Path,
) -> Result<()> {
    rep.section("Coupling-shaft health (thesis ch. 6)");
    rep.para(
        &format!(
            "τ_sh = K·Δθ + B·Δω + τ0 (Eq. 6.1) tracked by {} (λ = {}) at {} Hz: {}, then one sample in {} taken from the recording's {} Hz. Alarms when |ϑ_healthy − ϑ̂|/ϑ_healthy > {} for {} samples (Eq. 6.3; the change reported is (ϑ̂ − ϑ_healthy)/ϑ_healthy), healthy K = {} N·m/rad, B = {} N·m·s/rad.",
            r.method,
            cfg.lambda,
            r.input_rate_hz / r.every as f64,
            r.lowpass_hz.map_or_else(
                || "Δθ, Δω and τ_sh unfiltered (the low-pass cut-off is above the Nyquist frequency)".to_string(),
                |f| format!("Δθ, Δω and τ_sh low-passed at {f} Hz (zero phase, Butterworth of order 4)")
            ),
            r.every,
            r.input_rate_hz,
            cfg.bound,
            cfg.dwell,
            cfg.healthy.k,
            cfg.healthy.b
        ),
        None,
    );
    rep.table(
        &["parameter", "final estimate", "std error", "NMSE vs truth"],
        &[
            vec![
                "K [N·m/rad]".into(),
                format!("{:.2}", r.final_estimate.k),
                format!("{:.3e}", r.final_std_err.k),
                r.nmse.map_or("—".into(), |n| format!("{:.2e}", n.k)),
            ],
            vec![
                "B [N·m·s/rad]".into(),
                format!("{:.4}", r.final_estimate.b),
                format!("{:.3e}", r.final_std_err.b),
                r.nmse.map_or("—".into(), |n| format!("{:.2e}", n.b)),
            ],
            vec![
                "τ0 [N·m]".into(),
                format!("{:.4}", r.final_estimate.tau0),
                format!("{:.3e}", r.final_std_err.tau0),
                "—".into(),
            ],
        ],
    );
    if r.alarms.is_empty() {
        rep.para("No alarm.", Some("ok"));
    } else {
        for a in &r.alarms {
            rep.para(
                &format!(
                    "ALARM: {} moved — beyond the bound from t = {:.3} s (raised at {:.3} s), changed by {:+.1} % from healthy.",
                    a.param,
                    a.t_start_s,
                    a.t_raised_s,
                    100.0 * a.change
                ),
                Some("alarm"),
            );
        }
    }
    let svg = dir.join("shaft.svg");
    plot_tracks(r, cfg, &svg)?;
    rep.svg(&svg)
}

/// K and B over time: the estimate, its ±3σ band, the truth when known, the healthy value and
/// the alarm bounds around it (Eq. 6.3), and the instants alarms were raised.
fn plot_tracks(r: &ShaftMonitor, cfg: &MonitorConfig, path: &Path) -> Result<()> {
    // Leave out the estimator's first 0.1 s: from ϑ0 = 0 its start-up spans orders of
    // magnitude and would flatten everything after it.
    let start = r.t.iter().position(|&t| t - r.t[0] >= 0.1).unwrap_or(0);
    let r = &ShaftMonitor {
        t: r.t[start..].to_vec(),
        k: r.k[start..].to_vec(),
        b: r.b[start..].to_vec(),
        tau0: r.tau0[start..].to_vec(),
        std_err: r.std_err[start..].to_vec(),
        truth: r
            .truth
            .as_ref()
            .map(|(k, b)| (k[start..].to_vec(), b[start..].to_vec())),
        ..r.clone()
    };
    let band = |v: &[f64], k: usize, sign: f64| -> Vec<f64> {
        v.iter()
            .zip(&r.std_err)
            .map(|(x, s)| x + sign * 3.0 * s[k])
            .collect()
    };
    let (k_hi, k_lo, b_hi, b_lo) = (
        band(&r.k, 0, 1.0),
        band(&r.k, 0, -1.0),
        band(&r.b, 1, 1.0),
        band(&r.b, 1, -1.0),
    );
    let mut panels = Vec::new();
    for (param, label, est, hi, lo, truth, healthy) in [
        (
            "K",
            "K [N·m/rad]",
            &r.k,
            &k_hi,
            &k_lo,
            r.truth.as_ref().map(|t| &t.0),
            cfg.healthy.k,
        ),
        (
            "B",
            "B [N·m·s/rad]",
            &r.b,
            &b_hi,
            &b_lo,
            r.truth.as_ref().map(|t| &t.1),
            cfg.healthy.b,
        ),
    ] {
        // The band first, light; the estimate over it; the truth thick and pale.
        let band = plot::BAND;
        let mut series = vec![
            Series {
                name: "±3σ".into(),
                x: &r.t,
                y: hi,
                color: band,
                reference: false,
            },
            Series {
                name: String::new(),
                x: &r.t,
                y: lo,
                color: band,
                reference: false,
            },
            Series {
                name: "estimate".into(),
                x: &r.t,
                y: est,
                color: PALETTE[0],
                reference: false,
            },
        ];
        if let Some(tv) = truth {
            series.insert(
                0,
                Series {
                    name: "truth (simulated)".into(),
                    x: &r.t,
                    y: tv,
                    color: PALETTE[1],
                    reference: true,
                },
            );
        }
        let bound = format!("alarm bounds (±{} %)", 100.0 * cfg.bound);
        let mut marks = vec![
            Mark::value("healthy", healthy, plot::REFERENCE),
            Mark::value(bound.as_str(), healthy * (1.0 + cfg.bound), PALETTE[3]),
            Mark::value(bound.as_str(), healthy * (1.0 - cfg.bound), PALETTE[3]),
        ];
        for a in r.alarms.iter().filter(|a| a.param == param) {
            marks.push(Mark::instant("alarm raised", a.t_raised_s, plot::ALARM));
        }
        panels.push(Panel {
            ylabel: label.into(),
            series,
            marks,
            ..Default::default()
        });
    }
    plot::panels(
        path,
        "Shaft stiffness and damping, tracked",
        "time [s]",
        &panels,
    )
}

fn shaft(a: &ShaftArgs) -> Result<()> {
    let cfg = config(&a.monitor)?;
    // The file read a chunk at a time, only the channels the monitor takes; a crank-angle
    // recording is put on a time basis as it is read.
    let mut reader = a.input.open(&a.data, &SHAFT_CHANNELS, &SHAFT_TRUTH)?;
    let mut tracks = match &a.tracks {
        Some(path) => Some(TrackFile::create(path, track_columns(&cfg))?),
        None => None,
    };
    let mut sink = |samples: &[ShaftSample], alarms: &[ShaftAlarm]| -> Result<(), String> {
        let Some(tf) = tracks.as_mut() else {
            return Ok(());
        };
        for s in samples {
            let alarm = |p: &str| {
                f64::from(u8::from(
                    alarms
                        .iter()
                        .any(|al| al.param == p && al.t_raised_s <= s.t_s),
                ))
            };
            let mut row = vec![
                s.t_s,
                s.estimate.k,
                s.std_err.k,
                s.estimate.b,
                s.std_err.b,
                s.estimate.tau0,
                alarm("K"),
                alarm("B"),
            ];
            if cfg.supervise {
                row.extend(s.frozen.map(|f| f64::from(u8::from(f))));
            }
            tf.row(row).map_err(|e| e.to_string())?;
        }
        Ok(())
    };
    let r = if reader.header().basis == Basis::CrankAngle {
        // At the mean rate of the whole recording, resampled as it is read.
        let header = reader.header().clone();
        let timed = file_time_basis_chunks(
            &a.data,
            &a.input.options(None)?,
            &header,
            Reading::new(&mut reader, &a.data),
        )
        .map_err(super::app_error(&a.data))?;
        monitor_shaft_tracked(timed, &cfg, &mut sink)
    } else {
        monitor_shaft_tracked(Reading::new(&mut reader, &a.data), &cfg, &mut sink)
    }
    .map_err(super::app_error(&a.data))?;
    if let Some(tf) = tracks {
        tf.close()?;
    }
    super::warn_read(&reader, &a.data);
    for w in &r.warnings {
        eprintln!("warning: {}: {w}", a.data.display());
    }
    let j = r.summary();
    if let Some(dir) = &a.out {
        report::write(
            dir,
            "physid — shaft monitor",
            &a.data,
            "shaft.json",
            &j,
            |rep, dir| report_section(rep, &r, &cfg, dir),
        )?;
    }
    if a.json {
        crate::provenance::print_json(&j)?;
        return Ok(());
    }
    outln!(
        "{}: {} over {} samples",
        a.data.display(),
        r.method,
        r.t.len()
    );
    outln!(
        "  K = {:.2} ± {:.2e} N·m/rad, B = {:.4} ± {:.2e} N·m·s/rad, τ0 = {:.4} N·m",
        r.final_estimate.k,
        r.final_std_err.k,
        r.final_estimate.b,
        r.final_std_err.b,
        r.final_estimate.tau0
    );
    if !r.unresolved.is_empty() {
        outln!(
            "  not resolved by the data: {} (their variance did not halve from P0: the value is the estimator's start, not the shaft's; no alarm is raised on it)",
            r.unresolved.join(", ")
        );
    }
    if r.nmse.is_some_and(|n| n.k.is_nan() && n.b.is_nan()) {
        outln!(
            "  NMSE against the recording's truth: none — the recording ends within the monitor's \
             {} s start-up",
            cfg.settle_s
        );
    } else if let Some(n) = r.nmse {
        outln!(
            "  NMSE against the recording's truth: K {:.2e}, B {:.2e}",
            n.k,
            n.b
        );
    }
    if r.alarms.is_empty() {
        outln!("  no alarm");
    }
    for al in &r.alarms {
        outln!(
            "  ALARM {}: from t = {:.3} s (raised {:.3} s), changed by {:+.1} % from healthy",
            al.param,
            al.t_start_s,
            al.t_raised_s,
            100.0 * al.change
        );
    }
    if let Some(dir) = &a.out {
        outln!("wrote {}", dir.join("report.html").display());
    }
    Ok(())
}
