//! The batch and on-line analyses: quantitative results against statsmodels, scaling modes and
//! centring against the dense sensitivity matrix, the on-line ranking against the batch one,
//! Gauss–Newton fits against closed forms, and errors.
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use nalgebra::DMatrix;
use physid_expr::ExprModel;
use physid_ident::*;

fn json(name: &str) -> serde_json::Value {
    let p = format!("{}/tests/golden/{name}", env!("CARGO_MANIFEST_DIR"));
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

fn floats(v: &serde_json::Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * b.abs().max(1e-300)
}

/// Fit + quantify equals statsmodels OLS: estimates, standard errors, t-values, Student-t 95 %
/// intervals, covariance (`golden/gen_statsmodels_ols.py`).
#[test]
fn quantitative_equals_statsmodels_ols() {
    let g = json("statsmodels_ols.json");
    let (x, y) = (floats(&g["x"]), floats(&g["y"]));
    let m = ExprModel::parse("b0 + b1*x + b2*x^2", &["b0", "b1", "b2"]).unwrap();
    let d = Data {
        inputs: vec![&x],
        y: Some(&y),
    };
    let fit = fit_subset(&m, &d, &[0.0, 0.0, 0.0], &[0, 1, 2], 10).unwrap();
    assert!(close(fit.rss, g["ssr"].as_f64().unwrap(), 1e-10));
    let s2 = fit.rss / (x.len() - 3) as f64;
    assert!(close(s2, g["scale"].as_f64().unwrap(), 1e-10));
    let q = quantify(&fit.gram, s2, &fit.theta, x.len()).unwrap();
    for i in 0..3 {
        assert!(close(fit.theta[i], floats(&g["params"])[i], 1e-9));
        assert!(close(q.std_err[i], floats(&g["bse"])[i], 1e-9));
        assert!(close(q.t_values[i], floats(&g["tvalues"])[i], 1e-9));
        let ci = floats(&g["conf_int"][i]);
        assert!(close(q.ci95[i].0, ci[0], 1e-9) && close(q.ci95[i].1, ci[1], 1e-9));
        for j in 0..3 {
            assert!(close(q.covariance[(i, j)], floats(&g["cov"][i])[j], 1e-9));
            let corr = q.covariance[(i, j)] / (q.std_err[i] * q.std_err[j]);
            assert!((q.correlation[(i, j)] - corr).abs() < 1e-14);
        }
    }
    // Linear model: one Gauss–Newton step from anywhere is the least-squares solution, and
    // the analysis's linearised residual equals it.
    assert_eq!(fit.iterations, 1);
    let a = analyse(
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
    assert!(close(a.linearised_rss(&[0, 1, 2]).unwrap(), fit.rss, 1e-9));
    // A singular Fisher information is an error, not a NaN.
    let sing = DMatrix::from_row_slice(2, 2, &[1.0, 1.0, 1.0, 1.0]);
    assert!(matches!(
        quantify(&sing, 1.0, &[1.0, 1.0], 10),
        Err(IdentError::Singular { .. })
    ));
}

/// The three scalings equal the dense matrix scaled by hand; the thesis guard counts the rows
/// where the output crosses zero.
#[test]
fn scaling_modes_and_guard() {
    let m = ExprModel::parse("A*sin(t) + B*cos(t)^2 + C", &["A", "B", "C"]).unwrap();
    let t: Vec<f64> = (0..400).map(|i| i as f64 * 0.05).collect();
    let d = Data {
        inputs: vec![&t],
        y: None,
    };
    let th = [2.0, 0.5, 0.1];
    let (_, jm, _) = sensitivity_matrix(&m, &d, &th, &[0, 1, 2], Scaling::None, 1e-3).unwrap();
    // Closed-form Jacobian.
    for (i, ti) in t.iter().enumerate() {
        assert!((jm[(i, 0)] - ti.sin()).abs() < 1e-15);
        assert!((jm[(i, 1)] - ti.cos().powi(2)).abs() < 1e-15);
        assert_eq!(jm[(i, 2)], 1.0);
    }
    let yv: Vec<f64> = t
        .iter()
        .map(|t| 2.0 * t.sin() + 0.5 * t.cos().powi(2) + 0.1)
        .collect();
    let rms = (yv.iter().map(|y| y * y).sum::<f64>() / yv.len() as f64).sqrt();
    let mean = yv.iter().sum::<f64>() / yv.len() as f64;
    let sd = (yv.iter().map(|y| (y - mean).powi(2)).sum::<f64>() / yv.len() as f64).sqrt();
    for (scaling, guard) in [
        (Scaling::Thesis, 1e-3),
        (Scaling::Thesis, 0.2),
        (Scaling::Sigma, 1e-3),
    ] {
        let (zm, _, guarded) = sensitivity_matrix(&m, &d, &th, &[0, 1, 2], scaling, guard).unwrap();
        let mut count = 0;
        for i in 0..t.len() {
            let div = match scaling {
                Scaling::Sigma => sd,
                _ if yv[i].abs() < guard * rms => {
                    count += 1;
                    (guard * rms).copysign(yv[i])
                }
                _ => yv[i],
            };
            for j in 0..3 {
                let want = jm[(i, j)] * th[j] / div;
                assert!((zm[(i, j)] - want).abs() <= 1e-12 * want.abs().max(1e-12));
            }
        }
        assert_eq!(guarded, count, "{scaling:?} {guard}");
        if guard == 0.2 {
            assert!(
                count > 0,
                "the output crosses zero: some rows must hit a wide guard"
            );
        }
        // The streamed analysis ranks the same Gram matrix.
        let a = analyse(
            &m,
            &d,
            &th,
            &[],
            IdentConfig {
                scaling,
                guard,
                centre: false,
            },
        )
        .unwrap();
        assert_eq!(a.guarded_rows, count);
        let dense = rank(&zm.clone().qr().r());
        assert_eq!(a.ranking.order(), dense.order());
        for (s, r) in a.ranking.steps.iter().zip(&dense.steps) {
            assert!(close(s.residual_ss, r.residual_ss, 1e-9));
        }
    }
}

/// Centring (Eq. 5.9 as printed) equals ranking the explicitly centred dense matrix; a
/// constant column then has nothing left.
#[test]
fn centring_equals_centred_columns() {
    let m = ExprModel::parse("A*x + B*x^2 + C", &["A", "B", "C"]).unwrap();
    let x: Vec<f64> = (0..200)
        .map(|i| (i as f64 * 0.37).sin() * 3.0 + 1.0)
        .collect();
    let d = Data {
        inputs: vec![&x],
        y: None,
    };
    let th = [1.0, 0.5, 2.0];
    let (zm, _, _) = sensitivity_matrix(&m, &d, &th, &[0, 1, 2], Scaling::Sigma, 1e-3).unwrap();
    let mut zc = zm.clone();
    for j in 0..3 {
        let mean = zm.column(j).mean();
        zc.column_mut(j).add_scalar_mut(-mean);
    }
    let a = analyse(
        &m,
        &d,
        &th,
        &[],
        IdentConfig {
            scaling: Scaling::Sigma,
            guard: 1e-3,
            centre: true,
        },
    )
    .unwrap();
    let gram = zc.transpose() * &zc;
    let ga = a.gram_scaled(&[0, 1]);
    for i in 0..2 {
        for j in 0..2 {
            assert!(close(ga[(i, j)], gram[(i, j)], 1e-9));
        }
    }
    assert_eq!(a.ranking.steps[2].param, 2);
    assert!(a.ranking.steps[2].relative < 1e-20, "{:?}", a.ranking);
    assert_eq!(a.estimable(Cutoff::Repeat), 2);
}

fn rows(n: usize, p: usize, seed: u64) -> Vec<Vec<f64>> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            (0..p)
                .map(|j| rng.random_range(-1.0..1.0) * (1.0 + j as f64))
                .collect()
        })
        .collect()
}

