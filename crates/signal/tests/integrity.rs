//! The integrity check finds each injected defect at its place, and nothing in clean data.
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_core::{Basis, Channel, Recording};
use physid_signal::encoder::counts_from_angle;
use physid_signal::integrity::{check, FindingKind, IntegrityOptions, MAX_PER_KIND};

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
        samples_per_cycle: None,
    }
}

#[test]
fn clean_data_has_only_the_leading_partial_cycle() {
    let (t, c, m) = clean();
    let r = check(
        &rec(vec![("t", t), ("count_en", c), ("tdc", m)], Basis::Time),
        &opts(),
    );
    assert_eq!(r.findings.len(), 1, "{:?}", r.findings);
    assert_eq!(r.findings[0].kind, FindingKind::IncompleteCycle);
    assert!(!r.ok);
}

#[test]
fn each_defect_is_found_where_it_is() {
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
    assert_eq!(r.findings.len(), 1);
    assert_eq!(r.findings[0].index, 1440);
    assert!(r.findings[0].detail.contains("715 samples"));
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
