//! `physid design`: which test makes an application's parameters estimable by its recursive
//! estimator, within the cell's limits, to what standard error, in how long (issue 45;
//! docs/design.md).

use super::simulate::SetArgs;
use crate::out::outln;
use crate::plot::{self, Panel, Series, PALETTE};
use crate::progress::Progress;
use crate::report::{self, Report};
use miette::{miette, IntoDiagnostic, Result};
use physid_apps::design::friction::{design_friction, select as friction_select, FrictionDesign};
use physid_apps::design::information::Criterion;
use physid_apps::design::profile::{Limits, ThrottleDraw};
use physid_apps::design::run::candidate_cell;
use physid_apps::design::shaft::{design_shaft, select, ShaftDesign, PARAMS};
use physid_apps::design::torque::{design_torque, select as torque_select, TorqueDesign};
use physid_apps::design::{Design, Designed};
use physid_apps::friction_fit::TorqueSource;
use physid_apps::shaft_monitor::{MonitorConfig, MonitorMethod};
use std::path::PathBuf;
use std::sync::Mutex;

/// Arguments of `physid design`.
#[derive(clap::Args)]
pub struct Args {
    /// The application: shaft (Application 1, K, B and the offset τ0 of Eq. 6.1), friction
    /// (Application 2, the friction model's coefficients c1 … c20 from motored cycles, §7.3) or
    /// torque (Application 3, the cyclic-torque model's M_rec, b, L, r, c1 … c10 from 1°
    /// samples, ch. 8).
    #[arg(long, value_parser = ["shaft", "friction", "torque"], default_value = "shaft")]
    app: String,
    /// The parameters to design for. Shaft: K, B, tau0 (the others are estimated alongside;
    /// default K,B), with a value the nominal value the test is designed at (K=1340 sets the
    /// cell's shaft.k). Friction: the coefficients the fit will estimate, e.g. c4,c17 (the others
    /// held at the engine model's values; `physid friction fit --estimate` the same). Torque:
    /// the cyclic-torque parameters, e.g. M_rec,b,L (at most three of M_rec, b, L, r: the
    /// model's scaling symmetry), estimated with --alongside (the others held at the cell
    /// engine's values; `physid torque fit --estimate` the same).
    #[arg(long, value_name = "NAME=VALUE,…", value_delimiter = ',')]
    params: Vec<String>,
    /// Torque: parameters the fit estimates alongside those designed for, not designed for
    /// themselves, or none [default: c1, the friction level — held at its nominal value the
    /// friction cubic's error biases the geometry by percent].
    #[arg(long, value_name = "NAME,…", value_delimiter = ',')]
    alongside: Vec<String>,
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
    /// [default: speed=800:3000,throttle=0:90,dspeed=500]; torque=LOW:HIGH [N·m] makes the
    /// candidates the dynamometer's torque demands (torque mode; the engine must then stay in
    /// the speed range, the run stops where it leaves it), dtorque=RATE [N·m/s] (default 50).
    #[arg(long, value_name = "NAME=LOW:HIGH", value_delimiter = ',')]
    limits: Vec<String>,
    /// Each candidate test's duration [s] [default: 120 for the shaft monitor and the friction
    /// fit, 5 (the thesis's ramp T2) for the cyclic torque].
    #[arg(long, visible_alias = "max-duration", value_name = "S", value_parser = super::range::positive)]
    duration: Option<f64>,
    /// The band a multisine candidate's frequencies are drawn in, LOW:HIGH [Hz].
    #[arg(long, value_name = "LOW:HIGH", value_parser = band, default_value = "0.05:2")]
    band: (f64, f64),
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
    /// Shaft, friction: the recording's sample rate the estimator will read [Hz] [default:
    /// 10000]. (The cyclic-torque fit reads one sample per crank degree.)
    #[arg(long, value_name = "HZ", value_parser = super::range::positive)]
    sample_rate: Option<f64>,
    /// Shaft: the monitor's estimator, rlsf (RLS with forgetting λ) or dsfc (its square-root
    /// form, the same estimates) [default: rlsf]. (The friction fit's is DSFC.)
    #[arg(long)]
    method: Option<String>,
    /// The estimator's forgetting factor, 0 < λ ≤ 1 [default: 0.98 for the shaft monitor, 1
    /// for the friction fit].
    #[arg(long, value_name = "LAMBDA", value_parser = super::range::forgetting, allow_negative_numbers = true)]
    lambda: Option<f64>,
    /// Shaft: the monitor's zero-phase low-pass cut-off before estimation [Hz] [default: 500].
    #[arg(long, value_name = "HZ", value_parser = super::range::positive, allow_negative_numbers = true)]
    lowpass: Option<f64>,
    /// Shaft: the monitor's estimator updates per second [Hz] [default: 2000].
    #[arg(long, value_name = "HZ", value_parser = super::range::positive, allow_negative_numbers = true)]
    update_rate: Option<f64>,
    /// Friction: DSFC's initial square-root covariance S0 = s0·I in relative coordinates
    /// c = c0·(1 + x) [default: 10, the thesis's].
    #[arg(long, value_parser = super::range::positive, allow_negative_numbers = true)]
    s0: Option<f64>,
    /// Friction: the motoring torque from the engine load cell (engine) or the shaft
    /// transducer (shaft) [default: engine].
    #[arg(long)]
    source: Option<String>,
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
    let bar = Mutex::new(Progress::new("designing", Some(a.candidates as u64)));
    let progress = |done: usize| {
        if let Ok(mut b) = bar.lock() {
            b.set(done as u64);
        }
    };
    let (r, title, subtitle, method) = match a.app.as_str() {
        "friction" => friction(a, limits, &progress)?,
        "torque" => torque(a, limits, &progress)?,
        _ => shaft(a, limits, &progress)?,
    };
    drop(bar);
    if let Some(dir) = &a.out {
        report::create_dir(dir)?;
        let text = r.scenario.to_toml().map_err(|e| miette!("{e}"))?;
        let path = dir.join("scenario.toml");
        std::fs::write(&path, format!("{}{text}", header(&r)))
            .map_err(|e| miette!("--out {}: {e}", path.display()))?;
        let mut rep = Report::new(&title, &subtitle);
        report_body(&mut rep, &r, dir, method)?;
        report::finish(dir, rep, "design.json", &r)?;
    }
    if a.json {
        outln!("{}", serde_json::to_string(&r).into_diagnostic()?);
        return Ok(());
    }
    print(&r, a, duration(a));
    Ok(())
}

