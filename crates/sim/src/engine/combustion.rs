//! The heat a burn releases into the cylinder: the seam ([`Combustion`]), the motored engine
//! ([`Motored`]) and a Wiebe burn ([`Wiebe`]).

use crate::params::EngineParams;
use std::f64::consts::PI;

/// Heat released into the cylinder by combustion [W] at an angle and state — the seam for a
/// fired engine. The motored engine has none.
pub trait Combustion {
    /// Heat release rate [W] at the crank angle in the cycle [deg, 0 … 720 from firing TDC],
    /// the speed ω [rad/s], the cylinder's pressure [Pa] and temperature [K].
    fn heat_release(&self, theta_cycle_deg: f64, omega: f64, p_cyl: f64, t_cyl: f64) -> f64;

    /// `∂Q̇/∂θ` [W/rad] at the same point, the state (pressure, temperature) and speed held:
    /// the burn's movement with the crank angle, for the solver's θ-column
    /// ([`Engine::theta_column`](super::Engine::theta_column)).
    fn heat_release_slope(&self, theta_cycle_deg: f64, omega: f64) -> f64;
}

/// A Wiebe burn (Heywood 1988, Eq. 9.32): the fraction burned
/// `x_b(θ) = 1 − exp(−a·((θ − θ₀)/Δθ)^(m+1))` from `θ₀` on, so the heat release rate is
/// `Q̇ = Q·dx_b/dθ·ω` with `dx_b/dθ = a·(m+1)/Δθ·z^m·exp(−a·z^(m+1))`, `z = (θ − θ₀)/Δθ`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wiebe {
    /// Heat released per cycle [J].
    pub q: f64,
    /// Start [deg after firing TDC].
    pub start: f64,
    /// Duration [deg].
    pub duration: f64,
    /// Efficiency parameter `a`.
    pub a: f64,
    /// Shape parameter `m`.
    pub m: f64,
}

impl Wiebe {
    /// The burn of `p`'s `engine.burn_*` parameters.
    pub fn of(p: &EngineParams) -> Self {
        Self {
            q: p.burn_q,
            start: p.burn_start,
            duration: p.burn_duration,
            a: p.burn_a,
            m: p.burn_m,
        }
    }

    /// The fraction burned at `atdc` [deg after firing TDC, −360 … 360].
    pub fn burned(&self, atdc: f64) -> f64 {
        let z = ((atdc - self.start) / self.duration).max(0.0);
        -(-self.a * z.powf(self.m + 1.0)).exp_m1()
    }

    /// The burn's progress `z = (θ − θ₀)/Δθ` at the crank angle in the cycle [deg, 0 … 720
    /// from firing TDC], where heat is released (`None`: no burn, or not burning yet).
    fn burning(&self, theta_cycle_deg: f64) -> Option<f64> {
        if self.q == 0.0 {
            return None;
        }
        let atdc = if theta_cycle_deg >= 360.0 {
            theta_cycle_deg - 720.0
        } else {
            theta_cycle_deg
        };
        let z = (atdc - self.start) / self.duration;
        (z > 0.0).then_some(z)
    }
}

impl Combustion for Wiebe {
    fn heat_release(&self, theta_cycle_deg: f64, omega: f64, _: f64, _: f64) -> f64 {
        let Some(z) = self.burning(theta_cycle_deg) else {
            return 0.0;
        };
        let zm = z.powf(self.m);
        let dx_deg = self.a * (self.m + 1.0) / self.duration * zm * (-self.a * zm * z).exp();
        self.q * dx_deg * omega.to_degrees()
    }

    /// `Q·ω·d²x_b/dθ²` with `d²x_b/dθ² = a·(m+1)/Δθ²·e^(−a·z^(m+1))·(m·z^(m−1) −
    /// a·(m+1)·z^(2m))` per degree², times 180/π for per radian.
    fn heat_release_slope(&self, theta_cycle_deg: f64, omega: f64) -> f64 {
        let Some(z) = self.burning(theta_cycle_deg) else {
            return 0.0;
        };
        let (a, m) = (self.a, self.m);
        let zm1 = z.powf(m - 1.0);
        let zm = zm1 * z;
        let ddx_deg = a * (m + 1.0) / (self.duration * self.duration)
            * (-a * zm * z).exp()
            * (m * zm1 - a * (m + 1.0) * zm * zm);
        self.q * ddx_deg * omega.to_degrees() * (180.0 / PI)
    }
}

/// No combustion.
#[derive(Debug, Clone, Copy, Default)]
pub struct Motored;

impl Combustion for Motored {
    fn heat_release(&self, _: f64, _: f64, _: f64, _: f64) -> f64 {
        0.0
    }

    fn heat_release_slope(&self, _: f64, _: f64) -> f64 {
        0.0
    }
}
