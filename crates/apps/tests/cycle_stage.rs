//! The cycle statistics as a stage: set up on the first chunk with `theta_en` and a wanted
//! channel, the crank-angle means against a closed form, a value that is not a number left out
//! as a dropout — named with its channel and sample, the cycle it cuts left out, the cycles
//! after it numbered on.
#![allow(clippy::unwrap_used)]

use physid_apps::cycle_stage::{CycleOutput, CycleStage};
use physid_apps::stage::Stage;
use physid_core::{Basis, Channel, Recording};
use std::f64::consts::PI;

/// `n` samples at 10 kHz from sample `from` of an engine at 1500 rpm: `t`, `theta_en` and
/// `p = 5 + 2·cos θ` (whose mean over a cycle is 5), without `theta_en` if `angle` is false.
fn chunk(from: usize, n: usize, angle: bool) -> Recording {
    let w = 1500.0 * 2.0 * PI / 60.0;
    let t: Vec<f64> = (from..from + n).map(|k| k as f64 * 1e-4).collect();
    let th: Vec<f64> = t.iter().map(|t| w * t).collect();
    let p: Vec<f64> = th.iter().map(|a| 5.0 + 2.0 * a.cos()).collect();
    let mut r = Recording::new(Basis::Time);
    let mut cols = vec![("t", "s", t), ("p_int", "Pa", p)];
    if angle {
        cols.push(("theta_en", "rad", th));
    }
    for (name, unit, values) in cols {
        r.push(Channel {
            name: name.into(),
            unit: unit.into(),
            values,
        })
        .unwrap();
    }
    r
}

#[test]
fn cycles_of_the_channels_a_stream_has() {
    let mut s = CycleStage::new(&["omega_en", "p_int"], 0.0, None);
    let mut out = Vec::new();
    // No angle yet: nothing set up, nothing out.
    s.push(&chunk(0, 1000, false), &mut out).unwrap();
    assert!(s.channels().is_empty() && out.is_empty());
    // 1 s at 1500 rpm from 0.1 s (θ from 15.7 to 172.8 rad): the cycles between 4π·2 and
    // 4π·13, 11 complete.
    for k in 0..10 {
        s.push(&chunk(1000 + k * 1000, 1000, true), &mut out)
            .unwrap();
    }
    s.finish(&mut out).unwrap();
    assert_eq!(s.channels(), ["p_int".to_string()]);
    let cycles = |out: &[CycleOutput]| -> Vec<_> {
        out.iter()
            .filter_map(|o| match o {
                CycleOutput::Cycle(c) => Some(c.clone()),
                CycleOutput::Dropout(_) => None,
            })
            .collect()
    };
    assert_eq!(cycles(&out).len(), 11, "{} outputs", out.len());
    assert_eq!(cycles(&out)[10].cycle, 10);
    for c in &cycles(&out) {
        // The trapezoidal mean over ≈0.9° steps: within 1e-4 of 5.
        assert!(
            (c.mean[0] - 5.0).abs() < 1e-4,
            "cycle {}: {}",
            c.cycle,
            c.mean[0]
        );
        assert!((c.max[0] - 7.0).abs() < 1e-3);
    }
    // A value not finite: an error naming the sample and the channel.
    let mut bad = chunk(11_000, 100, true);
    let mut p = bad.values("p_int").unwrap().to_vec();
    p[40] = f64::NAN;
    let mut r = Recording::new(Basis::Time);
    for ch in bad.channels() {
        let values = if ch.name == "p_int" {
            p.clone()
        } else {
            ch.values.clone()
        };
        r.push(Channel {
            name: ch.name.clone(),
            unit: ch.unit.clone(),
            values,
        })
        .unwrap();
    }
    bad = r;
    // A value that is not a number (at sample 11 040, θ = 173.4 rad, in cycle 11 from 4π·13):
    // a dropout, told once; cycle 11 left out, cycles 12 and 13 (to 4π·16 = 201.1 rad, sample
    // 12 800) reported as the uninterrupted stream's.
    out.clear();
    s.push(&bad, &mut out).unwrap();
    s.push(&chunk(11_100, 1900, true), &mut out).unwrap();
    let told: Vec<_> = out
        .iter()
        .filter_map(|o| match o {
            CycleOutput::Dropout(d) => Some((d.t_s, d.message())),
            CycleOutput::Cycle(_) => None,
        })
        .collect();
    assert_eq!(told.len(), 1, "{told:?}");
    assert!((told[0].0 - 1.104).abs() < 1e-9, "{told:?}");
    assert!(
        told[0]
            .1
            .starts_with("'p_int' is NaN at sample 11040 (t = 1.10")
            && told[0].1.contains(" s): the cycle it cuts is left out"),
        "{told:?}"
    );
    let after = cycles(&out);
    assert_eq!(after.iter().map(|c| c.cycle).collect::<Vec<_>>(), [12, 13]);
    for c in &after {
        assert!((c.mean[0] - 5.0).abs() < 1e-4 && (c.max[0] - 7.0).abs() < 1e-3);
    }
}
