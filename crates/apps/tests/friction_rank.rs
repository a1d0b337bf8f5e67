//! The friction design-parameter ranking (thesis §7.2, Table 7.1) against sympy's symbolic
//! derivatives of the model as SPEC §2.5 writes it (`golden/gen_friction_rank.py`), and the
//! thesis's qualitative findings.
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_apps::friction_rank::{friction_rank, RankError, RankGrid};
use physid_models::friction::{sandoval2002_preset, thesis_preset};
use serde_json::Value;

fn golden() -> Value {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/golden/friction_rank.json"
    ))
    .unwrap();
    serde_json::from_str(&text).unwrap()
}

#[test]
fn equals_sympy_on_the_thesis_grid() {
    let g = golden();
    let (d, st) = thesis_preset();
    let t = friction_rank(&d, &st, &RankGrid::default(), &[]).unwrap();
    let names: Vec<&str> = g["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    assert_eq!(t.parameters, names);
    let tests = g["tests"].as_array().unwrap();
    assert_eq!(t.tests.len(), 27);
    for (i, (ours, theirs)) in t.tests.iter().zip(tests).enumerate() {
        assert_eq!(ours.op.n_rpm, theirs["n_rpm"].as_f64().unwrap(), "test {i}");
        assert_eq!(ours.op.p_int_kpa, theirs["p_int_kpa"].as_f64().unwrap());
        assert_eq!(ours.op.t_oil_c, theirs["t_oil_c"].as_f64().unwrap());
        let tau = theirs["tau_nm"].as_f64().unwrap();
        assert!((ours.tau_nm - tau).abs() < 1e-12 * tau, "test {i}: tau");
        for (j, z) in theirs["sensitivity"].as_array().unwrap().iter().enumerate() {
            let z = z.as_f64().unwrap();
            assert!(
                (ours.sensitivity[j] - z).abs() < 1e-11,
                "test {}: z_{} = {} vs sympy {}",
                i + 1,
                names[j],
                ours.sensitivity[j],
                z
            );
        }
        let ranking: Vec<&str> = ours
            .order
            .iter()
            .map(|&j| t.parameters[j].as_str())
            .collect();
        let expect: Vec<&str> = theirs["ranking"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_str().unwrap())
            .collect();
        assert_eq!(ranking, expect, "test {}", i + 1);
        for (pos, &j) in ours.order.iter().enumerate() {
            assert_eq!(ours.rank[j], pos + 1);
        }
    }
}

/// τ_fri ∝ r exactly, so z_r = 1 everywhere; the crank–piston design parameters (B, S, r, Db,
/// Lb) outrank the valvetrain's (Di, De, Lv) in every test (thesis §7.2); the bore loses rank
/// as speed rises.
#[test]
fn thesis_findings() {
    for (d, st) in [thesis_preset(), sandoval2002_preset()] {
        let t = friction_rank(&d, &st, &RankGrid::default(), &[]).unwrap();
        let idx = |n: &str| t.parameters.iter().position(|p| p == n).unwrap();
        for test in &t.tests {
            assert!((test.sensitivity[idx("r")] - 1.0).abs() < 1e-12);
            let crank = ["B", "S", "r", "Db", "Lb"].map(|n| test.rank[idx(n)]);
            let valves = ["Di", "De", "Lv"].map(|n| test.rank[idx(n)]);
            assert!(crank.iter().max() < valves.iter().min(), "{:?}", test.op);
        }
        let b = idx("B");
        assert!(t.tests[0].rank[b] < t.tests[2].rank[b]);
    }
}

#[test]
fn subsets_and_errors() {
    let (d, st) = thesis_preset();
    let grid = RankGrid::default();
    let sub = friction_rank(&d, &st, &grid, &["Lv".into(), "B".into()]).unwrap();
    let full = friction_rank(&d, &st, &grid, &[]).unwrap();
    assert_eq!(sub.parameters, ["Lv", "B"]);
    assert_eq!(sub.tests[0].sensitivity[1], full.tests[0].sensitivity[0]);
    assert_eq!(sub.tests[0].rank, [2, 1]);
    assert_eq!(
        friction_rank(&d, &st, &grid, &["bore".into()]).unwrap_err(),
        RankError::UnknownParameter("bore".into())
    );
    let bad = RankGrid {
        n_rpm: vec![1000.0, f64::NAN],
        ..RankGrid::default()
    };
    let e = friction_rank(&d, &st, &bad, &[]).unwrap_err().to_string();
    assert!(e.contains("engine speed") && e.contains("NaN"), "{e}");
}
