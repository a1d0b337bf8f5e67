//! The acquisition chain on a simulated recording: encoder counts and a TDC marker at
//! 20 kHz become one sample per crank degree from the first marker, with every channel at
//! its value at that angle; inspection counts cycles and finds nothing wrong; filtering needs a
//! uniform time step.
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_apps::acquisition::{
    filter_channels, inspect, to_crank_angle, to_time_basis, AcquisitionOptions, FilterSpec,
    FilterStream, PhaseFrom,
};
use physid_apps::error::AppError;
use physid_core::{Basis, Channel, Recording, Recordings, Reopen};
use physid_signal::encoder::counts_from_angle;
use physid_signal::filter::{butter, Band};
use physid_signal::integrity::FindingKind;
use std::f64::consts::{PI, TAU};

/// 2 s at 20 kHz, θ = 105·t − 0.2 rad (1003 rpm), p = 1e5 + 1e4·cos(θ/2): a function of
/// the angle; the marker is high on the sample where θ passes each multiple of 2π.
fn recording() -> Recording {
    let n = 40_000;
    let t: Vec<f64> = (0..n).map(|i| i as f64 / 20_000.0).collect();
    let theta: Vec<f64> = t.iter().map(|t| 105.0 * t - 0.2).collect();
    let marker: Vec<f64> = (0..n)
        .map(|i| f64::from(i > 0 && (theta[i] / TAU).floor() > (theta[i - 1] / TAU).floor()))
        .collect();
    let p: Vec<f64> = theta
        .iter()
        .map(|th| 1e5 + 1e4 * (th / 2.0).cos())
        .collect();
    let mut r = Recording::new(Basis::Time);
    for (name, unit, v) in [
        ("t", "s", t),
        ("count_en", "-", counts_from_angle(&theta, 360)),
        ("tdc", "-", marker),
        ("p_int", "Pa", p),
    ] {
        r.push(Channel {
            name: name.into(),
            unit: unit.into(),
            values: v,
        })
        .unwrap();
    }
    r
}

#[test]
fn counts_to_one_sample_per_degree() {
    let rec = recording();
    let ca = to_crank_angle(&rec, &AcquisitionOptions::default(), 1.0).unwrap();
    assert_eq!(ca.basis, Basis::CrankAngle);
    assert_eq!(ca.names(), ["t", "theta", "cycle", "crank_deg", "p_int"]);
    let (cyc, deg, p, t) = (
        ca.values("cycle").unwrap(),
        ca.values("crank_deg").unwrap(),
        ca.values("p_int").unwrap(),
        ca.values("t").unwrap(),
    );
    assert_eq!((cyc[0], deg[0]), (0.0, 0.0));
    assert_eq!((cyc[720], deg[720]), (1.0, 0.0));
    // The first marker is where θ passes 0 (within one sample): p(θ) = 1e5 + 1e4·cos(θ/2)
    // with θ = crank angle + 720°·cycle.
    let q = TAU / 360.0;
    for k in (0..ca.len()).step_by(37) {
        let th_abs = deg[k].to_radians() + cyc[k] * 4.0 * PI;
        // The counts quantise the angle to q, the marker to one 20 kHz sample (0.3°).
        let tol = 1e4 * 0.5 * (q + 105.0 / 20_000.0);
        assert!(
            (p[k] - (1e5 + 1e4 * (th_abs / 2.0).cos())).abs() < tol,
            "{k}"
        );
        assert!(
            (t[k] - (th_abs + 0.2) / 105.0).abs() < (q + 105.0 / 20_000.0) / 105.0,
            "{k}: {} vs {}",
            t[k],
            (th_abs + 0.2) / 105.0
        );
    }
    // And back to a time basis at 10 kHz.
    let back = to_time_basis(&ca, 10_000.0).unwrap();
    assert_eq!(back.basis, Basis::Time);
    let dt = back
        .values("t")
        .unwrap()
        .windows(2)
        .map(|w| w[1] - w[0])
        .fold(0.0, f64::max);
    assert!((dt - 1e-4).abs() < 1e-12);
}

