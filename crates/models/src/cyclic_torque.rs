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
use physid_core::{GradientEngine, ParamModel, Scalar};

/// Parameter names, in order.
pub const PARAMS: [&str; 15] = [
    "M_rec", "b", "L", "r", "delta", "c1", "c2", "c3", "c4", "c5", "c6", "c7", "c8", "c9", "c10",
];
/// Their units (the friction cubic's coefficients give fmep in kPa from N in rpm and T in °C).
pub const UNITS: [&str; 15] = [
    "kg",
    "m",
    "m",
    "m",
    "m",
    "kPa",
    "kPa/rpm",
    "kPa/°C",
    "kPa/rpm²",
    "kPa/(rpm·°C)",
    "kPa/°C²",
    "kPa/rpm³",
    "kPa/(rpm²·°C)",
    "kPa/(rpm·°C²)",
    "kPa/°C³",
];
/// One line each (`b` here is the bore).
pub const DESCRIPTIONS: [&str; 15] = [
    "reciprocating mass (piston, rings, pin, part of the rod)",
    "bore",
    "connecting-rod length",
    "crank radius",
    "piston-pin offset",
    "friction cubic: constant",
    "friction cubic: N",
    "friction cubic: −T",
    "friction cubic: N²",
    "friction cubic: −N·T",
    "friction cubic: T²",
    "friction cubic: −N³",
    "friction cubic: N²·T",
    "friction cubic: N·T²",
    "friction cubic: −T³",
];
/// Input names, in order.
pub const INPUTS: [&str; 6] = ["theta", "omega", "alpha", "p_cyl", "p_crank", "T_oil"];

/// The engine of SPEC §2.4 in SI units (M_rec 0.8 kg, b 54 mm, L 88 mm, r 25.7 mm, δ 0) with
/// an illustrative friction cubic of plausible size — for tests and benchmarks, not a fit.
pub const ILLUSTRATIVE: [f64; 15] = [
    0.80, 0.054, 0.088, 0.0257, 0.0, 60.0, 0.02, 0.4, 1e-6, 1e-4, 2e-3, 1e-10, 1e-8, 1e-6, 1e-5,
];

/// The cyclic-torque model.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
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

/// The ten monomials of the friction cubic at (N, T) with the thesis's signs (app. B.4):
/// `fmep = Σ c_i·φ_i`, `φ = (1, N, −T, N², −NT, T², −N³, N²T, NT², −T³)`.
pub fn cubic_regressors(n: f64, t: f64) -> [f64; 10] {
    [
        1.0,
        n,
        -t,
        n * n,
        -(n * t),
        t * t,
        -(n * n * n),
        n * n * t,
        n * t * t,
        -(t * t * t),
    ]
}

/// The friction cubic `fmep(N, T) = Σ c_i·φ_i(N, T)` [kPa] ([`cubic_regressors`]).
pub fn fmep_cubic<T: Scalar>(c: &[T], n: f64, t: f64) -> T {
    fmep_of(c, &cubic_regressors(n, t))
}

/// `Σ c_i·φ_i` with the regressors given.
fn fmep_of<T: Scalar>(c: &[T], phi: &[f64; 10]) -> T {
    c[1..10]
        .iter()
        .zip(&phi[1..])
        .fold(c[0], |acc, (&c, &f)| acc + c * f)
}

impl CyclicTorque {
    /// `∂τ_eng/∂p_cyl = A_p·r·G(θ)` [N·m/Pa] at crank angle `theta` [rad] with the parameters
    /// `p` (app. B.4: the indicated torque is linear in `p_cyl − p_crank`): how a cylinder
    /// pressure's error enters the modelled torque.
    pub fn pressure_arm(&self, theta: f64, p: &[f64]) -> f64 {
        let u = [theta, 0.0, 0.0, 1.0, 0.0, 0.0];
        self.split(&u, p).0
    }

    /// The model split at the friction cubic: `τ = a − β·fmep` with `a = τ_ind − τ_rec` and
    /// `β = A_p·r·1e3/(2π)` (the torque of 1 kPa fmep). Reads only `M_rec, b, L, r, δ` of `p`.
    fn split<T: Scalar>(&self, u: &[f64], p: &[T]) -> (T, T) {
        self.split_at(u, p, u[0].sin_cos())
    }

