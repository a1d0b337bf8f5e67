//! The trigger-wheel decoder against raw signals with known truth, generated independently
//! (`golden/gen_wheels.py`, numpy only): an inductive pickup over a 60−3 wheel at 100 kHz
//! (amplitude growing 8× with speed, asymmetric teeth, noise, glitch pulses in the gap at low
//! speed) and a Hall sensor over a 36−1 wheel at 50 kHz with one tooth's pulse dropped and one
//! spurious pulse added.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_signal::integrity::FindingKind;
use physid_signal::wheel::{
    edges, index_teeth, recognise, EdgeDetector, EdgeOptions, Wheel, WheelAngles, WheelError,
    DROPOUT_RUNS_KEPT,
};
use serde_json::Value;
use std::path::PathBuf;

fn golden(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/golden")
        .join(name)
}

fn expected(file: &str) -> Value {
    let v: Value =
        serde_json::from_str(&std::fs::read_to_string(golden("wheels.json")).unwrap()).unwrap();
    v[file].clone()
}

/// t [s], the raw signal, the true angle [rad].
fn load(file: &str) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let opts = physid_io::ReadOptions {
        channels: Some(vec!["t".into(), "enc".into(), "theta_true".into()]),
        ..Default::default()
    };
    let rec = physid_io::read(golden(&format!("{file}.parquet")), &opts).unwrap();
    let t = rec.values("t").unwrap().to_vec();
    let v = rec.values("enc").unwrap().to_vec();
    // The true angle in µrad (a unit physid does not convert).
    let truth = rec
        .values("theta_true")
        .unwrap()
        .iter()
        .map(|a| a * 1e-6)
        .collect();
    (t, v, truth)
}

/// The samples of `a`'s findings of `kind`.
fn samples_of(a: &WheelAngles, kind: FindingKind) -> Vec<usize> {
    a.findings
        .iter()
        .filter(|f| f.kind == kind)
        .map(|f| f.index)
        .collect()
}

/// The largest deviation [deg] of `angle` from `truth` once their mean difference (the
/// unknown angle of the edge's level crossing on the tooth) is taken out, over the samples
/// where `angle` is known; and that mean [deg].
fn error_deg(angle: &[f64], truth: &[f64]) -> (f64, f64, usize) {
    let d: Vec<f64> = angle
        .iter()
        .zip(truth)
        .filter(|(a, _)| a.is_finite())
        .map(|(a, t)| a - t)
        .collect();
    let mean = d.iter().sum::<f64>() / d.len() as f64;
    let worst = d.iter().map(|x| (x - mean).abs()).fold(0.0, f64::max);
    (worst.to_degrees(), mean.to_degrees(), d.len())
}

#[test]
fn an_inductive_pickup_over_a_60_3_wheel_gives_the_angle_within_a_tenth_of_a_degree() {
    let exp = expected("wheel_vr_60m3");
    let (t, v, truth) = load("wheel_vr_60m3");
    let e = edges(&t, &v, &EdgeOptions::default()).unwrap();
    assert_eq!(e.glitches.len(), exp["glitches"].as_u64().unwrap() as usize);
    let wheel: Wheel = "60-3".parse().unwrap();
    let a = index_teeth(&e, wheel, "enc").unwrap();
    let problems: Vec<_> = a
        .findings
        .iter()
        .filter(|f| f.kind != FindingKind::Note)
        .collect();
    assert!(problems.is_empty(), "{problems:?}");
    assert_eq!(a.findings.len(), 1, "the glitches' note");
    let angle = a.angle_at(&t);
    let (worst, offset, n) = error_deg(&angle, &truth);
    assert!(worst < 0.1, "{worst}° off the truth");
    assert!(n > t.len() * 9 / 10, "{n} samples with an angle");
    // The edge is tooth 0's rising flank, on the wheel a fraction of a pitch before the tooth's
    // centre at half a pitch: the wheel's angle 0 is the truth's [0, 6°) modulo 360°.
    let zero = (-offset).rem_euclid(360.0);
    assert!(zero > 0.0 && zero < 6.0, "{zero}");
    let revs = exp["revolutions"].as_u64().unwrap() as usize;
    assert!(
        a.revolutions + 2 >= revs && a.revolutions <= revs,
        "{}",
        a.revolutions
    );
    let [lo, hi] = [0, 1].map(|i| exp["rpm"][i].as_f64().unwrap());
    // The cyclic fluctuation (±6 %) around the ramp.
    assert!(a.rpm.0 > 0.9 * lo && a.rpm.0 < 1.1 * lo, "{:?}", a.rpm);
    assert!(a.rpm.1 > 0.9 * hi && a.rpm.1 < 1.1 * hi, "{:?}", a.rpm);
}

