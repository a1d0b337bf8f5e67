//! criterion benchmarks of physid-sim: the whole test cell (engine, machine, drive,
//! driveline) stepping one crank degree at a time at 1000 rpm, full throttle and closed
//! throttle, with each of the two solvers (`solver.order` 4 and 2); throughput in simulated
//! seconds per wall second (the real-time factor); and the whole run with sensors and
//! acquisition (`run::simulate`, no file written).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use physid_sim::cell::{Inputs, TestCell};
use physid_sim::control::Demand;
use physid_sim::params::CellParams;
use physid_sim::run::{simulate, OutputBasis, RunOptions};
use physid_sim::scenario::named;
use std::f64::consts::PI;

fn cell(c: &mut Criterion) {
    let w = 1000.0 * PI / 30.0;
    let mut g = c.benchmark_group("testcell");
    g.sample_size(20);
    // One simulated second at 1000 rpm: 6000 one-degree steps.
    g.throughput(Throughput::Elements(6000));
    for (name, throttle, order) in [
        ("1000rpm_wot_1s", 90.0, 4.0),
        ("1000rpm_closed_1s", 0.0, 4.0),
        ("1000rpm_wot_1s_order2", 90.0, 2.0),
        ("1000rpm_closed_1s_order2", 0.0, 2.0),
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
/// (1000 rpm, full throttle) for 1 s after its 1 s of settling, one sample per crank degree
/// (the cell's steps, no resampling) and at 10 kHz — two simulated seconds per iteration, so
/// 12 000 steps.
fn whole_run(c: &mut Criterion) {
    let mut g = c.benchmark_group("simulate");
    g.sample_size(10);
    g.throughput(Throughput::Elements(12_000));
    let scenario = match named("torque-steady") {
        Some(s) => s,
        None => panic!("no scenario torque-steady"),
    };
    for (name, basis) in [
        ("t1_2s_crank", OutputBasis::Crank(1.0)),
        ("t1_2s_10khz", OutputBasis::Time(10_000.0)),
    ] {
        for order in [4.0, 2.0] {
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

criterion_group!(benches, cell, whole_run);
criterion_main!(benches);
