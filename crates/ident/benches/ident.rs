//! criterion benchmarks of the identifiability analysis: the batch ranking of 10⁶ × 15
//! sensitivity rows (stream into the triangular factor, then Alg. 5.1 on it), and the on-line
//! update at p = 15 over a 720-row window.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use physid_ident::workload::{rank_rows, rows, OnlineWorkload};
use std::hint::black_box;

fn batch(c: &mut Criterion) {
    let (n, p) = (1_000_000, 15);
    let data = rows(n, p);
    let mut g = c.benchmark_group("ident_batch");
    g.sample_size(10);
    g.throughput(Throughput::Elements(n as u64));
    g.bench_function("rank_1e6x15", |b| {
        b.iter(|| black_box(rank_rows(black_box(&data), p)))
    });
    g.finish();
}

fn online(c: &mut Criterion) {
    const BATCH: usize = 4096;
    let mut w = match OnlineWorkload::new(15, 720, 10_000) {
        Ok(w) => w,
        Err(e) => panic!("workload: {e}"),
    };
    let mut g = c.benchmark_group("ident_online");
    g.throughput(Throughput::Elements(BATCH as u64));
    g.bench_function("window720_p15", |b| {
        b.iter(|| {
            if let Err(e) = w.run(BATCH) {
                panic!("{e}");
            }
        })
    });
    g.finish();
}

criterion_group!(benches, batch, online);
criterion_main!(benches);