#[test]
fn inspection_counts_cycles_and_finds_what_is_wrong() {
    let rec = recording();
    let i = inspect(&rec, &AcquisitionOptions::default());
    assert_eq!(i.basis, "time");
    assert!((i.sample_rate_hz.unwrap() - 20_000.0).abs() < 1e-6);
    assert!((i.duration_s.unwrap() - 1.99995).abs() < 1e-9);
    // θ runs from −0.2 to 209.8 rad: 34 markers (at 0, 2π, …, 66π), 16 complete cycles.
    assert_eq!(i.cycles, Some(16));
    // Clean: no finding; the samples before the first marker are a note.
    assert!(
        i.integrity.ok && i.integrity.findings.is_empty(),
        "{:?}",
        i.integrity.findings
    );
    assert_eq!(i.integrity.notes.len(), 1, "{:?}", i.integrity.notes);
    let ca = to_crank_angle(&rec, &AcquisitionOptions::default(), 1.0).unwrap();
    let j = inspect(&ca, &AcquisitionOptions::default());
    assert_eq!(j.basis, "crank_angle");
    // 16 whole cycles and a partial one at the end, which the check notes.
    assert_eq!(j.cycles, Some(16));
    assert!(j.integrity.ok, "{:?}", j.integrity.findings);
    assert_eq!(j.integrity.notes.len(), 1, "{:?}", j.integrity.notes);
    assert!(j.integrity.notes[0].detail.contains("ends mid-cycle"));
}

#[test]
fn filtering_channels() {
    let mut rec = recording();
    let raw = rec.values("p_int").unwrap().to_vec();
    let spec = FilterSpec {
        band: Band::Lowpass,
        cutoff_hz: vec![100.0],
        order: 4,
        transfer_function: false,
    };
    filter_channels(&mut rec, &["p_int".into()], &spec).unwrap();
    let want = butter(4, &[100.0], Band::Lowpass, 20_000.0)
        .unwrap()
        .to_sos()
        .sosfiltfilt(&raw)
        .unwrap();
    assert!(rec.values("p_int").unwrap() == want.as_slice());
    // A gap in time is refused with its place.
    let mut t = rec.values("t").unwrap().to_vec();
    for v in &mut t[500..] {
        *v += 1e-3;
    }
    rec.replace_values("t", t).unwrap();
    let e = filter_channels(&mut rec, &["p_int".into()], &spec)
        .unwrap_err()
        .to_string();
    assert!(e.contains("not uniform at sample"), "{e}");
    let e = filter_channels(&mut recording(), &["p_cyl".into()], &spec)
        .unwrap_err()
        .to_string();
    assert!(e.contains("no channel 'p_cyl'"), "{e}");
}

/// `physid filter`'s stream (FilterStream) against the whole-record zero-phase filter: the
/// filtered channel within 1e-12 of the signal's scale however the recording is chunked (the
/// last samples bit for bit), the other channels untouched and row-aligned; a step in time at
/// a chunk boundary refused with its sample.
#[test]
fn the_filter_stream_is_the_whole_record_filter() {
    let rec = recording();
    let spec = FilterSpec {
        band: Band::Lowpass,
        cutoff_hz: vec![100.0],
        order: 4,
        transfer_function: false,
    };
    let mut whole = rec.clone();
    filter_channels(&mut whole, &["p_int".into()], &spec).unwrap();
    let want = whole.values("p_int").unwrap();
    let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for chunk in [2, 17, 4096, rec.len()] {
        let mut s = FilterStream::new(&["p_int".into()], &spec).unwrap();
        let mut parts = Vec::new();
        for start in (0..rec.len()).step_by(chunk) {
            parts.extend(s.push(&rec.slice(start..start + chunk)).unwrap());
        }
        parts.extend(s.finish().unwrap());
        let got: Vec<f64> = parts
            .iter()
            .flat_map(|p| p.values("p_int").unwrap().to_vec())
            .collect();
        assert_eq!(got.len(), want.len(), "chunk {chunk}");
        let worst = got
            .iter()
            .zip(want)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(worst <= 1e-12 * scale, "chunk {chunk}: {worst}");
        assert_eq!(
            got[got.len() - 10..],
            want[want.len() - 10..],
            "chunk {chunk}"
        );
        for name in ["t", "count_en", "tdc"] {
            let passed: Vec<f64> = parts
                .iter()
                .flat_map(|p| p.values(name).unwrap().to_vec())
                .collect();
            assert_eq!(passed, rec.values(name).unwrap(), "chunk {chunk}: {name}");
        }
    }
    // A step in time where a chunk starts.
    let mut t = rec.values("t").unwrap().to_vec();
    for v in &mut t[1000..] {
        *v += 1e-3;
    }
    let mut bad = rec.clone();
    bad.replace_values("t", t).unwrap();
    let mut s = FilterStream::new(&["p_int".into()], &spec).unwrap();
    s.push(&bad.slice(0..1000)).unwrap();
    let e = s.push(&bad.slice(1000..2000)).unwrap_err().to_string();
    assert!(e.contains("not uniform at sample 1000"), "{e}");
    let e = FilterStream::new(
        &["p_int".into()],
        &FilterSpec {
            transfer_function: true,
            ..spec
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("whole recordings only"), "{e}");
}

/// `rec`'s channels `names`.
fn pick(rec: &Recording, names: &[&str]) -> Recording {
    let mut r = Recording::new(rec.basis);
    for n in names {
        r.push(rec.channel(n).unwrap().clone()).unwrap();
    }
    r
}

/// `got` has `whole`'s channels, each equal bit for bit, and its metadata (`what`: the case).
fn same_bits(got: &Recording, whole: &Recording, what: &str) {
    assert_eq!(got.names(), whole.names(), "{what}");
    for name in whole.names() {
        let (a, b) = (got.values(name).unwrap(), whole.values(name).unwrap());
        assert_eq!(a.len(), b.len(), "{name} {what}");
        assert!(
            a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()),
            "{name} {what}"
        );
    }
    assert_eq!(got.meta, whole.meta, "{what}");
}

