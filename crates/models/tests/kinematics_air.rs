//! Kinematics against automatic differentiation and virtual work; the thesis's closed forms
//! against the virtual-work forms; air properties against Cantera's `air.yaml` values.
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use num_dual::{second_derivative, Dual2_64, DualNum};
use physid_models::air;
use physid_models::kinematics::Crank;

/// The engine of SPEC §2.4 (bore 54 mm, r 25.7 mm, L 88 mm, κ 9.5) with an offset.
fn crank(delta: f64) -> Crank<f64> {
    Crank {
        r: 0.0257,
        l: 0.088,
        delta,
        bore: 0.054,
        kappa: 9.5,
    }
}

/// s(θ) written independently, in θ as a second-order dual number.
fn s_dual(c: &Crank<f64>, theta: Dual2_64) -> Dual2_64 {
    let q = theta.sin() * c.r - c.delta;
    let top = ((c.r + c.l).powi(2) - c.delta * c.delta).sqrt();
    Dual2_64::from_re(top) - theta.cos() * c.r - (q * q * -1.0 + c.l * c.l).sqrt()
}

#[test]
fn derivatives_of_s_equal_automatic_differentiation() {
    for delta in [0.0, 0.002, -0.003] {
        let c = crank(delta);
        for k in 0..720 {
            let th = (k as f64).to_radians() + 0.001;
            let (s, ds, dds) = second_derivative(|t| s_dual(&c, t), th);
            assert!((c.s(th) - s).abs() < 1e-15, "s at {k}°");
            assert!(
                (c.ds(th) - ds).abs() < 1e-13 * c.r,
                "s' at {k}°: {} vs {ds}",
                c.ds(th)
            );
            assert!(
                (c.dds(th) - dds).abs() < 1e-12 * c.r,
                "s'' at {k}°: {} vs {dds}",
                c.dds(th)
            );
        }
    }
}

/// With δ ≠ 0, V is smallest at TDC θ = φ where s(φ) = 0, and the stroke is s at BDC (φ + π
/// for the crank; found here by search).
#[test]
fn offset_tdc_and_stroke() {
    let c = crank(0.004);
    let phi = c.phi();
    assert!(c.s(phi).abs() < 1e-15);
    let n = 200_000;
    let (mut vmin, mut vmax) = (f64::MAX, f64::MIN);
    for k in 0..n {
        let th = k as f64 / n as f64 * std::f64::consts::TAU;
        vmin = vmin.min(c.volume(th));
        vmax = vmax.max(c.volume(th));
    }
    assert!((vmin - c.volume(phi)).abs() < 1e-15);
    assert!(((vmax - vmin) / c.piston_area() - c.stroke()).abs() < 1e-9 * c.stroke());
    // δ = 0: stroke 2r and the displacement of SPEC §2.4 (≈ 118 cm³ with b = 54 mm, S = 51.4 mm).
    let c0 = crank(0.0);
    assert!((c0.stroke() - 2.0 * c0.r).abs() < 1e-15);
    let vd = c0.piston_area() * c0.stroke();
    assert!((vd - std::f64::consts::PI / 4.0 * 0.054f64.powi(2) * 0.0514).abs() < 1e-15);
}

/// Virtual work: ∫ τ_ind dθ over a cycle (τ_ind = (p − p_crank)·A_p·s') equals ∮ (p − p_crank) dV
/// for an arbitrary pressure trace — the first by Simpson's rule in θ, the second as a
/// Stieltjes sum over volume differences.
#[test]
fn virtual_work() {
    let c = crank(0.003);
    let p = |th: f64| 1e5 + 3e6 * (-(th - 0.2).powi(2) * 4.0).exp() + 2e4 * (3.0 * th).sin();
    let p_crank = 1.0e5;
    let n = 720 * 512; // midpoint Stieltjes sum: O(h²) error ≈ 1e-10 here
    let h = 4.0 * std::f64::consts::PI / n as f64;
    let tau = |th: f64| (p(th) - p_crank) * c.piston_area() * c.ds(th);
    let mut simpson = tau(0.0) + tau(n as f64 * h);
    for k in 1..n {
        simpson += tau(k as f64 * h) * if k % 2 == 1 { 4.0 } else { 2.0 };
    }
    simpson *= h / 3.0;
    let mut stieltjes = 0.0;
    for k in 0..n {
        let (a, b) = (k as f64 * h, (k + 1) as f64 * h);
        stieltjes += (p(0.5 * (a + b)) - p_crank) * (c.volume(b) - c.volume(a));
    }
    assert!(
        (simpson - stieltjes).abs() < 1e-9 * simpson.abs(),
        "{simpson} vs {stieltjes}"
    );
}

/// The thesis's closed forms with the signed root equal the virtual-work forms at δ = 0 over
/// the whole cycle: r·G = s', G1 = s'', G2 = s'. Taken literally (unsigned root) they are wrong
/// wherever sin θ < 0.
#[test]
fn thesis_closed_forms_equal_virtual_work_forms() {
    let c = crank(0.0);
    let mut literal_wrong = 0;
    for k in 0..720 {
        let th = (k as f64 + 0.5).to_radians();
        let (g, g1, g2) = c.thesis_g(th);
        assert!((c.r * g - c.ds(th)).abs() < 1e-12 * c.r, "r·G at {k}°");
        assert!((g1 - c.dds(th)).abs() < 1e-12 * c.r, "G1 at {k}°");
        assert!((g2 - c.ds(th)).abs() < 1e-12 * c.r, "G2 at {k}°");
        // The literal form: √((1−ψ)/ψ) without the sign.
        let psi = 1.0 - (c.r * th.sin() / c.l).powi(2);
        let g_literal = th.sin() + ((1.0 - psi) / psi).sqrt() * th.cos();
        if (c.r * g_literal - c.ds(th)).abs() > 1e-9 * c.r {
            literal_wrong += 1;
            assert!(th.sin() < 0.0);
        }
    }
    assert!(literal_wrong > 300, "{literal_wrong}");
}

/// Cantera's `air.yaml` (SPEC §2.5 verification 4): c_p within 0.3 %; h continuous at 1000 K
/// within 0.1 %; u = h − RT; γ at 300 K near 1.40.
#[test]
fn air_properties_against_cantera() {
    let reference = [
        (300.0, 1010.1),
        (400.0, 1022.1),
        (500.0, 1037.8),
        (600.0, 1057.4),
        (800.0, 1105.3),
        (1000.0, 1151.0),
    ];
    for (t, cp) in reference {
        let ours = air::cp(t);
        assert!(
            ((ours - cp) / cp).abs() < 3e-3,
            "c_p({t} K) = {ours} vs {cp}"
        );
    }
    let below = air::enthalpy(1000.0 - 1e-9);
    let above = air::enthalpy(1000.0);
    let scale = air::enthalpy(1000.0) - air::enthalpy(300.0);
    assert!((above - below).abs() < 1e-3 * scale);
    // The thesis's air (O₂ + 79/21 N₂, no argon): M = (31.999 + 3.7619·28.013)/4.7619 = 28.850.
    assert!(
        (air::molar_mass() - 28.850).abs() < 1e-3,
        "{}",
        air::molar_mass()
    );
    assert!((air::gas_constant() - 8314.34 / 28.850).abs() < 0.01);
    assert!((air::gamma(300.0) - 1.40).abs() < 0.005);
    let t = 700.0;
    assert!((air::internal_energy(t) - (air::enthalpy(t) - air::gas_constant() * t)).abs() < 1e-9);
}
