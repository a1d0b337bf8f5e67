//! The raw angle decoders on hostile signals: random samples drawn from values a broken DAQ
//! gives (NaN, ±∞, ±1e308, subnormals, a stuck level, noise, a real square wave) on times whose
//! steps range from 1e-300 s to 1e300 s, pause for a million steps and sometimes go back. Every case must come back as
//! angles or an error, never a panic (arithmetic overflow included: these tests run with
//! overflow checks), and give the same pushed in chunks as whole. Bounded: a fixed number of
//! cases, each at most 3000 samples.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_signal::quadrature::{decode, IndexRange, QuadratureDecoder};
use physid_signal::wheel::{edges, index_teeth, EdgeDetector, EdgeOptions, Wheel};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const CASES: u64 = 300;

/// One hostile sample value: a square wave of `period` samples at `i` most of the time,
/// otherwise something broken.
fn value(rng: &mut ChaCha8Rng, i: usize, period: usize, phase: usize) -> f64 {
    let wave = f64::from(u8::from((i + phase) % period < period / 2));
    match rng.random_range(0..100) {
        0 => f64::NAN,
        1 => f64::INFINITY,
        2 => f64::NEG_INFINITY,
        3 => 1e308,
        4 => -1e308,
        5 => 5e-324,
        6 => rng.random::<f64>() * 1e6 - 5e5,
        7 => 0.5,
        8..=11 => f64::NAN,
        _ => wave,
    }
}

/// A case's times and channels: `n` samples, the steps of one scale (sometimes going back).
fn case(seed: u64) -> (Vec<f64>, [Vec<f64>; 3], usize) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = rng.random_range(1..3000);
    let step = [1e-300, 1e-9, 1e-5, 1.0, 1e300][rng.random_range(0..5)];
    let back = rng.random_range(0..8) == 0;
    let mut t = Vec::with_capacity(n);
    let mut now = 0.0;
    for _ in 0..n {
        now += step * rng.random_range(0.5..1.5);
        if back && rng.random_range(0..500) == 0 {
            now -= 10.0 * step;
        }
        if rng.random_range(0..300) == 0 {
            // A pause of 1e6 steps (the recording stopped and went on).
            now += 1e6 * step;
        }
        t.push(now);
    }
    let period = rng.random_range(2..40);
    let chunk = rng.random_range(1..700);
    let channels = [0, period / 4, 0].map(|phase| {
        // A stuck or broken channel for the whole case now and then.
        let stuck =
            (rng.random_range(0..20) == 0).then(|| [f64::NAN, 0.0, 1.0][rng.random_range(0..3)]);
        (0..n)
            .map(|i| stuck.unwrap_or_else(|| value(&mut rng, i, period, phase)))
            .collect::<Vec<f64>>()
    });
    (t, channels, chunk)
}

#[test]
fn the_quadrature_decoder_takes_hostile_signals_without_panicking() {
    let mut decoded = 0;
    for seed in 0..CASES {
        let (t, [a, b, z], chunk) = case(seed);
        let whole = decode(&t, &a, &b, Some(&z), 100, ["a", "b", "z"]);
        decoded += usize::from(whole.is_ok());
        // Pushed in chunks: the same transitions, findings and error.
        let mut range = IndexRange::default();
        range.push(&z);
        let mut d = QuadratureDecoder::new(["a", "b", "z"], Some(range.range), 100);
        let (mut got, mut whole_d) = (
            Vec::new(),
            QuadratureDecoder::new(["a", "b", "z"], Some(range.range), 100),
        );
        for s in (0..t.len()).step_by(chunk) {
            let e = (s + chunk).min(t.len());
            d.push(&t[s..e], &a[s..e], &b[s..e], &z[s..e]);
            got.extend(std::iter::from_fn(|| d.pop()));
        }
        whole_d.push(&t, &a, &b, &z);
        let (r, rw) = (d.finish(), whole_d.finish());
        assert_eq!(r.is_ok(), rw.is_ok(), "case {seed}");
        got.extend(std::iter::from_fn(|| d.pop()));
        let want: Vec<_> = std::iter::from_fn(|| whole_d.pop()).collect();
        assert!(
            got.len() == want.len()
                && got
                    .iter()
                    .zip(&want)
                    .all(|(x, y)| x.t.to_bits() == y.t.to_bits() && x.edge == y.edge),
            "case {seed}"
        );
        assert_eq!(d.take_findings(), whole_d.take_findings(), "case {seed}");
    }
    // The cases are hostile, not hopeless: most decode (222 of the 300).
    assert!(decoded > CASES as usize / 2, "{decoded} of {CASES} decoded");
}

#[test]
fn the_wheel_decoder_takes_hostile_signals_without_panicking() {
    let wheel: Wheel = "12-1".parse().unwrap();
    for seed in 0..CASES {
        let (t, [v, ..], chunk) = case(1_000_000 + seed);
        let opts = EdgeOptions::default();
        let whole = edges(&t, &v, &opts);
        let mut d = EdgeDetector::new(&opts);
        for s in (0..t.len()).step_by(chunk) {
            let e = (s + chunk).min(t.len());
            d.push(&t[s..e], &v[s..e]);
        }
        let chunked = d.finish();
        match (&whole, &chunked) {
            (Ok(w), Ok(c)) => {
                assert_eq!(w.t.len(), c.t.len(), "case {seed}");
                assert!(
                    w.t.iter()
                        .zip(&c.t)
                        .all(|(x, y)| x.to_bits() == y.to_bits()),
                    "case {seed}"
                );
                let _ = index_teeth(w, wheel, "enc");
            }
            (Err(_), Err(_)) => {}
            _ => panic!(
                "case {seed}: whole {:?}, in chunks {:?}",
                whole.is_ok(),
                chunked.is_ok()
            ),
        }
    }
}

/// A dropout far longer than the transitions before it (1 s after samples 1e-300 s apart): the
/// speed before expects more counts than an integer holds; the count taken is told, with no
/// overflow, and the decoding goes on.
#[test]
fn a_dropout_of_1e300_periods_is_taken_without_overflow() {
    let n = 400;
    let mut t: Vec<f64> = (0..n).map(|i| i as f64 * 1e-300).collect();
    let line = |i: usize| (i % 8) < 4;
    let mut a: Vec<f64> = (0..n).map(|i| f64::from(u8::from(line(i)))).collect();
    let b: Vec<f64> = (0..n).map(|i| f64::from(u8::from(line(i + 2)))).collect();
    for (i, x) in t.iter_mut().enumerate().skip(200) {
        *x = 1.0 + i as f64 * 1e-6;
    }
    a[199] = f64::NAN;
    let mut b = b;
    b[199] = f64::NAN;
    let q = decode(&t, &a, &b, None, 100, ["a", "b", "z"]).unwrap();
    assert!(
        q.findings
            .iter()
            .any(|f| f.index == 200 && f.detail.contains("taken as")),
        "{:#?}",
        q.findings
    );
}
