//! The coupling shaft (thesis Eq. 3.4 / 6.1, SPEC §2.1 and §7):
//!
//! ```text
//! τ_sh = K_sh·Δθ + B_sh·Δω (+ τ_0),   Δθ = θ_dy − θ_en,  Δω = ω_dy − ω_en
//! ```
//!
//! linear in its parameters: stiffness `K` [N·m/rad], damping `B` [N·m·s/rad] and, optionally,
//! a torque offset `tau0` [N·m]. Real encoders have an unknown zero offset `θ_off` between them
//! (SPEC §7): the measured `Δθ_m = Δθ + θ_off` gives `τ_sh = K·Δθ_m + B·Δω − K·θ_off`, a
//! constant that `tau0 = −K·θ_off` absorbs (and that a transducer zero error adds to).
//!
//! Inputs are the recording's channels `theta_dy`, `theta_en` [rad], `omega_dy`, `omega_en`
//! [rad/s] (DESIGN.md channel table); the measured output is `torque_shaft` [N·m].

use physid_core::{ParamModel, Scalar};

/// Parameter names (with the offset), in order.
pub const PARAMS: [&str; 3] = ["K", "B", "tau0"];
/// Their units.
pub const UNITS: [&str; 3] = ["N·m/rad", "N·m·s/rad", "N·m"];
/// One line each (`B` here is the shaft's damping, not a bore).
pub const DESCRIPTIONS: [&str; 3] = [
    "coupling-shaft stiffness",
    "coupling-shaft damping",
    "torque offset (encoders' zero offset, transducer zero)",
];
/// Input channel names, in order.
pub const INPUTS: [&str; 4] = ["theta_dy", "theta_en", "omega_dy", "omega_en"];
/// Nominal K [N·m/rad] and B [N·m·s/rad]: the yellow spider of thesis Table 6.1, the default
/// of its app. B.1 (SPEC §2.1).
pub const NOMINAL: [f64; 2] = [1250.0, 0.95];

/// The measured output channel.
pub const OUTPUT: &str = "torque_shaft";

/// The shaft torque `K·Δθ + B·Δω` [N·m] (Eq. 3.4), generic so that the simulator and the
/// estimators share it.
pub fn torque<T: Scalar>(k: T, b: T, delta_theta: f64, delta_omega: f64) -> T {
    k * delta_theta + b * delta_omega
}

/// The shaft model: parameters `K`, `B` and, with an offset, `tau0`.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Shaft {
    params: Vec<String>,
    inputs: Vec<String>,
}

impl Shaft {
    /// The model of Eq. 6.1; with `offset` the torque-offset parameter `tau0` is appended.
    pub fn new(offset: bool) -> Self {
        let names: &[&str] = if offset {
            &["K", "B", "tau0"]
        } else {
            &["K", "B"]
        };
        Self {
            params: names.iter().map(|s| s.to_string()).collect(),
            inputs: INPUTS.iter().map(|s| s.to_string()).collect(),
        }
    }

    /// Whether the torque-offset parameter is estimated.
    pub fn has_offset(&self) -> bool {
        self.params.len() == 3
    }

    /// The regressor `φ = [Δθ, Δω(, 1)]` of Eq. 6.1 from the four input channels, written into
    /// `phi` (length 2 or 3, as the model's parameters) — the linear estimators' form.
    ///
    /// # Panics
    /// If `inputs` or `phi` do not have the model's lengths (the caller's invariant).
    pub fn regressor(&self, inputs: &[f64], phi: &mut [f64]) {
        assert_eq!(inputs.len(), INPUTS.len(), "shaft inputs");
        assert_eq!(phi.len(), self.params.len(), "shaft regressor length");
        phi[0] = inputs[0] - inputs[1];
        phi[1] = inputs[2] - inputs[3];
        if let Some(c) = phi.get_mut(2) {
            *c = 1.0;
        }
    }
}

impl ParamModel for Shaft {
    fn param_names(&self) -> &[String] {
        &self.params
    }

    fn input_names(&self) -> &[String] {
        &self.inputs
    }

    fn eval<T: Scalar>(&self, u: &[f64], p: &[T]) -> T {
        let tau = torque(p[0], p[1], u[0] - u[1], u[2] - u[3]);
        match p.get(2) {
            Some(&tau0) => tau + tau0,
            None => tau,
        }
    }
}
