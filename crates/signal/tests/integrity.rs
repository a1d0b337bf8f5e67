//! The integrity check finds each injected defect at its place, and nothing in clean data.
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_core::{Basis, Channel, Recording};
use physid_signal::encoder::counts_from_angle;
use physid_signal::integrity::{
    check, Finding, FindingKind, Integrity, IntegrityCheck, IntegrityOptions, IntegrityStream,
    MAX_PER_KIND,
};

fn rec(channels: Vec<(&str, Vec<f64>)>, basis: Basis) -> Recording {
    let mut r = Recording::new(basis);
    for (name, values) in channels {
        r.push(Channel {
            name: name.into(),
            unit: String::new(),
            values,
        })
        .unwrap();
    }
    r
}

/// 2 s at 10 kHz of an engine at 100 rad/s: counts of a 360-pulse encoder and a TDC marker
/// high on the sample where the angle passes each whole revolution (from 0.05 rad on).
fn clean() -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let n = 20_000;
    let t: Vec<f64> = (0..n).map(|i| i as f64 * 1e-4).collect();
    let theta: Vec<f64> = t.iter().map(|t| 100.0 * t - 0.05).collect();
    let counts = counts_from_angle(&theta, 360);
    let marker: Vec<f64> = (0..n)
        .map(|i| {
            let rev = |k: usize| (theta[k] / std::f64::consts::TAU).floor();
            f64::from(i > 0 && rev(i) > rev(i - 1))
        })
        .collect();
    (t, counts, marker)
}

fn opts() -> IntegrityOptions {
    IntegrityOptions {
        encoders: vec![("count_en".into(), 360)],
        marker: Some("tdc".into()),
        marker_encoder: None,
        samples_per_cycle: None,
    }
}

#[test]
fn clean_data_is_ok_with_a_note_of_the_leading_partial_cycle() {
    let (t, c, m) = clean();
    let r = check(
        &rec(vec![("t", t), ("count_en", c), ("tdc", m)], Basis::Time),
        &opts(),
    );
    assert!(r.ok && r.findings.is_empty(), "{:?}", r.findings);
    assert_eq!(r.notes.len(), 1, "{:?}", r.notes);
    assert_eq!(r.notes[0].kind, FindingKind::Note);
    assert!(r.notes[0].detail.contains("starts mid-revolution"));
}

/// The dynamometer's encoder behind a shaft that twists ±`twist` rad at 7 Hz: its count is off
/// the engine's marker by a few pulses each way, which is no finding; pulses lost from it add
/// up over ten revolutions and are found where they start.
#[test]
fn a_second_encoder_is_checked_over_revolutions_not_against_the_marker() {
    let (t, c, m) = clean();
    let theta_dy: Vec<f64> = t
        .iter()
        .map(|t| 100.0 * t - 0.05 + 0.02 * (2.0 * std::f64::consts::PI * 7.0 * t).sin())
        .collect();
    let dy = counts_from_angle(&theta_dy, 1024);
    let o = IntegrityOptions {
        encoders: vec![("count_en".into(), 360), ("count_dy".into(), 1024)],
        ..opts()
    };
    let r = check(
        &rec(
            vec![
                ("t", t.clone()),
                ("count_en", c.clone()),
                ("tdc", m.clone()),
                ("count_dy", dy.clone()),
            ],
            Basis::Time,
        ),
        &o,
    );
    assert!(r.ok, "{:?}", r.findings);
    // The twist moves count_dy against the marker by a few pulses (0.02 rad ≈ 3.3 pulses).
    let edges: Vec<usize> = (1..m.len()).filter(|&i| m[i] == 1.0).collect();
    let off = edges
        .windows(2)
        .map(|w| (dy[w[1]] - dy[w[0]] - 1024.0).abs())
        .fold(0.0, f64::max);
    assert!(
        off >= 2.0,
        "the twist should move the count against the marker: {off}"
    );
    // 1 % of the pulses lost from sample 10 000 on: 10 pulses a revolution.
    let mut lossy = dy.clone();
    let mut lost = 0.0;
    for i in 10_000..lossy.len() {
        if dy[i] > dy[i - 1] && (dy[i] as u64).is_multiple_of(100) {
            lost += dy[i] - dy[i - 1];
        }
        lossy[i] -= lost;
    }
    let r = check(
        &rec(
            vec![("t", t), ("count_en", c), ("tdc", m), ("count_dy", lossy)],
            Basis::Time,
        ),
        &o,
    );
    let pl: Vec<_> = r
        .findings
        .iter()
        .filter(|f| f.kind == FindingKind::PulseLoss)
        .collect();
    assert!(!pl.is_empty(), "{:?}", r.findings);
    assert!(pl.iter().all(|f| f.detail.contains("'count_dy'")));
    // The first span found is the one the loss starts in.
    let first = pl[0].index;
    let span_end = edges[edges.iter().position(|&e| e == first).unwrap() + 10];
    assert!(first <= 10_000 && 10_000 < span_end, "{first} {span_end}");
    assert!(r.findings.iter().all(|f| f.kind == FindingKind::PulseLoss));
}

