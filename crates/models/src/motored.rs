//! The motored cylinder pressure around TDC: polytropic compression and expansion through the
//! slider-crank volume (SPEC §2.3, [`Crank`]) with the valves closed, a loss of charge and heat
//! that lowers `p·Vⁿ` as the crank turns, a sensor offset, and the TDC not where the recording
//! puts it. Every parameter is physical:
//!
//! ```text
//! p_m(θ) = p_bdc · (V(−π)/V(α))ⁿ · exp(−k_loss·(α + π)) + p_offset,   α = (θ − tdc_shift)·π/180
//! V(−π)/V(α) = ε·S / (S + (ε − 1)·s(α))                               (V_c = V_d/(ε − 1))
//! ```
//!
//! with `θ` the recording's crank angle [deg after its TDC], `s` the piston's displacement from
//! TDC (Eq. 3.29) and `S` the stroke:
//!
//! | name       | unit          | meaning                                                        |
//! |------------|---------------|----------------------------------------------------------------|
//! | `eps`      | –             | compression ratio ε                                            |
//! | `tdc_shift`| deg           | where the true TDC lies on the recording's crank angle        |
//! | `p_offset` | pressure unit | what the sensor reads above the true pressure (pegging offset) |
//! | `n`        | –             | polytropic exponent                                            |
//! | `p_bdc`    | pressure unit | the pressure at BDC before compression                         |
//! | `k_loss`   | 1/rad         | the rate at which `p·Vⁿ` falls (heat lost, gas blown by)       |
//!
//! Without loss (`k_loss = 0`) the trace is symmetric about TDC; with it the peak comes before
//! TDC — the *thermodynamic loss angle* — where `n·V'/V = −k_loss`, so that reading the TDC off
//! the peak is wrong by that angle and fitting `tdc_shift` with `k_loss` is not. Only the ratio
//! `r/L` and ε enter (`V(−π)/V(α)` is dimensionless): the bore does not, the stroke only scales.
//!
//! The model describes the closed part of the cycle only; fit it over a window inside IVC…EVO
//! (the applications default to −120° … 120°).

use crate::kinematics::Crank;
use physid_core::{ParamModel, Scalar};
use std::f64::consts::PI;

/// The parameter names, in order.
pub const PARAMS: [&str; 6] = ["eps", "tdc_shift", "p_offset", "n", "p_bdc", "k_loss"];
/// Their units (`P` for the pressure channel's unit).
pub const UNITS: [&str; 6] = ["-", "deg", "P", "-", "P", "1/rad"];
/// One line each.
pub const DESCRIPTIONS: [&str; 6] = [
    "compression ratio",
    "TDC on the recording's crank angle",
    "sensor offset (pegging)",
    "polytropic exponent",
    "pressure at BDC before compression",
    "loss rate of p·V^n (heat, blow-by)",
];
/// The input channel: the recording's crank angle after its TDC [deg], −360 … 360.
pub const INPUT: &str = "atdc_deg";

/// The motored-pressure model on a known geometry (crank radius, rod; no pin offset).
#[derive(Debug, Clone)]
pub struct Motored {
    crank: Crank<f64>,
    stroke: f64,
    params: Vec<String>,
    inputs: Vec<String>,
}

impl Motored {
    /// The model for a stroke and connecting rod [m] (any consistent unit: only `r/L` and the
    /// stroke's ratio to the displacement enter).
    pub fn new(stroke: f64, rod: f64) -> Self {
        let crank = Crank {
            r: 0.5 * stroke,
            l: rod,
            delta: 0.0,
            bore: 1.0,
            kappa: 2.0,
        };
        Self {
            crank,
            stroke,
            params: PARAMS.iter().map(|s| s.to_string()).collect(),
            inputs: vec![INPUT.to_string()],
        }
    }

    /// The slider crank (bore and compression ratio placeholders: only `r`, `L` enter).
    pub fn crank(&self) -> Crank<f64> {
        self.crank
    }

