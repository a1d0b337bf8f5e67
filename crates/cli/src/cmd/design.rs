//! `physid design`: which test makes an application's parameters estimable by its recursive
//! estimator, within the cell's limits, to what standard error, in how long (issue 45;
//! docs/design.md).

use super::simulate::SetArgs;
use crate::out::outln;
use crate::plot::{self, Panel, Series, PALETTE};
use crate::progress::Progress;
use crate::report::{self, Report};
use miette::{miette, IntoDiagnostic, Result};
use physid_apps::design::information::Criterion;
use physid_apps::design::profile::{Limits, ThrottleDraw};
use physid_apps::design::shaft::{design_shaft, select, ShaftDesign, PARAMS};
use physid_apps::design::{Design, Designed};
use physid_apps::shaft_monitor::{MonitorConfig, MonitorMethod};
use std::path::PathBuf;
use std::sync::Mutex;

/// Arguments of `physid design`.
#[derive(clap::Args)]
pub struct Args {
    /// The application: shaft (Application 1, K, B and the offset τ0 of Eq. 6.1). The friction
    /// and cyclic-torque applications are not designed for yet.
    #[arg(long, value_parser = ["shaft"], default_value = "shaft")]
    app: String,
    /// The parameters to design for (the others are estimated alongside), e.g. K,B; with a
    /// value, the nominal value the test is designed at (K=1340 sets the cell's shaft.k),
    /// otherwise the cell's.
    #[arg(
        long,
        value_name = "NAME=VALUE,…",
        value_delimiter = ',',
        default_value = "K,B"
    )]
    params: Vec<String>,
    /// How candidates are ranked: d (the confidence ellipsoid's volume), a (the mean
    /// variance), e (the worst direction) — each the mean over the test after the estimator's
    /// start-up, relative to the nominal values — or time (the shortest time until every
    /// relative standard error stays below --target-rel-se; the test is cut there).
    #[arg(long, default_value = "d")]
    criterion: Criterion,
    /// The relative standard error wanted for each parameter, e.g. 0.01 (reported as the time
    /// each test takes to reach it; the time criterion's target).
    #[arg(long, value_name = "FRACTION", value_parser = super::range::positive)]
    target_rel_se: Option<f64>,
    /// The cell's limits, comma-separated or repeated: speed=LOW:HIGH [rpm],
    /// throttle=LOW:HIGH [deg], dspeed=RATE (the speed demand's largest rate) [rpm/s]
    /// [default: speed=800:3000,throttle=0:90,dspeed=500].
    #[arg(long, value_name = "NAME=LOW:HIGH", value_delimiter = ',')]
    limits: Vec<String>,
    /// Each candidate test's duration [s].
    #[arg(long, visible_alias = "max-duration", value_name = "S", default_value_t = 120.0, value_parser = super::range::positive)]
    duration: f64,
    /// How many candidate profiles (drawn from the families steps, ramps, APRBS, multisine
    /// and constant in turn).
    #[arg(long, value_name = "N", default_value_t = 200)]
    candidates: usize,
    /// The candidates' random seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Worker threads (0: every core).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// The recording's sample rate the monitor will read [Hz].
    #[arg(long, value_name = "HZ", default_value_t = 10_000.0, value_parser = super::range::positive)]
    sample_rate: f64,
    /// The shaft monitor's estimator: rlsf (RLS with forgetting λ) or dsfc (its square-root
    /// form, the same estimates).
    #[arg(long, default_value = "rlsf")]
    method: String,
    /// The estimator's forgetting factor, 0 < λ ≤ 1.
    #[arg(long, value_name = "LAMBDA", default_value_t = 0.98, value_parser = super::range::forgetting, allow_negative_numbers = true)]
    lambda: f64,
    /// The monitor's zero-phase low-pass cut-off before estimation [Hz].
    #[arg(long, value_name = "HZ", default_value_t = 500.0, value_parser = super::range::positive, allow_negative_numbers = true)]
    lowpass: f64,
    /// The monitor's estimator updates per second [Hz].
    #[arg(long, value_name = "HZ", default_value_t = 2000.0, value_parser = super::range::positive, allow_negative_numbers = true)]
    update_rate: f64,
    #[command(flatten)]
    set: SetArgs,
    /// The design's directory: scenario.toml (the designed test, which `physid simulate
    /// --scenario DIR/scenario.toml` runs), design.json, report.html and its SVGs.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Print the result as JSON (the scenario, `predicted_std_err`, the curves, the thesis's
    /// test judged alike, the ranking).
    #[arg(long)]
    json: bool,
}

