//! The motored single-cylinder engine (SPEC §2.2–2.5): filling and emptying of three control
//! volumes — intake manifold, cylinder, exhaust — through the throttle, the valves and the
//! exhaust orifice, in either direction; Woschni heat transfer; NASA-polynomial air; slider-
//! crank volume; indicated, reciprocating and friction torque.
//!
//! For each volume (Eq. 3.20–3.27), with `h_up` the enthalpy of the gas flowing in:
//!
//! ```text
//! dm/dt       = Σ ṁ_in − Σ ṁ_out
//! m·c_v·dT/dt = −Q̇_w − p·dV/dt + Σ ṁ_in·(h_up − u) − Σ ṁ_out·R·T
//! p           = m·R·T/V
//! ```
//!
//! Two more states count the mass exchanged with the ambient (in through the throttle, out
//! through the exhaust orifice) so that mass conservation is checkable to round-off.
//!
//! Motored unless `engine.burn_q` is set (every thesis experiment is motored): then a Wiebe
//! burn ([`Wiebe`]) releases that much heat per cycle into the cylinder's energy equation, the
//! term `+Q̇_comb` of `m·c_v·dT/dt` — fired scenarios for combustion analysis. [`Combustion`] is
//! the seam.
//!
//! Here: the engine and its outputs. `orifice.rs`: the compressible flow between the volumes;
//! `geometry.rs`: the valve, throttle and cam areas and lifts; `stability.rs`: the network's
//! largest eigenvalue; `jacobian.rs`: the gas equations' Jacobian for the Rosenbrock step;
//! `combustion.rs`: the burn.

use crate::numeric::{powi, wrap720};
use crate::params::{AmbientParams, EngineParams};
use physid_models::air;
use physid_models::friction::{self, Design, Settings, SpeedForm};
use physid_models::kinematics::Crank;
use std::f64::consts::PI;

mod combustion;
mod geometry;
mod jacobian;
mod orifice;
mod stability;

pub use combustion::*;
pub use geometry::*;
pub use jacobian::*;
pub use orifice::*;
pub use stability::*;

/// Index of the volumes in the state.
pub const INT: usize = 0;
/// Cylinder.
pub const CYL: usize = 1;
/// Exhaust.
pub const EXH: usize = 2;

/// Gas state: masses `[m_int, m_cyl, m_exh]` [kg], temperatures `[T_int, T_cyl, T_exh]` [K],
/// cumulative mass in from and out to the ambient [kg].
pub type GasState = [f64; 8];

/// The torques at one instant (SPEC §2.3), and what the driveline needs to solve for α.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct EngineTorque {
    /// Indicated (gas) torque `(p_cyl − p_crank)·A_p·s'` [N·m].
    pub indicated: f64,
    /// The velocity part of the reciprocating torque `M_rec·s'·s''·ω²` [N·m].
    pub rec_velocity: f64,
    /// The added inertia `M_rec·s'²` [kg·m²] (its torque `M_rec·s'²·α` is solved, not iterated).
    pub rec_inertia: f64,
    /// Friction torque (mechanical fmep, without pumping) [N·m], opposing rotation.
    pub friction: f64,
}

/// The slider-crank at one angle, computed once per evaluation and shared by the gas dynamics
/// and the torques.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CrankPoint {
    /// Crank angle θ [rad].
    pub theta: f64,
    /// Piston displacement from TDC s(θ) [m].
    pub s: f64,
    /// ds/dθ [m/rad].
    pub ds: f64,
    /// d²s/dθ² [m/rad²].
    pub dds: f64,
}

/// Instantaneous engine quantities a step reports.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct EngineOutputs {
    /// Pressures `[p_int, p_cyl, p_exh]` [Pa].
    pub p: [f64; 3],
    /// Cylinder volume [m³].
    pub v_cyl: f64,
    /// Mass flows [kg/s]: throttle (ambient → int), intake valve (int → cyl), exhaust valve
    /// (cyl → exh), orifice (exh → ambient).
    pub flows: [f64; 4],
    /// Wall heat flow out of the cylinder [W].
    pub q_wall: f64,
    /// Effective flow areas `C_d·A` [m²] of the same four restrictions.
    pub areas: [f64; 4],
    /// Ratios of specific heats `γ = c_p/c_v` of the three volumes' gas.
    pub gamma: [f64; 3],
    /// The cylinder's `d(p·V)/dt = R·(ṁ·T + m·dT/dt)` [W] (`p·V = m·R·T`, Eq. 3.20–3.27):
    /// the slope a dense output between steps interpolates `p·V` with.
    pub pv_rate: f64,
}