#[test]
fn a_crank_angle_recording_is_checked_by_its_angle_not_its_time_step() {
    // Three cycles at one sample per degree, the time step following a varying speed.
    let n = 3 * 720;
    let deg: Vec<f64> = (0..n).map(|k| (k % 720) as f64).collect();
    let cycle: Vec<f64> = (0..n).map(|k| (k / 720) as f64).collect();
    let mut t = vec![0.0];
    for k in 1..n {
        let w = 100.0 + 30.0 * (k as f64 / 50.0).sin(); // rad/s
        t.push(t[k - 1] + 1f64.to_radians() / w);
    }
    let o = IntegrityOptions {
        samples_per_cycle: Some(720),
        ..Default::default()
    };
    let build = |t: Vec<f64>, deg: Vec<f64>, cycle: Vec<f64>| {
        rec(
            vec![("t", t), ("cycle", cycle), ("crank_deg", deg)],
            Basis::CrankAngle,
        )
    };
    let r = check(&build(t.clone(), deg.clone(), cycle.clone()), &o);
    assert!(r.ok && r.notes.is_empty(), "{:?} {:?}", r.findings, r.notes);
    // Samples 999..1004 lost: found at 999, as 5 samples, and the cycle as short.
    let cut = |v: &Vec<f64>| [&v[..999], &v[1004..]].concat();
    let r = check(&build(cut(&t), cut(&deg), cut(&cycle)), &o);
    let lost: Vec<_> = r
        .findings
        .iter()
        .filter(|f| f.kind == FindingKind::LostSamples)
        .collect();
    assert_eq!(lost.len(), 1, "{:?}", r.findings);
    assert_eq!(lost[0].index, 999);
    assert!(
        lost[0].detail.contains("about 5 samples missing"),
        "{}",
        lost[0].detail
    );
    let short: Vec<_> = r
        .findings
        .iter()
        .filter(|f| f.kind == FindingKind::IncompleteCycle)
        .collect();
    assert_eq!((short.len(), short[0].index), (1, 720), "{:?}", r.findings);
    // Across a cycle boundary: samples 1438..1442 (the end of cycle 1, the start of cycle 2).
    let cut = |v: &Vec<f64>| [&v[..1438], &v[1442..]].concat();
    let r = check(&build(cut(&t), cut(&deg), cut(&cycle)), &o);
    let lost: Vec<_> = r
        .findings
        .iter()
        .filter(|f| f.kind == FindingKind::LostSamples)
        .collect();
    assert_eq!((lost.len(), lost[0].index), (1, 1438), "{:?}", r.findings);
    assert!(
        lost[0].detail.contains("about 4 samples missing"),
        "{}",
        lost[0].detail
    );
}