/// On a sliding window the on-line ranking equals the batch ranking of the same rows (order,
/// residuals to 1e-9 relative); with forgetting it equals the batch ranking of the rows
/// weighted by √λ^(n−i). Rows where a column loses excitation move it down the ranking.
#[test]
fn online_equals_batch() {
    let p = 6;
    let mut data = rows(3000, p, 3);
    // From row 2000 on, column 4 is almost a copy of column 1: it loses its own excitation.
    for r in data.iter_mut().skip(2000) {
        r[4] = 0.5 * r[1] + 1e-2 * r[4];
    }
    let w = 500;
    let mut on = OnlineIdent::new(p, Memory::Window(w)).unwrap();
    for (i, r) in data.iter().enumerate() {
        on.update(r).unwrap();
        if (i + 1) % 250 == 0 && i + 1 >= w {
            let mut f = TriangularFactor::new(p);
            for r in &data[i + 1 - w..=i] {
                f.add_row(r);
            }
            let batch = rank(&f.r());
            let online = on.ranking();
            assert_eq!(online.order(), batch.order(), "sample {i}");
            for (a, b) in online.steps.iter().zip(&batch.steps) {
                assert!(
                    close(a.residual_ss, b.residual_ss, 1e-9),
                    "sample {i}: {} vs {}",
                    a.residual_ss,
                    b.residual_ss
                );
            }
        }
    }
    let sup = on.supported(Cutoff::Relative(1e-3));
    assert!(
        !sup[4] && sup.iter().filter(|&&s| s).count() == p - 1,
        "{sup:?}"
    );

    let lambda: f64 = 0.995;
    let mut on = OnlineIdent::new(p, Memory::Forgetting(lambda)).unwrap();
    for r in &data[..1000] {
        on.update(r).unwrap();
    }
    let mut f = TriangularFactor::new(p);
    for (i, r) in data[..1000].iter().enumerate() {
        let wgt = lambda.powf((999 - i) as f64 / 2.0);
        let scaled: Vec<f64> = r.iter().map(|v| v * wgt).collect();
        f.add_row(&scaled);
    }
    let (a, b) = (on.ranking(), rank(&f.r()));
    assert_eq!(a.order(), b.order());
    for (x, y) in a.steps.iter().zip(&b.steps) {
        assert!(close(x.residual_ss, y.residual_ss, 1e-9));
    }
    // Bad input is refused with the state untouched.
    let before = on.ranking();
    assert!(on.update(&[1.0, f64::NAN, 0.0, 0.0, 0.0, 0.0]).is_err());
    assert!(on.update(&[1.0]).is_err());
    assert_eq!(on.ranking(), before);
    assert!(OnlineIdent::new(3, Memory::Forgetting(1.5)).is_err());
    assert!(OnlineIdent::new(3, Memory::Window(0)).is_err());
}