    /// [`split`](Self::split) with the crank angle's sine and cosine given.
    fn split_at<T: Scalar>(&self, u: &[f64], p: &[T], trig: (f64, f64)) -> (T, T) {
        let (omega, alpha, p_cyl, p_crank) = (u[1], u[2], u[3], u[4]);
        let crank = Crank {
            r: p[3],
            l: p[2],
            delta: p[4],
            bore: p[1],
            kappa: T::from(10.0), // not used by the torque
        };
        let (g, g1, g2) = crank.thesis_g_at(trig);
        let r = p[3];
        let area_r = crank.piston_area() * r;
        let a = area_r * g * (p_cyl - p_crank) - p[0] * r * g * (g1 * (omega * omega) + g2 * alpha);
        (a, area_r * (1e3 / (2.0 * std::f64::consts::PI)))
    }
}

/// Speed in rpm from ω [rad/s].
fn rpm(omega: f64) -> f64 {
    omega * 30.0 / std::f64::consts::PI
}

impl ParamModel for CyclicTorque {
    fn param_names(&self) -> &[String] {
        &self.params
    }

    fn input_names(&self) -> &[String] {
        &self.inputs
    }

    fn eval<T: Scalar>(&self, u: &[f64], p: &[T]) -> T {
        let (a, beta) = self.split(u, p);
        a - beta * fmep_cubic(&p[5..15], rpm(u[1]), u[5])
    }

    /// The sigma points share the inputs: the crank angle's sine and cosine and the friction
    /// cubic's regressors once for all of them (equal to `eval` of each, bit for bit: tested).
    fn eval_many(&self, inputs: &[f64], params: &[f64], out: &mut [f64]) {
        let trig = inputs[0].sin_cos();
        let phi = cubic_regressors(rpm(inputs[1]), inputs[5]);
        let len = params.len().checked_div(out.len()).unwrap_or(0);
        for (k, o) in out.iter_mut().enumerate() {
            let p = &params[k * len..(k + 1) * len];
            let (a, beta) = self.split_at(inputs, p, trig);
            *o = a - beta * fmep_of(&p[5..15], &phi);
        }
    }

    /// The model is affine in `c1 … c10`: `∂τ/∂c_i = −β·φ_i(N, T)` with `β` and `φ` of
    /// [`split`](Self::split) and [`cubic_regressors`], exact. Only `M_rec, b, L, r, δ` go
    /// through forward mode, in one dual evaluation instead of two.
    fn value_and_gradient_with(
        &self,
        engine: &mut GradientEngine,
        u: &[f64],
        p: &[f64],
        free: &[usize],
        grad: &mut [f64],
    ) -> f64 {
        const NONLINEAR: usize = 5;
        // The free nonlinear parameters and where their partials go in `grad`.
        let (mut nl, mut at, mut k) = ([0; NONLINEAR], [0; NONLINEAR], 0);
        for (pos, &j) in free.iter().enumerate() {
            if j < NONLINEAR {
                if k == NONLINEAR {
                    // A parameter listed twice: forward mode handles any list.
                    return engine.forward(p, free, grad, |d| self.eval(u, d));
                }
                (nl[k], at[k]) = (j, pos);
                k += 1;
            }
        }
        let (n, t) = (rpm(u[1]), u[5]);
        let fmep = fmep_cubic(&p[5..15], n, t);
        let (value, beta) = if k == 0 {
            let (a, beta) = self.split(u, p);
            (a - beta * fmep, beta)
        } else {
            let mut beta = 0.0;
            let mut g = [0.0; NONLINEAR];
            let value = engine.forward(p, &nl[..k], &mut g[..k], |d| {
                let (a, b) = self.split(u, d);
                beta = b.re;
                a - b * fmep
            });
            for (&pos, &gj) in at[..k].iter().zip(&g) {
                grad[pos] = gj;
            }
            (value, beta)
        };
        let phi = cubic_regressors(n, t);
        for (&j, gj) in free.iter().zip(grad.iter_mut()) {
            if j >= NONLINEAR {
                *gj = -beta * phi[j - NONLINEAR];
            }
        }
        value
    }
}
