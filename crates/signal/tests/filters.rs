//! Butterworth design and zero-phase filtering against scipy (`golden/gen_scipy_filters.py`).
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_signal::filter::{butter, Band, FilterError};
use serde_json::Value;

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

#[test]
fn equals_scipy_butter_filtfilt_and_sosfiltfilt() {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/golden/scipy_filters.json"
    ))
    .unwrap();
    let g: Value = serde_json::from_str(&text).unwrap();
    let fs = g["fs"].as_f64().unwrap();
    let x = floats(&g["x"]);
    let amp = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for c in g["cases"].as_array().unwrap() {
        let order = c["order"].as_u64().unwrap() as usize;
        let wn = floats(&c["wn"]);
        let band = match c["btype"].as_str().unwrap() {
            "lowpass" => Band::Lowpass,
            "highpass" => Band::Highpass,
            _ => Band::Bandpass,
        };
        let label = format!("{band:?} order {order} at {wn:?} Hz");
        let zpk = butter(order, &wn, band, fs).unwrap();
        let tf = zpk.to_ba();
        for (ours, theirs) in [(&tf.b, floats(&c["b"])), (&tf.a, floats(&c["a"]))] {
            let scale = theirs.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for (o, t) in ours.iter().zip(&theirs) {
                assert!((o - t).abs() <= 1e-12 * scale, "{label}: {o} vs {t}");
            }
        }
        for (o, t) in tf.lfilter_zi().iter().zip(floats(&c["zi"])) {
            assert!(
                (o - t).abs() <= 1e-7 * t.abs().max(1.0),
                "{label}: zi {o} vs {t}"
            );
        }
        let y = tf.filtfilt(&x).unwrap();
        let ys = zpk.to_sos().sosfiltfilt(&x).unwrap();
        for (name, ours, theirs) in [
            ("filtfilt", &y, floats(&c["filtfilt"])),
            ("sosfiltfilt", &ys, floats(&c["sosfiltfilt"])),
        ] {
            let err = ours
                .iter()
                .zip(&theirs)
                .fold(0.0f64, |m, (o, t)| m.max((o - t).abs()));
            assert!(err <= 1e-10 * amp, "{label} {name}: max error {err:e}");
        }
    }
}

#[test]
fn design_and_input_errors() {
    let e = butter(0, &[10.0], Band::Lowpass, 100.0).unwrap_err();
    assert!(e.to_string().contains("order 0"), "{e}");
    let e = butter(2, &[60.0], Band::Lowpass, 100.0).unwrap_err();
    assert!(e.to_string().contains("Nyquist frequency 50 Hz"), "{e}");
    let e = butter(2, &[10.0], Band::Bandpass, 100.0).unwrap_err();
    assert!(e.to_string().contains("needs 2 cut-off"), "{e}");
    let e = butter(2, &[20.0, 10.0], Band::Bandpass, 100.0).unwrap_err();
    assert!(e.to_string().contains("low < high"), "{e}");
    let tf = butter(4, &[10.0], Band::Lowpass, 100.0).unwrap().to_ba();
    assert_eq!(
        tf.filtfilt(&[1.0; 15]).unwrap_err(),
        FilterError::TooShort {
            len: 15,
            padlen: 15
        }
    );
    let mut x = vec![1.0; 100];
    x[42] = f64::NAN;
    assert!(matches!(
        tf.filtfilt(&x).unwrap_err(),
        FilterError::NonFinite { index: 42, .. }
    ));
    // A constant passes a low-pass unchanged (steady-state initial conditions).
    let y = tf.filtfilt(&[3.5; 200]).unwrap();
    assert!(y.iter().all(|v| (v - 3.5).abs() < 1e-12));
}

/// The settling length: from the sections' poles, equal to the design's own poles' (the zpk's
/// largest radius), and the impulse response after it below the tolerance (of its peak, within
/// the few-fold a cascade of similar poles adds).
#[test]
fn a_filter_settles_in_the_samples_its_slowest_pole_says() {
    for (order, wn, band, fs) in [
        (4, vec![5e3, 20e3], Band::Bandpass, 360e3),
        (4, vec![5e3, 20e3], Band::Bandpass, 60e3),
        (2, vec![100.0], Band::Lowpass, 10e3),
        (4, vec![500.0], Band::Highpass, 10e3),
    ] {
        let zpk = butter(order, &wn, band, fs).unwrap();
        let sos = zpk.to_sos();
        let radius = zpk.p.iter().fold(0.0f64, |m, p| m.max(p.norm()));
        for tol in [1e-6, 1e-12] {
            let n = sos.settle_samples(tol);
            assert_eq!(
                n,
                (tol.ln() / radius.ln()).ceil() as usize,
                "{band:?} {wn:?}"
            );
            let len = 4 * n + 10;
            let mut x = vec![0.0; len];
            x[0] = 1.0;
            let mut y = vec![0.0; len];
            sos.sosfilt_into(&x, &mut vec![[0.0; 2]; sos.sections.len()], &mut y);
            let peak = y.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let tail = y[n..].iter().fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(
                tail < 20.0 * tol * peak,
                "{band:?} {wn:?} tol {tol}: {tail} of {peak} after {n}"
            );
        }
    }
    // A stretch's tail, the backward pass stopped at its start: the whole's values, bit for bit.
    let sos = butter(4, &[5e3, 20e3], Band::Bandpass, 360e3)
        .unwrap()
        .to_sos();
    let x: Vec<f64> = (0..3000)
        .map(|i| (i as f64 * 0.37).sin() + 0.01 * i as f64)
        .collect();
    let whole = sos.sosfiltfilt(&x).unwrap();
    for from in [0, 1, 1234, 2999, 3000] {
        assert_eq!(
            sos.sosfiltfilt_from(&x, from).unwrap(),
            whole[from..],
            "{from}"
        );
    }
    let unstable = physid_signal::filter::Sos {
        sections: vec![[1.0, 0.0, 0.0, 1.0, -2.0, 1.1]],
    };
    assert_eq!(unstable.settle_samples(1e-9), usize::MAX);
}
