//! The friction model: regression form = physical form over the operating grid, regressor by
//! regressor; viscosity; units; torque conversion; sensitivities exact.
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_models::friction::{
    fmep, fmep_regression, nominal_coefficients, preset, regressors, s_mu, sandoval2002_preset,
    tau_nm, thesis_preset, viscosity, Design, OperatingPoint, Settings, SpeedForm, Variant,
    OIL_GRADES, PRESETS, T_REF_C,
};

fn grid() -> Vec<OperatingPoint> {
    let mut g = Vec::new();
    for n in [750.0, 1000.0, 3000.0, 5000.0] {
        for p_int in [10.0, 55.0, 100.0] {
            for t in [20.0, 55.0, 90.0] {
                g.push(OperatingPoint {
                    n_rpm: n,
                    p_int_kpa: p_int,
                    p_atm_kpa: 100.1,
                    t_oil_c: t,
                });
            }
        }
    }
    g
}

/// Issue 5, verification 3: with the nominal coefficients the regression form equals the
/// physical form to 1e-12 over the grid — in total, and with each regressor tested on its own
/// (zeroing coefficient i removes exactly c_i·φ_i from the physical total).
#[test]
fn regression_form_equals_physical_form() {
    for name in PRESETS {
        let (d, st) = preset(name).unwrap();
        regression_equals_physical(&d, &st);
    }
}

fn regression_equals_physical(d: &Design<f64>, st: &Settings) {
    let (d, st) = (*d, *st);
    let c = nominal_coefficients(&st);
    for op in grid() {
        let phys = fmep(&d, &st, &op).total();
        let phi = regressors(&d, &st, &op);
        let reg = fmep_regression(&c, &phi);
        assert!(
            (reg - phys).abs() <= 1e-12 * phys.abs(),
            "{op:?}: {reg} vs {phys}"
        );
        for i in 0..20 {
            let mut ci = c;
            ci[i] = 0.0;
            let without = fmep_regression(&ci, &phi);
            let term = c[i] * phi[i];
            assert!(
                ((phys - without) - term).abs() <= 1e-12 * phys.abs(),
                "regressor {}: {}",
                i + 1,
                term
            );
        }
    }
}

/// The speed form (the terms gathered by their dependence on N, the test cell's) equals the
/// physical form's mechanical fmep to 1e-13 over the grid and at speeds between, for every
/// preset (both variants) and with the design moved off the preset.
#[test]
fn speed_form_equals_physical_form() {
    for name in PRESETS {
        let (d, st) = preset(name).unwrap();
        let moved = Design {
            b: d.b * 1.07,
            s: d.s * 0.93,
            kappa: d.kappa + 1.5,
            lv: d.lv * 1.2,
            db: d.db * 0.9,
            ..d
        };
        for d in [d, moved] {
            for op in grid() {
                let form = SpeedForm::new(&d, &st, s_mu(&st, op.t_oil_c));
                for n_rpm in [op.n_rpm, op.n_rpm * 0.613, 50.0] {
                    let op = OperatingPoint { n_rpm, ..op };
                    let want = fmep(&d, &st, &op).mechanical();
                    let got = form.mechanical(n_rpm, op.p_int_kpa / op.p_atm_kpa);
                    assert!(
                        (got - want).abs() <= 1e-13 * want.abs(),
                        "{name} {op:?}: {got} vs {want}"
                    );
                }
            }
        }
    }
}