/// Cut `rec` into chunks of `n` samples (0: whole).
/// `rec` gone over in passes, cut into chunks of `first` samples on the first pass, twice as
/// many on the second, and so on (0: whole).
struct Cut<'a> {
    rec: &'a Recording,
    first: usize,
    passes: std::cell::Cell<usize>,
}

fn cut_passes(rec: &Recording, first: usize) -> Cut<'_> {
    Cut {
        rec,
        first,
        passes: std::cell::Cell::new(0),
    }
}

impl Reopen<Recordings, AppError> for Cut<'_> {
    fn pass(
        &self,
        visit: &mut dyn for<'c> FnMut(&'c Recording) -> Result<(), AppError>,
    ) -> Result<(), AppError> {
        self.passes.set(self.passes.get() + 1);
        for chunk in cut(self.rec, self.first * self.passes.get()) {
            visit(&chunk?)?;
        }
        Ok(())
    }
}

fn cut(rec: &Recording, n: usize) -> Vec<Result<Recording, physid_apps::error::AppError>> {
    if n == 0 {
        return vec![Ok(rec.clone())];
    }
    (0..rec.len())
        .step_by(n)
        .map(|s| Ok(rec.slice(s..(s + n).min(rec.len()))))
        .collect()
}

/// An encoder's counts resampled as they come, in two passes over the file (the counts and the
/// marker; then the channels with the counts read ahead of them), give the whole recording's
/// crank-angle samples bit for bit, however each pass is cut — with the engine standing still
/// for 0.3 s (no count step for 6000 samples), without a marker, and when the counts are a
/// trigger wheel's (the same error).
#[test]
fn counts_resampled_as_they_come_equal_the_whole() {
    use physid_apps::acquisition::{counts_crank_angle_chunks, CountsScan};
    let mut rec = recording();
    // The engine stands still from 0.8 s to 1.1 s.
    let t = rec.values("t").unwrap().to_vec();
    let theta: Vec<f64> = t
        .iter()
        .map(|&t| 105.0 * (t.min(0.8) + (t - 1.1).max(0.0)) - 0.2)
        .collect();
    rec.replace_values("count_en", counts_from_angle(&theta, 360))
        .unwrap();
    let stream = |rec: &Recording, cuts: [usize; 3]| {
        let counts =
            CountsScan::new(rec, &AcquisitionOptions::default())?.scan(cut(rec, cuts[0]))?;
        let (header, chunks) = counts_crank_angle_chunks(
            &counts,
            &pick(rec, &["t", "p_int"]),
            cut(&pick(rec, &["t", "count_en"]), cuts[1]),
            cut(&pick(rec, &["t", "p_int"]), cuts[2]),
            &AcquisitionOptions::default(),
            1.0,
        )?;
        let mut out = header;
        for c in chunks {
            out.append(&c?)?;
        }
        Ok::<_, physid_apps::error::AppError>(out)
    };
    let no_marker = pick(&rec, &["t", "count_en", "p_int"]);
    for rec in [&rec, &no_marker] {
        let whole = to_crank_angle(rec, &AcquisitionOptions::default(), 1.0).unwrap();
        assert!(whole.len() > 1000);
        for cuts in [
            [0, 0, 0],
            [1, 7, 13],
            [4096, 1, 997],
            [997, 4096, 1],
            [7, 0, 4096],
        ] {
            let got = stream(rec, cuts).unwrap();
            same_bits(&got, &whole, &format!("{cuts:?}"));
        }
    }
    // A 60−2 wheel's 58 teeth counted as a 58-pulse encoder: the same error, before anything.
    let mut wheel = rec.clone();
    let teeth: Vec<f64> = theta
        .iter()
        .map(|&th| {
            let rev = (th / TAU).floor();
            rev * 58.0 + ((th / TAU - rev) * 60.0).floor().min(57.0)
        })
        .collect();
    wheel.replace_values("count_en", teeth).unwrap();
    let opts = AcquisitionOptions {
        encoders: vec![("count_en".into(), 58)],
        ..Default::default()
    };
    let whole = to_crank_angle(&wheel, &opts, 1.0).unwrap_err().to_string();
    assert!(whole.contains("not equally spaced"), "{whole}");
    for cuts in [[1], [997]] {
        // The first pass says it; the second is not started.
        let e = CountsScan::new(&wheel, &opts)
            .unwrap()
            .scan(cut(&wheel, cuts[0]))
            .unwrap_err();
        assert_eq!(e.to_string(), whole);
    }
}