/// A flag the other application takes, refused with which one it belongs to.
fn refuse(app: &str, given: bool, flag: &str, of: &str) -> Result<()> {
    if given {
        return Err(miette!(
            "{flag} is {of}'s setting; --app {app} does not take it"
        ));
    }
    Ok(())
}

/// `LOW:HIGH` in Hz, 0 < LOW ≤ HIGH.
fn band(s: &str) -> std::result::Result<(f64, f64), String> {
    let bad = || format!("'{s}': expected LOW:HIGH in Hz, 0 < LOW ≤ HIGH, e.g. 0.05:2");
    let (a, b) = s.split_once(':').ok_or_else(bad)?;
    let (a, b): (f64, f64) = (
        a.trim().parse().map_err(|_| bad())?,
        b.trim().parse().map_err(|_| bad())?,
    );
    if !(a.is_finite() && b.is_finite() && 0.0 < a && a <= b) {
        return Err(bad());
    }
    Ok((a, b))
}

/// The candidates' duration [s]: the application's default unless given.
fn duration(a: &Args) -> f64 {
    a.duration
        .unwrap_or(if a.app == "torque" { 5.0 } else { 120.0 })
}

/// The design's common part: `names` (`selected` of them designed for), the limits, the
/// throttle's draw.
fn design(
    a: &Args,
    limits: Limits,
    names: Vec<String>,
    selected: Vec<usize>,
    throttle: ThrottleDraw,
) -> Design {
    Design {
        names,
        selected,
        criterion: a.criterion,
        target_rel_se: a.target_rel_se,
        limits,
        throttle,
        band: a.band,
        duration: duration(a),
        candidates: a.candidates,
        seed: a.seed,
        threads: a.threads,
    }
}