#[test]
fn a_count_going_back_is_found_where_it_does() {
    let (t, mut c, m) = clean();
    for v in &mut c[4321..] {
        *v -= 500.0;
    }
    let r = check(
        &rec(vec![("t", t), ("count_en", c), ("tdc", m)], Basis::Time),
        &opts(),
    );
    let back: Vec<_> = r
        .findings
        .iter()
        .filter(|f| f.kind == FindingKind::CountBackwards)
        .collect();
    assert_eq!((back.len(), back[0].index), (1, 4321), "{:?}", r.findings);
}

/// [`clean`] with defects: 3 samples lost after sample 5000, a repeated time stamp at 7000,
/// time going back at 9000, two pulses lost around 12 000, the marker after 15 000 displaced
/// 40 samples late (returned: where it was).
fn defective() -> (Vec<f64>, Vec<f64>, Vec<f64>, usize) {
    let (mut t, mut c, mut m) = clean();
    // Lost samples: remove 3 samples' worth of time after sample 5000.
    for v in &mut t[5001..] {
        *v += 3e-4;
    }
    // A repeated time stamp, then time going back (the rest of the record shifted).
    for v in &mut t[7000..] {
        *v -= 1e-4;
    }
    for v in &mut t[9000..] {
        *v -= 1.1e-4;
    }
    // Two pulses lost between the markers around sample 12 000 (permanently).
    for v in &mut c[12_000..] {
        *v -= 2.0;
    }
    // A marker displaced by one sample late (the count moves on meanwhile) near 15 000.
    let edges: Vec<usize> = (1..m.len()).filter(|&i| m[i] == 1.0).collect();
    let e = *edges.iter().find(|&&e| e > 15_000).unwrap();
    m[e] = 0.0;
    m[e + 40] = 1.0; // 40 samples ≈ 23 pulses late
    (t, c, m, e)
}

#[test]
fn each_defect_is_found_where_it_is() {
    let (t, c, m, e) = defective();
    // A NaN in a channel.
    let mut p = vec![1e5; t.len()];
    p[123] = f64::NAN;
    let r = check(
        &rec(
            vec![("t", t), ("count_en", c), ("tdc", m), ("p_cyl", p)],
            Basis::Time,
        ),
        &opts(),
    );
    let find = |k: FindingKind| {
        r.findings
            .iter()
            .filter(|f| f.kind == k)
            .collect::<Vec<_>>()
    };
    let lost = find(FindingKind::LostSamples);
    assert_eq!(lost.len(), 1);
    assert_eq!(lost[0].index, 5001);
    assert!(
        lost[0].detail.contains("about 3 samples missing"),
        "{}",
        lost[0].detail
    );
    assert_eq!(find(FindingKind::DuplicatedSamples)[0].index, 7000);
    assert_eq!(find(FindingKind::NonMonotonicTime)[0].index, 9000);
    let pl = find(FindingKind::PulseLoss);
    assert_eq!(pl.len(), 1, "{:?}", r.findings);
    assert!(
        pl[0].index < 12_000 && pl[0].detail.contains("358 pulses"),
        "{}",
        pl[0].detail
    );
    let sync = find(FindingKind::OutOfSync);
    assert_eq!(sync.len(), 1, "{:?}", r.findings);
    assert_eq!(sync[0].index, e + 40);
    let nf = find(FindingKind::NonFinite);
    assert_eq!(nf[0].index, 123);
    assert!(nf[0].detail.contains("p_cyl"));
}

#[test]
fn crank_angle_cycles_and_the_cap() {
    let mut cycle: Vec<f64> = (0..3 * 720).map(|k| (k / 720) as f64).collect();
    cycle.truncate(3 * 720 - 5);
    let r = check(
        &rec(vec![("cycle", cycle)], Basis::CrankAngle),
        &IntegrityOptions {
            samples_per_cycle: Some(720),
            ..Default::default()
        },
    );
    // A short last cycle is the recording ending mid-cycle: a note.
    assert!(r.ok, "{:?}", r.findings);
    assert_eq!(r.notes.len(), 1);
    assert_eq!(r.notes[0].index, 1440);
    assert!(
        r.notes[0].detail.contains("715 samples") && r.notes[0].detail.contains("ends mid-cycle")
    );
    // Hundreds of duplicated samples: listed up to the cap, then summarised.
    let t: Vec<f64> = (0..1000).map(|i| (i / 2) as f64).collect();
    let r = check(
        &rec(vec![("t", t)], Basis::Time),
        &IntegrityOptions::default(),
    );
    assert_eq!(r.findings.len(), MAX_PER_KIND + 1);
    assert!(r.findings.iter().any(|f| f.detail.contains("500 findings")));
}