/// The true angle [rad] of the wheel test's engine at `t` [s]: 600 rpm rising to 1140 rpm at
/// 0.9 s, standing still until 1.2 s, then turning at 1140 rpm.
fn wheel_theta(t: f64) -> f64 {
    let u = t.min(0.9);
    let rev = 10.0 * u + 5.0 * u * u + 19.0 * (t - 1.2).max(0.0);
    TAU * rev + 0.3
}

/// 2 s at 50 kHz of a Hall sensor over a 60−2 wheel (the tooth edge at the start of each
/// tooth, the gap after tooth 57), one tooth's pulse lost at 0.5 s, and a cylinder pressure
/// peaking at 460° + 720°·k of `wheel_theta`: 100° after the reference tooth's edge (the first
/// after the first gap, at 360°) in the even revolutions from it.
fn wheel_recording() -> Recording {
    let n = 100_000;
    let t: Vec<f64> = (0..n).map(|i| i as f64 / 50_000.0).collect();
    let pitch = TAU / 60.0;
    let enc: Vec<f64> = t
        .iter()
        .map(|&t| {
            let th = wheel_theta(t);
            let tooth = (th / pitch).floor();
            let present = tooth.rem_euclid(60.0) < 58.0 && !(0.4999..0.5008).contains(&t);
            f64::from(present && th / pitch - tooth < 0.5)
        })
        .collect();
    let p: Vec<f64> = t
        .iter()
        .map(|&t| {
            // The angle from a firing TDC, in (−2π, 2π].
            let from = (wheel_theta(t) - 100f64.to_radians() - TAU).rem_euclid(2.0 * TAU);
            let d = if from > TAU { from - 2.0 * TAU } else { from };
            1e5 + 2e6 * (-(d / 0.3).powi(2)).exp()
        })
        .collect();
    let mut r = Recording::new(Basis::Time);
    for (name, unit, v) in [("t", "s", t), ("enc", "V", enc), ("p_cyl", "Pa", p)] {
        r.push(Channel {
            name: name.into(),
            unit: unit.into(),
            values: v,
        })
        .unwrap();
    }
    r
}