/// Issue 5, verification 5: the Vogel form with the table's constants for every grade;
/// `s_μ = 1` at T_ref in the original model, while the thesis code's scaling √(u_uo·μ/μ_ref)
/// is √u_uo there (1 only for u_uo = 1 grades).
#[test]
fn viscosity_of_every_grade() {
    let (_, thesis) = thesis_preset();
    let (_, original) = sandoval2002_preset();
    for (name, oil) in OIL_GRADES {
        let (k, t1, t2, uuo) = (oil.k, oil.theta1, oil.theta2, oil.u_uo);
        let thesis = Settings { oil, ..thesis };
        let original = Settings { oil, ..original };
        let mu90 = viscosity(oil, 90.0);
        assert!(
            (mu90 - k * (t1 / (t2 + 90.0)).exp()).abs() < 1e-12 * mu90,
            "{name}"
        );
        assert!(
            viscosity(oil, 20.0) > viscosity(oil, 90.0),
            "{name}: thinner when hot"
        );
        assert!(
            (s_mu(&thesis, T_REF_C) - uuo.sqrt()).abs() < 1e-15,
            "{name}"
        );
        assert!((s_mu(&original, T_REF_C) - 1.0).abs() < 1e-15, "{name}");
        let t = 40.0;
        let expect = (k * (t1 / (t2 + t)).exp() / (k * (t1 / (t2 + T_REF_C)).exp())).sqrt();
        assert!(
            (s_mu(&original, t) - expect).abs() < 1e-13 * expect,
            "{name}"
        );
    }
}

/// The two variants differ exactly where SPEC §2.5 says: at T_ref with a u_uo = 1 grade the
/// hydrodynamic terms agree, so the totals differ by the auxiliary polynomials alone, and the
/// 4.12 kPa constant moves from rfmep to vfmep.
#[test]
fn variants_differ_where_the_spec_says() {
    let (d, thesis) = thesis_preset();
    let sae30 = OIL_GRADES.iter().find(|g| g.0 == "SAE30").unwrap();
    let oil = sae30.1;
    let thesis = Settings { oil, ..thesis };
    let original = Settings {
        variant: Variant::Sandoval2002,
        ..thesis
    };
    for n in [1000.0, 3000.0, 5000.0] {
        let op = OperatingPoint {
            n_rpm: n,
            p_int_kpa: 55.0,
            p_atm_kpa: 100.1,
            t_oil_c: T_REF_C,
        };
        let (a, b) = (fmep(&d, &thesis, &op), fmep(&d, &original, &op));
        let aux_a = 8.32 + 1.86e-3 * n + 7.45e-7 * n * n;
        let aux_b = 6.23 + 5.22e-3 * n - 1.79e-7 * n * n;
        assert!((a.afmep - aux_a).abs() < 1e-12 && (b.afmep - aux_b).abs() < 1e-12);
        assert!(((a.rfmep - 4.12) - b.rfmep).abs() < 1e-12);
        assert!(((b.vfmep - 4.12) - a.vfmep).abs() < 1e-12);
        assert!((a.cfmep - b.cfmep).abs() < 1e-12 && (a.pmep - b.pmep).abs() < 1e-12);
        assert!(((a.total() - b.total()) - (aux_a - aux_b)).abs() < 1e-10);
    }
    // Away from T_ref, the original scales the three hydrodynamic terms by s_μ: colder oil,
    // more friction than the thesis code's constant grade factor.
    let cold = OperatingPoint {
        n_rpm: 3000.0,
        p_int_kpa: 55.0,
        p_atm_kpa: 100.1,
        t_oil_c: 20.0,
    };
    assert!(fmep(&d, &original, &cold).vfmep > fmep(&d, &thesis, &cold).vfmep);
    assert!(preset("sandoval2002").is_some() && preset("nope").is_none());
}

/// Issue 5, verification 6: the same torque from the correlations' units (mm, rpm, kPa, °C)
/// and from SI inputs (m, rad/s, Pa, K) written independently.
#[test]
fn si_inputs_give_the_same_torque() {
    let (d, st) = thesis_preset();
    let op = OperatingPoint {
        n_rpm: 2400.0,
        p_int_kpa: 55.0,
        p_atm_kpa: 100.1,
        t_oil_c: 35.0,
    };
    let si = Design {
        b: 0.054,
        s: 0.0515,
        kappa: 12.0,
        di: 0.027,
        de: 0.023,
        lv: 0.009,
        db: 0.052,
        lb: 0.013,
        r: 0.0257,
    };
    let op_si = OperatingPoint::from_si(
        2400.0 * 2.0 * std::f64::consts::PI / 60.0,
        55e3,
        100.1e3,
        308.15,
    );
    let d_si = Design::from_si(si);
    let a = tau_nm(fmep(&d, &st, &op).total(), &d);
    let b = tau_nm(fmep(&d_si, &st, &op_si).total(), &d_si);
    assert!((a - b).abs() < 1e-12 * a.abs(), "{a} vs {b}");
}

