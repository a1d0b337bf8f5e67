//! Indirect field-oriented control of the dynamometer (SPEC §2.6, Eq. 3.58–3.64, Fig. 3.13),
//! sampled once per solver step with the voltages held over it (a digital drive).
//!
//! ```text
//! rotor-flux observer  dλ̂_rd/dt = (L_m·i_sd − λ̂_rd)/τ_r,       τ_r = L_r/R_r
//! slip                 ω_slp = L_m·i_sq/(τ_r·λ̂_rd) (measured i_sq), ω_syn = ω_r + ω_slp
//!                      (the frame follows the rotor angle from the encoder plus the slip angle)
//! torque               τ = (p/2)·(L_m/L_r)·λ̂_rd·i_sq              (Eq. 3.61–3.62, with i_sd fixed)
//! speed PI → i_sq*,  flux PI → i_sd*,  current PIs → v_sd*, v_sq*
//! ```
//!
//! with the thesis's gains. Added, as a real drive has them (documented in SPEC §2.6): a
//! current limit on |i*| (the drive's rms output current, √3 times it in the power-invariant
//! dq frame), a voltage limit on |v*|, conditional-integration anti-windup on every PI, the
//! nominal rotor flux as the flux reference, and decoupling feed-forward on the current loops
//! (`−ω_syn·σL_s·i_sq` on d, `ω_syn·(σL_s·i_sd + (L_m/L_r)·λ̂_rd)` on q) without which the
//! q-axis integrator would have to build up the whole back-EMF. Torque mode takes a torque
//! demand instead of a speed demand.

use crate::machine::Machine;
use crate::numeric::expm1;
use crate::params::DynoParams;

/// A PI controller with output limits and conditional integration.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Pi {
    /// Proportional gain.
    pub kp: f64,
    /// Integral gain.
    pub ki: f64,
    /// Integrator state (in output units).
    pub integral: f64,
}

impl Pi {
    /// Output for error `e` over `dt`, clamped to `[lo, hi]`; the integrator only moves when
    /// that does not push further into a limit.
    #[inline]
    pub fn update(&mut self, e: f64, dt: f64, lo: f64, hi: f64) -> f64 {
        let candidate = self.integral + self.ki * e * dt;
        let u = self.kp * e + candidate;
        if (u > hi && e > 0.0) || (u < lo && e < 0.0) {
            limit(self.kp * e + self.integral, lo, hi)
        } else {
            self.integral = candidate;
            limit(u, lo, hi)
        }
    }
}

/// `u` within `[lo, hi]`; NaN when the limits are not numbers (a state that left the physical
/// domain: the run's check names it, where `f64::clamp` would panic).
#[inline]
fn limit(u: f64, lo: f64, hi: f64) -> f64 {
    if lo <= hi {
        u.clamp(lo, hi)
    } else {
        f64::NAN
    }
}

/// What the drive is asked for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Demand {
    /// Shaft speed [rad/s].
    Speed(f64),
    /// Torque [N·m].
    Torque(f64),
}

/// The drive's commands for one step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Command {
    /// Stator voltages `[v_sd, v_sq]` [V].
    pub v: [f64; 2],
    /// Slip speed ω_slp [rad/s]; the frame turns at `ω_r + ω_slp` with the rotor's angle
    /// (from the encoder), so it stays on the flux while the speed changes within a step.
    pub w_slp: f64,
    /// Current references `[i_sd*, i_sq*]` [A].
    pub i_ref: [f64; 2],
}

/// The field-oriented drive.
#[derive(Debug, Clone)]
pub struct Drive {
    machine: Machine,
    speed: Pi,
    flux: Pi,
    id: Pi,
    iq: Pi,
    /// Observed rotor flux λ̂_rd [Wb].
    pub flux_est: f64,
    /// Flux reference [Wb].
    pub flux_ref: f64,
    i_max: f64,
    v_max: f64,
    sigma_ls: f64,
    /// `1/τ_r = R_r/L_r` [1/s] and `L_m/L_r`, once.
    inv_tau_r: f64,
    lm_over_lr: f64,
}

/// The rotor flux at no load, nominal voltage and frequency [Wb]: `L_m·i_m` with the
/// magnetising current `V_ph/(X_ls + X_m)` (√3 of it in dq).
pub fn nominal_flux(p: &DynoParams, m: &Machine) -> f64 {
    let i_m = p.v_nom / 3f64.sqrt() / (p.xls + p.xm);
    m.lm * 3f64.sqrt() * i_m
}

impl Drive {
    /// A drive for the machine, magnetised at its flux reference.
    pub fn new(p: &DynoParams, machine: Machine) -> Self {
        let flux_ref = if p.flux_ref > 0.0 {
            p.flux_ref
        } else {
            nominal_flux(p, &machine)
        };
        let i_sd0 = flux_ref / machine.lm;
        Self {
            machine,
            speed: Pi {
                kp: p.speed_kp,
                ki: p.speed_ki,
                integral: 0.0,
            },
            flux: Pi {
                kp: p.flux_kp,
                ki: p.flux_ki,
                integral: i_sd0,
            },
            id: Pi {
                kp: p.current_kp,
                ki: p.current_ki,
                integral: machine.rs * i_sd0,
            },
            iq: Pi {
                kp: p.current_kp,
                ki: p.current_ki,
                integral: 0.0,
            },
            flux_est: flux_ref,
            flux_ref,
            i_max: 3f64.sqrt() * p.current_limit,
            v_max: p.voltage_limit * p.v_nom,
            sigma_ls: machine.ls - machine.lm * machine.lm / machine.lr,
            inv_tau_r: 1.0 / machine.rotor_time_constant(),
            lm_over_lr: machine.lm / machine.lr,
        }
    }