/// A trigger wheel's raw signal resampled as it comes — three passes over `t` and the wheel's
/// channel (where the gap is; what the decoding found and where the firing TDC is, with the
/// pressure's samples; then read ahead of the channels) — gives the whole recording's
/// crank-angle samples and report bit for bit, however each of the five inputs is cut, with
/// the engine standing still for 0.3 s (15 000 samples without an edge) and a tooth lost. The
/// whole recording's angle is the true one within 0.1° (the edges are interpolated between
/// samples 0.14° apart) outside the standstill, and the firing revolution is the pressure's.
#[test]
fn a_wheel_resampled_as_it_comes_equals_the_whole() {
    use physid_apps::acquisition::sensor::{
        sensor_calibration, sensor_crank_angle_chunks, sensor_decoded, SensorFound,
    };
    use physid_apps::acquisition::{to_crank_angle_decoded, AngleSensor, AngleSpec};
    let rec = wheel_recording();
    let spec = AngleSpec {
        sensor: AngleSensor::Wheel {
            channel: "enc".into(),
            wheel: "60-2".parse().unwrap(),
            edges: Default::default(),
        },
        tdc_offset_deg: 100.0,
        phase_from: PhaseFrom::channel("p_cyl"),
    };
    let opts = AcquisitionOptions {
        sensor: Some(spec.clone()),
        ..Default::default()
    };
    let (whole, report) = to_crank_angle_decoded(&rec, &opts, 1.0).unwrap();
    let report = report.unwrap();
    assert!(
        report.phase.contains("even revolutions"),
        "{}",
        report.phase
    );
    // The lost tooth; the standstill, a dropout across which the count is unsure; the next gap,
    // where it is counted again (a whole number of cycles on: the phase holds).
    let kinds: Vec<_> = report.findings.iter().map(|f| f.kind).collect();
    assert_eq!(
        kinds,
        [
            FindingKind::PulseLoss,
            FindingKind::OutOfSync,
            FindingKind::OutOfSync
        ],
        "{:?}",
        report.findings
    );
    // Against the truth: crank_deg 0 at the firing TDC, at 460° (mod 720°) of the true angle.
    let (t, deg) = (
        whole.values("t").unwrap(),
        whole.values("crank_deg").unwrap(),
    );
    assert!(whole.len() > 10_000);
    let mut worst = 0.0f64;
    for (&t, &d) in t.iter().zip(deg) {
        if (0.88..1.25).contains(&t) {
            continue;
        }
        let truth = (wheel_theta(t) - 460f64.to_radians()).to_degrees();
        let off = (truth - d + 360.0).rem_euclid(720.0) - 360.0;
        worst = worst.max(off.abs());
    }
    assert!(worst < 0.1, "{worst}° off the true angle");
    let stream = |cuts: [usize; 5]| {
        let wheel = pick(&rec, &["t", "enc"]);
        let cal = sensor_calibration(&spec, &cut_passes(&wheel, cuts[0]))?;
        let decoded = sensor_decoded(
            &spec,
            &cal,
            cut(&wheel, cuts[1]),
            cut(&pick(&rec, &["t", "p_cyl"]), cuts[2]),
        )?;
        let channels = pick(&rec, &["t", "p_cyl"]);
        let found = SensorFound { cal, decoded };
        let (header, chunks) = sensor_crank_angle_chunks(
            &spec,
            &found,
            &channels,
            cut(&wheel, cuts[3]),
            cut(&channels, cuts[4]),
            &opts,
            1.0,
        )?;
        let mut out = header;
        for c in chunks {
            out.append(&c?)?;
        }
        Ok::<_, physid_apps::error::AppError>((out, found.decoded))
    };
    for cuts in [
        [0, 0, 0, 0, 0],
        [1, 7, 13, 997, 1],
        [4096, 1, 997, 13, 4096],
        [997, 4096, 1, 1, 7],
        [7, 0, 4096, 4096, 0],
    ] {
        let (got, decoded) = stream(cuts).unwrap();
        same_bits(&got, &whole, &format!("{cuts:?}"));
        assert_eq!(decoded.tdc.to_bits(), report.tdc.to_bits(), "{cuts:?}");
        assert_eq!(
            (
                &decoded.summary,
                &decoded.phase,
                &decoded.findings,
                &decoded.wheel
            ),
            (
                &report.summary,
                &report.phase,
                &report.findings,
                &report.wheel
            ),
            "{cuts:?}"
        );
    }
    // The wrong wheel: the first pass says so.
    let wrong = AngleSpec {
        sensor: AngleSensor::Wheel {
            channel: "enc".into(),
            wheel: "36-1".parse().unwrap(),
            edges: Default::default(),
        },
        ..spec.clone()
    };
    let e = sensor_calibration(&wrong, &cut_passes(&pick(&rec, &["t", "enc"]), 997)).unwrap_err();
    assert!(e.to_string().contains("'enc'"), "{e}");
}

