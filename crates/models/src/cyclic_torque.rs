//! Cyclic engine torque (thesis Eq. 8.2, SPEC §9): the model of the end-of-line cold test,
//!
//! ```text
//! τ_eng = τ_ind − τ_rec − τ_fri
//! τ_ind = (p_cyl − p_crank)·(π b²/4)·r·G                 (app. B.4)
//! τ_rec = M_rec·r·G·(G1·ω² + G2·α)
//! τ_fri = fmep·1e3·(π b²/4)·r/(2π),   N = 30ω/π [rpm], T = T_oil [°C]
//! fmep  = c1 + c2N − c3T + c4N² − c5NT + c6T² − c7N³ + c8N²T + c9NT² − c10T³   [kPa]
//! ```
//!
//! with `G, G1, G2` the thesis's closed forms with the signed root
//! ([`Crank::thesis_g`](crate::kinematics::Crank::thesis_g)). Inputs: `theta` [rad], `omega`
//! [rad/s], `alpha` [rad/s²], `p_cyl`, `p_crank` [Pa], `T_oil` [°C]. Parameters: `M_rec` [kg],
//! `b`, `L`, `r`, `delta` [m], `c1 … c10` (fmep in kPa). The friction cubic is a fit of the
//! mean-value model ([`fit_friction_cubic`](crate::friction_fit::fit_friction_cubic)).

use crate::kinematics::Crank;
use physid_core::{ParamModel, Scalar};

/// Parameter names, in order.
pub const PARAMS: [&str; 15] = [
    "M_rec", "b", "L", "r", "delta", "c1", "c2", "c3", "c4", "c5", "c6", "c7", "c8", "c9", "c10",
];
/// Input names, in order.
pub const INPUTS: [&str; 6] = ["theta", "omega", "alpha", "p_cyl", "p_crank", "T_oil"];

/// The engine of SPEC §2.4 in SI units (M_rec 0.8 kg, b 54 mm, L 88 mm, r 25.7 mm, δ 0) with
/// an illustrative friction cubic of plausible size — for tests and benchmarks, not a fit.
pub const ILLUSTRATIVE: [f64; 15] = [
    0.80, 0.054, 0.088, 0.0257, 0.0, 60.0, 0.02, 0.4, 1e-6, 1e-4, 2e-3, 1e-10, 1e-8, 1e-6, 1e-5,
];

/// The cyclic-torque model.
#[derive(Debug, Clone)]
pub struct CyclicTorque {
    params: Vec<String>,
    inputs: Vec<String>,
}

impl Default for CyclicTorque {
    fn default() -> Self {
        Self {
            params: PARAMS.iter().map(|s| s.to_string()).collect(),
            inputs: INPUTS.iter().map(|s| s.to_string()).collect(),
        }
    }
}

/// The friction cubic `fmep(N, T)` [kPa] with the thesis's signs (app. B.4).
pub fn fmep_cubic<T: Scalar>(c: &[T], n: f64, t: f64) -> T {
    c[0] + c[1] * n - c[2] * t + c[3] * (n * n) - c[4] * (n * t) + c[5] * (t * t)
        - c[6] * (n * n * n)
        + c[7] * (n * n * t)
        + c[8] * (n * t * t)
        - c[9] * (t * t * t)
}

impl ParamModel for CyclicTorque {
    fn param_names(&self) -> &[String] {
        &self.params
    }

    fn input_names(&self) -> &[String] {
        &self.inputs
    }

    fn eval<T: Scalar>(&self, u: &[f64], p: &[T]) -> T {
        let (theta, omega, alpha, p_cyl, p_crank, t_oil) = (u[0], u[1], u[2], u[3], u[4], u[5]);
        let crank = Crank {
            r: p[3],
            l: p[2],
            delta: p[4],
            bore: p[1],
            kappa: T::from(10.0), // not used by the torque
        };
        let (g, g1, g2) = crank.thesis_g(theta);
        let r = p[3];
        let area_r = crank.piston_area() * r;
        let n = omega * 30.0 / std::f64::consts::PI;
        // τ_ind − τ_fri = A·r·(G·Δp − fmep·1e3/(2π)), shared factor A·r.
        let fmep = fmep_cubic(&p[5..15], n, t_oil);
        let ind_fri =
            area_r * (g * (p_cyl - p_crank) - fmep * (1e3 / (2.0 * std::f64::consts::PI)));
        let rec = p[0] * r * g * (g1 * (omega * omega) + g2 * alpha);
        ind_fri - rec
    }
}