#[test]
fn units_off_the_table_are_found() {
    let mut r = Recording::new(Basis::Time);
    for (name, unit) in [
        ("T_oil", "degC"),
        ("omega_en", "rad/s"),
        ("mine", "furlong"),
    ] {
        r.push(Channel {
            name: name.into(),
            unit: unit.into(),
            values: vec![1.0, 2.0],
        })
        .unwrap();
    }
    let i = check(&r, &IntegrityOptions::default());
    assert_eq!(i.findings.len(), 1, "{:?}", i.findings);
    assert_eq!(i.findings[0].kind, FindingKind::UnitMismatch);
    assert!(i.findings[0]
        .detail
        .contains("'T_oil' is in 'degC'; physid expects 'K'"));
}

/// The stream the live service runs finds what the whole-record check finds — the same kinds
/// at the same samples with the same words — for chunks of 1, 17, 4096 samples and whole:
/// time defects, lost pulses, a displaced marker, a second encoder losing pulses over spans,
/// and the cap with its summary.
/// The stream, in chunks of 1, 17, 4096 or whole, finds each defect [`defective`] placed where
/// it placed it (by construction, not by another check: samples lost at 5001, a repeated stamp
/// at 7000, time going back at 9000, the marker 40 samples late) — and so what the whole-record
/// check finds, finding for finding.
#[test]
fn the_stream_finds_what_the_whole_record_check_finds() {
    let (t, c, m, e) = defective();
    let theta_dy: Vec<f64> = (0..t.len()).map(|i| i as f64 * 1e-2 - 0.05).collect();
    let mut dy = counts_from_angle(&theta_dy, 1024);
    let mut lost = 0.0;
    for (i, v) in dy.iter_mut().enumerate().skip(10_000) {
        if i % 97 == 0 {
            lost += 1.0;
        }
        *v -= lost;
    }
    let o = IntegrityOptions {
        encoders: vec![("count_en".into(), 360), ("count_dy".into(), 1024)],
        ..opts()
    };
    let r = rec(
        vec![("t", t), ("count_en", c), ("tdc", m), ("count_dy", dy)],
        Basis::Time,
    );
    let sorted = |mut v: Vec<Finding>| {
        v.sort_by(|a, b| (a.index, &a.detail).cmp(&(b.index, &b.detail)));
        v
    };
    let whole = sorted(check(&r, &o).findings);
    let kinds = |k| whole.iter().filter(|f| f.kind == k).count();
    assert!(kinds(FindingKind::OutOfSync) == 1 && kinds(FindingKind::LostSamples) == 1);
    assert!(kinds(FindingKind::PulseLoss) >= 2, "{whole:?}");
    let at = |k| -> Vec<usize> {
        whole
            .iter()
            .filter(|f| f.kind == k)
            .map(|f| f.index)
            .collect()
    };
    assert_eq!(at(FindingKind::LostSamples), [5001]);
    assert_eq!(at(FindingKind::DuplicatedSamples), [7000]);
    assert_eq!(at(FindingKind::NonMonotonicTime), [9000]);
    assert_eq!(at(FindingKind::OutOfSync), [e + 40]);
    for chunk in [1, 17, 4096, r.len()] {
        let mut s = IntegrityStream::new(&o, Basis::Time, Some(1e-4));
        let mut out = Vec::new();
        for start in (0..r.len()).step_by(chunk) {
            s.push(&r.slice(start..(start + chunk).min(r.len())), &mut out);
        }
        assert_eq!(s.samples(), r.len());
        s.finish(&mut out);
        assert_eq!(sorted(out), whole, "chunk {chunk}");
    }
    // Hundreds of duplicated samples: the cap and the summary, as the whole-record check.
    let dup = rec(
        vec![("t", (0..1000).map(|i| (i / 2) as f64).collect())],
        Basis::Time,
    );
    let mut s = IntegrityStream::new(&IntegrityOptions::default(), Basis::Time, None);
    let mut out = Vec::new();
    for start in (0..1000).step_by(17) {
        s.push(&dup.slice(start..(start + 17).min(1000)), &mut out);
    }
    s.finish(&mut out);
    assert_eq!(
        sorted(out),
        sorted(check(&dup, &IntegrityOptions::default()).findings)
    );
}