/// A quadrature encoder's channels resampled as they come — the index's level, then the
/// decoding (the angle 0, the span after the shaft last turned back), then the samples' angle,
/// then the channels with the encoder read ahead — give the whole recording's crank-angle
/// samples and report bit for bit, however each input is cut: `physid-signal`'s golden
/// encoder (500 lines at 200 kHz, turning back 40° first; numpy), its true angle carried as a
/// channel and within 0.1° of the crank angle the resampling gives.
#[test]
fn a_quadrature_encoder_resampled_as_it_comes_equals_the_whole() {
    use physid_apps::acquisition::sensor::{
        sensor_calibration, sensor_crank_angle_chunks, sensor_decoded, SensorFound,
    };
    use physid_apps::acquisition::{to_crank_angle_decoded, AngleSensor, AngleSpec};
    let golden = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../signal/tests/golden/quadrature_500.parquet");
    let rec = physid_io::read(&golden, &Default::default()).unwrap();
    let spec = AngleSpec {
        sensor: AngleSensor::Quadrature {
            a: "enc_a".into(),
            b: "enc_b".into(),
            z: Some("enc_z".into()),
            lines: 500,
        },
        tdc_offset_deg: 30.0,
        phase_from: PhaseFrom::First,
    };
    let opts = AcquisitionOptions {
        sensor: Some(spec.clone()),
        ..Default::default()
    };
    let (whole, report) = to_crank_angle_decoded(&rec, &opts, 1.0).unwrap();
    let report = report.unwrap();
    assert!(
        report.summary.contains("after it last turned back"),
        "{}",
        report.summary
    );
    assert!(whole.len() > 300, "{}", whole.len());
    // The true angle [µrad] at each crank-angle sample: 30° + 720°·k + crank_deg from the
    // index (the truth's 0), within 0.1°.
    let (deg, truth) = (
        whole.values("crank_deg").unwrap(),
        whole.values("theta_true").unwrap(),
    );
    let cycle = whole.values("cycle").unwrap();
    for i in 0..whole.len() {
        let want = 30.0 + 720.0 * cycle[i] + deg[i];
        let off = (truth[i] * 1e-6).to_degrees() - want;
        assert!(off.abs() < 0.1, "sample {i}: {off}°");
    }
    let sensor = pick(&rec, &["t", "enc_a", "enc_b", "enc_z"]);
    let mut channels = pick(&rec, &["t", "theta_true"]);
    channels.meta.clone_from(&rec.meta);
    let stream = |cuts: [usize; 5]| {
        let cal = sensor_calibration(&spec, &cut_passes(&sensor, cuts[0]))?;
        let decoded = sensor_decoded(
            &spec,
            &cal,
            cut(&sensor, cuts[1]),
            cut(&pick(&rec, &["t"]), cuts[2]),
        )?;
        let found = SensorFound { cal, decoded };
        let (header, chunks) = sensor_crank_angle_chunks(
            &spec,
            &found,
            &channels,
            cut(&sensor, cuts[3]),
            cut(&channels, cuts[4]),
            &opts,
            1.0,
        )?;
        let mut out = header;
        for c in chunks {
            out.append(&c?)?;
        }
        Ok::<_, physid_apps::error::AppError>((out, found.decoded))
    };
    for cuts in [
        [0, 0, 0, 0, 0],
        [1, 7, 13, 997, 1],
        [4096, 1, 997, 13, 4096],
        [997, 4095, 1, 1, 7],
    ] {
        let (got, decoded) = stream(cuts).unwrap();
        same_bits(&got, &whole, &format!("{cuts:?}"));
        assert_eq!(decoded.tdc.to_bits(), report.tdc.to_bits(), "{cuts:?}");
        assert_eq!(
            (&decoded.summary, &decoded.phase, &decoded.findings),
            (&report.summary, &report.phase, &report.findings),
            "{cuts:?}"
        );
    }
}

