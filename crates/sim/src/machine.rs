//! The dynamometer's induction machine in the synchronous dq frame (SPEC §2.6, Eq. 3.51–3.57),
//! power-invariant Park transform, flux linkages as states:
//!
//! ```text
//! dλ_sd/dt = v_sd − R_s i_sd + ω_syn λ_sq      dλ_sq/dt = v_sq − R_s i_sq − ω_syn λ_sd
//! dλ_rd/dt =      − R_r i_rd + ω_slp λ_rq      dλ_rq/dt =      − R_r i_rq − ω_slp λ_rd
//! λ = M·i,  M = [[Ls,0,Lm,0],[0,Ls,0,Lm],[Lm,0,Lr,0],[0,Lm,0,Lr]]
//! τ = (p/2)·(λ_rq i_rd − λ_rd i_rq)
//! ```
//!
//! and, independently, its per-phase steady-state equivalent circuit — the drive engineer's
//! torque–speed curve, and the check of the dq model.

use crate::params::DynoParams;
use nalgebra::Complex;
use std::f64::consts::PI;

/// Flux linkages `[λ_sd, λ_sq, λ_rd, λ_rq]` [Wb].
pub type Flux = [f64; 4];

/// The machine's inductances and constants.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Machine {
    /// Stator resistance [Ω].
    pub rs: f64,
    /// Rotor resistance [Ω].
    pub rr: f64,
    /// Stator self inductance [H].
    pub ls: f64,
    /// Rotor self inductance [H].
    pub lr: f64,
    /// Magnetising inductance [H].
    pub lm: f64,
    /// Pole pairs.
    pub pole_pairs: f64,
    /// `1/(L_s·L_r − L_m²)`.
    inv_det: f64,
}

impl Machine {
    /// From the reactances at the nominal frequency.
    pub fn new(p: &DynoParams) -> Self {
        let w = 2.0 * PI * p.f_nom;
        let (ls, lr, lm) = ((p.xls + p.xm) / w, (p.xlr + p.xm) / w, p.xm / w);
        Self {
            rs: p.rs,
            rr: p.rr,
            ls,
            lr,
            lm,
            pole_pairs: p.poles / 2.0,
            inv_det: 1.0 / (ls * lr - lm * lm),
        }
    }

    /// Currents `[i_sd, i_sq, i_rd, i_rq]` from the fluxes (`M⁻¹λ`, by 2×2 blocks).
    pub fn currents(&self, l: &Flux) -> [f64; 4] {
        let (ls, lr, lm, inv_d) = (self.ls, self.lr, self.lm, self.inv_det);
        [
            (lr * l[0] - lm * l[2]) * inv_d,
            (lr * l[1] - lm * l[3]) * inv_d,
            (ls * l[2] - lm * l[0]) * inv_d,
            (ls * l[3] - lm * l[1]) * inv_d,
        ]
    }

    /// Electromagnetic torque [N·m] (Eq. 3.57).
    pub fn torque(&self, l: &Flux) -> f64 {
        let i = self.currents(l);
        self.pole_pairs * (l[3] * i[2] - l[2] * i[3])
    }

    /// Flux derivatives for stator voltages `v = [v_sd, v_sq]` [V], frame speed `w_syn` and
    /// rotor electrical speed `w_r` [rad/s].
    pub fn derivatives(&self, l: &Flux, v: [f64; 2], w_syn: f64, w_r: f64) -> Flux {
        let i = self.currents(l);
        let w_slp = w_syn - w_r;
        [
            v[0] - self.rs * i[0] + w_syn * l[1],
            v[1] - self.rs * i[1] - w_syn * l[0],
            -self.rr * i[2] + w_slp * l[3],
            -self.rr * i[3] - w_slp * l[2],
        ]
    }

    /// Rotor time constant `L_r/R_r` [s].
    pub fn rotor_time_constant(&self) -> f64 {
        self.lr / self.rr
    }

    /// The steady state of the dq model at stator voltage amplitude `v_dq` (power-invariant,
    /// numerically the line-to-line rms), frequency `f` and slip `s`: fluxes from the linear
    /// equations with all derivatives zero (v along d).
    pub fn dq_steady_state(&self, v_dq: f64, f: f64, slip: f64) -> Flux {
        // Unknown currents; λ = M i; equations in currents:
        //  0 = v_sd − Rs i_sd + ω (Ls i_sq + Lm i_rq)
        //  0 = v_sq − Rs i_sq − ω (Ls i_sd + Lm i_rd)
        //  0 = −Rr i_rd + sω (Lm i_sq + Lr i_rq)
        //  0 = −Rr i_rq − sω (Lm i_sd + Lr i_rd)
        let w = 2.0 * PI * f;
        let ws = slip * w;
        let a = nalgebra::Matrix4::new(
            -self.rs,
            w * self.ls,
            0.0,
            w * self.lm,
            -w * self.ls,
            -self.rs,
            -w * self.lm,
            0.0,
            0.0,
            ws * self.lm,
            -self.rr,
            ws * self.lr,
            -ws * self.lm,
            0.0,
            -ws * self.lr,
            -self.rr,
        );
        let b = nalgebra::Vector4::new(-v_dq, 0.0, 0.0, 0.0);
        let i = a.lu().solve(&b).unwrap_or_else(nalgebra::Vector4::zeros);
        [
            self.ls * i[0] + self.lm * i[2],
            self.ls * i[1] + self.lm * i[3],
            self.lm * i[0] + self.lr * i[2],
            self.lm * i[1] + self.lr * i[3],
        ]
    }
}

/// A point of the steady-state torque–speed curve from the per-phase equivalent circuit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CircuitPoint {
    /// Slip.
    pub slip: f64,
    /// Shaft speed [rpm].
    pub speed_rpm: f64,
    /// Electromagnetic torque [N·m].
    pub torque_nm: f64,
    /// Stator current [A rms per phase].
    pub current_a_rms: f64,
    /// Power factor.
    pub power_factor: f64,
}

/// The per-phase equivalent circuit (star, phase voltage `V_LL/√3`) at slip `s`:
/// `Z = R_s + jX_ls + jX_m ∥ (R_r/s + jX_lr)`, `T = 3·|I_r|²·(R_r/s)/ω_sync,mech`, with the
/// reactances scaled from `f_nom` to `f`.
pub fn equivalent_circuit(p: &DynoParams, v_ll: f64, f: f64, slip: f64) -> CircuitPoint {
    let k = f / p.f_nom;
    let (xls, xlr, xm) = (p.xls * k, p.xlr * k, p.xm * k);
    let vph = v_ll / 3f64.sqrt();
    let j = Complex::new(0.0, 1.0);
    let zr = Complex::new(p.rr / slip, 0.0) + j * xlr;
    let zm = j * xm;
    let z = Complex::new(p.rs, 0.0) + j * xls + zm * zr / (zm + zr);
    let is = Complex::new(vph, 0.0) / z;
    let ir = is * zm / (zm + zr);
    let w_sync_mech = 2.0 * PI * f / (p.poles / 2.0);
    let torque = 3.0 * ir.norm_sqr() * (p.rr / slip) / w_sync_mech;
    CircuitPoint {
        slip,
        speed_rpm: (1.0 - slip) * 60.0 * f / (p.poles / 2.0),
        torque_nm: torque,
        current_a_rms: is.norm(),
        power_factor: (is.arg()).cos(),
    }
}
