//! `physid bench`: updates per second of every estimator on one core, against the real-time
//! need of 108 000 samples/s (thesis Eq. 4.1: 9000 rpm at one sample per crank degree).

use crate::out::outln;
use miette::{IntoDiagnostic, Result};
use physid_apps::example_5_1::{Model51, EXPRESSION, NOMINAL};
use physid_core::{GradientEngine, ParamModel};
use physid_estim::workload::{standard_methods, NonlinearWorkload, Workload};
use physid_estim::{NlMethod, SigmaPoints};
use physid_expr::ExprModel;
use physid_models::cyclic_torque::{CyclicTorque, ILLUSTRATIVE};
use serde_json::json;
use std::time::{Duration, Instant};

/// The real-time need: 9000 rpm · 360 samples/rev / 60 s (Eq. 4.1).
pub const REALTIME_SAMPLES_PER_S: f64 = 108_000.0;

/// Arguments of `physid bench`.
#[derive(clap::Args)]
pub struct Args {
    /// Print the results as JSON.
    #[arg(long)]
    pub json: bool,
    /// Time spent on each measurement [s].
    #[arg(long, default_value_t = 0.5)]
    pub seconds: f64,
    #[command(subcommand)]
    what: Option<What>,
}

/// What else to measure.
#[derive(clap::Subcommand)]
enum What {
    /// The fleet under load: N cells publishing at real time (one sample per crank degree at
    /// 1000–3000 rpm) to a NATS JetStream server, workers processing the shaft monitor and the
    /// cycle statistics; event latency, messages and bytes through the server, samples lost or
    /// doubled. Starts its own nats-server on 127.0.0.1 unless --nats is given.
    ///
    /// Example: physid bench fleet --cells 10,25,50 --seconds 20 --json
    Fleet(FleetArgs),
    /// The combustion analysis alone: a cycle's figures, and the live stage's whole path from a
    /// time-basis stream, against a four-cylinder engine at 6000 rpm at 0.1° (the lines
    /// combustion_* of the full run).
    ///
    /// Example: physid bench --seconds 2 combustion
    Combustion,
}

/// Arguments of `physid bench fleet`.
#[derive(clap::Args)]
struct FleetArgs {
    /// Cells, or a list of cell counts run one after another (each on a fresh server).
    #[arg(long, value_delimiter = ',', default_value = "10")]
    cells: Vec<usize>,
    /// Recording seconds each cell publishes.
    #[arg(long, default_value_t = 20.0, value_parser = super::range::positive)]
    seconds: f64,
    /// The slowest cell [rpm].
    #[arg(long, default_value_t = 1000.0, value_parser = super::range::positive)]
    rpm_min: f64,
    /// The fastest cell [rpm].
    #[arg(long, default_value_t = 3000.0, value_parser = super::range::positive)]
    rpm_max: f64,
    /// Workers (threads of this process).
    #[arg(long, default_value_t = 1)]
    workers: usize,
    /// A publisher's chunk [s]: how much its data acquisition hands on at a time.
    #[arg(long, default_value_t = 0.02, value_parser = super::range::positive)]
    chunk: f64,
    /// The recording time a frame carries [s] (`physid live --nats --frame`): the chunks are
    /// gathered into frames of this much, to the nearest chunk. 0: a frame per chunk.
    #[arg(long, value_name = "S", default_value_t = physid_live::fleet::publish::FRAME_S, value_parser = super::range::nonnegative)]
    frame: f64,
    /// An existing server instead of a local one (its traffic is then not reported).
    #[arg(long, value_name = "URL")]
    nats: Option<String>,
    /// Print one JSON object per run.
    #[arg(long)]
    json: bool,
}