/// A time channel that goes back, repeats, or jumps is named at the sample where it does — not
/// at sample 1 because one jump moved the mean step (issue 41, item 7).
#[test]
fn a_time_that_goes_back_or_jumps_is_named_where_it_does() {
    let grid: Vec<f64> = (0..20_000).map(|k| k as f64 * 1e-4).collect();
    let with = |f: &dyn Fn(&mut Vec<f64>)| {
        let mut t = grid.clone();
        f(&mut t);
        physid_apps::acquisition::uniform_step(&t)
            .unwrap_err()
            .to_string()
    };
    let back = with(&|t| t[15_000..].iter_mut().for_each(|v| *v -= 1.0));
    assert!(
        back.starts_with("the time goes back at sample 15000 ("),
        "{back}"
    );
    let repeat = with(&|t| t[15_000] = t[14_999]);
    assert!(
        repeat.starts_with("the time repeats at sample 15000"),
        "{repeat}"
    );
    let jump = with(&|t| t[15_000..].iter_mut().for_each(|v| *v += 1.0));
    assert!(
        jump.starts_with("the time step is not uniform at sample 15000"),
        "{jump}"
    );
    let dt = physid_apps::acquisition::uniform_step(&grid).unwrap();
    assert!((dt - 1e-4).abs() < 1e-16, "{dt}");
}

/// The stream's step check names the sample from the stream's start, whichever chunk it falls
/// in, and takes steps across chunk boundaries: a 0.2 % longer step at sample 7 (the second
/// chunk's second) is found, one 0.05 % longer is not.
#[test]
fn the_stream_step_check_counts_samples_across_chunks() {
    use physid_apps::acquisition::StepCheck;
    let t = |k: usize| k as f64 * 1e-3;
    let mut ok = StepCheck::new(1e-3);
    let mut times: Vec<f64> = (0..12).map(t).collect();
    times[7..].iter_mut().for_each(|v| *v += 0.5e-6);
    for chunk in times.chunks(6) {
        ok.check(chunk).unwrap();
    }
    let mut bad = StepCheck::new(1e-3);
    let mut times: Vec<f64> = (0..12).map(t).collect();
    times[7..].iter_mut().for_each(|v| *v += 2e-6);
    bad.check(&times[..6]).unwrap();
    let e = bad.check(&times[6..]).unwrap_err().to_string();
    assert!(
        e.starts_with("the time step is not uniform at sample 7 (0.001002"),
        "{e}"
    );
    // The boundary step itself: sample 6 against sample 5.
    let mut edge = StepCheck::new(1e-3);
    edge.check(&[0.0, 1e-3]).unwrap();
    let e = edge.check(&[2.01e-3]).unwrap_err().to_string();
    assert!(e.contains("at sample 2 "), "{e}");
}

/// A DAQ's stamps rounded to the microsecond at 72 046 Hz (steps of 13 and 14 µs): a uniform
/// clock, its period the mean step — by the whole-record check and the stream's alike; a sample
/// dropped among them is still refused where it is.
#[test]
fn stamps_rounded_to_the_microsecond_are_a_uniform_clock() {
    use physid_apps::acquisition::{uniform_step, StepCheck};
    let fs = 72_046.0;
    let t: Vec<f64> = (0..50_000)
        .map(|k| (k as f64 / fs * 1e6).round() * 1e-6)
        .collect();
    let dt = uniform_step(&t).unwrap();
    assert!((1.0 / dt / fs - 1.0).abs() < 1e-6, "{} Hz", 1.0 / dt);
    let mut s = StepCheck::new(uniform_step(&t[..1000]).unwrap());
    for chunk in t.chunks(777) {
        s.check(chunk).unwrap();
    }
    let mut dropped = t.clone();
    dropped.remove(30_000);
    let e = uniform_step(&dropped).unwrap_err().to_string();
    assert!(e.contains("not uniform at sample 30000"), "{e}");
    let mut s = StepCheck::new(dt);
    let e = s.check(&dropped).unwrap_err().to_string();
    assert!(e.contains("at sample 30000"), "{e}");
}