/// Chunk by chunk (any size) the edges are those of the whole signal.
#[test]
fn the_edges_of_a_stream_are_those_of_the_whole_signal() {
    let (t, v, _) = load("wheel_vr_60m3");
    let whole = edges(&t, &v, &EdgeOptions::default()).unwrap();
    for size in [1, 333, 4096, 65_536] {
        let mut d = EdgeDetector::new(&EdgeOptions::default());
        for (tc, vc) in t.chunks(size).zip(v.chunks(size)) {
            d.push(tc, vc);
        }
        assert_eq!(d.finish().unwrap(), whole, "chunks of {size}");
    }
}

/// Samples not finite (a dropout in the acquisition) are skipped, never guessed over: a run
/// between two edges changes no edge; a run over an edge loses that edge, which the indexing
/// counts as a missing tooth — and the angle everywhere stays within a tenth of a degree of the
/// generator's truth. Each run is a finding at its first sample; in chunks of any size the
/// same.
#[test]
fn a_dropout_in_the_signal_is_skipped_and_an_edge_it_hides_counted_missing() {
    let (t, v, truth) = load("wheel_vr_60m3");
    let clean = edges(&t, &v, &EdgeOptions::default()).unwrap();
    // Between two edges (well clear of both), over an edge (a few samples either side of it),
    // and inside the first samples the automatic level starts from (+∞ there).
    let k = clean.t.len() / 2;
    let between = (clean.index[k] + clean.index[k + 1]) / 2 - 3;
    let over = clean.index[k + 200] - 3;
    let early = 100;
    let mut bad = v.clone();
    bad[between..between + 6].fill(f64::NAN);
    bad[over..over + 6].fill(f64::NAN);
    bad[early] = f64::INFINITY;
    let e = edges(&t, &bad, &EdgeOptions::default()).unwrap();
    assert_eq!(e.dropouts.samples, 13);
    assert_eq!(e.dropouts.runs, 3);
    let runs: Vec<(usize, usize)> = e
        .dropouts
        .first
        .iter()
        .map(|r| (r.index, r.samples))
        .collect();
    assert_eq!(runs, [(early, 1), (between, 6), (over, 6)]);
    // Every edge but the hidden one: exactly up to it; after it within a twentieth of a sample
    // (the automatic level follows each tooth's swing, and the hidden tooth's is not seen).
    let kept: Vec<(f64, usize)> = clean
        .t
        .iter()
        .zip(&clean.index)
        .filter(|(_, &i)| i != clean.index[k + 200])
        .map(|(&t, &i)| (t, i))
        .collect();
    let got: Vec<(f64, usize)> = e.t.iter().copied().zip(e.index.iter().copied()).collect();
    let dt = t[1] - t[0];
    let differ = got.iter().zip(&kept).position(|(a, b)| {
        a.1 != b.1 || (a.0 != b.0 && (b.1 < over || (a.0 - b.0).abs() > 0.05 * dt))
    });
    assert!(
        got.len() == kept.len() && differ.is_none(),
        "{} edges against {}; the first that differs: {:?}",
        got.len(),
        kept.len(),
        differ.map(|i| (got[i], kept[i]))
    );
    let a = index_teeth(&e, "60-3".parse().unwrap(), "enc").unwrap();
    let at = |kind| samples_of(&a, kind);
    assert_eq!(at(FindingKind::NonFinite), [early, between, over]);
    assert_eq!(
        at(FindingKind::PulseLoss),
        [clean.index[k + 201]],
        "{:?}",
        a.findings
    );
    let detail = &a.findings.iter().find(|f| f.index == over).unwrap().detail;
    assert!(
        detail.contains("'enc': 6 sample(s) from sample"),
        "{detail}"
    );
    assert!(detail.contains("NaN"), "{detail}");
    let (worst, _, _) = error_deg(&a.angle_at(&t), &truth);
    assert!(worst < 0.1, "{worst}° off the truth");
    for size in [1, 333, 4096] {
        let mut d = EdgeDetector::new(&EdgeOptions::default());
        for (tc, vc) in t.chunks(size).zip(bad.chunks(size)) {
            d.push(tc, vc);
        }
        let c = d.finish().unwrap();
        assert!(c == e, "chunks of {size}: {} edges", c.t.len());
    }
}

