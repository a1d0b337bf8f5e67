//! The cycle statistics as a stage: set up on the first chunk with `theta_en` and a wanted
//! channel, the crank-angle means against a closed form, a value not finite named with its
//! channel.
#![allow(clippy::unwrap_used)]

use physid_apps::cycle_stage::CycleStage;
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
    assert_eq!(out.len(), 11, "{} cycles", out.len());
    for c in &out {
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
    let e = s.push(&bad, &mut out).unwrap_err().to_string();
    assert!(e.contains("p_int"), "{e}");
}