fn in_chunks(r: &Recording, o: &IntegrityOptions, chunk: usize) -> Integrity {
    let mut c = IntegrityCheck::new(o, &r.slice(0..0));
    for start in (0..r.len()).step_by(chunk) {
        c.push(&r.slice(start..start + chunk));
    }
    c.finish()
}

/// The whole check on a file read a chunk at a time is the check on the whole recording —
/// findings, notes and `ok` equal — for chunks of 1, 17, 4096 and whole: time defects, a NaN,
/// lost pulses, a displaced marker, a unit off the table; on a crank-angle basis, samples lost
/// inside a cycle and across a cycle boundary, incomplete cycles, a recording that starts and
/// ends mid-cycle.
#[test]
fn the_whole_check_in_chunks_is_the_check_on_the_whole() {
    let (t, c, m, _) = defective();
    let mut p = vec![1e5; t.len()];
    p[123] = f64::NAN;
    p[17_000] = f64::INFINITY;
    let mut r = rec(
        vec![("t", t), ("count_en", c), ("tdc", m), ("p_cyl", p)],
        Basis::Time,
    );
    r.push(Channel {
        name: "T_oil".into(),
        unit: "degC".into(),
        values: vec![90.0; r.len()],
    })
    .unwrap();
    let whole = check(&r, &opts());
    assert!(
        whole.findings.len() >= 6 && !whole.notes.is_empty(),
        "{whole:?}"
    );
    for chunk in [1, 17, 4096, r.len()] {
        assert_eq!(in_chunks(&r, &opts(), chunk), whole, "chunk {chunk}");
    }
    // No marker in the recording: a note, in chunks too.
    let no_marker = rec(
        vec![
            ("t", r.values("t").unwrap().to_vec()),
            ("tdc", vec![0.0; r.len()]),
        ],
        Basis::Time,
    );
    let w = check(&no_marker, &opts());
    assert!(w.notes[0].detail.contains("no TDC marker"));
    assert_eq!(in_chunks(&no_marker, &opts(), 999), w);

    // Crank angle: starts 100 samples into cycle 0, loses samples 999..1004 and 2158..2162
    // (across the boundary of cycles 2 and 3: both short), ends 5 samples short.
    let n = 5 * 720;
    let deg: Vec<f64> = (0..n).map(|k| (k % 720) as f64).collect();
    let cycle: Vec<f64> = (0..n).map(|k| (k / 720) as f64).collect();
    let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-4).collect();
    let cut = |v: &Vec<f64>| [&v[100..999], &v[1004..2158], &v[2162..n - 5]].concat();
    let ca = rec(
        vec![
            ("t", cut(&t)),
            ("cycle", cut(&cycle)),
            ("crank_deg", cut(&deg)),
        ],
        Basis::CrankAngle,
    );
    let o = IntegrityOptions {
        samples_per_cycle: Some(720),
        ..Default::default()
    };
    let whole = check(&ca, &o);
    let count = |k| whole.findings.iter().filter(|f| f.kind == k).count();
    assert_eq!(count(FindingKind::LostSamples), 2, "{whole:?}");
    assert_eq!(count(FindingKind::IncompleteCycle), 3, "{whole:?}");
    assert_eq!(whole.notes.len(), 2, "{whole:?}");
    for chunk in [1, 17, 720, ca.len()] {
        assert_eq!(in_chunks(&ca, &o, chunk), whole, "chunk {chunk}");
    }
}