/// Many dropouts: the first [`DROPOUT_RUNS_KEPT`] are findings one by one, the rest a note
/// that counts them; what the detector holds does not grow with them.
#[test]
fn many_dropouts_are_counted_past_those_told_one_by_one() {
    let (t, v, _) = load("wheel_vr_60m3");
    let clean = edges(&t, &v, &EdgeOptions::default()).unwrap();
    let mut bad = v.clone();
    let at: Vec<usize> = (100..130)
        .map(|j| (clean.index[j] + clean.index[j + 1]) / 2)
        .collect();
    for &i in &at {
        bad[i] = f64::NAN;
    }
    let e = edges(&t, &bad, &EdgeOptions::default()).unwrap();
    assert_eq!((e.dropouts.samples, e.dropouts.runs), (30, 30));
    assert_eq!(e.dropouts.first.len(), DROPOUT_RUNS_KEPT);
    assert_eq!(e.t, clean.t, "no edge is near a dropout");
    let a = index_teeth(&e, "60-3".parse().unwrap(), "enc").unwrap();
    let told: Vec<usize> = a
        .findings
        .iter()
        .filter(|f| f.kind == FindingKind::NonFinite)
        .map(|f| f.index)
        .collect();
    assert_eq!(told, at[..DROPOUT_RUNS_KEPT]);
    let note = a
        .findings
        .iter()
        .find(|f| f.detail.contains("more run(s)"))
        .expect("the note of the rest");
    assert!(note.detail.contains("10 more run(s)"), "{}", note.detail);
    assert!(
        note.detail.contains("30 sample(s) in all"),
        "{}",
        note.detail
    );
}

#[test]
fn a_hall_sensor_over_a_36_1_wheel_with_a_missing_and_an_extra_edge() {
    let exp = expected("wheel_hall_36m1");
    let (t, v, truth) = load("wheel_hall_36m1");
    let e = edges(&t, &v, &EdgeOptions::default()).unwrap();
    let a = index_teeth(&e, "36-1".parse().unwrap(), "enc").unwrap();
    let at = |kind| samples_of(&a, kind);
    assert_eq!(
        at(FindingKind::PulseLoss),
        [exp["missing_edge_sample"].as_u64().unwrap() as usize]
    );
    assert_eq!(
        at(FindingKind::ExtraPulses),
        [exp["extra_edge_sample"].as_u64().unwrap() as usize]
    );
    assert_eq!(a.findings.len(), 2, "{:?}", a.findings);
    let (worst, _, _) = error_deg(&a.angle_at(&t), &truth);
    assert!(worst < 0.1, "{worst}° off the truth");
}

#[test]
fn a_wheel_that_does_not_match_says_what_was_found() {
    let (t, v, _) = load("wheel_vr_60m3");
    let e = edges(&t, &v, &EdgeOptions::default()).unwrap();
    let err = index_teeth(&e, "60-2".parse().unwrap(), "enc").unwrap_err();
    let msg = err.to_string();
    assert!(msg.contains("57 teeth between gaps"), "{msg}");
    assert!(msg.contains("expected 58"), "{msg}");
    assert!(msg.contains("60-3"), "{msg}");
    let err = index_teeth(&e, "36-1".parse().unwrap(), "enc").unwrap_err();
    assert!(err.to_string().contains("'enc'"), "{err}");
}

