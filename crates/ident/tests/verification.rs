//! Identifiability against independent evidence: the worked numbers (closed forms,
//! Brun et al., Box & Lucas, Wu et al.), a numpy implementation of Alg. 5.1, and the dense
//! sensitivity matrix.
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use nalgebra::DMatrix;
use physid_expr::ExprModel;
use physid_ident::*;

fn names(a: &Analysis) -> Vec<&str> {
    a.ranking
        .steps
        .iter()
        .map(|s| a.names[s.param].as_str())
        .collect()
}

/// Issue 4, verification 2: `y = a·b·x + c·x²`, x = 1…4, ϑ0 = (1, 1, 1).
#[test]
fn abc_model_ranking_and_collinearity() {
    let m = ExprModel::parse("a*b*x + c*x^2", &["a", "b", "c"]).unwrap();
    let x = [1.0, 2.0, 3.0, 4.0];
    let d = Data {
        inputs: vec![&x],
        y: None,
    };
    let a = analyse(&m, &d, &[1.0, 1.0, 1.0], &[], IdentConfig::default()).unwrap();
    assert_eq!(names(&a), ["c", "a", "b"]);
    let res: Vec<f64> = a.ranking.steps.iter().map(|s| s.residual_ss).collect();
    assert!((res[0] - 1.896944).abs() < 1e-6, "{res:?}");
    assert!((res[1] - 0.109386).abs() < 1e-6, "{res:?}");
    assert!(res[2].abs() < 1e-6, "{res:?}");
    // Closed forms: SS_c = Σ (x/(1+x))², the residual of a after c from the 2×2 Gram.
    let za: Vec<f64> = x.iter().map(|x| 1.0 / (1.0 + x)).collect();
    let zc: Vec<f64> = x.iter().map(|x| x / (1.0 + x)).collect();
    let dot = |u: &[f64], v: &[f64]| u.iter().zip(v).map(|(a, b)| a * b).sum::<f64>();
    assert!((res[0] - dot(&zc, &zc)).abs() < 1e-14);
    let ra = dot(&za, &za) - dot(&za, &zc).powi(2) / dot(&zc, &zc);
    assert!((res[1] - ra).abs() < 1e-14);
    assert_eq!(a.estimable(Cutoff::Repeat), 2);
    assert!((a.collinearity(&[0, 2]) - 2.8183).abs() < 1e-4);
    assert!(a.collinearity(&[0, 1]).is_infinite());
    let none = analyse(
        &m,
        &d,
        &[1.0, 1.0, 1.0],
        &[],
        IdentConfig {
            scaling: Scaling::None,
            ..Default::default()
        },
    )
    .unwrap();
    assert!((none.collinearity(&[0, 2]) - 5.8095).abs() < 1e-4);
}

/// Issue 4, verification 3: collinearity indices of given matrices.
#[test]
fn collinearity_of_given_matrices() {
    let s = DMatrix::from_fn(5, 2, |i, j| (i + 1) as f64 * if j == 0 { 1.0 } else { 2.0 });
    assert!(collinearity_index(&(s.transpose() * &s)).is_infinite());
    let m = DMatrix::from_row_slice(
        4,
        2,
        &[-0.400, -0.374, 0.255, 0.797, 0.690, -0.472, -0.546, 0.049],
    );
    let g = collinearity_index(&(m.transpose() * &m));
    assert!((g - 1.0002).abs() < 1e-4, "{g}");
}