/// Torque: τ = fmep·V_d/(4π) for a four-stroke (Eq. 3.44), with V_d = π B²/4 · 2r in SI units —
/// independently of the code's B²·r form; and the fmep of the thesis engine at 1000 rpm is a
/// plausible motored loss (100–300 kPa with pumping at 35 kPa manifold pressure).
#[test]
fn torque_units_and_magnitude() {
    let (d, st) = thesis_preset();
    let op = OperatingPoint {
        n_rpm: 1000.0,
        p_int_kpa: 35.0,
        p_atm_kpa: 100.1,
        t_oil_c: 90.0,
    };
    let f = fmep(&d, &st, &op).total();
    let vd_m3 = std::f64::consts::PI / 4.0 * (d.b / 1000.0).powi(2) * 2.0 * (d.r / 1000.0);
    let tau = f * 1e3 * vd_m3 / (4.0 * std::f64::consts::PI);
    assert!((tau_nm(f, &d) - tau).abs() < 1e-12 * tau);
    assert!((100.0..300.0).contains(&f), "fmep {f} kPa");
}

#[test]
fn set_by_name_changes_one_thing_and_explains_mistakes() {
    use physid_models::friction::set_by_name;
    let (mut d, mut st) = thesis_preset();
    set_by_name(&mut d, &mut st, "B", "56").unwrap();
    set_by_name(&mut d, &mut st, "oil", "sae30").unwrap();
    set_by_name(&mut d, &mut st, "valvetrain", "DOHC_I").unwrap();
    set_by_name(&mut d, &mut st, "nb", "5").unwrap();
    assert_eq!((d.b, d.s), (56.0, 51.5));
    let (o, v) = (st.oil, st.valvetrain);
    assert_eq!(
        (o.k, o.theta1, o.theta2, o.u_uo),
        (0.0246, 1432.29, 132.94, 1.0)
    );
    assert_eq!((v.cff, v.com), (600.0, 25.8));
    assert_eq!(st.nb, 5.0);
    let e = set_by_name(&mut d, &mut st, "oil", "5W31")
        .unwrap_err()
        .to_string();
    assert!(e.contains("0W40") && e.contains("SAE50"), "{e}");
    let e = set_by_name(&mut d, &mut st, "S", "-3")
        .unwrap_err()
        .to_string();
    assert!(e.contains("S=-3") && e.contains("> 0"), "{e}");
    let e = set_by_name(&mut d, &mut st, "stroke", "3")
        .unwrap_err()
        .to_string();
    assert!(e.contains("'stroke'") && e.contains("kappa"), "{e}");
}

#[test]
fn regression_model_is_the_torque_of_the_physical_form() {
    use physid_core::{GradientEngine, ParamModel};
    use physid_models::friction::{FrictionRegression, FrictionTorque};
    for name in PRESETS {
        let (d, st) = preset(name).unwrap();
        let reg = FrictionRegression::new(d, st);
        let phys = FrictionTorque::new(st);
        let c0 = reg.nominal();
        let mut grad = vec![0.0; 20];
        let mut engine = GradientEngine::new(20);
        for op in grid() {
            let u = FrictionTorque::inputs(&op);
            let a = reg.eval::<f64>(&u, &c0);
            let b = phys.eval::<f64>(&u, &d.to_array());
            assert!(
                (a - b).abs() <= 1e-12 * b.abs(),
                "{name} {op:?}: {a} vs {b}"
            );
            // Linear in the coefficients: the exact gradient is the regressor.
            engine.value_and_gradient(&reg, &u, &c0, &(0..20).collect::<Vec<_>>(), &mut grad);
            let psi = reg.regressor(&op);
            for j in 0..20 {
                assert!((grad[j] - psi[j]).abs() <= 1e-15 * psi[j].abs().max(1e-300));
            }
        }
    }
}
