//! The gas network's Jacobian for the Rosenbrock step: the pressures' network in factored
//! form `J = U·Vᵀ` (rank 3) and the crank angle's column `∂f/∂θ`, both built from the
//! balances of Eq. 3.20–3.27 per unit of each flow.

use super::orifice::per_volume;
use super::{
    Combustion, CrankPoint, Engine, EngineOutputs, GasLinearisation, GasState, CYL, EXH, INT,
};
use crate::numeric::wrap720;
use physid_models::air;
use std::f64::consts::PI;

/// The gas equations' Jacobian in factored form, `J = U·Vᵀ` ([`Engine::network_jacobian`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NetworkJacobian {
    /// `U`: each gas state's derivative per unit pressure of each volume [per Pa].
    pub u: [[f64; 3]; 8],
    /// `Vᵀ`: each volume's pressure per unit of its mass and its temperature, `[p/m, p/T]`.
    pub v: [[f64; 2]; 3],
    /// `Vᵀ`'s entry for the crank angle: the cylinder's pressure per radian at a fixed state,
    /// `∂p_cyl/∂θ` [Pa/rad] (0 without the θ-column).
    pub p_theta: f64,
    /// The rates' direct movement with the crank angle at a fixed state, beside the pressure's
    /// [per rad] ([`Engine::theta_column`]; 0 without it).
    pub theta: [f64; 8],
}

impl Engine {
    /// The gas equations' Jacobian through the pressure network, `J ≈ U·Vᵀ` (rank 3): the
    /// flows respond to the pressures by their slopes
    /// ([`flow_and_slopes`](super::flow_and_slopes): `δṁ = ∂ṁ/∂p_from·δp_from +
    /// ∂ṁ/∂p_to·δp_to`, the upstream temperature held); the pressures to
    /// the state through `p = m·R·T/V` (`∂p/∂m = p/m`, `∂p/∂T = p/T`, the cylinder's volume
    /// held); and the state's derivatives to the flows through the balances of Eq. 3.20–3.27
    /// ([`Balances`]). `U` is 8 × 3 (state × volume), `Vᵀ` has two entries per volume. Every
    /// column of `U` sums to zero over the masses and the exchange counters, as every flow
    /// conserves mass: a step built on it conserves mass exactly as the flows do. `out` and
    /// `lin` are from [`gas_derivatives_at`](Self::gas_derivatives_at) at the state `x`.
    /// Without the crank angle's column ([`theta_column`](Self::theta_column)).
    #[inline(always)]
    pub fn network_jacobian(
        &self,
        x: &GasState,
        out: &EngineOutputs,
        lin: &GasLinearisation,
    ) -> NetworkJacobian {
        self.jacobian_with(&Balances::new(x, lin), x, out, lin)
    }

    /// [`network_jacobian`](Self::network_jacobian) with the balances computed.
    #[inline(always)]
    fn jacobian_with(
        &self,
        b: &Balances,
        x: &GasState,
        out: &EngineOutputs,
        lin: &GasLinearisation,
    ) -> NetworkJacobian {
        let f = out.flows;
        // U = F·Q, flow by flow: the outer product of the rows a flow moves (F's column) and
        // the pressures that move it (Q's row).
        let mut u = [[0.0; 3]; 8];
        let mut outer = |rows: &[(usize, f64)], cols: &[(usize, f64)]| {
            for &(r, fr) in rows {
                for &(c, qc) in cols {
                    u[r][c] += fr * qc;
                }
            }
        };
        let [s_th, s_iv, s_ev, s_or] = lin.flow_slopes;
        // Throttle, ambient → int (its slope in the ambient pressure is not a state's).
        outer(&b.throttle(f[0], self.h_amb), &[(INT, s_th[1])]);
        // The valves, each from volume `a` to volume `b`: int → cyl, cyl → exh.
        outer(&b.valve(INT, CYL, f[1]), &[(INT, s_iv[0]), (CYL, s_iv[1])]);
        outer(&b.valve(CYL, EXH, f[2]), &[(CYL, s_ev[0]), (EXH, s_ev[1])]);
        // Exhaust orifice, exh → ambient.
        outer(&b.orifice(f[3], self.h_amb), &[(EXH, s_or[0])]);
        let p = out.p;
        NetworkJacobian {
            u,
            v: per_volume(|i| [p[i] / x[i], p[i] / x[3 + i]]),
            p_theta: 0.0,
            theta: [0.0; 8],
        }
    }