/// Run `physid design`.
pub fn run(a: &Args) -> Result<()> {
    let limits = Limits::parse(&a.limits.join(",")).map_err(|e| miette!("--limits {e}"))?;
    let method = a
        .method
        .parse::<MonitorMethod>()
        .map_err(|e| miette!("--method {e}"))?;
    let mut cell = a.set.params()?;
    let mut set = a.set.pairs()?;
    let chosen = select(&a.params, &mut cell).map_err(|e| miette!("{e}"))?;
    set.extend(chosen.set);
    let selected = chosen.selected;
    let shaft = ShaftDesign {
        monitor: MonitorConfig {
            method,
            lambda: a.lambda,
            cutoff_hz: a.lowpass,
            rate_hz: a.update_rate,
            ..MonitorConfig::default()
        },
        cell,
        rate_hz: a.sample_rate,
    };
    let design = Design {
        names: PARAMS.iter().map(|s| s.to_string()).collect(),
        selected,
        criterion: a.criterion,
        target_rel_se: a.target_rel_se,
        limits,
        throttle: ThrottleDraw::Linear,
        duration: a.duration,
        candidates: a.candidates,
        seed: a.seed,
        threads: a.threads,
    };
    let bar = Mutex::new(Progress::new("designing", Some(a.candidates as u64)));
    let r = design_shaft(&shaft, &design, &set, &|done| {
        if let Ok(mut b) = bar.lock() {
            b.set(done as u64);
        }
    })
    .map_err(|e| miette!("{e}"))?;
    drop(bar);
    if let Some(dir) = &a.out {
        report::create_dir(dir)?;
        let text = r.scenario.to_toml().map_err(|e| miette!("{e}"))?;
        let path = dir.join("scenario.toml");
        std::fs::write(&path, format!("{}{text}", header(&r)))
            .map_err(|e| miette!("--out {}: {e}", path.display()))?;
        let mut rep = Report::new(
            "Experiment design: the shaft monitor",
            &format!(
                "{} of K, B, τ0 (Eq. 6.1), λ = {}, {} Hz updates after a {} Hz low-pass, from a {} Hz recording",
                shaft.monitor.method.name(),
                shaft.monitor.lambda,
                shaft.monitor.rate_hz,
                shaft.monitor.cutoff_hz,
                shaft.rate_hz
            ),
        );
        report_body(&mut rep, &r, dir)?;
        report::finish(dir, rep, "design.json", &r)?;
    }
    if a.json {
        outln!("{}", serde_json::to_string(&r).into_diagnostic()?);
        return Ok(());
    }
    print(&r, a);
    Ok(())
}

/// The predicted standard error of the `k`-th parameter where the designed test ends.
fn end(r: &Designed, k: usize) -> f64 {
    r.predicted_std_err
        .get(&r.params[k])
        .copied()
        .unwrap_or(f64::NAN)
}

/// The scenario file's comment: what it was designed for and what it predicts.
fn header(r: &Designed) -> String {
    let mut s = format!(
        "# Designed by physid design for {} ({:?} criterion) over {} candidates.\n",
        r.params.join(", "),
        r.criterion,
        r.evaluated
    );
    for (p, se) in &r.predicted_std_err {
        s.push_str(&format!(
            "# predicted standard error of {p} at the end: {se:.4e}\n"
        ));
    }
    s
}

