//! Thesis Example 5.2 reproduced with numbers (issue 2, verification 6; SPEC §5.1).
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_apps::example_5_2::{example_5_2, Example52Config};

fn rel(a: f64, b: f64) -> f64 {
    ((a - b) / b).abs()
}

#[test]
fn example_5_2_numbers() {
    let r = example_5_2(&Example52Config::default()).unwrap();
    let idx = |t: f64| r.t.iter().position(|&s| s >= t - 1e-9).unwrap();
    let (rls, rlsf, vf) = (
        r.track("rls").unwrap(),
        r.track("rlsf").unwrap(),
        r.track("rlsvf").unwrap(),
    );
    // All estimators within 2 % of A = 10, B = 0.5 before the step (from 2 s to 5 s).
    for tr in [rls, rlsf, vf] {
        for k in idx(2.0)..=idx(5.0) {
            assert!(
                rel(tr.a[k], 10.0) < 0.02,
                "{} A at t = {}: {}",
                tr.method,
                r.t[k],
                tr.a[k]
            );
            assert!(
                rel(tr.b[k], 0.5) < 0.02,
                "{} B at t = {}: {}",
                tr.method,
                r.t[k],
                tr.b[k]
            );
        }
    }
    let end = r.t.len() - 1;
    // Plain RLS does not track: still more than 20 % off A = 4 at t = 10 s.
    assert!(rel(rls.a[end], 4.0) > 0.20, "RLS A at 10 s: {}", rls.a[end]);
    // Vector forgetting: within 2 % of A = 4 from t = 7 s on, B within 1 % throughout 5–10 s.
    for k in idx(7.0)..=end {
        assert!(
            rel(vf.a[k], 4.0) < 0.02,
            "VF A at t = {}: {}",
            r.t[k],
            vf.a[k]
        );
    }
    let max_dev = |b: &[f64]| (idx(5.0)..=end).map(|k| rel(b[k], 0.5)).fold(0.0, f64::max);
    assert!(max_dev(&vf.b) < 0.01, "VF B deviation {}", max_dev(&vf.b));
    // RLSF tracks A too, but its B is disturbed more than vector forgetting's.
    assert!(rel(rlsf.a[end], 4.0) < 0.02);
    assert!(
        max_dev(&rlsf.b) > max_dev(&vf.b),
        "RLSF {} vs VF {}",
        max_dev(&rlsf.b),
        max_dev(&vf.b)
    );
    println!(
        "max |B−0.5|/0.5 over 5–10 s: RLSF {:.4}, VF {:.4}, RLS {:.4}; RLS A(10 s) = {:.3}",
        max_dev(&rlsf.b),
        max_dev(&vf.b),
        max_dev(&rls.b),
        rls.a[end]
    );
}