/// Downdating: removing every added row but a few leaves the factor of those few.
#[test]
fn downdate_inverts_update() {
    let data = rows(50, 4, 9);
    let mut f = TriangularFactor::new(4);
    for r in &data {
        f.add_row(r);
    }
    for r in &data[..40] {
        f.remove_row(r).unwrap();
    }
    let mut g = TriangularFactor::new(4);
    for r in &data[40..] {
        g.add_row(r);
    }
    let (a, b) = (f.gram(), g.gram());
    for i in 0..4 {
        for j in 0..4 {
            assert!((a[(i, j)] - b[(i, j)]).abs() < 1e-10 * b[(i, i)].abs());
        }
    }
    // Removing a row that was never there fails and changes nothing.
    let before = f.r();
    assert!(f.remove_row(&[100.0, 0.0, 0.0, 0.0]).is_err());
    assert_eq!(f.r(), before);
}

/// A nonlinear fit converges to the generating parameters on noise-free data; Wu's criterion
/// along the ranking keeps the parameters that matter.
#[test]
fn gauss_newton_and_wu_along_a_ranking() {
    let m = ExprModel::parse("A*exp(-B*t) + C*t + D*t^2", &["A", "B", "C", "D"]).unwrap();
    let t: Vec<f64> = (0..300).map(|i| i as f64 * 0.02).collect();
    let truth = [2.0, 0.8, 0.3, 0.0];
    // D is truly zero; deterministic "noise" of rms ≈ 0.01.
    let y: Vec<f64> = t
        .iter()
        .enumerate()
        .map(|(i, t)| {
            2.0 * (-0.8 * t).exp()
                + 0.3 * t
                + 0.01 * ((i * 7919 % 1000) as f64 / 1000.0 - 0.5) * 3.46
        })
        .collect();
    let d = Data {
        inputs: vec![&t],
        y: Some(&y),
    };
    let fit = fit_subset(&m, &d, &[1.5, 1.0, 0.2, 0.0], &[0, 1, 2], 50).unwrap();
    for (f, t) in fit.theta.iter().zip(&truth).take(3) {
        assert!((f - t).abs() < 0.02, "{:?}", fit.theta);
    }
    let a = analyse(&m, &d, &[2.0, 0.8, 0.3, 0.01], &[], IdentConfig::default()).unwrap();
    let (wu, j) = wu_along_ranking(&m, &d, &a, None, 50).unwrap();
    assert_eq!(j.len(), 4);
    assert!(j.windows(2).all(|w| w[1] <= w[0] * (1.0 + 1e-9)), "{j:?}");
    // K* keeps A, B, C (whatever their order) and drops D.
    let kept: Vec<&str> = a
        .top(wu.k_star)
        .iter()
        .map(|&i| a.names[i].as_str())
        .collect();
    assert!(
        !kept.contains(&"D") || wu.k_star == 4,
        "{kept:?} {:?}",
        wu.r_cc
    );
    assert!(wu.k_star >= 3, "{:?}", wu.r_cc);
}

