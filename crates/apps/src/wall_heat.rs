//! The heat lost to the cylinder's walls, which the gross heat release adds back to the net
//! ([`crate::combustion`]): Woschni's correlation (Woschni 1967, SAE 670931; Heywood 1988,
//! Eq. 12.19), over each step of the heat release at the step's mean pressure, volume and gas
//! temperature,
//!
//! * `Q̇_w = h·A_w·(T − T_w)`, `A_w = πB²/2 + 4V/B` (head, piston and the liner uncovered);
//! * `h = 3.26·B^−0.2·p^0.8·T^−0.55·w^0.8` [W/(m²K)], B in m, p in kPa, T in K;
//! * `w = C₁·S̄_p + C₂·(V_d·T_r)/(p_r·V_r)·(p − p_m)` [m/s]: the mean piston speed
//!   `S̄_p = 2·S·N` and, from the start of combustion on, the gas motion combustion adds —
//!   `p_r`, `V_r`, `T_r` the state at intake valve closing (the gas temperature's reference),
//!   `p_m = p_r·(V_r/V)ⁿ` the motored pressure at the same volume (`n` the cycle's compression
//!   exponent, else γ). `C₁` = 2.28 for compression and expansion, `C₂` = 3.24·10⁻³ m/(s·K)
//!   for combustion and expansion and 0 for compression (Heywood); `C₂` = 0 is the motored
//!   form, the thesis's and the virtual cell's (Eq. 3.10–3.12).
//! * The start of combustion: the net apparent heat release's burn start — its smallest value
//!   before its largest, where the mass fraction burned is 0 ([`crate::combustion`]'s burn
//!   angles) — found from the net heat release first.
//!
//! Each step lasts `Δθ/(6·N)` seconds at the cycle's mean speed `N` [rpm].

use serde::{Deserialize, Serialize};

/// Woschni's `C₁` for compression and expansion (Heywood §12.4.3; the thesis's Table 3.1).
pub const WOSCHNI_C1: f64 = 2.28;

/// Woschni's `C₂` for combustion and expansion [m/(s·K)] (Heywood §12.4.3).
pub const WOSCHNI_C2: f64 = 3.24e-3;

/// The wall heat that makes the heat release gross (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WallHeat {
    /// The wall temperature [K].
    pub t_wall_k: f64,
    /// Woschni's `C₁` for compression and expansion.
    pub c1: f64,
    /// Woschni's `C₂` from the start of combustion [m/(s·K)] (0: the motored form).
    #[serde(default)]
    pub c2: f64,
}

/// What the wall heat needs of the engine and the cycle: bore and stroke [m], the cycle's speed
/// [rpm] and its compression exponent (the motored pressure's, with `C₂`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cylinder {
    /// Bore [m].
    pub bore: f64,
    /// Stroke [m].
    pub stroke: f64,
    /// Mean speed [rpm].
    pub rpm: f64,
    /// The cycle's polytropic exponent of compression, when found.
    pub n_compression: Option<f64>,
}

/// Woschni's wall heat of one cycle, its constants worked out once.
pub(crate) struct Woschni {
    t_wall_k: f64,
    bore: f64,
    /// `3.26·B^−0.2`.
    k_bore: f64,
    /// `C₁·S̄_p` [m/s].
    w_piston: f64,
    /// `C₂·V_d·T_r/(p_r·V_r)` [m/(s·Pa)].
    w_combustion: f64,
    /// `p_r`, `V_r` and the motored pressure's exponent.
    reference: (f64, f64, f64),
    /// Seconds per degree.
    s_per_deg: f64,
}

impl Woschni {
    /// The wall heat `w` for `cyl` with the reference state at IVC (`p_r` [Pa], `V_r` [m³],
    /// `T_r` [K]) and the heat release's `gamma` (the motored pressure's exponent without the
    /// cycle's own).
    pub(crate) fn new(
        w: &WallHeat,
        cyl: &Cylinder,
        (p_r, v_r, t_r): (f64, f64, f64),
        gamma: f64,
    ) -> Self {
        let vd = std::f64::consts::PI / 4.0 * cyl.bore * cyl.bore * cyl.stroke;
        Self {
            t_wall_k: w.t_wall_k,
            bore: cyl.bore,
            k_bore: 3.26 * cyl.bore.powf(-0.2),
            w_piston: w.c1 * 2.0 * cyl.stroke * cyl.rpm / 60.0,
            w_combustion: w.c2 * vd * t_r / (p_r * v_r),
            reference: (p_r, v_r, cyl.n_compression.unwrap_or(gamma)),
            s_per_deg: 1.0 / (6.0 * cyl.rpm),
        }
    }

    /// Whether the combustion term is there (`C₂` > 0): the start of combustion is needed.
    pub(crate) fn has_combustion_term(&self) -> bool {
        self.w_combustion != 0.0
    }

    /// The heat lost over a step of `dθ` degrees at the mean pressure `p` [Pa], volume `v`
    /// [m³] and gas temperature `t` [K], with the combustion term or not [J].
    pub(crate) fn step(&self, p: f64, v: f64, t: f64, d_deg: f64, burning: bool) -> f64 {
        let mut w = self.w_piston;
        if burning {
            let (p_r, v_r, n) = self.reference;
            w += self.w_combustion * (p - p_r * (v_r / v).powf(n));
        }
        let h = self.k_bore * (p * 1e-3).powf(0.8) * t.powf(-0.55) * w.max(0.0).powf(0.8);
        let area = std::f64::consts::PI * self.bore * self.bore / 2.0 + 4.0 * v / self.bore;
        h * area * (t - self.t_wall_k) * d_deg * self.s_per_deg
    }
}