/// `physid bench fleet`.
fn fleet(a: &FleetArgs) -> Result<()> {
    use physid_live::fleet::{load, local::LocalServer, NatsTarget};
    if !a.json {
        outln!("machine: {}", machine());
        outln!(
            "{:>5} {:>8} {:>10} {:>9} {:>9} {:>9} {:>8} {:>10} {:>11} {:>9} {:>10} {:>10} {:>10}",
            "cells",
            "workers",
            "samples/s",
            "p50 ms",
            "p99 ms",
            "max ms",
            "lag s",
            "msgs/s in",
            "MB/s in",
            "real time",
            "take-on ms",
            "CPU physid",
            "CPU server"
        );
    }
    for &cells in &a.cells {
        let server = match &a.nats {
            Some(_) => None,
            None => Some(LocalServer::start(&[]).map_err(|e| miette::miette!("{e}"))?),
        };
        let url = a
            .nats
            .clone()
            .or_else(|| server.as_ref().map(|s| s.url("")))
            .unwrap_or_default();
        let target = NatsTarget::new(&url, None).map_err(|e| miette::miette!("{e}"))?;
        let cfg = load::LoadConfig {
            cells,
            seconds: a.seconds,
            rpm: (a.rpm_min, a.rpm_max),
            workers: a.workers,
            chunk_s: a.chunk,
            frame_s: a.frame,
        };
        let r =
            load::run_load(&target, server.as_ref(), &cfg).map_err(|e| miette::miette!("{e}"))?;
        if a.json {
            let mut v = serde_json::to_value(&r).into_diagnostic()?;
            v["machine"] = json!(machine());
            outln!("{v}");
        } else {
            outln!(
                "{:>5} {:>8} {:>10.0} {:>9.1} {:>9.1} {:>9.1} {:>8.3} {:>10.0} {:>11.2} {:>9} {:>10.0} {:>10.2} {:>10.2}",
                r.cells,
                r.workers,
                r.samples_per_s,
                r.latency_ms[0],
                r.latency_ms[1],
                r.latency_ms[2],
                r.publisher_lag_s,
                r.msgs_per_s.map_or(f64::NAN, |m| m[0]),
                r.bytes_per_s.map_or(f64::NAN, |b| b[0] / 1e6),
                if r.real_time { "yes" } else { "no" },
                r.first_estimate_ms,
                r.cpu_physid.unwrap_or(f64::NAN),
                r.cpu_server.unwrap_or(f64::NAN)
            );
            // The accounting, every run: published = processed and nothing refused is what
            // "real time" also requires.
            outln!(
                "      samples published {}, processed {}{}; frames refused {}, resent {}; cells ended {} of {}",
                r.samples_published,
                r.samples_processed,
                if r.samples_processed == r.samples_published { "" } else { " (NOT ALL)" },
                r.frames_refused,
                r.frames_resent,
                r.cells_ended,
                r.cells
            );
            for n in &r.notes {
                outln!("      {n}");
            }
        }
    }
    Ok(())
}

/// The machine: CPU model and core count.
pub fn machine() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_string());
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    format!("{cpu}, {cores} cores, {}", std::env::consts::OS)
}

/// Operations per second of `batch_fn` (which performs `batch` operations per call): repeated
/// calls until `budget` has passed; the best of three rounds (the least disturbed by the rest
/// of the machine).
fn rate(batch: usize, budget: Duration, mut batch_fn: impl FnMut() -> Result<()>) -> Result<f64> {
    batch_fn()?; // warm-up
    let mut best: f64 = 0.0;
    for _ in 0..3 {
        let start = Instant::now();
        let mut n = 0usize;
        while start.elapsed() < budget / 3 {
            batch_fn()?;
            n += batch;
        }
        best = best.max(n as f64 / start.elapsed().as_secs_f64());
    }
    Ok(best)
}