/// Issue 4, verification 4: Box & Lucas (1959), two-point design.
#[test]
fn box_lucas_design_criteria() {
    let m = ExprModel::parse("t1/(t1-t2)*(exp(-t2*t) - exp(-t1*t))", &["t1", "t2"]).unwrap();
    let t = [1.229, 6.858];
    let d = Data {
        inputs: vec![&t],
        y: None,
    };
    let cfg = IdentConfig {
        scaling: Scaling::None,
        ..Default::default()
    };
    let a = analyse(&m, &d, &[0.7, 0.2], &[], cfg).unwrap();
    let c = a.design_criteria(&[0, 1], 1.0);
    assert!((c.d - 0.6568).abs() < 1e-4, "{c:?}");
    assert!((c.a - 5.148).abs() < 1e-3, "{c:?}");
    assert!((c.e - 0.2069).abs() < 1e-4, "{c:?}");
    assert!((c.modified_e - 15.34).abs() < 1e-2, "{c:?}");
    // The same from the dense sensitivity matrix.
    let (_, j, _) = sensitivity_matrix(&m, &d, &[0.7, 0.2], &[0, 1], Scaling::None, 1e-3).unwrap();
    let c2 = design_criteria(&(j.transpose() * &j));
    assert!((c.d - c2.d).abs() < 1e-12 && (c.a - c2.a).abs() < 1e-10);
}

/// Issue 4, verification 5: Wu et al.'s criterion.
#[test]
fn wu_criterion_numbers() {
    let w = wu_criterion(&[120.0, 40.0, 21.0, 20.0], 20).unwrap();
    let expect = [4.70, 0.80, -0.0167, 0.0];
    for (a, b) in w.r_cc.iter().zip(expect) {
        assert!((a - b).abs() < 1e-3, "{:?}", w.r_cc);
    }
    assert_eq!(w.k_star, 3);
    assert!(wu_criterion(&[], 5).is_none());
}

/// The streamed factor and the pivoted Gram–Schmidt on it reproduce numpy's straightforward
/// Alg. 5.1 (least squares per step; `bench/peers/alg51.py golden`).
#[test]
fn ranking_equals_numpy_alg51() {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/golden/alg51.json"
    ))
    .unwrap();
    let g: serde_json::Value = serde_json::from_str(&text).unwrap();
    let p = g["p"].as_u64().unwrap() as usize;
    let mut f = TriangularFactor::new(p);
    for row in g["Z"].as_array().unwrap() {
        let r: Vec<f64> = row
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        f.add_row(&r);
    }
    let ranking = rank(&f.r());
    let order: Vec<usize> = g["order"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap() as usize)
        .collect();
    assert_eq!(ranking.order(), order);
    for (s, r) in ranking
        .steps
        .iter()
        .zip(g["residual_ss"].as_array().unwrap())
    {
        let r = r.as_f64().unwrap();
        assert!(
            (s.residual_ss - r).abs() <= 1e-9 * r,
            "{} vs {r}",
            s.residual_ss
        );
    }
}

/// Example 5.1 (SPEC §4) with exciting inputs: estimable D, C, B, A, F; E unidentifiable
/// because x/y is half of 2x/y — whatever the inputs.
#[test]
fn example_5_1() {
    let m = ExprModel::parse(
        "sin(A)*x + B^2*y*cos(x) + sqrt(C)*x^2 + D*y^2 + E*x/y + F*2*x/y",
        &["A", "B", "C", "D", "E", "F"],
    )
    .unwrap();
    let n = 2000;
    let x: Vec<f64> = (0..n)
        .map(|i| 30.0 * (0.007 * i as f64).sin() + (1.3 * i as f64).sin())
        .collect();
    let y: Vec<f64> = (0..n)
        .map(|i| 30.0 + 3.0 * (0.0045 * i as f64).cos() + (2.9 * i as f64).cos())
        .collect();
    let d = Data {
        inputs: vec![&x, &y],
        y: None,
    };
    let a = analyse(
        &m,
        &d,
        &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0],
        &[],
        IdentConfig::default(),
    )
    .unwrap();
    assert_eq!(names(&a), ["D", "C", "B", "A", "F", "E"]);
    assert_eq!(a.estimable(Cutoff::Repeat), 5);
    assert_eq!(a.guarded_rows, 0);
    // E and F are exactly collinear.
    let e = a.names.iter().position(|n| n == "E").unwrap();
    let f = a.names.iter().position(|n| n == "F").unwrap();
    assert!(a.collinearity(&[e, f]).is_infinite());
}
