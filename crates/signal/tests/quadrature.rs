//! The quadrature decoder against a numpy-generated A/B/Z encoder with the true angle
//! (`golden/gen_wheels.py`): 500 lines, digital, 200 kHz; the shaft turns back 40° first, then
//! forward to 1200 rpm with cyclic fluctuation; every edge jittered by up to 3 % of a line.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_signal::quadrature::decode;
use std::path::PathBuf;

fn load() -> Vec<Vec<f64>> {
    let path =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden/quadrature_500.parquet");
    let rec = physid_io::read(&path, &Default::default()).unwrap();
    ["t", "enc_a", "enc_b", "enc_z", "theta_true"]
        .iter()
        .map(|n| rec.values(n).unwrap().to_vec())
        .collect()
}

#[test]
fn both_ways_within_a_tenth_of_a_degree_of_the_truth() {
    let c = load();
    let (t, a, b, z) = (&c[0], &c[1], &c[2], &c[3]);
    let truth: Vec<f64> = c[4].iter().map(|x| x * 1e-6).collect();
    let q = decode(t, a, b, Some(z), 500, ["enc_a", "enc_b", "enc_z"]).unwrap();
    assert!(q.findings.is_empty(), "{:?}", q.findings);
    // 40° back is 40/360·2000 = 222 quarter-line steps.
    assert!(
        (q.backward as i64 - 222).abs() <= 1,
        "{} steps back",
        q.backward
    );
    // Index pulses turning forward: the wheel's 0 passed forward at the end of the rocking,
    // then once per revolution.
    assert!(q.index_t.len() >= 4, "{:?}", q.index_t);
    let angle = q.angle_at(t);
    // Angle 0 at the index's rising edge: the truth's 0 (the index is high from 0 to a
    // quarter line), so no offset to take out here — only the edge's own jitter.
    let mut worst: f64 = 0.0;
    for (x, y) in angle.iter().zip(&truth) {
        if x.is_finite() {
            worst = worst.max((x - y).abs());
        }
    }
    // The bound, 0.1°. Measured 0.047°: the edges' jitter (±3 % of a line, 0.022°)
    // and half a sample at 1200 rpm (0.018°), on the edges and on the index that sets 0.
    assert!(worst.to_degrees() < 0.1, "{}°", worst.to_degrees());
}

#[test]
fn bad_encoder_signals_are_refused_by_name() {
    let c = load();
    let (t, a, b) = (&c[0], &c[1], &c[2]);
    let flat = vec![0.0; t.len()];
    let e = decode(t, a, &flat, None, 500, ["a", "b", "z"]).unwrap_err();
    assert!(e.to_string().contains("'b': flat"), "{e}");
    let mut nan = a.clone();
    nan[77] = f64::NAN;
    let e = decode(t, &nan, b, None, 500, ["a", "b", "z"]).unwrap_err();
    assert!(e.to_string().contains("'a': sample 77"), "{e}");
    assert!(decode(t, a, b, None, 0, ["a", "b", "z"]).is_err());
    // An index claimed every 400 lines on a 500-line encoder: each pulse out of place.
    let q = decode(t, a, b, Some(&c[3]), 400, ["a", "b", "z"]).unwrap();
    assert!(!q.findings.is_empty());
    assert!(
        q.findings[0]
            .detail
            .contains("not a whole number of revolutions of 1600"),
        "{:?}",
        q.findings
    );
}