/// Run the benchmark.
pub fn run(args: &Args) -> Result<()> {
    if let Some(What::Fleet(a)) = &args.what {
        return fleet(a);
    }
    let budget = Duration::from_secs_f64(args.seconds.clamp(0.01, 60.0));
    let mut results = Vec::new();
    if let Some(What::Combustion) = &args.what {
        if !args.json {
            outln!("machine: {}", machine());
        }
        super::bench_combustion::combustion(budget, args.json, &mut results, |n, b, f| {
            rate(n, b, f)
        })?;
        if args.json {
            let out = json!({"machine": machine(), "results": results});
            outln!("{}", serde_json::to_string_pretty(&out).into_diagnostic()?);
        }
        return Ok(());
    }
    if !args.json {
        outln!("machine: {}", machine());
        outln!("real-time need: {REALTIME_SAMPLES_PER_S:.0} samples/s (thesis Eq. 4.1)\n");
        outln!(
            "{:<8} {:>4} {:>16} {:>14}",
            "method",
            "p",
            "updates/s",
            "× real time"
        );
    }
    for p in [2usize, 6, 20] {
        for method in standard_methods(p) {
            let name = method.name();
            let mut w = Workload::new(method, p, 4096).into_diagnostic()?;
            let r = rate(4096, budget, || {
                w.run(std::hint::black_box(4096)).into_diagnostic()
            })?;
            if !args.json {
                outln!(
                    "{name:<8} {p:>4} {r:>16.0} {:>14.0}",
                    r / REALTIME_SAMPLES_PER_S
                );
            }
            results.push(json!({"name": name, "p": p, "updates_per_s": r}));
        }
    }
    // RLS over whole arrays, its tracks recorded after every row (what `run` does from
    // Python: crates/py, physid_estim::tracks) — the native reference of the Python package,
    // at p = 2 and 20.
    for p in [2usize, 20] {
        let (rows, y) = physid_estim::workload::data(p, 4096);
        let names: Vec<String> = (1..=p).map(|i| format!("p{i}")).collect();
        let params = physid_core::ParamSet::zeros(names).into_diagnostic()?;
        let spec = physid_estim::EstimatorSpec::new(physid_estim::MethodName::Rls);
        for std_err in [false, true] {
            let mut e =
                physid_estim::build_linear(&spec, &params, &params.all_free()).into_diagnostic()?;
            let r = rate(4096, budget, || {
                let t = physid_estim::tracks::track(&mut e, &rows, &y, p, p, false, std_err)
                    .map_err(|m| miette::miette!("{m}"))?;
                std::hint::black_box(t);
                Ok(())
            })?;
            let name = if std_err {
                "rls_tracks_se"
            } else {
                "rls_tracks"
            };
            if !args.json {
                outln!(
                    "{name:<8} {p:>4} {r:>16.0} {:>14.0}   (run over arrays: estimate{} after every row)",
                    r / REALTIME_SAMPLES_PER_S,
                    if std_err { " and standard errors" } else { "" }
                );
            }
            results.push(json!({"name": name, "p": p, "updates_per_s": r}));
        }
    }
    // Non-linear estimators on the 10-parameter benchmark model (the cyclic-torque model's
    // cost profile), scaled coordinates.
    for method in [
        NlMethod::Ekf,
        NlMethod::Ukf(SigmaPoints::default()),
        NlMethod::Srukf(SigmaPoints::default()),
    ] {
        let name = method.name();
        let mut w = NonlinearWorkload::new(method, 720).into_diagnostic()?;
        let r = rate(720, budget, || w.run(720).into_diagnostic())?;
        if !args.json {
            outln!(
                "{name:<8} {:>4} {r:>16.0} {:>14.0}",
                10,
                r / REALTIME_SAMPLES_PER_S
            );
        }
        results.push(json!({"name": name, "p": 10, "updates_per_s": r}));
    }
    // The EKF and the UKF over the same model typed as a formula (`--expr`): its gradient and
    // its sigma points through the formula's tape.
    for (name, method) in [
        ("ekf_expr", NlMethod::Ekf),
        ("ukf_expr", NlMethod::Ukf(SigmaPoints::default())),
    ] {
        let model = ExprModel::parse(
            physid_estim::workload::BENCH10_FORMULA,
            &physid_estim::workload::BENCH10_FORMULA_PARAMS,
        )
        .map_err(|e| miette::miette!("{e}"))?;
        let mut w = NonlinearWorkload::with_model(model, method, 720).into_diagnostic()?;
        let r = rate(720, budget, || w.run(720).into_diagnostic())?;
        if !args.json {
            outln!(
                "{name:<8} {:>4} {r:>16.0} {:>14.0}   (the same model as a formula, --expr)",
                10,
                r / REALTIME_SAMPLES_PER_S
            );
        }
        results.push(json!({"name": name, "p": 10, "updates_per_s": r}));
    }
    // Model evaluation: Example 5.1's model as an expression and written in Rust, values and
    // exact gradients (6 parameters).
    let expr = ExprModel::parse(EXPRESSION, &["A", "B", "C", "D", "E", "F"])
        .map_err(|e| miette::miette!("{e}"))?;
    let native = Model51::default();
    let data: Vec<[f64; 2]> = (0..1024)
        .map(|i| {
            [
                (i as f64 * 0.01).sin() + 1.2,
                1.0 + 0.5 * (i as f64 * 0.003).cos(),
            ]
        })
        .collect();
    let free: Vec<usize> = (0..6).collect();
    let mut engine = GradientEngine::new(6);
    let mut grad = [0.0; 6];
    let eval_rate = |m: &dyn Fn(&[f64]) -> f64| {
        rate(data.len(), budget, || {
            let s: f64 = data.iter().map(|u| m(std::hint::black_box(u))).sum();
            std::hint::black_box(s);
            Ok(())
        })
    };
    let rates = [
        (
            "native",
            "value",
            eval_rate(&|u| native.eval::<f64>(u, std::hint::black_box(&NOMINAL)))?,
        ),
        (
            "expr",
            "value",
            eval_rate(&|u| expr.eval::<f64>(u, std::hint::black_box(&NOMINAL)))?,
        ),
    ];
    let mut grad_rate = |m: &dyn physid_core::DynModel| {
        rate(data.len(), budget, || {
            let s: f64 = data
                .iter()
                .map(|u| {
                    let p = std::hint::black_box(&NOMINAL);
                    m.value_and_gradient(&mut engine, u, p, &free, &mut grad)
                })
                .sum();
            std::hint::black_box(s);
            Ok(())
        })
    };
    let grad_rates = [
        ("native", "gradient", grad_rate(&native)?),
        ("expr", "gradient", grad_rate(&expr)?),
    ];
    for (name, what, r) in rates.iter().chain(&grad_rates) {
        if !args.json {
            outln!("{name:<8} {what:>9} {r:>11.0} evaluations/s (Example 5.1 model)");
        }
        results.push(json!({"name": name, "what": what, "evals_per_s": r}));
    }
    // The cyclic-torque model (Eq. 8.2) with its full 15-parameter gradient, one crank degree
    // per sample over two revolutions.
    let torque = CyclicTorque::default();
    let p15 = ILLUSTRATIVE;
    let samples: Vec<[f64; 6]> = (0..720)
        .map(|k| {
            let th = (k as f64).to_radians();
            [
                th,
                104.7,
                2.0,
                1e5 + 1.5e6 * (-(th - 0.1).powi(2) * 8.0).exp(),
                1e5,
                60.0,
            ]
        })
        .collect();
    let free15: Vec<usize> = (0..15).collect();
    let mut engine15 = GradientEngine::new(15);
    let mut grad15 = [0.0; 15];
    let r = rate(samples.len(), budget, || {
        let s: f64 = samples
            .iter()
            .map(|u| {
                let p = std::hint::black_box(&p15);
                engine15.value_and_gradient(&torque, u, p, &free15, &mut grad15)
            })
            .sum();
        std::hint::black_box(s);
        Ok(())
    })?;
    if !args.json {
        outln!("cyclic_torque_grad {r:>11.0} evaluations/s with the 15-parameter gradient");
    }
    results.push(json!({"name": "cyclic_torque_grad", "p": 15, "evals_per_s": r}));
    // Identifiability: the batch ranking of precomputed sensitivity rows (stream into the
    // triangular factor, then Alg. 5.1 on it), the full analysis of the cyclic-torque model
    // over a recording (exact sensitivities, both factors, ranking), and the on-line update
    // over a 720-row window — all at p = 15.
    let rows = physid_ident::workload::rows(100_000, 15);
    let r = rate(100_000, budget, || {
        std::hint::black_box(physid_ident::workload::rank_rows(&rows, 15));
        Ok(())
    })?;
    if !args.json {
        outln!("ident_batch {r:>14.0} rows/s ranked (p = 15)");
    }
    results.push(json!({"name": "ident_batch", "p": 15, "rows_per_s": r}));
    let cols: Vec<Vec<f64>> = (0..6)
        .map(|c| (0..7200).map(|k| samples[k % 720][c]).collect())
        .collect();
    let data = physid_ident::Data {
        inputs: cols.iter().map(|c| c.as_slice()).collect(),
        y: None,
    };
    let r = rate(7200, budget, || {
        physid_ident::analyse(
            &torque,
            &data,
            &p15,
            &[],
            physid_ident::IdentConfig::default(),
        )
        .map(|a| std::hint::black_box(a.ranking.steps.len()))
        .map_err(|e| miette::miette!("{e}"))?;
        Ok(())
    })?;
    if !args.json {
        outln!("ident_cyclic_torque {r:>6.0} rows/s analysed (Eq. 8.2, 15 parameters)");
    }
    results.push(json!({"name": "ident_cyclic_torque", "p": 15, "rows_per_s": r}));
    let mut w = physid_ident::workload::OnlineWorkload::new(15, 720, 10_000)
        .map_err(|e| miette::miette!("{e}"))?;
    let r = rate(4096, budget, || {
        w.run(4096).map_err(|e| miette::miette!("{e}"))
    })?;
    if !args.json {
        outln!(
            "ident_online {r:>13.0} rows/s (p = 15, 720-row window) {:>8.0}× real time",
            r / REALTIME_SAMPLES_PER_S
        );
    }
    results.push(json!({"name": "ident_online", "p": 15, "rows_per_s": r}));
    // The virtual test cell at one-degree steps, 1000 rpm, full throttle: simulated seconds
    // per wall-clock second (the real-time factor), with the default solver (`solver.order`
    // 2, ROS2) and with RK4 (4).
    //
    // `testcell`: the whole test cell as a run delivers it — engine, machine, drive,
    // driveline, sensors and acquisition, one 38-channel sample per crank degree, no file —
    // the T1 scenario (1000 rpm, full throttle) recorded from its start (no settling, so that
    // every step is acquired) for 0.5 s. `rate` counts simulated milliseconds.
    let scenario = physid_sim::scenario::Scenario {
        settle: 0.0,
        ..physid_sim::scenario::named("torque-steady")
            .ok_or_else(|| miette::miette!("no scenario torque-steady"))?
    };
    let recorded: f64 = 0.5;
    let simulated_ms = (1000.0 * recorded).round() as usize;
    // `testcell_step2`: the same at the solver's 2° step (a design's candidates' step), the
    // samples at each degree from the acquisition's interpolation between steps.
    for (name, order, step_deg) in [
        ("testcell", 2.0, 1.0),
        ("testcell_rk4", 4.0, 1.0),
        ("testcell_step2", 2.0, 2.0),
    ] {
        let opts = physid_sim::run::RunOptions {
            params: physid_sim::params::CellParams {
                order,
                step_deg,
                ..Default::default()
            },
            duration: Some(recorded),
            basis: physid_sim::run::OutputBasis::Crank(1.0),
            ..Default::default()
        };
        let ms_per_s = rate(simulated_ms, budget, || {
            let rec = physid_sim::run::simulate(&scenario, &opts, |_| {})
                .map_err(|e| miette::miette!("{e}"))?;
            std::hint::black_box(rec);
            Ok(())
        })?;
        let realtime = ms_per_s / 1000.0;
        let steps_per_s = realtime * 6000.0;
        if !args.json {
            outln!(
                "{name:<21} {steps_per_s:>10.0} samples/s: {realtime:.0}× real time — the \
                 whole test cell with sensors and acquisition, 1000 rpm, one sample per degree \
                 (solver.order {order}, solver.step_deg {step_deg})"
            );
        }
        results.push(json!({"name": name, "realtime_factor": realtime,
            "steps_per_s": steps_per_s, "solver_order": order, "solver_step_deg": step_deg}));
    }
    // `testcell_dynamics`: the cell's dynamics alone (engine, machine, drive, driveline; no
    // sensors, no acquisition), stepped after 0.5 s of settling.
    for (name, order) in [("testcell_dynamics", 2.0), ("testcell_dynamics_rk4", 4.0)] {
        let w = 1000.0 * std::f64::consts::PI / 30.0;
        let params = physid_sim::params::CellParams {
            order,
            ..Default::default()
        };
        let mut cell =
            physid_sim::cell::TestCell::new(params, w, 0.0).map_err(|e| miette::miette!("{e}"))?;
        let input = physid_sim::cell::Inputs {
            demand: physid_sim::control::Demand::Speed(w),
            throttle_deg: 90.0,
        };
        while cell.time() < 0.5 {
            cell.step(&input);
        }
        // `rate` counts batches of 600 steps = 0.1 simulated seconds.
        let (sub0, mut steps) = (cell.substeps(), 0u64);
        let steps_per_s = rate(600, budget, || {
            for _ in 0..600 {
                std::hint::black_box(cell.step(&input));
            }
            steps += 600;
            Ok(())
        })?;
        let realtime = steps_per_s / 6000.0;
        // Sub-steps per one-degree step (RK4: more than one where the gas flows are stiff).
        let substeps = (cell.substeps() - sub0) as f64 / steps.max(1) as f64;
        if !args.json {
            outln!(
                "{name:<21} {steps_per_s:>10.0} steps/s: {realtime:.0}× real time — the cell's \
                 dynamics alone, 1000 rpm (solver.order {order}, {substeps:.2} sub-steps per \
                 step)"
            );
        }
        results.push(json!({"name": name, "realtime_factor": realtime,
            "steps_per_s": steps_per_s, "substeps_per_step": substeps, "solver_order": order}));
    }
    super::bench_combustion::combustion(budget, args.json, &mut results, |n, b, f| rate(n, b, f))?;
    super::bench_twin::twin(args.json, &mut results)?;
    if args.json {
        let out = json!({"machine": machine(), "results": results});
        outln!("{}", serde_json::to_string_pretty(&out).into_diagnostic()?);
    }
    Ok(())
}
