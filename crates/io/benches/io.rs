//! criterion benchmark of physid-io: reading 10 channels × 10⁷ samples from Parquet (the
//! issue's need: < 2 s), and reading 2 of them (memory and time proportional to the channels
//! asked for). The file (~800 MB, Snappy) is written once to the temporary directory.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use physid_core::{Basis, Channel, Recording};
use physid_io::{read_parquet, write_parquet};
use std::hint::black_box;

fn parquet(c: &mut Criterion) {
    let n = 10_000_000;
    let path = std::env::temp_dir().join("physid-bench-10x1e7.parquet");
    if !path.exists() {
        let mut r = Recording::new(Basis::Time);
        for k in 0..10 {
            let values: Vec<f64> = (0..n)
                .map(|i| ((i * (k + 1)) as f64 * 1e-4).sin() * 100.0 + k as f64)
                .collect();
            if let Err(e) = r.push(Channel {
                name: format!("ch{k}"),
                unit: "V".into(),
                values,
            }) {
                panic!("{e}");
            }
        }
        if let Err(e) = write_parquet(&path, &r) {
            panic!("{e}");
        }
    }
    let mut g = c.benchmark_group("parquet_read");
    g.sample_size(10);
    g.throughput(Throughput::Elements(10 * n as u64));
    g.bench_function("10ch_1e7", |b| {
        b.iter(|| black_box(read_parquet(&path, None).map(|r| r.len())))
    });
    g.throughput(Throughput::Elements(2 * n as u64));
    let two = ["ch3".to_string(), "ch7".to_string()];
    g.bench_function("2of10ch_1e7", |b| {
        b.iter(|| black_box(read_parquet(&path, Some(&two)).map(|r| r.len())))
    });
    g.finish();
    // Writing: a tenth of the recording read above, to a file of its own.
    let tenth = match read_parquet(&path, None) {
        Ok(r) => r.slice(0..n / 10),
        Err(e) => panic!("{e}"),
    };
    let out = std::env::temp_dir().join("physid-bench-write-10x1e6.parquet");
    let mut g = c.benchmark_group("parquet_write");
    g.sample_size(10);
    g.throughput(Throughput::Elements(n as u64));
    g.bench_function("10ch_1e6", |b| {
        b.iter(|| black_box(write_parquet(&out, &tenth).is_ok()))
    });
    g.finish();
}

criterion_group!(benches, parquet);
criterion_main!(benches);