/// What the gas network's Jacobian ([`Engine::network_jacobian`]) needs beyond the outputs,
/// from the same evaluation.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct GasLinearisation {
    /// The four flows' slopes `[∂ṁ/∂p_from, ∂ṁ/∂p_to]` [kg/(s·Pa)] ([`flow_and_slopes`]).
    pub flow_slopes: [[f64; 2]; 4],
    /// Specific enthalpies [J/kg] of the three volumes' gas.
    pub enthalpy: [f64; 3],
    /// Specific heats at constant volume [J/(kg·K)].
    pub cv: [f64; 3],
}

/// The engine with its derived constants.
#[derive(Debug, Clone)]
pub struct Engine {
    /// Parameters.
    pub p: EngineParams,
    /// Ambient.
    pub amb: AmbientParams,
    crank: Crank<f64>,
    area_p: f64,
    v_clear: f64,
    stroke: f64,
    orifice_area: f64,
    h_amb: f64,
    /// The ambient as a restriction's upstream gas.
    amb_gas: OrificeGas,
    woschni_k: f64,
    settings: Settings,
    design: Design<f64>,
    iv: ValveGeometry,
    ev: ValveGeometry,
    iv_cam: Cam,
    ev_cam: Cam,
    /// Ψ's slope in the linear band at γ = 1.4, `Ψ(1 − band)/band` (the stiffness estimate's).
    band_slope: f64,
    /// The friction model's speed form at the oil temperature [K] it is for (s_μ depends on
    /// the oil temperature alone).
    friction_form: (f64, SpeedForm),
    /// Constants of the geometry: the piston pin's height at TDC (the crank's), the clearance
    /// volume's height `V_c/A_p` [m], the manifolds' inverse volumes [1/m³].
    tdc_height: f64,
    clearance_height: f64,
    inv_v_int: f64,
    inv_v_exh: f64,
}

impl Engine {
    /// The engine for these parameters.
    pub fn new(p: &EngineParams, amb: &AmbientParams) -> Self {
        let crank = Crank {
            r: p.crank_radius,
            l: p.rod,
            delta: p.pin_offset,
            bore: p.bore,
            kappa: p.kappa,
        };
        let (_, settings) = friction::thesis_preset();
        // The friction model on this engine's geometry (mm) with the thesis preset's oil and
        // valvetrain.
        let (mut design, _) = friction::thesis_preset();
        design.b = p.bore * 1e3;
        design.s = crank.stroke() * 1e3;
        design.r = p.crank_radius * 1e3;
        design.kappa = p.kappa;
        design.lv = p.lift_max * 1e3;
        design.di = p.iv_d * 1e3;
        design.de = p.ev_d * 1e3;
        Self {
            p: p.clone(),
            amb: amb.clone(),
            area_p: crank.piston_area(),
            v_clear: crank.clearance_volume(),
            stroke: crank.stroke(),
            crank,
            orifice_area: PI * p.exh_orifice * p.exh_orifice / 4.0,
            h_amb: air::enthalpy(amb.t),
            amb_gas: OrificeGas::from_gamma(amb.p, amb.t, air::gamma(amb.t)),
            woschni_k: 3.26 * p.bore.powf(-0.2),
            settings,
            design,
            iv: ValveGeometry::new(p.iv_d, p.iv_di, p.seat_angle),
            ev: ValveGeometry::new(p.ev_d, p.ev_di, p.seat_angle),
            iv_cam: Cam::new(p.ivo, p.ivc, p.lift_max, p.lift_exponent as u32),
            ev_cam: Cam::new(p.evo, p.evc, p.lift_max, p.lift_exponent as u32),
            band_slope: psi(1.0 - LINEAR_BAND, 1.4) / LINEAR_BAND,
            friction_form: (
                p.t_oil,
                SpeedForm::new(
                    &design,
                    &settings,
                    friction::s_mu(&settings, p.t_oil - 273.15),
                ),
            ),
            tdc_height: crank.tdc_height(),
            clearance_height: crank.clearance_volume() / crank.piston_area(),
            inv_v_int: 1.0 / p.v_int,
            inv_v_exh: 1.0 / p.v_exh,
        }
    }

