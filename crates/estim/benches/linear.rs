//! criterion benchmarks of the linear estimators: updates per second for each method at
//! p = 2, 6, 20 on the standard workload (`physid_estim::workload`).

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use physid_estim::workload::{standard_methods, Workload};

const BATCH: usize = 4096;

fn linear(c: &mut Criterion) {
    let mut g = c.benchmark_group("linear_update");
    g.throughput(Throughput::Elements(BATCH as u64));
    for p in [2usize, 6, 20] {
        for method in standard_methods(p) {
            let name = method.name();
            let mut w = match Workload::new(method, p, BATCH) {
                Ok(w) => w,
                Err(e) => panic!("workload {name} p={p}: {e}"),
            };
            g.bench_with_input(BenchmarkId::new(name, p), &p, |b, _| {
                b.iter(|| w.run(BATCH))
            });
        }
    }
    g.finish();
}

criterion_group!(benches, linear);
criterion_main!(benches);