#[test]
fn errors_name_the_problem() {
    let m = ExprModel::parse("A*x + B", &["A", "B"]).unwrap();
    let x = [1.0, 2.0, f64::NAN, 4.0];
    let d = Data {
        inputs: vec![&x],
        y: None,
    };
    let e = analyse(&m, &d, &[1.0, 1.0], &[], IdentConfig::default()).unwrap_err();
    assert!(
        matches!(&e, IdentError::BadValue { row: 2, column, value } if column == "x" && value.is_nan())
    );
    assert!(e.to_string().contains("row 2, x"), "{e}");
    let short = [1.0, 2.0];
    let y = [1.0, 2.0, 3.0];
    let d = Data {
        inputs: vec![&short],
        y: Some(&y),
    };
    let e = analyse(&m, &d, &[1.0, 1.0], &[], IdentConfig::default()).unwrap_err();
    assert!(e.to_string().contains("output column has 3 rows"), "{e}");
    let zero = [0.0; 5];
    let d = Data {
        inputs: vec![&zero],
        y: None,
    };
    let e = analyse(
        &ExprModel::parse("A*x", &["A"]).unwrap(),
        &d,
        &[1.0],
        &[],
        IdentConfig::default(),
    )
    .unwrap_err();
    assert!(e.to_string().contains("--scaling none"), "{e}");
    let e = analyse(&m, &d, &[1.0], &[], IdentConfig::default()).unwrap_err();
    assert!(
        e.to_string().contains("1 nominal values for 2 parameters"),
        "{e}"
    );
}

/// A parameter with nominal value 0 has no relative sensitivity: its column is scaled by 1
/// (not zeroed, which would call it unidentifiable) and reported.
#[test]
fn zero_nominal_is_unit_scaled_and_reported() {
    let m = ExprModel::parse("A*x + B", &["A", "B"]).unwrap();
    let x: Vec<f64> = (0..50).map(|i| 1.0 + i as f64 * 0.1).collect();
    let d = Data {
        inputs: vec![&x],
        y: None,
    };
    let a = analyse(&m, &d, &[2.0, 0.0], &[], IdentConfig::default()).unwrap();
    assert_eq!(a.unit_scaled, [1]);
    assert_eq!(a.estimable(Cutoff::Repeat), 2);
    // Column B = 1·1/y = 1/(2x): its sum of squares in closed form.
    let ss_b: f64 = x.iter().map(|x| (0.5 / x).powi(2)).sum();
    assert!(close(a.ranking.column_ss[1], ss_b, 1e-12));
    let none = analyse(
        &m,
        &d,
        &[2.0, 0.0],
        &[],
        IdentConfig {
            scaling: Scaling::None,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(none.unit_scaled.is_empty());
}
