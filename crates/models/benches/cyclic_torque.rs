//! criterion benchmarks of the cyclic-torque model (Eq. 8.2, issue 5's speed target): the
//! value, the value with its full 15-parameter exact gradient (the model's own
//! `value_and_gradient_with`: forward mode for M_rec, b, L, r, δ, the affine c1 … c10 exactly
//! from the cubic's monomials), and the same gradient by plain forward mode through `eval` (two
//! 8-wide dual evaluations) for comparison. 720 samples, one per crank degree over a cycle, as
//! in `physid bench`'s `cyclic_torque_grad`.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use physid_core::{GradientEngine, ParamModel};
use physid_models::cyclic_torque::{CyclicTorque, ILLUSTRATIVE};
use std::hint::black_box;

fn samples() -> Vec<[f64; 6]> {
    (0..720)
        .map(|k| {
            let th = (k as f64).to_radians();
            let p_cyl = 1e5 + 1.5e6 * (-(th - 0.1).powi(2) * 8.0).exp();
            [th, 104.7, 2.0, p_cyl, 1e5, 60.0]
        })
        .collect()
}

fn cyclic_torque(c: &mut Criterion) {
    let model = CyclicTorque::default();
    let p = ILLUSTRATIVE;
    let data = samples();
    let free: Vec<usize> = (0..15).collect();
    let mut engine = GradientEngine::new(15);
    let mut grad = [0.0; 15];
    let mut g = c.benchmark_group("cyclic_torque");
    g.throughput(Throughput::Elements(data.len() as u64));
    g.bench_function("value", |b| {
        b.iter(|| {
            data.iter()
                .map(|u| model.eval::<f64>(black_box(u), black_box(&p)))
                .sum::<f64>()
        })
    });
    g.bench_function("gradient15", |b| {
        b.iter(|| {
            data.iter()
                .map(|u| {
                    engine.value_and_gradient(&model, black_box(u), black_box(&p), &free, &mut grad)
                })
                .sum::<f64>()
        })
    });
    g.bench_function("gradient15_forward_mode", |b| {
        b.iter(|| {
            data.iter()
                .map(|u| {
                    engine.forward(black_box(&p), &free, &mut grad, |d| {
                        model.eval(black_box(u), d)
                    })
                })
                .sum::<f64>()
        })
    });
    g.finish();
}

criterion_group!(benches, cyclic_torque);
criterion_main!(benches);