    /// Set the oil temperature [K] (a live parameter: a fault or a warm-up changes it).
    pub fn set_oil_temperature(&mut self, t_oil: f64) {
        self.p.t_oil = t_oil;
        if self.friction_form.0 != t_oil {
            self.friction_form = (t_oil, self.friction_form_at(t_oil));
        }
    }

    /// The mean-value friction model of this engine (SPEC §2.5): its geometry in mm with the
    /// thesis preset's oil, valvetrain and counts.
    pub fn friction_model(&self) -> (Design<f64>, Settings) {
        (self.design, self.settings)
    }

    /// The slider-crank.
    pub fn crank(&self) -> &Crank<f64> {
        &self.crank
    }

    /// Displacement volume [m³].
    pub fn displacement(&self) -> f64 {
        self.area_p * self.stroke
    }

    /// Cylinder volume at θ [m³].
    pub fn volume(&self, theta: f64) -> f64 {
        self.v_clear + self.area_p * self.crank.motion(theta).0
    }

    /// Cylinder volume [m³] at a crank point.
    pub fn volume_at(&self, k: &CrankPoint) -> f64 {
        self.v_clear + self.area_p * k.s
    }

    /// All volumes at ambient pressure and temperature, the cylinder at angle θ.
    pub fn ambient_state(&self, theta: f64) -> GasState {
        let r = air::gas_constant();
        let (p, t) = (self.amb.p, self.amb.t);
        let m = |v: f64| p * v / (r * t);
        [
            m(self.p.v_int),
            m(self.volume(theta)),
            m(self.p.v_exh),
            t,
            t,
            t,
            0.0,
            0.0,
        ]
    }

    /// The friction model's speed form at oil temperature `t_oil` [K].
    fn friction_form_at(&self, t_oil: f64) -> SpeedForm {
        let smu = friction::s_mu(&self.settings, t_oil - 273.15);
        SpeedForm::new(&self.design, &self.settings, smu)
    }

    /// Friction torque magnitude [N·m] at speed ω [rad/s] and manifold pressure [Pa]: the
    /// mean-value model's mechanical fmep (no pumping — the gas exchange is simulated), in its
    /// speed form, scaled by `friction_scale`; speeds below 50 rpm use 50 rpm's value (the
    /// correlations have `1 + 500/N` terms).
    pub fn friction_torque(&self, omega: f64, p_int: f64) -> f64 {
        let n_rpm = (omega.abs() * (30.0 / PI)).max(50.0);
        // The form for the oil temperature in force, unless the field was changed behind it.
        let (t_oil, form) = self.friction_form;
        let f = if t_oil == self.p.t_oil {
            form.mechanical(n_rpm, p_int / self.amb.p)
        } else {
            self.friction_form_at(self.p.t_oil)
                .mechanical(n_rpm, p_int / self.amb.p)
        };
        self.p.friction_scale * friction::tau_nm(f, &self.design)
    }

    /// The slider-crank at θ [rad].
    pub fn crank_point(&self, theta: f64) -> CrankPoint {
        self.crank_point_sin_cos(theta, theta.sin_cos())
    }

    /// The slider-crank at θ [rad] given `(sin θ, cos θ)`.
    pub fn crank_point_sin_cos(&self, theta: f64, sc: (f64, f64)) -> CrankPoint {
        let (s, ds, dds) = self.crank.motion_from(self.tdc_height, sc);
        CrankPoint { theta, s, ds, dds }
    }

    /// Torques at θ, ω with cylinder pressure `p_cyl` and the friction magnitude `fric`
    /// (evaluated once per step by the caller): friction opposes rotation, smoothed through
    /// zero speed over ±0.5 rad/s.
    pub fn torque(&self, theta: f64, omega: f64, p_cyl: f64, fric: f64) -> EngineTorque {
        self.torque_at(&self.crank_point(theta), omega, p_cyl, fric)
    }

    /// [`torque`](Self::torque) at a computed [`CrankPoint`].
    pub fn torque_at(&self, k: &CrankPoint, omega: f64, p_cyl: f64, fric: f64) -> EngineTorque {
        let (ds, dds) = (k.ds, k.dds);
        let m = self.p.m_rec;
        EngineTorque {
            indicated: (p_cyl - self.amb.p) * self.area_p * ds,
            rec_velocity: m * ds * dds * omega * omega,
            rec_inertia: m * ds * ds,
            friction: fric * smooth_sign(omega / 0.5),
        }
    }

