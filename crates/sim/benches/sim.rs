//! criterion benchmarks of physid-sim: the test cell's dynamics (engine, machine, drive,
//! driveline) stepping one crank degree at a time at 1000 rpm, full throttle and closed
//! throttle (`testcell/*`), with each of the two solvers (`solver.order` 2, the default, and
//! 4); throughput in simulated seconds per wall second (the real-time factor); the whole test
//! cell with sensors and acquisition (`simulate/*`: `run::simulate`, no file written); and the
//! pieces of a step (`parts/*`).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use physid_sim::cell::{Inputs, TestCell};
use physid_sim::control::Demand;
use physid_sim::engine::Motored;
use physid_sim::params::CellParams;
use physid_sim::run::{simulate, OutputBasis, RunOptions};
use physid_sim::scenario::{named, Scenario};
use std::f64::consts::PI;
use std::hint::black_box;

fn cell(c: &mut Criterion) {
    let w = 1000.0 * PI / 30.0;
    let mut g = c.benchmark_group("testcell");
    g.sample_size(20);
    // One simulated second at 1000 rpm: 6000 one-degree steps.
    g.throughput(Throughput::Elements(6000));
    for (name, throttle, order) in [
        ("1000rpm_wot_1s_order2", 90.0, 2.0),
        ("1000rpm_closed_1s_order2", 0.0, 2.0),
        ("1000rpm_wot_1s_order4", 90.0, 4.0),
        ("1000rpm_closed_1s_order4", 0.0, 4.0),
    ] {
        let params = CellParams {
            order,
            ..CellParams::default()
        };
        let mut cell = match TestCell::new(params, w, 0.0) {
            Ok(c) => c,
            Err(e) => panic!("{e}"),
        };
        let input = Inputs {
            demand: Demand::Speed(w),
            throttle_deg: throttle,
        };
        // Warm up to the periodic state.
        while cell.time() < 1.0 {
            cell.step(&input);
        }
        g.bench_function(name, |b| {
            b.iter(|| {
                let t1 = cell.time() + 1.0;
                while cell.time() < t1 {
                    std::hint::black_box(cell.step(&input));
                }
            })
        });
    }
    g.finish();
}

/// The whole test cell with its sensors and acquisition: `run::simulate` of the T1 scenario
/// (1000 rpm, full throttle) recorded from its start (no settling, so that every step is
/// acquired), one sample per crank degree (the cell's steps, no resampling) and at 10 kHz —
/// one simulated second per iteration, 6000 steps.
fn whole_run(c: &mut Criterion) {
    let mut g = c.benchmark_group("simulate");
    g.sample_size(10);
    g.throughput(Throughput::Elements(6000));
    let scenario = match named("torque-steady") {
        Some(s) => Scenario { settle: 0.0, ..s },
        None => panic!("no scenario torque-steady"),
    };
    for (name, basis) in [
        ("t1_1s_crank", OutputBasis::Crank(1.0)),
        ("t1_1s_10khz", OutputBasis::Time(10_000.0)),
    ] {
        for order in [2.0, 4.0] {
            let opts = RunOptions {
                params: CellParams {
                    order,
                    ..CellParams::default()
                },
                duration: Some(1.0),
                basis,
                ..RunOptions::default()
            };
            g.bench_function(format!("{name}_order{order}"), |b| {
                b.iter(|| match simulate(&scenario, &opts, |_| {}) {
                    Ok(rec) => std::hint::black_box(rec),
                    Err(e) => panic!("{e}"),
                })
            });
        }
    }
    g.finish();
}

/// The pieces of a step, each over the 720 states of a steady cycle at 1000 rpm, full throttle
/// (independent calls: their throughput, not their latency inside a step): one evaluation of
/// the gas equations (crank kinematics included), the gas network's Jacobian, the friction
/// magnitude; and the cell with the engine switched off (driveline, machine, drive, friction
/// magnitude, step control, the sample), one simulated second per iteration.
fn parts(c: &mut Criterion) {
    let w = 1000.0 * PI / 30.0;
    let mut cell = match TestCell::new(CellParams::default(), w, 0.0) {
        Ok(c) => c,
        Err(e) => panic!("{e}"),
    };
    let input = Inputs {
        demand: Demand::Speed(w),
        throttle_deg: 90.0,
    };
    while cell.time() < 1.0 {
        cell.step(&input);
    }
    let states: Vec<[f64; 17]> = (0..720)
        .map(|_| {
            cell.step(&input);
            *cell.state()
        })
        .collect();
    let engine = cell.engine().clone();
    let a_th = engine.throttle_cd_area(90.0);
    let gas = |x: &[f64; 17]| {
        let mut g = [0.0; 8];
        g.copy_from_slice(&x[..8]);
        g
    };
    let evaluated: Vec<_> = states
        .iter()
        .map(|x| {
            let k = engine.crank_point(x[10]);
            let (_, out, lin) = engine.gas_derivatives_at(&k, x[11], a_th, &gas(x), &Motored);
            (gas(x), out, lin)
        })
        .collect();
    let mut g = c.benchmark_group("parts");
    g.throughput(Throughput::Elements(720));
    g.bench_function("gas_evaluation", |b| {
        b.iter(|| {
            for x in &states {
                let g = gas(black_box(x));
                black_box(engine.gas_derivatives(x[10], x[11], a_th, &g, &Motored));
            }
        })
    });
    g.bench_function("network_jacobian", |b| {
        b.iter(|| {
            for (x, out, lin) in &evaluated {
                black_box(engine.network_jacobian(black_box(x), out, lin));
            }
        })
    });
    g.bench_function("friction_magnitude", |b| {
        b.iter(|| {
            for x in &states {
                black_box(engine.friction_torque(black_box(x[11]), 9e4 + x[0]));
            }
        })
    });
    g.throughput(Throughput::Elements(6000));
    for order in [4.0, 2.0] {
        let mut params = CellParams {
            order,
            ..CellParams::default()
        };
        params.engine.active = 0.0;
        let mut cell = match TestCell::new(params, w, 0.0) {
            Ok(c) => c,
            Err(e) => panic!("{e}"),
        };
        while cell.time() < 1.0 {
            cell.step(&input);
        }
        g.bench_function(format!("cell_engine_off_1s_order{order}"), |b| {
            b.iter(|| {
                let t1 = cell.time() + 1.0;
                while cell.time() < t1 {
                    black_box(cell.step(&input));
                }
            })
        });
    }
    g.finish();
}

criterion_group!(benches, cell, whole_run, parts);
criterion_main!(benches);
