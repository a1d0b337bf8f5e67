//! Expression model vs the same model written in Rust: values and exact gradients
//! (thesis Example 5.1's model, six parameters, two inputs).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use physid_apps::example_5_1::{Model51, EXPRESSION};
use physid_core::{GradientEngine, ParamModel};
use physid_expr::ExprModel;
use std::hint::black_box;

const N: usize = 1024;

fn bench(c: &mut Criterion) {
    let names = ["A", "B", "C", "D", "E", "F"];
    let expr = match ExprModel::parse(EXPRESSION, &names) {
        Ok(m) => m,
        Err(e) => panic!("{e}"),
    };
    let native = Model51::default();
    let data: Vec<[f64; 2]> = (0..N)
        .map(|i| {
            [
                (i as f64 * 0.01).sin() + 1.2,
                1.0 + (i as f64 * 0.003).cos() * 0.5,
            ]
        })
        .collect();
    let p = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
    let free: Vec<usize> = (0..6).collect();
    let mut g = c.benchmark_group("model_eval");
    g.throughput(Throughput::Elements(N as u64));
    g.bench_function("native_value", |b| {
        b.iter(|| {
            data.iter()
                .map(|u| native.eval::<f64>(black_box(u), black_box(&p)))
                .sum::<f64>()
        })
    });
    g.bench_function("expr_value", |b| {
        b.iter(|| {
            data.iter()
                .map(|u| expr.eval::<f64>(black_box(u), black_box(&p)))
                .sum::<f64>()
        })
    });
    let mut engine = GradientEngine::new(6);
    let mut grad = [0.0; 6];
    g.bench_function("native_gradient", |b| {
        b.iter(|| {
            data.iter()
                .map(|u| {
                    engine.value_and_gradient(
                        &native,
                        black_box(u),
                        black_box(&p),
                        &free,
                        &mut grad,
                    )
                })
                .sum::<f64>()
        })
    });
    g.bench_function("expr_gradient", |b| {
        b.iter(|| {
            data.iter()
                .map(|u| {
                    engine.value_and_gradient(&expr, black_box(u), black_box(&p), &free, &mut grad)
                })
                .sum::<f64>()
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