    /// Effective throttle flow area `C_d·A_th` [m²] at an opening [deg] (constant over a step:
    /// the caller evaluates it once).
    pub fn throttle_cd_area(&self, throttle_deg: f64) -> f64 {
        let e = &self.p;
        e.cd_throttle
            * throttle_area(
                throttle_deg,
                e.throttle_d,
                e.throttle_shaft,
                e.throttle_closed,
                e.throttle_leak,
            )
    }

    /// Time derivative of the gas state at crank angle θ [rad], speed ω [rad/s], effective
    /// throttle area [m²] ([`throttle_cd_area`](Self::throttle_cd_area)); also the pressures
    /// and flows.
    pub fn gas_derivatives(
        &self,
        theta: f64,
        omega: f64,
        a_th: f64,
        x: &GasState,
        comb: &impl Combustion,
    ) -> (GasState, EngineOutputs) {
        let (d, out, _) = self.gas_derivatives_at(&self.crank_point(theta), omega, a_th, x, comb);
        (d, out)
    }

    /// [`gas_derivatives`](Self::gas_derivatives) at a computed [`CrankPoint`], with the
    /// [`GasLinearisation`] of the same evaluation (dropped by the compiler where unused).
    #[inline(always)]
    pub fn gas_derivatives_at(
        &self,
        k: &CrankPoint,
        omega: f64,
        a_th: f64,
        x: &GasState,
        comb: &impl Combustion,
    ) -> (GasState, EngineOutputs, GasLinearisation) {
        let e = &self.p;
        let r = air::gas_constant();
        let v_cyl = self.volume_at(k);
        let dv_cyl = self.area_p * k.ds * omega;
        let inv_v = [self.inv_v_int, 1.0 / v_cyl, self.inv_v_exh];
        let t = [x[3], x[4], x[5]];
        let p = per_volume(|i| x[i] * r * t[i] * inv_v[i]);
        // Each volume's c_p and h once: c_v = c_p − R, u = h − R·T, γ = c_p/c_v.
        let ch = per_volume(|i| air::cp_and_enthalpy(t[i]));
        let (cp, h) = (per_volume(|i| ch[i].0), per_volume(|i| ch[i].1));
        let cv = per_volume(|i| cp[i] - r);
        let u = [h[0] - r * t[0], h[1] - r * t[1], h[2] - r * t[2]];
        let sqrt_rt = per_volume(|i| (r * t[i]).sqrt());
        let gas = per_volume(|i| OrificeGas::new(p[i], sqrt_rt[i], cp[i]));
        let deg = wrap720(k.theta.to_degrees());
        let l_in = self.iv_cam.lift(deg);
        let l_ex = self.ev_cam.lift(deg);
        let a_in = e.cd_valve * self.iv.area(l_in);
        let a_ex = e.cd_valve * self.ev.area(l_ex);
        let a_or = e.cd_exh * self.orifice_area;
        let amb = &self.amb_gas;
        // Flows (positive in the direction ambient → int → cyl → exh → ambient) and the
        // enthalpy of the gas each carries (the upstream side's).
        let (f_th, s_th) = flow_and_slopes(a_th, [amb, &gas[INT]]);
        let (f_iv, s_iv) = flow_and_slopes(a_in, [&gas[INT], &gas[CYL]]);
        let (f_ev, s_ev) = flow_and_slopes(a_ex, [&gas[CYL], &gas[EXH]]);
        let (f_or, s_or) = flow_and_slopes(a_or, [&gas[EXH], amb]);
        let up = |f: f64, h1: f64, h2: f64| if f >= 0.0 { h1 } else { h2 };
        let h_th = up(f_th, self.h_amb, h[INT]);
        let h_iv = up(f_iv, h[INT], h[CYL]);
        let h_ev = up(f_ev, h[CYL], h[EXH]);
        let h_or = up(f_or, h[EXH], self.h_amb);
        // Woschni (Eq. 3.10–3.12), motored (C2 = 0); p in kPa.
        let q_wall = if e.heat_transfer != 0.0 {
            let gas_exchange = l_in > 0.0 || l_ex > 0.0;
            let c1 = if gas_exchange {
                e.woschni_c1_gas
            } else {
                e.woschni_c1_closed
            };
            let w = c1 * self.stroke * omega.abs() * (1.0 / PI);
            // 3.26·b^−0.2·p^0.8·T^−0.55·w^0.8 with p in kPa. With p = ρ·R·T this is
            // 3.26·b^−0.2·(ρ·R·w)^0.8·T^0.25: one logarithm and one exponential, T^¼ as
            // √(√(R·T)/√R).
            let hc = if w > 0.0 {
                let rho_r_w = x[1] * r * inv_v[CYL] * 1e-3 * w;
                let t_quarter = (sqrt_rt[CYL] * (1.0 / r.sqrt())).sqrt();
                self.woschni_k * (0.8 * rho_r_w.ln()).exp() * t_quarter
            } else {
                0.0
            };
            let area = PI * e.bore * (e.bore / 2.0 + self.clearance_height + k.s);
            hc * area * (t[CYL] - e.t_wall)
        } else {
            0.0
        };
        let q_comb = comb.heat_release(deg, omega, p[CYL], t[CYL]);
        // Contribution of a flow `f` (positive into volume `i`) whose upstream gas has enthalpy
        // `h_up`: in, `f·(h_up − u_i)`; out (f < 0), the volume's own gas, `f·R·T_i`.
        let term = |i: usize, f: f64, h_up: f64| -> f64 {
            if f >= 0.0 {
                f * (h_up - u[i])
            } else {
                f * r * t[i]
            }
        };
        let e_int = term(INT, f_th, h_th) + term(INT, -f_iv, h_iv);
        let e_cyl = term(CYL, f_iv, h_iv) + term(CYL, -f_ev, h_ev);
        let e_exh = term(EXH, f_ev, h_ev) + term(EXH, -f_or, h_or);
        let dm = [f_th - f_iv, f_iv - f_ev, f_ev - f_or];
        let dt = [
            e_int / (x[0] * cv[0]),
            (e_cyl - q_wall + q_comb - p[CYL] * dv_cyl) / (x[1] * cv[1]),
            e_exh / (x[2] * cv[2]),
        ];
        (
            [dm[0], dm[1], dm[2], dt[0], dt[1], dt[2], f_th, f_or],
            EngineOutputs {
                p,
                v_cyl,
                flows: [f_th, f_iv, f_ev, f_or],
                q_wall,
                areas: [a_th, a_in, a_ex, a_or],
                gamma: [cp[0] / cv[0], cp[1] / cv[1], cp[2] / cv[2]],
                pv_rate: r * (dm[CYL] * t[CYL] + x[CYL] * dt[CYL]),
            },
            GasLinearisation {
                flow_slopes: [s_th, s_iv, s_ev, s_or],
                enthalpy: h,
                cv,
            },
        )
    }

