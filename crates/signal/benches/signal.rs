//! criterion benchmarks of physid-signal: zero-phase Butterworth filtering (order 4 low-pass,
//! ba and sos; order 4 band-pass, sos and parallel) of 10⁶ samples, encoder decoding (Eq. 4.3) of 10⁷ counts, and a trigger wheel's
//! raw signal decoded into the crank angle (1.2 s of an inductive pickup at 100 kHz: edges,
//! teeth, the angle at every sample), and a time-basis stream taken onto a 0.1° crank-angle grid
//! (`CycleStream`'s curves as the combustion stage takes them — the pressure, the time at three
//! points: 20 cycles at 6000 rpm, 360 kHz, the samples on the grid's angles or half a step off
//! them).

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
    // Knock's band-pass: four sections.
    let band = match butter(4, &[500.0, 2000.0], Band::Bandpass, 10_000.0) {
        Ok(z) => z,
        Err(e) => panic!("{e}"),
    };
    let (sections, Some(parallel)) = (band.to_sos(), band.to_parallel()) else {
        panic!("the band-pass has no parallel form")
    };
    g.bench_function("sos_bandpass_order4_1e6", |b| {
        b.iter(|| black_box(sections.sosfiltfilt(black_box(&x))))
    });
    // The same as parallel branches.
    g.bench_function("parallel_bandpass_order4_1e6", |b| {
        b.iter(|| black_box(parallel.filtfilt_from(black_box(&x), 0)))
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

/// The quadrature decoder on the golden 500-line encoder (200 kHz, 0.6 s; A, B, Z) with the
/// angle at every sample — the dropout handling's cost on a clean signal.
fn quadrature(c: &mut Criterion) {
    use physid_signal::quadrature::decode;
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/golden/quadrature_500.parquet");
    let rec = match physid_io::read(&path, &Default::default()) {
        Ok(r) => r,
        Err(e) => panic!("{e}"),
    };
    let column = |n: &str| match rec.values(n) {
        Ok(v) => v.to_vec(),
        Err(e) => panic!("{e}"),
    };
    let (t, a, b, z) = (
        column("t"),
        column("enc_a"),
        column("enc_b"),
        column("enc_z"),
    );
    let mut g = c.benchmark_group("quadrature");
    g.throughput(Throughput::Elements(t.len() as u64));
    g.bench_function("decode_500_200khz_0.6s", |bench| {
        bench.iter(|| {
            let q = decode(black_box(&t), &a, &b, Some(&z), 500, ["a", "b", "z"]);
            black_box(q.map(|q| q.angle_at(&t)))
        })
    });
    g.finish();
}

fn grid(c: &mut Criterion) {
    use physid_signal::cycles::CycleStream;
    let cycles = 20;
    let n = cycles * 7200;
    let mut g = c.benchmark_group("cycle_stream");
    g.throughput(Throughput::Elements(n as u64));
    for (name, offset) in [("on_grid", 0.0), ("half_step_off", 0.05)] {
        let deg: Vec<f64> = (0..n).map(|k| k as f64 * 0.1 + offset).collect();
        let t: Vec<f64> = deg.iter().map(|d| d / 36_000.0).collect();
        let theta: Vec<f64> = deg.iter().map(|d| d.to_radians()).collect();
        let p: Vec<f64> = theta.iter().map(|a| 1e5 * (2.0 + a.cos())).collect();
        g.bench_function(format!("curves_0.1deg_{name}_20_cycles"), |b| {
            b.iter(|| {
                // As the combustion stage: the pressure, and the time at three points.
                let mut s = match CycleStream::new(1, 0.0, Some(0.1))
                    .and_then(|s| s.with_times_at(&[0, 3600, 7199]))
                {
                    Ok(s) => s.curves_only(),
                    Err(e) => panic!("{e}"),
                };
                let mut out = Vec::with_capacity(cycles);
                for from in (0..n).step_by(3600) {
                    let to = (from + 3600).min(n);
                    let r = s.push(&t[from..to], &theta[from..to], &[&p[from..to]], &mut out);
                    if let Err(e) = r {
                        panic!("{e}");
                    }
                    for c in out.drain(..) {
                        if let Some(curve) = c.curve {
                            s.recycle(black_box(curve));
                        }
                    }
                }
            })
        });
    }
    g.finish();
}

criterion_group!(benches, filtfilt, encoder, wheel, quadrature, grid);
criterion_main!(benches);