#[test]
fn bad_signals_are_refused_with_the_sample() {
    let t: Vec<f64> = (0..10_000).map(|i| i as f64 * 1e-5).collect();
    let flat = vec![1.5; t.len()];
    let err = edges(&t, &flat, &EdgeOptions::default()).unwrap_err();
    assert!(err.to_string().contains("flat"), "{err}");
    // Equally spaced teeth: no gap.
    let even: Vec<f64> = t
        .iter()
        .map(|&ti| {
            if (ti * 6000.0).fract() < 0.5 {
                5.0
            } else {
                0.0
            }
        })
        .collect();
    let e = edges(&t, &even, &EdgeOptions::default()).unwrap();
    let err = index_teeth(&e, "60-2".parse().unwrap(), "enc").unwrap_err();
    assert!(err.to_string().contains("no gap"), "{err}");
    // Nothing but dropouts: said, not a panic.
    let err = edges(&t, &vec![f64::NAN; t.len()], &EdgeOptions::default()).unwrap_err();
    assert!(
        err.to_string()
            .contains("none of its 10000 samples is finite"),
        "{err}"
    );
    // Time not increasing: the sample named, a dropout's time checked too.
    let mut back = t.clone();
    back[5000] = back[4998];
    let mut v = even.clone();
    v[5000] = f64::NAN;
    assert!(matches!(
        edges(&back, &v, &EdgeOptions::default()),
        Err(WheelError::Time { index: 5000, .. })
    ));
    // Too few edges (none at all included) for two revolutions: an error, not a panic.
    let none = physid_signal::wheel::Edges {
        t: vec![],
        index: vec![],
        glitches: vec![],
        dropouts: Default::default(),
        samples: 0,
    };
    assert!(index_teeth(&none, "60-2".parse().unwrap(), "enc").is_err());
    for bad in ["60", "60-0", "6-3", "x-1"] {
        assert!(bad.parse::<Wheel>().is_err(), "{bad}");
    }
}

/// The engine's speed falling 8× at once (the golden recording played twice end to end: from
/// 2400 rpm back to 300 rpm): the automatic level starts again from the smaller swing after
/// [`physid_signal::wheel::SILENCE`] tooth periods without an edge, the joint is reported, and
/// after the next gap the angle is again within a tenth of a degree of the truth.
#[test]
fn the_level_recovers_when_the_amplitude_falls_at_once() {
    let (t, v, truth) = load("wheel_vr_60m3");
    let n = t.len();
    let dt = t[1] - t[0];
    let t2: Vec<f64> = (0..2 * n).map(|i| i as f64 * dt).collect();
    let v2: Vec<f64> = v.iter().chain(&v).copied().collect();
    let once = edges(&t, &v, &EdgeOptions::default()).unwrap();
    let e = edges(&t2, &v2, &EdgeOptions::default()).unwrap();
    assert!(e.t.len() + 5 >= 2 * once.t.len(), "{} edges", e.t.len());
    let a = index_teeth(&e, "60-3".parse().unwrap(), "enc").unwrap();
    assert!(
        a.findings
            .iter()
            .any(|f| f.kind != FindingKind::Note && f.index >= n && f.index < n + 2000),
        "{:?}",
        a.findings
    );
    // The second copy from its second revolution on, against its own truth.
    let from = n + truth
        .iter()
        .position(|&x| x > 2.0 * std::f64::consts::TAU)
        .unwrap();
    let angle = a.angle_at(&t2[from..]);
    let (worst, _, _) = error_deg(&angle, &truth[from - n..]);
    assert!(worst < 0.1, "{worst}° off the truth after the joint");
}

/// The golden raw signals are recognised as the wheels they are, without being told; a
/// regular pulse train without a gap and a sine are not wheels.
#[test]
fn a_wheel_is_recognised_from_its_signal_alone() {
    for (file, want) in [("wheel_vr_60m3", "60-3"), ("wheel_hall_36m1", "36-1")] {
        let (t, v, _) = load(file);
        let e = edges(&t, &v, &EdgeOptions::default()).unwrap();
        let r = recognise(&e).unwrap_or_else(|| panic!("{file}: not recognised"));
        assert_eq!(r.wheel.to_string(), want, "{file}");
        assert!(r.gaps >= 3);
    }
    let t: Vec<f64> = (0..100_000).map(|i| f64::from(i) * 1e-5).collect();
    let square: Vec<f64> = t
        .iter()
        .map(|x| f64::from(u8::from((x * 1e3).fract() < 0.5)))
        .collect();
    let e = edges(&t, &square, &EdgeOptions::default()).unwrap();
    assert!(e.t.len() > 50 && recognise(&e).is_none());
    let sine: Vec<f64> = t.iter().map(|x| (x * 50.0).sin()).collect();
    let e = edges(&t, &sine, &EdgeOptions::default()).unwrap();
    assert!(recognise(&e).is_none());
}