    /// The gas system's fastest rate [1/s] at this state: the largest eigenvalue of the
    /// linearised pressure network. In the linear band a restriction is a conductance
    /// `g = C_d·A·S/√(R·T_up)` (`S` the band's slope, the largest slope of Ψ), and a volume's
    /// pressure moves as `dp_i/dt = γ·R·T_i/V_i · Σ ṁ_in`, so `dp/dt = −D·L·p` with `D =
    /// diag(γ·R·T_i/V_i)` and `L` the network's Laplacian (restrictions to the ambient on the
    /// diagonal only). `D·L` has the eigenvalues of the symmetric `D^½·L·D^½`; its largest is
    /// computed from above ([`largest_eigenvalue_tridiag3`]). `out` are the outputs of
    /// [`gas_derivatives`](Self::gas_derivatives) at the state `x`. The solver sub-steps when
    /// `rate·dt` would leave RK4's stability interval (2.78 on the real axis); it needs the rate
    /// only above `enough` [1/s], so the search stops at the first upper bound at or below it
    /// (pass 0 for the eigenvalue itself).
    pub fn stiffness(&self, x: &GasState, out: &EngineOutputs, enough: f64) -> f64 {
        let r = air::gas_constant();
        let v = [self.p.v_int, out.v_cyl, self.p.v_exh];
        let t = [x[3], x[4], x[5]];
        let [g_th, g_iv, g_ev, g_or] = self.conductances(x, out);
        let d = [0, 1, 2].map(|i| out.gamma[i] * r * t[i] / v[i]);
        // D^½·L·D^½ for the chain int — cyl — exh: tridiagonal.
        largest_eigenvalue_tridiag3(
            [
                d[0] * (g_th + g_iv),
                d[1] * (g_iv + g_ev),
                d[2] * (g_ev + g_or),
            ],
            [-(d[0] * d[1]).sqrt() * g_iv, -(d[1] * d[2]).sqrt() * g_ev],
            enough,
        )
    }

