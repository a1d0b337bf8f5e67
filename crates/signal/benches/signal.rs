//! criterion benchmarks of physid-signal: zero-phase Butterworth filtering (order 4 low-pass,
//! ba and sos) of 10⁶ samples, encoder decoding (Eq. 4.3) of 10⁷ counts, and a trigger wheel's
//! raw signal decoded into the crank angle (1.2 s of an inductive pickup at 100 kHz: edges,
//! teeth, the angle at every sample).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use physid_signal::encoder::Encoder;
use physid_signal::filter::{butter, Band};
use std::hint::black_box;

fn filtfilt(c: &mut Criterion) {
    let n = 1_000_000;
    let x: Vec<f64> = (0..n)
        .map(|i| (i as f64 * 0.013).sin() + 0.1 * (i as f64 * 1.7).cos())
        .collect();
    let zpk = match butter(4, &[500.0], Band::Lowpass, 10_000.0) {
        Ok(z) => z,
        Err(e) => panic!("{e}"),
    };
    let (tf, sos) = (zpk.to_ba(), zpk.to_sos());
    let mut g = c.benchmark_group("filtfilt");
    g.throughput(Throughput::Elements(n as u64));
    g.bench_function("ba_order4_1e6", |b| {
        b.iter(|| black_box(tf.filtfilt(black_box(&x))))
    });
    g.bench_function("sos_order4_1e6", |b| {
        b.iter(|| black_box(sos.sosfiltfilt(black_box(&x))))
    });
    g.finish();
}

fn encoder(c: &mut Criterion) {
    let n = 10_000_000;
    let counts: Vec<f64> = (0..n).map(|i| (i as f64 * 5.73).floor()).collect();
    let enc = Encoder { ppr: 360 };
    let mut g = c.benchmark_group("encoder");
    g.throughput(Throughput::Elements(n as u64));
    g.bench_function("speed_counts_1e7", |b| {
        b.iter(|| black_box(enc.speed_counts(black_box(&counts), 1e-3)))
    });
    g.finish();
}

fn wheel(c: &mut Criterion) {
    use physid_signal::wheel::{edges, index_teeth, EdgeOptions};
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden/wheel_vr_60m3.parquet");
    let opts = physid_io::ReadOptions {
        channels: Some(vec!["t".into(), "enc".into()]),
        ..Default::default()
    };
    let rec = match physid_io::read(&path, &opts) {
        Ok(r) => r,
        Err(e) => panic!("{e}"),
    };
    let (t, v) = match (rec.values("t"), rec.values("enc")) {
        (Ok(t), Ok(v)) => (t.to_vec(), v.to_vec()),
        _ => panic!("t, enc"),
    };
    let wheel = match "60-3".parse() {
        Ok(w) => w,
        Err(e) => panic!("{e}"),
    };
    let mut g = c.benchmark_group("wheel");
    g.throughput(Throughput::Elements(t.len() as u64));
    g.bench_function("decode_60m3_100khz_1.2s", |b| {
        b.iter(|| {
            let e = edges(black_box(&t), black_box(&v), &EdgeOptions::default());
            let a = e.and_then(|e| index_teeth(&e, wheel, "enc"));
            black_box(a.map(|a| a.angle_at(&t)))
        })
    });
    g.finish();
}

criterion_group!(benches, filtfilt, encoder, wheel);
criterion_main!(benches);
