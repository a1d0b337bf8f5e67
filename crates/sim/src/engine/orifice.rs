//! Compressible flow through an orifice (the valves and the throttle between the volumes):
//! the flow function ψ, each side's gas constants ([`OrificeGas`]) and the flow with its
//! slopes ([`flow_and_slopes`]).

use super::*;
use crate::numeric::expm1;

/// Below this pressure ratio deficit (1 − p_dn/p_up) the orifice flow is linearised in the
/// pressure difference: the isentropic form has an infinite slope at equal pressures, which
/// makes the equations stiff for no physical reason.
pub(super) const LINEAR_BAND: f64 = 0.02;
/// `ln(1 − LINEAR_BAND)` (a constant: the band's edge; tested against the library `ln`).
pub(super) const LN_BAND_EDGE: f64 = -0.020202707317519466;

/// Isentropic flow function Ψ(pr) (Eq. 3.16) for a gas of ratio of specific heats γ: choked
/// below the critical ratio `pr* = (2/(γ+1))^(γ/(γ−1))`, subsonic above, linear in `1 − pr` in
/// the last [`LINEAR_BAND`]. [`OrificeGas::psi`] with γ's two constants.
pub fn psi(pr: f64, gamma: f64) -> f64 {
    OrificeGas::from_gamma(0.0, 1.0, gamma).psi(pr)
}

/// A volume's gas as the orifice equation (Eq. 3.16) needs it when the flow leaves that volume,
/// computed once per volume per evaluation: the pressure, `1/√(R·T)`, `1/γ` and `2γ/(γ−1)`.
/// With `c_v = c_p − R`, `1/γ = c_v/c_p` and `2γ/(γ−1) = 2·c_p/R`: the flow function itself
/// divides nothing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrificeGas {
    /// Pressure [Pa].
    pub p: f64,
    inv_sqrt_rt: f64,
    inv_gamma: f64,
    /// `2γ/(γ−1)`.
    k: f64,
    /// Ψ's constants, where the gas's γ stays (the ambient's).
    fixed: Option<PsiConstants>,
}

/// The constants of Ψ for one γ: the critical ratio, the choked Ψ, Ψ at the linear band's edge.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct PsiConstants {
    crit: f64,
    choked: f64,
    band_edge: f64,
}

impl OrificeGas {
    /// Gas at pressure `p` [Pa] with `√(R·T)` [m/s] and `c_p` [J/(kg·K)] at its temperature
    /// (`1/γ = c_v/c_p`).
    pub fn new(p: f64, sqrt_rt: f64, cp: f64) -> Self {
        let r = air::gas_constant();
        Self {
            p,
            inv_sqrt_rt: 1.0 / sqrt_rt,
            inv_gamma: (cp - r) / cp,
            k: cp * (2.0 / r),
            fixed: None,
        }
    }

    /// Gas at pressure `p` [Pa], temperature `t` [K] with ratio of specific heats γ, which
    /// stays (a reservoir such as the ambient): the critical ratio, the choked Ψ and Ψ at the
    /// band's edge are computed here, once.
    pub fn from_gamma(p: f64, t: f64, gamma: f64) -> Self {
        let mut g = Self {
            p,
            inv_sqrt_rt: 1.0 / (air::gas_constant() * t).sqrt(),
            inv_gamma: 1.0 / gamma,
            k: 2.0 * gamma / (gamma - 1.0),
            fixed: None,
        };
        let ln_c = g.ln_two_over_gamma_plus_one();
        g.fixed = Some(PsiConstants {
            crit: (0.5 * g.k * ln_c).exp(),
            choked: g.psi_choked(ln_c),
            band_edge: g.band_edge(),
        });
        g
    }

    /// Ψ at the band's edge pe = 1 − band, with y = ln pe: pe^(1/γ) = e^(y/γ) and
    /// 1 − pe^((γ−1)/γ) = −expm1(y·(1 − 1/γ)), both of small arguments (no cancellation).
    pub(super) fn band_edge(&self) -> f64 {
        // `expm1`: its series where the argument is small (every γ > 1.01), the library's for a
        // gas whose state has left the physical domain (the run's check names it).
        let a = 1.0 + expm1(LN_BAND_EDGE * self.inv_gamma);
        a * (-self.k * expm1(LN_BAND_EDGE * (1.0 - self.inv_gamma))).sqrt()
    }

    /// `ln(2/(γ+1)) = ln(2·(1/γ)/(1 + 1/γ))`.
    pub(super) fn ln_two_over_gamma_plus_one(&self) -> f64 {
        (2.0 * self.inv_gamma / (1.0 + self.inv_gamma)).ln()
    }

    /// The choked Ψ from `ln(2/(γ+1))`: with `(γ+1)/(2(γ−1)) = (k/2)·(γ+1)/(2γ) = k·(1 + 1/γ)/4`.
    pub(super) fn psi_choked(&self, ln_c: f64) -> f64 {
        (0.25 * self.k * (1.0 + self.inv_gamma) * ln_c).exp() / self.inv_gamma.sqrt()
    }