    /// Machine fluxes of the magnetised, unloaded machine (the initial condition that matches
    /// [`Drive::new`]).
    pub fn magnetised_flux(&self) -> [f64; 4] {
        let m = &self.machine;
        let i_sd = self.flux_ref / m.lm;
        [m.ls * i_sd, 0.0, m.lm * i_sd, 0.0]
    }

    /// Torque per unit i_sq at the observed flux, `(p/2)(L_m/L_r)·λ̂_rd` [N·m/A].
    pub fn torque_constant(&self) -> f64 {
        let m = &self.machine;
        m.pole_pairs * m.lm / m.lr * self.flux_est
    }

    /// One sample: measured shaft speed `w_m` [rad/s], stator currents `[i_sd, i_sq]` in the
    /// drive's frame, the demand, the step `dt`.
    pub fn update(&mut self, w_m: f64, i: [f64; 2], demand: Demand, dt: f64) -> Command {
        let m = self.machine;
        // Observer (exact discretisation of the first-order lag: 1 − e^(−dt/τ_r)).
        self.flux_est += (m.lm * i[0] - self.flux_est) * -expm1(-dt * self.inv_tau_r);
        let flux = self.flux_est.max(1e-3 * self.flux_ref);
        let i_sd_ref = self
            .flux
            .update(self.flux_ref - self.flux_est, dt, -self.i_max, self.i_max);
        let iq_max = (self.i_max * self.i_max - i_sd_ref * i_sd_ref)
            .max(0.0)
            .sqrt();
        let i_sq_ref = match demand {
            Demand::Speed(w_ref) => self.speed.update(w_ref - w_m, dt, -iq_max, iq_max),
            Demand::Torque(t) => (t / self.torque_constant().max(1e-9)).clamp(-iq_max, iq_max),
        };
        // Slip from the measured q current (the loops are fast; during current limiting the
        // command and the current differ, and the measured one keeps the frame on the flux).
        let w_slp = m.lm * i[1] * self.inv_tau_r / flux;
        let w_syn = m.pole_pairs * w_m + w_slp;
        // Current loops with decoupling feed-forward; the voltage vector limited.
        let ff_d = -w_syn * self.sigma_ls * i[1];
        let ff_q = w_syn * (self.sigma_ls * i[0] + self.lm_over_lr * flux);
        let vd = self
            .id
            .update(i_sd_ref - i[0], dt, -self.v_max - ff_d, self.v_max - ff_d)
            + ff_d;
        let vq = self
            .iq
            .update(i_sq_ref - i[1], dt, -self.v_max - ff_q, self.v_max - ff_q)
            + ff_q;
        // Scaled onto the limit circle only when outside it (the root only then).
        let mag2 = vd * vd + vq * vq;
        let k = if mag2 > self.v_max * self.v_max {
            self.v_max / mag2.sqrt()
        } else {
            1.0
        };
        Command {
            v: [vd * k, vq * k],
            w_slp,
            i_ref: [i_sd_ref, i_sq_ref],
        }
    }
}

/// Inverse Park (power-invariant): phase quantities `[a, b, c]` from `[d, q]` at the frame
/// angle θ given as `(sin θ, cos θ)`; the phases b and c at θ ∓ 2π/3 by the angle-addition
/// formulas (cos(2π/3) = −1/2, sin(2π/3) = √3/2).
pub fn inverse_park(dq: [f64; 2], (s, c): (f64, f64)) -> [f64; 3] {
    let k = (2.0f64 / 3.0).sqrt();
    let h = 3f64.sqrt() / 2.0;
    // (sin, cos) of θ − 2π/3 and θ + 2π/3.
    let (sb, cb) = (-0.5 * s - h * c, -0.5 * c + h * s);
    let (sc, cc) = (-0.5 * s + h * c, -0.5 * c - h * s);
    let phase = |sa: f64, ca: f64| k * (dq[0] * ca - dq[1] * sa);
    [phase(s, c), phase(sb, cb), phase(sc, cc)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn inverse_park_is_the_rotation_by_thirds() {
        // Against the definition with each phase's own cosine and sine.
        let k = (2.0f64 / 3.0).sqrt();
        for i in 0..100 {
            let theta = -7.0 + 0.37 * f64::from(i);
            let dq = [3.0 - 0.1 * f64::from(i), -1.5];
            let got = inverse_park(dq, theta.sin_cos());
            for (n, shift) in [0.0, 2.0 * PI / 3.0, -2.0 * PI / 3.0].iter().enumerate() {
                let a = theta - shift;
                let want = k * (dq[0] * a.cos() - dq[1] * a.sin());
                assert!((got[n] - want).abs() < 1e-14, "{theta} {n}");
            }
            // Balanced: the phases sum to zero.
            assert!(got.iter().sum::<f64>().abs() < 1e-14);
        }
    }
}
