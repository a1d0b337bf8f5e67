//! Zero-phase filtering on a stream against the whole-record `sosfiltfilt` (itself equal to
//! scipy's, `tests/filters.rs`): the same output however the input is chunked, the interior
//! within 1e-12 of the signal's scale, the last samples bit for bit, and no sample held longer
//! than the stated latency.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_signal::filter::{butter, Band, FilterError, Sos};
use physid_signal::stream::ZeroPhaseStream;

/// A test signal: two tones, a step and deterministic pseudo-noise.
fn signal(n: usize) -> Vec<f64> {
    let mut s: u64 = 0x9e37_79b9_7f4a_7c15;
    (0..n)
        .map(|i| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            let noise = (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            let t = i as f64 / 10_000.0;
            3.0 * (2.0 * std::f64::consts::PI * 37.0 * t).sin()
                + 0.5 * (2.0 * std::f64::consts::PI * 1900.0 * t).sin()
                + if i > n / 3 { 2.0 } else { 0.0 }
                + noise
        })
        .collect()
}

fn stream(sos: &Sos, x: &[f64], chunk: usize) -> (Vec<f64>, usize) {
    let mut z = ZeroPhaseStream::new(sos, None, None);
    let mut out = Vec::new();
    for c in x.chunks(chunk) {
        z.push(c, &mut out).unwrap();
        // Nothing waits longer than the latency.
        assert!(
            out.len() + z.latency() >= z.taken(),
            "{} of {}",
            out.len(),
            z.taken()
        );
    }
    z.finish(&mut out).unwrap();
    (out, z.lookahead())
}

#[test]
fn streaming_equals_the_whole_record_however_chunked() {
    let x = signal(20_000);
    let scale = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for (sos, what) in [
        (
            butter(4, &[500.0], Band::Lowpass, 10_000.0)
                .unwrap()
                .to_sos(),
            "low-pass 4th order 500 Hz",
        ),
        (
            butter(2, &[50.0], Band::Highpass, 10_000.0)
                .unwrap()
                .to_sos(),
            "high-pass 2nd order 50 Hz",
        ),
        (
            butter(3, &[20.0, 400.0], Band::Bandpass, 10_000.0)
                .unwrap()
                .to_sos(),
            "band-pass 3rd order 20–400 Hz",
        ),
    ] {
        let whole = sos.sosfiltfilt(&x).unwrap();
        let (first, lookahead) = stream(&sos, &x, 1);
        assert_eq!(first.len(), x.len(), "{what}");
        for chunk in [17, 4096, x.len()] {
            let (out, _) = stream(&sos, &x, chunk);
            assert_eq!(out, first, "{what}: chunks of {chunk}");
        }
        let worst = first
            .iter()
            .zip(&whole)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        eprintln!("{what}: lookahead {lookahead}, worst |stream − whole| = {worst:.2e} (scale {scale:.1})");
        assert!(worst < 1e-12 * scale, "{what}: {worst:e}");
        let n = x.len();
        assert_eq!(
            first[n - lookahead..],
            whole[n - lookahead..],
            "{what}: the end"
        );
    }
}

#[test]
fn lookahead_follows_the_filter_and_bad_input_is_refused() {
    let slow = butter(4, &[20.0], Band::Lowpass, 10_000.0)
        .unwrap()
        .to_sos();
    let fast = butter(4, &[2000.0], Band::Lowpass, 10_000.0)
        .unwrap()
        .to_sos();
    let (ls, lf) = (
        ZeroPhaseStream::new(&slow, None, None).lookahead(),
        ZeroPhaseStream::new(&fast, None, None).lookahead(),
    );
    assert!(ls > 10 * lf, "a lower cut-off rings longer: {ls} vs {lf}");
    let mut z = ZeroPhaseStream::new(&fast, None, Some(64));
    let mut out = Vec::new();
    z.push(&[1.0, 2.0, 3.0], &mut out).unwrap();
    let e = z.push(&[4.0, f64::NAN], &mut out).unwrap_err();
    assert!(
        matches!(e, FilterError::NonFinite { index: 4, value } if value.is_nan()),
        "{e}"
    );
    assert_eq!(z.taken(), 3, "the refused chunk is not taken");
    let e = z.finish(&mut out).unwrap_err();
    assert!(matches!(e, FilterError::TooShort { len: 3, .. }), "{e}");
}

/// The stream against scipy itself (`golden/gen_scipy_filters.py`, not through the whole-record
/// path): scipy's `sosfiltfilt` of the golden signal for every low-pass, high-pass and band
/// case, the golden signal pushed in chunks of 1, 97 and 1000 samples — within 1e-10 of the
/// signal's scale, as the whole-record filter is.
#[test]
fn the_stream_equals_scipy_sosfiltfilt() {
    use serde_json::Value;
    let floats = |v: &Value| -> Vec<f64> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/golden/scipy_filters.json"
    ))
    .unwrap();
    let g: Value = serde_json::from_str(&text).unwrap();
    let fs = g["fs"].as_f64().unwrap();
    let x = floats(&g["x"]);
    let amp = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let mut cases = 0;
    for c in g["cases"].as_array().unwrap() {
        let order = c["order"].as_u64().unwrap() as usize;
        let wn = floats(&c["wn"]);
        let band = match c["btype"].as_str().unwrap() {
            "lowpass" => Band::Lowpass,
            "highpass" => Band::Highpass,
            _ => Band::Bandpass,
        };
        let sos = butter(order, &wn, band, fs).unwrap().to_sos();
        let scipy = floats(&c["sosfiltfilt"]);
        for chunk in [1, 97, 1000] {
            let (y, _) = stream(&sos, &x, chunk);
            assert_eq!(y.len(), scipy.len(), "{band:?} {order} {wn:?}");
            let err = y
                .iter()
                .zip(&scipy)
                .fold(0.0f64, |m, (o, t)| m.max((o - t).abs()));
            assert!(
                err <= 1e-10 * amp,
                "{band:?} order {order} at {wn:?} Hz, chunks of {chunk}: max error {err:e}"
            );
        }
        cases += 1;
    }
    assert!(cases >= 10, "{cases} cases");
}