    /// Ψ(pr) for this gas upstream (Eq. 3.16). Subsonic, with `a = pr^(1/γ) = e^(ln(pr)/γ)`,
    /// `Ψ² = 2γ/(γ−1)·(pr^(2/γ) − pr^((γ+1)/γ)) = 2γ/(γ−1)·a·(a − pr)`: one `ln`, one `exp`, one
    /// square root. Choked (`pr < pr*`), `Ψ = √γ·(2/(γ+1))^((γ+1)/(2(γ−1)))`. In the linear
    /// band, the band edge's value (by short series) times `(1 − pr)/band`.
    pub fn psi(&self, pr: f64) -> f64 {
        self.psi_and_slope(pr).0
    }

    /// `(Ψ(pr), dΨ/dpr)`: [`psi`](Self::psi) and its slope — subsonic, from `Ψ² = k·a·(a − pr)`
    /// and `da/dpr = a/(γ·pr)`, `dΨ/dpr = k·a·((2a − pr)/γ − pr)/(2·pr·Ψ)`; choked, 0; in the
    /// band, `−Ψ(1 − band)/band`.
    pub fn psi_and_slope(&self, pr: f64) -> (f64, f64) {
        let (inv_g, k) = (self.inv_gamma, self.k);
        // Choked below pr* = (2/(γ+1))^(γ/(γ−1)), i.e. ln pr ≤ (k/2)·ln(2/(γ+1)). The critical
        // ratio is below e^(−1/2) = 0.6065 for every γ > 1: above 0.61 the flow is subsonic
        // without computing it.
        let choked = match self.fixed {
            Some(c) => pr < c.crit,
            None => {
                pr <= 0.0 || (pr < 0.61 && pr.ln() <= 0.5 * k * self.ln_two_over_gamma_plus_one())
            }
        };
        if choked {
            let psi = match self.fixed {
                Some(c) => c.choked,
                None => self.psi_choked(self.ln_two_over_gamma_plus_one()),
            };
            (psi, 0.0)
        } else if pr < 1.0 - LINEAR_BAND {
            let a = (pr.ln() * inv_g).exp();
            let psi = (k * a * (a - pr)).max(0.0).sqrt();
            let slope = k * a * ((2.0 * a - pr) * inv_g - pr) / (2.0 * pr * psi);
            (psi, slope)
        } else {
            let edge = match self.fixed {
                Some(c) => c.band_edge,
                None => self.band_edge(),
            };
            let slope = edge * (1.0 / LINEAR_BAND);
            (slope * (1.0 - pr).max(0.0), -slope)
        }
    }
}

/// `tanh(x)`, with `±1` (its correctly rounded value) for `|x| ≥ 22` without the library call:
/// the friction's sign, smoothed through zero speed.
pub(super) fn smooth_sign(x: f64) -> f64 {
    if x.abs() >= 22.0 {
        x.signum()
    } else {
        x.tanh()
    }
}

/// `[f(INT), f(CYL), f(EXH)]`, inline (an array's `map` through a closure is not always).
#[inline(always)]
pub(super) fn per_volume<T>(f: impl Fn(usize) -> T) -> [T; 3] {
    [f(INT), f(CYL), f(EXH)]
}

/// Mass flow from side 0 to side 1 [kg/s] (negative: 1 → 0) through an effective area
/// `cd_a` [m²] (Eq. 3.16), `ṁ = C_d·A·p_up/√(R·T_up)·Ψ(p_dn/p_up)` — the upstream side's gas
/// sets the flow — and its slopes `[∂ṁ/∂p_0, ∂ṁ/∂p_1]` [kg/(s·Pa)] (the upstream gas's
/// temperature held): with `c = C_d·A/√(R·T_up)`, `∂ṁ/∂p_dn = c·Ψ'` and
/// `∂ṁ/∂p_up = c·(Ψ − pr·Ψ')`.
pub fn flow_and_slopes(cd_a: f64, side: [&OrificeGas; 2]) -> (f64, [f64; 2]) {
    if cd_a <= 0.0 {
        return (0.0, [0.0; 2]);
    }
    let [g0, g1] = side;
    if g0.p >= g1.p {
        let (c, pr) = (cd_a * g0.inv_sqrt_rt, g1.p / g0.p);
        let (psi, dpsi) = g0.psi_and_slope(pr);
        (c * g0.p * psi, [c * (psi - pr * dpsi), c * dpsi])
    } else {
        let (c, pr) = (cd_a * g1.inv_sqrt_rt, g0.p / g1.p);
        let (psi, dpsi) = g1.psi_and_slope(pr);
        (-c * g1.p * psi, [-c * dpsi, -c * (psi - pr * dpsi)])
    }
}