    /// [`network_jacobian`](Self::network_jacobian) with the crank angle's column: how the gas
    /// equations' rates move with θ at a fixed state, `∂f/∂θ` [per rad] — the moving piston
    /// and valves, the non-autonomous term a Rosenbrock step needs to keep its order where the
    /// gas is stiff (without it, the cylinder's pressure, tied to a manifold's through an open
    /// valve, follows a moving volume a step late: the error halves with the step instead of
    /// quartering). Through the cylinder's pressure `∂p/∂θ = −p·V′/V` (`V′ = A_p·s′`) it
    /// acts on the flows as `U`'s column does (`p_theta`, a third entry of `Vᵀ`); directly
    /// (`theta`), on the cylinder's temperature through the work `−p·dV/dt` (`∂/∂θ =
    /// −A_p·ω·(∂p/∂θ·s′ + p·s″)`), the wall heat (its area `π·b·s′` and `h_c ∝ V^−0.8`) and
    /// the burn ([`Combustion::heat_release_slope`]), and on the valves' flows through their
    /// areas (`∂ṁ/∂θ = ṁ·A′/A`, each flow's column of the balances). `k` is the crank point of
    /// `x`'s evaluation, `omega` its speed.
    pub fn theta_column(
        &self,
        k: &CrankPoint,
        omega: f64,
        x: &GasState,
        out: &EngineOutputs,
        lin: &GasLinearisation,
        comb: &impl Combustion,
    ) -> NetworkJacobian {
        let b = Balances::new(x, lin);
        let mut j = self.jacobian_with(&b, x, out, lin);
        let (p, v) = (out.p[CYL], out.v_cyl);
        let dv = self.area_p * k.ds;
        let p_theta = -p * dv / v;
        let inv_mcv = b.inv_mcv[CYL];
        let mut theta = [0.0; 8];
        // The work term, the wall heat and the burn, on the cylinder's temperature.
        let work = -self.area_p * omega * (p_theta * k.ds + p * k.dds);
        let wall = if out.q_wall != 0.0 {
            let b = self.p.bore;
            let area = PI * b * (b / 2.0 + self.clearance_height + k.s);
            out.q_wall * (PI * b * k.ds / area - 0.8 * dv / v)
        } else {
            0.0
        };
        let deg = wrap720(k.theta.to_degrees());
        let burn = comb.heat_release_slope(deg, omega);
        theta[3 + CYL] = (work - wall + burn) * inv_mcv;
        // The valves' areas, where they move: on the curtain (open, below the port's area).
        let cd = self.p.cd_valve;
        for (n, (cam, geometry), (from, to)) in [
            (1, (&self.iv_cam, &self.iv), (INT, CYL)),
            (2, (&self.ev_cam, &self.ev), (CYL, EXH)),
        ] {
            let area = out.areas[n];
            if area > 0.0 && area < cd * geometry.port_area() {
                let (lift, dlift_deg) = cam.lift_and_slope(deg);
                let darea = cd * geometry.area_slope(lift) * dlift_deg * (180.0 / PI);
                let dflow = out.flows[n] * darea / area;
                for (r, c) in b.valve(from, to, out.flows[n]) {
                    theta[r] += c * dflow;
                }
            }
        }
        j.p_theta = p_theta;
        j.theta = theta;
        j
    }
}

/// The balances of Eq. 3.20–3.27 per unit of each flow: the gas state's rates per kg/s of a
/// flow, as `(state index, rate)` — mass ±1; temperature `(h_up − u)/(m·c_v)` for gas coming
/// in, `−R·T/(m·c_v)` for gas leaving; the ambient exchange counters ±1. Each flow's column of
/// the Jacobian's `U` and of the crank angle's column.
struct Balances {
    t: [f64; 3],
    h: [f64; 3],
    u: [f64; 3],
    inv_mcv: [f64; 3],
}

impl Balances {
    #[inline(always)]
    fn new(x: &GasState, lin: &GasLinearisation) -> Self {
        let r = air::gas_constant();
        let t = [x[3], x[4], x[5]];
        let h = lin.enthalpy;
        Self {
            t,
            h,
            u: per_volume(|i| h[i] - r * t[i]),
            inv_mcv: per_volume(|i| 1.0 / (x[i] * lin.cv[i])),
        }
    }

    /// `∂(dT_i/dt)/∂ṁ` for a flow `q` entering volume `i` with sign `s` (+1: positive flow
    /// enters), whose upstream enthalpy is `h_up` when it enters.
    #[inline(always)]
    fn dt_dq(&self, i: usize, s: f64, q: f64, h_up: f64) -> f64 {
        if s * q >= 0.0 {
            s * (h_up - self.u[i]) * self.inv_mcv[i]
        } else {
            s * air::gas_constant() * self.t[i] * self.inv_mcv[i]
        }
    }

    /// The throttle's column (ambient → int, flow `q`).
    #[inline(always)]
    fn throttle(&self, q: f64, h_amb: f64) -> [(usize, f64); 3] {
        [
            (INT, 1.0),
            (3 + INT, self.dt_dq(INT, 1.0, q, h_amb)),
            (6, 1.0),
        ]
    }

    /// A valve's column, from volume `a` to volume `b` (flow `q`).
    #[inline(always)]
    fn valve(&self, a: usize, b: usize, q: f64) -> [(usize, f64); 4] {
        [
            (a, -1.0),
            (b, 1.0),
            (3 + a, self.dt_dq(a, -1.0, q, self.h[b])),
            (3 + b, self.dt_dq(b, 1.0, q, self.h[a])),
        ]
    }

    /// The exhaust orifice's column (exh → ambient, flow `q`).
    #[inline(always)]
    fn orifice(&self, q: f64, h_amb: f64) -> [(usize, f64); 3] {
        [
            (EXH, -1.0),
            (3 + EXH, self.dt_dq(EXH, -1.0, q, h_amb)),
            (7, 1.0),
        ]
    }
}