/// The report: the chosen profile, its predicted standard errors along the test beside the
/// thesis's tests', and the candidates' ranking.
fn report_body(rep: &mut Report, r: &Designed, dir: &std::path::Path) -> Result<()> {
    rep.section("The designed test");
    rep.para(
        &format!(
            "{} candidate profiles (steps, ramps, APRBS, multisines and held operating points within the limits) were each run on the virtual cell without noise and put through the monitor's own low-pass and decimation; the information its estimator gathers with its forgetting, and the noise's autocovariance after the low-pass, give the covariance of its estimates at every moment (docs/design.md). Chosen by the {:?} criterion over the test after the estimator's start-up: {} ({}).",
            r.evaluated,
            r.criterion,
            r.chosen.name,
            r.chosen.family.map_or("thesis test", |f| f.name())
        ),
        None,
    );
    let mut rows = Vec::new();
    for (k, p) in r.params.iter().enumerate() {
        let mut row = vec![
            p.clone(),
            format!("{:.4e}", end(r, k)),
            format!(
                "{:.3e}",
                end(r, k) * r.chosen.rel_std_err[k] / r.chosen.std_err[k]
            ),
            format!("{:.3e}", r.chosen.median_rel_std_err[k]),
        ];
        for b in &r.baselines {
            row.push(format!("{:.3e}", b.median_rel_std_err[k]));
        }
        rows.push(row);
    }
    let names: Vec<String> = r
        .baselines
        .iter()
        .map(|b| {
            format!(
                "{}: median relative{}",
                b.name,
                if b.within_limits {
                    ""
                } else {
                    " (outside the limits)"
                }
            )
        })
        .collect();
    let mut head = vec![
        "parameter",
        "std err at the end",
        "relative",
        "median relative",
    ];
    head.extend(names.iter().map(String::as_str));
    rep.table(&head, &rows);
    let dt = 0.05;
    let n = (r.scenario.duration / dt).ceil() as usize;
    let t: Vec<f64> = (0..=n).map(|k| k as f64 * dt).collect();
    let speed: Vec<f64> = t.iter().map(|&t| r.scenario.speed.value(t)).collect();
    let throttle: Vec<f64> = t.iter().map(|&t| r.scenario.throttle.value(t)).collect();
    // A held level's axis around it, not down to its last digit.
    let around = |v: &[f64], pad: f64| {
        let (lo, hi) = v
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            });
        Some((lo - pad, hi + pad))
    };
    let rel: Vec<Vec<(Vec<f64>, Vec<f64>)>> = std::iter::once(&r.chosen)
        .chain(&r.baselines)
        .map(|e| {
            let t0 = e.curve.t.first().copied().unwrap_or(0.0);
            e.curve
                .std_err
                .iter()
                .zip(&e.rel_std_err)
                .zip(&e.std_err)
                .map(|((c, rel), abs)| {
                    let scale = if *abs > 0.0 { rel / abs } else { 1.0 };
                    (
                        e.curve.t.iter().map(|x| x - t0).collect(),
                        c.iter().map(|v| v * scale).collect(),
                    )
                })
                .collect()
        })
        .collect();
    let mut panels = vec![
        Panel {
            ylabel: "speed demand [rpm]".into(),
            series: vec![Series {
                name: "designed".into(),
                x: &t,
                y: &speed,
                color: PALETTE[0],
                reference: false,
            }],
            y_range: around(&speed, 50.0),
            ..Default::default()
        },
        Panel {
            ylabel: "throttle [deg]".into(),
            series: vec![Series {
                name: "designed".into(),
                x: &t,
                y: &throttle,
                color: PALETTE[0],
                reference: false,
            }],
            y_range: around(&throttle, 5.0),
            ..Default::default()
        },
    ];
    for (k, p) in r.params.iter().enumerate() {
        let mut series = Vec::new();
        for (j, curves) in rel.iter().enumerate() {
            let name = if j == 0 {
                "designed".to_string()
            } else {
                r.baselines[j - 1].name.clone()
            };
            series.push(Series {
                name,
                x: &curves[k].0,
                y: &curves[k].1,
                color: PALETTE[j % PALETTE.len()],
                reference: j > 0,
            });
        }
        panels.push(Panel {
            ylabel: format!("σ({p}) / {p} (predicted)"),
            series,
            ..Default::default()
        });
    }
    let svg = dir.join("design.svg");
    plot::panels(
        &svg,
        "The designed test and its predicted errors",
        "time [s]",
        &panels,
    )?;
    rep.svg(&svg)?;
    rep.section("Candidates");
    let rows: Vec<Vec<String>> = r
        .ranking
        .iter()
        .take(20)
        .map(|(n, f, s)| vec![n.clone(), f.name().to_string(), format!("{s:.4}")])
        .collect();
    rep.table(
        &["candidate (best 20)", "family", "criterion (mean)"],
        &rows,
    );
    if !r.unidentifiable.is_empty() {
        rep.para(
            &format!(
                "Structurally unidentifiable on these limits: {}.",
                r.unidentifiable.join(", ")
            ),
            Some("alarm"),
        );
    }
    Ok(())
}

fn print(r: &Designed, a: &Args) {
    outln!(
        "designed {} ({}) from {} candidates in {:.1} s",
        r.chosen.name,
        r.chosen.family.map_or("thesis test", |f| f.name()),
        r.evaluated,
        r.elapsed_s
    );
    outln!(
        "{:<8} {:>14} {:>12} {:>16}",
        "param",
        "std err (end)",
        "rel (end)",
        "rel (median)"
    );
    for (k, p) in r.params.iter().enumerate() {
        outln!(
            "{p:<8} {:>14.4e} {:>12.3e} {:>16.3e}",
            end(r, k),
            end(r, k) * r.chosen.rel_std_err[k] / r.chosen.std_err[k],
            r.chosen.median_rel_std_err[k]
        );
    }
    if let Some(t) = a.target_rel_se {
        match r.chosen.time_to_target_s {
            Some(s) => outln!("every relative standard error ≤ {t} from {s:.1} s on"),
            None => outln!("the target {t} is not held to the end of the test"),
        }
    }
    for b in &r.baselines {
        outln!(
            "thesis test {} ({} s{}): median relative std err {}",
            b.name,
            a.duration,
            if b.within_limits {
                ""
            } else {
                ", outside the limits"
            },
            b.median_rel_std_err
                .iter()
                .zip(&r.params)
                .map(|(v, p)| format!("{p} {v:.3e}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    if !r.unidentifiable.is_empty() {
        outln!(
            "structurally unidentifiable on these limits: {}",
            r.unidentifiable.join(", ")
        );
    }
    for c in &r.collinear {
        outln!(
            "nearly collinear: {} and {} (ρ = {:.3})",
            c.params[0],
            c.params[1],
            c.correlation
        );
    }
    if !r.failed.is_empty() {
        outln!("{} candidates left out:", r.failed.len());
        for (n, why) in r.failed.iter().take(5) {
            outln!("  {n}: {why}");
        }
    }
    if let Some(p) = &a.out {
        outln!(
            "wrote {0}/scenario.toml (physid simulate --scenario {0}/scenario.toml) and {0}/design.json",
            p.display()
        );
    }
}