    /// The four restrictions' conductances `∂ṁ/∂Δp` [kg/(s·Pa)] at their steepest (the linear
    /// band's slope `S`): `g = C_d·A·S/√(R·T_up)`, the upstream gas's temperature setting it.
    /// `out` are the outputs of [`gas_derivatives`](Self::gas_derivatives) at the state `x`.
    fn conductances(&self, x: &GasState, out: &EngineOutputs) -> [f64; 4] {
        let slope = self.band_slope;
        let r = air::gas_constant();
        let t = [x[3], x[4], x[5]];
        let p = out.p;
        let [a_throttle, a_in, a_ex, a_or] = out.areas;
        let g = |cd_a: f64, p1: f64, t1: f64, p2: f64, t2: f64| {
            let t_up = if p1 >= p2 { t1 } else { t2 };
            cd_a * slope / (r * t_up).sqrt()
        };
        let (amb_p, amb_t) = (self.amb.p, self.amb.t);
        [
            g(a_throttle, amb_p, amb_t, p[INT], t[INT]),
            g(a_in, p[INT], t[INT], p[CYL], t[CYL]),
            g(a_ex, p[CYL], t[CYL], p[EXH], t[EXH]),
            g(a_or, p[EXH], t[EXH], amb_p, amb_t),
        ]
    }

    /// Total internal energy of the gas in the three volumes [J] (for conservation checks).
    pub fn internal_energy(&self, x: &GasState) -> f64 {
        (0..3).map(|i| x[i] * air::internal_energy(x[3 + i])).sum()
    }