/// The crank→time stage (`TimeBasisStream`, what `monitor`, `live --replay` and `convert
/// --time-basis` run on a crank-angle file) against closed forms: an engine accelerating from
/// 1200 rpm at 300 rad/s², sampled every 1° of crank (so its time step shrinks), with
/// x = 3 + 2·t (linear in time: linear interpolation is exact) and the crank angle itself. On
/// the 5 kHz grid from the first time, in chunks of 1, 50 and 4096: the times are t₀ + i/5000,
/// x is 3 + 2·t within 1e-12, and the angle within the interpolation's bound
/// α·h²/8 (h the longest 1° step) of θ(t) = ω₀·t + α·t²/2.
#[test]
fn the_time_basis_stream_against_closed_forms() {
    use physid_apps::acquisition::TimeBasisStream;
    let (w0, alpha) = (1200.0 * std::f64::consts::PI / 30.0, 300.0);
    // t at θ = k·1° (θ(t) = ω₀t + αt²/2), for 4 s of running.
    let t_at = |th: f64| (-w0 + (w0 * w0 + 2.0 * alpha * th).sqrt()) / alpha;
    let n = ((w0 * 4.0 + alpha * 8.0).to_degrees()) as usize;
    let th: Vec<f64> = (0..n).map(|k| (k as f64).to_radians()).collect();
    let t: Vec<f64> = th.iter().map(|&a| t_at(a)).collect();
    let x: Vec<f64> = t.iter().map(|&t| 3.0 + 2.0 * t).collect();
    let mut rec = Recording::new(Basis::CrankAngle);
    for (name, unit, v) in [("t", "s", &t), ("x", "", &x), ("theta_en", "rad", &th)] {
        rec.push(Channel {
            name: name.into(),
            unit: unit.into(),
            values: v.clone(),
        })
        .unwrap();
    }
    let h = t[1] - t[0];
    let bound = alpha * h * h / 8.0 + 1e-12;
    for chunk in [1, 50, 4096] {
        let mut s = TimeBasisStream::new(&rec, 5000.0).unwrap();
        let mut out = s.header().unwrap();
        for c in cut(&rec, chunk) {
            out.append(&s.push(&c.unwrap()).unwrap()).unwrap();
        }
        out.append(&s.finish().unwrap()).unwrap();
        let (ot, ox, oth) = (
            out.values("t").unwrap(),
            out.values("x").unwrap(),
            out.values("theta_en").unwrap(),
        );
        assert_eq!(
            ot.len(),
            (t[n - 1] * 5000.0).floor() as usize + 1,
            "chunks of {chunk}"
        );
        for i in 0..ot.len() {
            assert!(
                (ot[i] - i as f64 / 5000.0).abs() < 1e-12,
                "t[{i}] = {}",
                ot[i]
            );
            assert!(
                (ox[i] - (3.0 + 2.0 * ot[i])).abs() < 1e-12,
                "x[{i}] = {}",
                ox[i]
            );
            let truth = w0 * ot[i] + alpha * ot[i] * ot[i] / 2.0;
            assert!(
                (oth[i] - truth).abs() <= bound,
                "θ[{i}] = {} against {truth} (bound {bound:e})",
                oth[i]
            );
        }
    }
}

/// Time stamps rounded to 1 µs at 72 046 Hz (steps alternating 13 and 14 µs, as a real lab
/// logger's): the sample rate is the mean step's — within 1e-5 of 72 046 Hz, where the median
/// step gave 71 428.571 Hz — the jitter is noted, and the integrity stays ok; stamps that are
/// not rounded are said nothing about.
#[test]
fn jittered_time_stamps_give_the_mean_rate_and_say_so() {
    let rate = 72_046.0;
    let n = 20_000;
    let make = |round: bool| {
        let t: Vec<f64> = (0..n)
            .map(|k| {
                let t = k as f64 / rate;
                if round {
                    (t * 1e6).round() * 1e-6
                } else {
                    t
                }
            })
            .collect();
        let mut rec = Recording::new(Basis::Time);
        for (name, unit, values) in [("t", "s", t), ("x", "V", vec![1.0; n])] {
            rec.push(Channel {
                name: name.into(),
                unit: unit.into(),
                values,
            })
            .unwrap();
        }
        inspect(&rec, &AcquisitionOptions::default())
    };
    let i = make(true);
    let hz = i.sample_rate_hz.unwrap();
    assert!((hz / rate - 1.0).abs() < 1e-5, "{hz} Hz");
    assert!(i.integrity.ok, "{:?}", i.integrity.findings);
    let note = i
        .integrity
        .notes
        .iter()
        .find(|f| f.detail.starts_with("the time stamps are jittered"))
        .expect("the jitter noted");
    assert!(
        note.detail.contains("0.013000 … 0.014000 ms") && note.detail.contains("71428.571 Hz"),
        "{}",
        note.detail
    );
    let clean = make(false);
    assert!((clean.sample_rate_hz.unwrap() / rate - 1.0).abs() < 1e-9);
    assert!(!clean
        .integrity
        .notes
        .iter()
        .any(|f| f.detail.contains("jittered")));
}