/// A 360-pulse analog encoder with an analog index (`golden/gen_pulse_encoder.py`, numpy): the
/// encoder's edges through the wheel's detector (its glitch rejection), the index's through its
/// own at the level midway in its range, the reference placed by the index pulses
/// ([`IndexSurvey`]) and checked at every one ([`ToothIndex::index_pulse`]): the angle within a
/// tenth of a degree of the truth from 600 to 3000 rpm, the missing pulse a finding at its
/// sample, the glitches rejected on both channels, angle 0 the first edge after the index.
#[test]
fn a_pulse_encoder_with_an_index_gives_the_angle_within_a_tenth_of_a_degree() {
    use physid_signal::wheel::{in_time_order, IndexSurvey, ToothIndex};
    let v: Value =
        serde_json::from_str(&std::fs::read_to_string(golden("pulse_encoder.json")).unwrap())
            .unwrap();
    let opts = physid_io::ReadOptions {
        channels: Some(vec![
            "t".into(),
            "enc".into(),
            "idx".into(),
            "theta_true".into(),
        ]),
        ..Default::default()
    };
    let rec = physid_io::read(golden("pulse_encoder_360.parquet"), &opts).unwrap();
    let t = rec.values("t").unwrap().to_vec();
    let (enc, idx) = (rec.values("enc").unwrap(), rec.values("idx").unwrap());
    let truth: Vec<f64> = rec
        .values("theta_true")
        .unwrap()
        .iter()
        .map(|a| a * 1e-6)
        .collect();
    let e = edges(&t, enc, &EdgeOptions::default()).unwrap();
    assert_eq!(e.glitches.len(), v["glitches"].as_u64().unwrap() as usize);
    let (lo, hi) = idx
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    let index_opts = EdgeOptions {
        threshold: Some((0.5 * (lo + hi), 0.2 * (hi - lo))),
        ..Default::default()
    };
    let z = edges(&t, idx, &index_opts).unwrap();
    let revs = v["revolutions"].as_u64().unwrap() as usize;
    assert!(
        z.t.len() == revs || z.t.len() == revs + 1,
        "{} index pulses",
        z.t.len()
    );
    assert_eq!(z.glitches.len(), 1);
    let pairs: Vec<(f64, usize)> = e.t.iter().copied().zip(e.index.iter().copied()).collect();
    let survey = std::cell::RefCell::new(IndexSurvey::new(360, "enc", "idx"));
    in_time_order(
        &pairs,
        &z.t,
        |x, i| survey.borrow_mut().push(x, i),
        |x| survey.borrow_mut().pulse(x),
    );
    let gap = survey.into_inner().finish().unwrap();
    let index = std::cell::RefCell::new(ToothIndex::new(&gap, "enc"));
    index.borrow_mut().glitches(e.glitches.len(), e.glitches[0]);
    let (mut et, mut ea) = (Vec::new(), Vec::new());
    in_time_order(
        &pairs,
        &z.t,
        |x, i| index.borrow_mut().push(x, i),
        |x| index.borrow_mut().index_pulse(x),
    );
    let mut index = index.into_inner();
    let report = index.finish().unwrap();
    while let Some((x, a, _)) = index.pop() {
        et.push(x);
        ea.push(a);
    }
    let kinds: Vec<_> = report.findings.iter().map(|f| (f.kind, f.index)).collect();
    assert_eq!(
        kinds,
        [
            (FindingKind::Note, e.glitches[0]),
            (
                FindingKind::PulseLoss,
                v["missing_edge_sample"].as_u64().unwrap() as usize
            )
        ],
        "{:?}",
        report.findings
    );
    let angle = physid_signal::wheel::pchip_at(&et, &ea, &t);
    let (worst, offset, n) = error_deg(&angle, &truth);
    assert!(worst < 0.1, "{worst}° off the truth");
    assert!(n > t.len() * 9 / 10, "{n} samples with an angle");
    // Angle 0: the first rising edge after the index (a quarter line after the wheel's 0):
    // the line's start, 1° on the wheel, modulo 360°.
    let zero = (-offset).rem_euclid(360.0);
    assert!((zero - 1.0).abs() < 0.05, "angle 0 at {zero}° on the wheel");
    assert!(report.revolutions + 2 >= revs && report.revolutions <= revs);
    // The wrong pulse count is refused with what the index shows.
    let wrong = std::cell::RefCell::new(IndexSurvey::new(500, "enc", "idx"));
    in_time_order(
        &pairs,
        &z.t,
        |x, i| wrong.borrow_mut().push(x, i),
        |x| wrong.borrow_mut().pulse(x),
    );
    let err = wrong.into_inner().finish().unwrap_err().to_string();
    assert!(err.contains("360 edges between the index pulses"), "{err}");
}