    /// Enthalpy of ambient air [J/kg].
    pub fn ambient_enthalpy(&self) -> f64 {
        self.h_amb
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use physid_models::friction::OperatingPoint;

    #[test]
    fn band_edge_equals_the_subsonic_form() {
        // Ψ is continuous at the band's edge: the series form equals the isentropic formula.
        for gamma in [1.25, 1.3, 1.35, 1.4, 1.5, 5.0 / 3.0] {
            let pe: f64 = 1.0 - LINEAR_BAND;
            let a = pe.powf(1.0 / gamma);
            let sub = a * (2.0 * gamma / (gamma - 1.0) * (1.0 - pe / a)).sqrt();
            let edge = psi(pe, gamma);
            assert!((edge - sub).abs() < 1e-12 * sub, "{gamma}: {edge} vs {sub}");
            // Linear inside the band.
            assert!((psi(0.99, gamma) - 0.5 * edge).abs() < 1e-15);
        }
    }

    #[test]
    fn largest_eigenvalue_from_above() {
        // Against nalgebra's symmetric eigenvalue solver: never below, within 1e-3 above.
        let cases = [
            ([2.0, 2.0, 2.0], [-1.0, -1.0]),     // 2 − √2, 2, 2 + √2
            ([1.0, 5.0, 3.0], [0.0, 0.0]),       // decoupled
            ([1.0, 400.0, 2.0], [-15.0, -20.0]), // a small cylinder between two manifolds
            ([3e7, 2e8, 9e7], [-4e7, -1.2e8]),
            ([0.0, 0.0, 0.0], [0.0, 0.0]),
        ];
        for (a, b) in cases {
            let m = nalgebra::Matrix3::new(
                a[0], b[0], 0.0, //
                b[0], a[1], b[1], //
                0.0, b[1], a[2],
            );
            let exact = m.symmetric_eigenvalues().max();
            let l = largest_eigenvalue_tridiag3(a, b, 0.0);
            let tol = 1e-12 * exact.abs().max(1.0);
            // Asked for the rate only above twice the eigenvalue, it stops at an upper bound at
            // or below that level.
            let early = largest_eigenvalue_tridiag3(a, b, 2.0 * exact);
            assert!(
                early >= exact - tol && early <= 2.0 * exact + tol,
                "{a:?} {b:?}: {early} vs {exact}"
            );
            assert!(
                l >= exact - tol && l <= exact * (1.0 + 1e-3) + tol,
                "{a:?} {b:?}: {l} vs {exact}"
            );
        }
    }

    #[test]
    fn friction_follows_the_oil_temperature() {
        // Against the mean-value model's physical form evaluated directly at each oil
        // temperature: through set_oil_temperature, and with the field changed behind the
        // cached speed form.
        let p = crate::params::CellParams::default();
        let mut e = Engine::new(&p.engine, &p.ambient);
        let (omega, p_int) = (100.0, 8e4);
        for t_oil in [300.0, 340.0, 363.15, 300.0] {
            let (design, settings) = e.friction_model();
            let op = OperatingPoint {
                n_rpm: omega * 30.0 / PI,
                p_int_kpa: p_int / 1e3,
                p_atm_kpa: p.ambient.p / 1e3,
                t_oil_c: t_oil - 273.15,
            };
            let f = friction::fmep(&design, &settings, &op).mechanical();
            let want = p.engine.friction_scale * friction::tau_nm(f, &design);
            e.set_oil_temperature(t_oil);
            assert!(
                (e.friction_torque(omega, p_int) - want).abs() <= 1e-12 * want,
                "{t_oil}"
            );
            let mut behind = Engine::new(&p.engine, &p.ambient);
            behind.p.t_oil = t_oil;
            assert!((behind.friction_torque(omega, p_int) - want).abs() <= 1e-12 * want);
        }
    }

    #[test]
    fn smooth_sign_is_tanh() {
        for x in [
            -1e3, -22.0, -21.9, -3.0, -1e-3, 0.0, 0.5, 19.0, 22.0, 22.1, 1e6,
        ] {
            assert_eq!(smooth_sign(x), x.tanh(), "{x}");
        }
    }

    #[test]
    fn woschni_heat_flow_is_the_correlation() {
        // Eq. 3.10–3.12 with powers, against the gas derivatives' rewritten form.
        let p = crate::params::CellParams::default();
        let e = Engine::new(&p.engine, &p.ambient);
        for (theta, omega, t_cyl) in [(0.3, 104.7, 650.0), (3.5, 300.0, 420.0), (6.0, 60.0, 900.0)]
        {
            let mut x = e.ambient_state(theta);
            x[4] = t_cyl;
            let (_, out) = e.gas_derivatives(theta, omega, 1e-5, &x, &Motored);
            let en = &p.engine;
            let k = e.crank_point(theta);
            let deg = wrap720(theta.to_degrees());
            let open = e.iv_cam.lift(deg) > 0.0 || e.ev_cam.lift(deg) > 0.0;
            let c1 = if open {
                en.woschni_c1_gas
            } else {
                en.woschni_c1_closed
            };
            let w = c1 * e.stroke * omega / PI;
            let hc = 3.26
                * en.bore.powf(-0.2)
                * (out.p[CYL] / 1e3).powf(0.8)
                * t_cyl.powf(-0.55)
                * w.powf(0.8);
            let area = PI * en.bore * en.bore / 2.0 + PI * en.bore * (e.v_clear / e.area_p + k.s);
            let q = hc * area * (t_cyl - en.t_wall);
            assert!(
                (out.q_wall - q).abs() < 1e-12 * q.abs(),
                "{} vs {q}",
                out.q_wall
            );
        }
    }

    #[test]
    fn band_edge_logarithm_is_the_library_value() {
        assert_eq!(LN_BAND_EDGE, (1.0 - LINEAR_BAND).ln());
    }

    #[test]
    fn valve_area_curtain_then_port() {
        // Eq. 3.33–3.35 by hand: d = 30 mm, di = 26 mm, 45° seat.
        let (d, di) = (0.030, 0.026);
        let c = std::f64::consts::FRAC_1_SQRT_2;
        let lv = di * di / (2.0 * c * (d + di));
        assert_eq!(valve_area(0.0, d, di, 45.0), 0.0);
        let curtain = |l: f64| PI * (d + di) / 2.0 * l * c;
        for l in [1e-4, 1e-3, 0.5 * lv, lv] {
            let a = valve_area(l, d, di, 45.0);
            assert!(
                (a - curtain(l)).abs() <= 1e-15 * curtain(l).max(1e-300),
                "{l}"
            );
        }
        let port = PI * di * di / 4.0;
        assert!((valve_area(2.0 * lv, d, di, 45.0) - port).abs() < 1e-18);
        // Continuous where the curtain reaches the port area.
        assert!((curtain(lv) - port).abs() < 1e-15 * port);
    }
}