    /// `V(−π)/V(α)` for the compression ratio `eps` at the true angle `alpha` [rad].
    pub fn volume_ratio<T: Scalar>(&self, eps: T, alpha: T) -> T {
        let s = self.crank.s_at(alpha);
        eps * self.stroke / ((eps - 1.0) * s + self.stroke)
    }
}

impl ParamModel for Motored {
    fn param_names(&self) -> &[String] {
        &self.params
    }

    fn input_names(&self) -> &[String] {
        &self.inputs
    }

    fn eval<T: Scalar>(&self, u: &[f64], p: &[T]) -> T {
        let (eps, shift, offset, n, p_bdc, k) = (p[0], p[1], p[2], p[3], p[4], p[5]);
        let alpha = (-shift + u[0]) * (PI / 180.0);
        let ln_ratio = self.volume_ratio(eps, alpha).ln();
        p_bdc * (n * ln_ratio - k * (alpha + PI)).exp() + offset
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model() -> Motored {
        Motored::new(0.09, 0.15)
    }

    /// The textbook volume, written out here: V = V_c + A·(r(1 − cos a) + L − √(L² − r² sin² a)).
    fn ratio(eps: f64, a: f64) -> f64 {
        let (r, l) = (0.045, 0.15);
        let s = r * (1.0 - a.cos()) + l - (l * l - (r * a.sin()).powi(2)).sqrt();
        let vc = 0.09 / (eps - 1.0);
        (vc + 0.09) / (vc + s)
    }

    #[test]
    fn without_loss_it_is_the_polytrope_through_the_slider_crank() {
        let m = model();
        let th = [10.0, 0.0, 0.0, 1.35, 1e5, 0.0];
        for deg in [-180.0, -120.0, -30.0, 0.0, 17.0, 90.0] {
            let want = 1e5 * ratio(10.0, f64::to_radians(deg)).powf(1.35);
            let got = m.eval::<f64>(&[deg], &th);
            assert!((got - want).abs() <= 1e-9 * want, "{deg}: {got} vs {want}");
        }
        // p_bdc at BDC, ε^n at TDC.
        assert!((m.eval::<f64>(&[-180.0], &th) - 1e5).abs() < 1e-6);
        assert!((m.eval::<f64>(&[0.0], &th) - 1e5 * 10f64.powf(1.35)).abs() < 1e-4);
    }

    #[test]
    fn the_offsets_shift_and_the_loss_moves_the_peak_before_tdc() {
        let m = model();
        let base = [16.0, 0.0, 0.0, 1.33, 1e5, 0.0];
        let mut shifted = base;
        shifted[1] = 0.7;
        shifted[2] = -2e4;
        for deg in [-100.0, -5.0, 3.0, 60.0] {
            let want = m.eval::<f64>(&[deg - 0.7], &base) - 2e4;
            let got = m.eval::<f64>(&[deg], &shifted);
            assert!((got - want).abs() < 1e-6 * want.abs());
        }
        // The peak with a loss: where n·V'/V = −k, i.e. d ln p/dα = 0; found on a fine grid.
        let mut lossy = base;
        lossy[5] = 0.05;
        let peak = (-3000..=3000)
            .map(|i| f64::from(i) * 1e-3)
            .max_by(|a, b| {
                m.eval::<f64>(&[*a], &lossy)
                    .total_cmp(&m.eval::<f64>(&[*b], &lossy))
            })
            .unwrap_or(0.0);
        assert!(peak < -0.1, "the motored peak lies before TDC: {peak}°");
        // … where the closed form says: n·(d ln V/dα) = −k with V' by central differences.
        let dlnv = |deg: f64| {
            let h = 1e-4;
            let v = |d: f64| 1.0 / ratio(16.0, f64::to_radians(d));
            (v(deg + h).ln() - v(deg - h).ln()) / (2.0 * h.to_radians())
        };
        assert!((1.33 * dlnv(peak) + 0.05).abs() < 2e-3 * 1.33 * dlnv(-10.0).abs());
    }
}