/// The shaft monitor's design: the result, the report's title and subtitle.
fn shaft(
    a: &Args,
    limits: Limits,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<(Designed, String, String, &'static str)> {
    refuse("shaft", a.s0.is_some(), "--s0", "the friction fit")?;
    refuse("shaft", a.source.is_some(), "--source", "the friction fit")?;
    refuse(
        "shaft",
        !a.alongside.is_empty(),
        "--alongside",
        "the cyclic-torque fit",
    )?;
    let method = a
        .method
        .as_deref()
        .unwrap_or("rlsf")
        .parse::<MonitorMethod>()
        .map_err(|e| miette!("--method {e}"))?;
    let mut set = a.set.pairs()?;
    let mut cell = candidate_cell(a.set.params()?, &set);
    let params = if a.params.is_empty() {
        vec!["K".to_string(), "B".to_string()]
    } else {
        a.params.clone()
    };
    let chosen = select(&params, &mut cell).map_err(|e| miette!("{e}"))?;
    set.extend(chosen.set);
    let shaft = ShaftDesign {
        monitor: MonitorConfig {
            method,
            lambda: a.lambda.unwrap_or(0.98),
            cutoff_hz: a.lowpass.unwrap_or(500.0),
            rate_hz: a.update_rate.unwrap_or(2000.0),
            ..MonitorConfig::default()
        },
        cell,
        rate_hz: a.sample_rate.unwrap_or(10_000.0),
    };
    let names = PARAMS.iter().map(|s| s.to_string()).collect();
    let design = design(a, limits, names, chosen.selected, ThrottleDraw::Linear);
    let r = design_shaft(&shaft, &design, &set, progress).map_err(|e| miette!("{e}"))?;
    let subtitle = format!(
        "{} of K, B, τ0 (Eq. 6.1), λ = {}, {} Hz updates after a {} Hz low-pass, from a {} Hz recording",
        shaft.monitor.method.name(),
        shaft.monitor.lambda,
        shaft.monitor.rate_hz,
        shaft.monitor.cutoff_hz,
        shaft.rate_hz
    );
    Ok((
        r,
        "Experiment design: the shaft monitor".into(),
        subtitle,
        "each run was put through the monitor's own low-pass and decimation, and the information its estimator gathers with its forgetting, with the noise's autocovariance after the low-pass, gives the covariance of its estimates at every moment; candidates are ranked over the test after the estimator's start-up",
    ))
}

/// The friction characterisation's design: the result, the report's title and subtitle.
fn friction(
    a: &Args,
    limits: Limits,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<(Designed, String, String, &'static str)> {
    for (given, flag) in [
        (a.method.is_some(), "--method"),
        (a.lowpass.is_some(), "--lowpass"),
        (a.update_rate.is_some(), "--update-rate"),
    ] {
        refuse("friction", given, flag, "the shaft monitor")?;
    }
    refuse(
        "friction",
        !a.alongside.is_empty(),
        "--alongside",
        "the cyclic-torque fit",
    )?;
    if a.params.is_empty() {
        return Err(miette!(
            "--app friction needs --params: the coefficients the fit will estimate, e.g. c4,c17 (`physid friction rank` ranks them on a recording)"
        ));
    }
    let names = friction_select(&a.params).map_err(|e| miette!("{e}"))?;
    let cell = candidate_cell(a.set.params()?, &a.set.pairs()?);
    let mut fd = FrictionDesign::new(cell, a.sample_rate.unwrap_or(10_000.0));
    if let Some(l) = a.lambda {
        fd.fit.lambda = l;
    }
    if let Some(s0) = a.s0 {
        fd.fit.s0 = s0;
    }
    if let Some(src) = &a.source {
        fd.fit.source = TorqueSource::parse(src)
            .ok_or_else(|| miette!("--source '{src}': expected engine or shaft"))?;
    }
    let selected = (0..names.len()).collect();
    let design = design(a, limits, names, selected, ThrottleDraw::Pressure);
    let mut r = design_friction(&fd, &design, progress).map_err(|e| miette!("{e}"))?;
    r.scenario.set.extend(a.set.pairs()?);
    let subtitle = format!(
        "DSFC of {} from steady motored cycles (the others at the engine model's values), λ = {}, S0 = {}·I, the motoring torque from the {}, from a {} Hz recording",
        design.names.join(", "),
        fd.fit.lambda,
        fd.fit.s0,
        match fd.fit.source {
            TorqueSource::Engine => "engine's load cell",
            TorqueSource::Shaft => "shaft transducer",
        },
        fd.rate_hz
    );
    Ok((
        r,
        "Experiment design: the friction characterisation".into(),
        subtitle,
        "the fit's own stage kept each run's steady cycles, and the information its estimator gathers from them (without forgetting, λ = 1), with the load cell's noise averaged over each cycle, gives the covariance of its estimates after every cycle — where the data do not yet resolve a coefficient the curve does not start; candidates are ranked by their errors at the test's end",
    ))
}

/// The cyclic-torque fit's design: the result, the report's title and subtitle.
fn torque(
    a: &Args,
    limits: Limits,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<(Designed, String, String, &'static str)> {
    for (given, flag, of) in [
        (a.method.is_some(), "--method", "the shaft monitor"),
        (a.lowpass.is_some(), "--lowpass", "the shaft monitor"),
        (
            a.update_rate.is_some(),
            "--update-rate",
            "the shaft monitor",
        ),
        (a.s0.is_some(), "--s0", "the friction fit"),
        (a.source.is_some(), "--source", "the friction fit"),
    ] {
        refuse("torque", given, flag, of)?;
    }
    if a.lambda.is_some() {
        return Err(miette!(
            "--lambda: the cyclic-torque filter does not forget (a drifting parameter is tracked with `physid torque fit --track`); --app torque does not take it"
        ));
    }
    if a.sample_rate.is_some() {
        return Err(miette!(
            "--sample-rate: the cyclic-torque fit reads one sample per crank degree; --app torque does not take it"
        ));
    }
    if a.params.is_empty() {
        return Err(miette!(
            "--app torque needs --params: the parameters the fit will estimate, e.g. M_rec,b,L (`physid torque identify` ranks them on a recording)"
        ));
    }
    let designed = torque_select(&a.params).map_err(|e| miette!("{e}"))?;
    let along: Vec<String> = match a.alongside.as_slice() {
        [] => vec!["c1".to_string()],
        [none] if none == "none" => Vec::new(),
        v => torque_select(v).map_err(|e| miette!("--alongside: {e}"))?,
    };
    let mut names = designed.clone();
    names.extend(along.into_iter().filter(|n| !designed.contains(n)));
    let cell = candidate_cell(a.set.params()?, &a.set.pairs()?);
    let td = TorqueDesign::new(cell).map_err(|e| miette!("{e}"))?;
    let selected = (0..designed.len()).collect();
    let design = design(a, limits, names, selected, ThrottleDraw::Linear);
    let mut r = design_torque(&td, &design, progress).map_err(|e| miette!("{e}"))?;
    r.scenario.set.extend(a.set.pairs()?);
    let alongside = &design.names[designed.len()..];
    let subtitle = format!(
        "{} on {}° samples of Eq. 8.2 of {}{} (the others at the cell engine's values), P0 = {}·I in scaled coordinates",
        td.fit.method.as_str().to_uppercase(),
        td.step_deg,
        designed.join(", "),
        if alongside.is_empty() {
            String::new()
        } else {
            format!(" with {} alongside", alongside.join(", "))
        },
        td.fit.p0
    );
    Ok((
        r,
        "Experiment design: the cyclic engine torque".into(),
        subtitle,
        "each run was sampled every crank degree, and the model's exact sensitivities there, with the load cell's noise and the cylinder-pressure transducer's through the indicated torque's arm, give the covariance of the filter's estimates (no forgetting) along the test; candidates are ranked by their errors at the test's end",
    ))
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
fn report_body(rep: &mut Report, r: &Designed, dir: &std::path::Path, method: &str) -> Result<()> {
    rep.section("The designed test");
    rep.para(
        &format!(
            "{} candidate profiles (steps, ramps, APRBS, multisines and held operating points within the limits) were each run on the virtual cell without noise; {method} (docs/design.md). Chosen by the {:?} criterion: {} ({}).",
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
            row.push(format!("{:.3e}", b.rel_std_err[k]));
            row.push(format!("{:.3e}", b.median_rel_std_err[k]));
        }
        rows.push(row);
    }
    let names: Vec<String> = r
        .baselines
        .iter()
        .flat_map(|b| {
            let outside = if b.within_limits {
                ""
            } else {
                " (outside the limits)"
            };
            [
                format!("{}{outside}: relative at the end", b.name),
                format!("{}{outside}: median relative", b.name),
            ]
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
            // log₁₀ of the relative error: the curves span decades (the start, a parameter the
            // test resolves late); the recording's time, as the profile's.
            e.curve
                .std_err
                .iter()
                .zip(&e.rel_std_err)
                .zip(&e.std_err)
                .map(|((c, rel), abs)| {
                    let scale = if *abs > 0.0 { rel / abs } else { 1.0 };
                    e.curve
                        .t
                        .iter()
                        .zip(c)
                        .map(|(&t, &v)| (t, (v * scale).log10()))
                        .filter(|(_, v)| v.is_finite())
                        .unzip()
                })
                .collect()
        })
        .collect();
    let mut panels = vec![
        Panel {
            ylabel: if r.scenario.torque_mode {
                "torque demand [N·m]".into()
            } else {
                "speed demand [rpm]".into()
            },
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
            ylabel: format!("log₁₀ σ({p})/{p} (predicted)"),
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
    rep.section("Identifiability along the test");
    rep.para(
        "The orthogonal method (Alg. 5.1) on the information the estimator holds at each moment of the designed test: the parameters in the order they are resolved, each with the information left to it after those before, relative to the first's (thesis Table 6.1's relative residual). A parameter at 0 is not resolved yet.",
        None,
    );
    let p = r
        .chosen
        .identifiability
        .first()
        .map_or(0, |x| x.ranked.len());
    let rows: Vec<Vec<String>> = r
        .chosen
        .identifiability
        .iter()
        .map(|x| {
            std::iter::once(format!("{:.1}", x.t_s))
                .chain(x.ranked.iter().map(|(n, v)| format!("{n} ({v:.1e})")))
                .collect()
        })
        .collect();
    let ranks: Vec<String> = (1..=p).map(|k| format!("rank {k}")).collect();
    let mut head = vec!["t [s]"];
    head.extend(ranks.iter().map(String::as_str));
    rep.table(&head, &rows);
    rep.section("Candidates");
    let rows: Vec<Vec<String>> = r
        .ranking
        .iter()
        .take(20)
        .map(|(n, f, s)| vec![n.clone(), f.name().to_string(), format!("{s:.4}")])
        .collect();
    rep.table(&["candidate (best 20)", "family", "criterion"], &rows);
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

/// `NAME value, …`.
fn listed(v: &[f64], names: &[String]) -> String {
    v.iter()
        .zip(names)
        .map(|(v, p)| format!("{p} {v:.3e}"))
        .collect::<Vec<_>>()
        .join(", ")
}

fn print(r: &Designed, a: &Args, duration: f64) {
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
            Some(s) => outln!(
                "every relative standard error ≤ {} from {s:.1} s on",
                physid_core::Num(t)
            ),
            None => outln!(
                "the target {} is not held to the end of the test",
                physid_core::Num(t)
            ),
        }
    }
    for b in &r.baselines {
        outln!(
            "thesis test {} ({} s{}): relative std err at the end {}; median {}",
            b.name,
            duration,
            if b.within_limits {
                ""
            } else {
                ", outside the limits"
            },
            listed(&b.rel_std_err, &r.params),
            listed(&b.median_rel_std_err, &r.params)
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
