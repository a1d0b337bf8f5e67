//! One cycle's combustion from its cylinder pressure (Heywood 1988, *Internal Combustion Engine
//! Fundamentals*, §9.2): the apparent (net) heat release, the burn angles, the pressure's peak
//! and steepest rise between the samples — what `physid cycles` adds to each cycle's figures.
//!
//! * **Apparent net heat release**, single zone (Heywood Eq. 9.25):
//!   `dQ_n = γ/(γ−1)·p·dV + 1/(γ−1)·V·dp`, summed over each step with the step's mean `p̄`, `V̄`
//!   (second order) from the window's first angle ([`HEAT_WINDOW`], −90° … 120° ATDC by
//!   default). No wall heat, crevices or blow-by: what they take is in `Q_n` (it is net). γ is
//!   constant, or γ(T) of air (NASA polynomials, [`physid_models::air`]) at the step's mean gas
//!   temperature ([`GasTemperature`]) — for an ideal gas of constant `R` the formula with γ(T)
//!   is the energy equation `dQ = m·c_v(T)·dT + p·dV` itself (`m·dT = (p·dV + V·dp)/R`).
//! * **Mean gas temperature** ([`GasTemperature`]): the ideal gas with the mass trapped at IVC,
//!   `T = T_IVC · p·V / (p_IVC·V_IVC)` (Heywood §9.2.1), its peak in the window `t_max_k`.
//! * **Gross heat release** ([`WallHeat`], with the gas temperature): the net plus the heat lost
//!   to the walls, Woschni's (Heywood Eq. 12.19) with its combustion term from the start of
//!   combustion, or without it (`C₂` = 0: the thesis's Eq. 3.10–3.12, the virtual cell's) —
//!   [`crate::wall_heat`].
//! * **Burn angles** (mass fraction burned, the heat-release method): `x_b = (Q − Q_min)/(Q_max
//!   − Q_min)`, `Q_max` the largest `Q` in the window and `Q_min` the smallest before it; MFBk is
//!   where `x_b` first reaches k % after `Q_min`, linearly between the samples. The heat
//!   released is `Q_max − Q_min`.
//! * **Burn angles by Rassweiler & Withrow** (1938; Heywood §9.2.1, Eq. 9.13–9.16), with
//!   [`BurnMethod::RassweilerWithrow`]: over each step the pressure rise the volume change alone
//!   would give, `p_i·((V_i/V_{i+1})ⁿ − 1)`, is set apart from the rest, `Δp_c = p_{i+1} −
//!   p_i·(V_i/V_{i+1})ⁿ`, which is taken as proportional to the mass burned in the step once
//!   referred to one volume: `Δm ∝ Δp_c·V_i`. The mass fraction burned is their sum, normalised
//!   as the heat release's (smallest before largest); `n` the polytropic exponent given, else the
//!   cycle's compression exponent, else γ. With `n = γ` the method is the constant-γ heat
//!   release to first order in the step (`Δp_c·V ≈ (γ−1)·ΔQ`); the heat released stays the
//!   heat-release method's.
//! * **Fired or motored**: fired when the heat released is at least [`FIRED_FRACTION`] of
//!   `p_max·V_d` (a motored cycle's apparent heat release is its wall heat, negative, and noise);
//!   the burn angles are given for fired cycles only.
//! * **Peak and steepest rise between samples**: the parabola through the largest sample and its
//!   two neighbours puts `p_max`'s angle within a small fraction of the step; the largest central
//!   difference `(p_{k+1} − p_{k−1})/(θ_{k+1} − θ_{k−1})` in the window is `dp/dθ_max`, at `θ_k`.
//!   A peak that is a jump (an ideal cycle's heat added at once) is placed within half a step.

use crate::error::AppError;
use serde::Serialize;

/// γ of the heat release when none is given: Heywood's 1.35 for the burned-gas side of a
/// single-zone analysis (§9.2.2 suggests 1.3–1.35).
pub const DEFAULT_GAMMA: f64 = 1.35;

/// The heat release's window [deg ATDC] when none is given: after IVC, before EVO on most
/// engines.
pub const HEAT_WINDOW: (f64, f64) = (-90.0, 120.0);

/// A cycle releasing less heat than this fraction of `p_max·V_d` is motored (see the module
/// docs).
pub const FIRED_FRACTION: f64 = 0.05;

/// The burn fractions whose angles are given unless others are asked for [%].
pub const MFB: [f64; 3] = [10.0, 50.0, 90.0];

/// The mean gas temperature's reference: the gas trapped at intake valve closing.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct GasTemperature {
    /// Intake valve closing [deg ATDC].
    pub ivc_deg: f64,
    /// The gas temperature then [K].
    pub t_ivc_k: f64,
}

use crate::wall_heat::Woschni;
pub use crate::wall_heat::{Cylinder, WallHeat, WOSCHNI_C1, WOSCHNI_C2};

/// How the burn angles' mass fraction burned is found (see the module docs).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, serde::Deserialize)]
pub enum BurnMethod {
    /// From the apparent heat release (the default).
    #[default]
    HeatRelease,
    /// Rassweiler & Withrow's pressure-rise method, with a polytropic exponent (`None`: the
    /// cycle's compression exponent, else γ).
    RassweilerWithrow {
        /// The polytropic exponent `n`.
        exponent: Option<f64>,
    },
}

impl BurnMethod {
    /// The method by name — `heat` or `rw` (Rassweiler–Withrow, with `exponent` if given) —
    /// what `--mfb-method` and `--rw-exponent` (and Python's `mfb_method`, `rw_exponent`) take.
    pub fn parse(name: &str, exponent: Option<f64>) -> Result<Self, AppError> {
        match (name, exponent) {
            ("heat", None) => Ok(Self::HeatRelease),
            ("heat", Some(n)) => Err(AppError::Invalid(format!(
                "--rw-exponent {n:?} is Rassweiler–Withrow's: give it with --mfb-method rw"
            ))),
            ("rw", exponent) => Ok(Self::RassweilerWithrow { exponent }),
            (other, _) => Err(AppError::Invalid(format!(
                "--mfb-method {other}: expected heat (the apparent heat release) or rw (Rassweiler–Withrow's pressure rise)"
            ))),
        }
    }
}

/// How the heat release is computed.
#[derive(Debug, Clone, PartialEq, Serialize, serde::Deserialize)]
pub struct HeatRelease {
    /// The ratio of specific heats γ (constant, unless `temperature` is given).
    pub gamma: f64,
    /// The mean gas temperature's reference: then γ(T) at it, and its peak.
    pub temperature: Option<GasTemperature>,
    /// The wall heat added (gross heat release; needs `temperature`).
    pub wall: Option<WallHeat>,
    /// The window [deg ATDC].
    pub window: (f64, f64),
    /// The burn fractions whose angles are given [%], each in (0, 100).
    pub mfb: Vec<f64>,
    /// How the burn angles are found.
    #[serde(default)]
    pub method: BurnMethod,
}

impl Default for HeatRelease {
    fn default() -> Self {
        Self {
            gamma: DEFAULT_GAMMA,
            window: HEAT_WINDOW,
            mfb: MFB.to_vec(),
            temperature: None,
            wall: None,
            method: BurnMethod::HeatRelease,
        }
    }
}

impl HeatRelease {
    /// Refused unless 1 < γ < 2, the window lies within −360° … 360° ATDC, its start first,
    /// the burn fractions are within (0, 100) % and the gas temperature's reference is one.
    pub fn validate(&self) -> Result<(), AppError> {
        let (lo, hi) = self.window;
        if !(self.gamma > 1.0 && self.gamma < 2.0) {
            return Err(AppError::Invalid(format!(
                "heat release: γ = {:?}: expected a ratio of specific heats between 1 and 2 (1.35 for a single-zone analysis)",
                self.gamma
            )));
        }
        if !(lo < hi && lo >= -360.0 && hi <= 360.0) {
            return Err(AppError::Invalid(format!(
                "heat release: window {lo}° … {hi}° ATDC: expected a start before the end, within −360° … 360°"
            )));
        }
        if let Some(g) = &self.temperature {
            if !(g.t_ivc_k > 0.0 && g.t_ivc_k.is_finite() && (-360.0..=0.0).contains(&g.ivc_deg)) {
                return Err(AppError::Invalid(format!(
                    "--gas-temperature {},{}: expected the intake valve's closing in −360 … 0° ATDC and the gas temperature then in K (> 0), e.g. -140,320",
                    physid_core::Num(g.ivc_deg),
                    physid_core::Num(g.t_ivc_k)
                )));
            }
        }
        if let Some(w) = &self.wall {
            if self.temperature.is_none() {
                return Err(AppError::Invalid(
                    "--wall-heat needs the gas temperature (--gas-temperature IVC_DEG,T_IVC): the wall heat is Woschni's at the mean gas temperature".into(),
                ));
            }
            if !(w.t_wall_k > 0.0 && w.t_wall_k.is_finite() && w.c1 >= 0.0) {
                return Err(AppError::Invalid(format!(
                    "--wall-heat {}: expected the wall temperature in K (> 0), e.g. 400",
                    physid_core::Num(w.t_wall_k)
                )));
            }
            if !(w.c2 >= 0.0 && w.c2 < 0.1) {
                return Err(AppError::Invalid(format!(
                    "--woschni-c2 {}: expected Woschni's combustion term in m/(s·K), ≥ 0 and small (3.24e-3 is his; 0 the motored form)",
                    physid_core::Num(w.c2)
                )));
            }
        }
        if let BurnMethod::RassweilerWithrow { exponent: Some(n) } = self.method {
            if !(n > 1.0 && n < 2.0) {
                return Err(AppError::Invalid(format!(
                    "--rw-exponent {n:?}: expected a polytropic exponent between 1 and 2 (1.3 ± 0.05 is usual; without it the cycle's compression exponent)"
                )));
            }
        }
        if let Some(bad) = self.mfb.iter().find(|k| !(**k > 0.0 && **k < 100.0)) {
            return Err(AppError::Invalid(format!(
                "--mfb {bad:?}: expected burn fractions in per cent, between 0 and 100 (e.g. 5,10,50,90,95)"
            )));
        }
        Ok(())
    }
}

/// One cycle's combustion figures (see the module docs). Serialized flat: `heat_release_j`,
/// `fired`, `mfbK_deg` for each burn fraction K with an angle, `dp_max_pa_per_deg`,
/// `dp_max_deg`, and `misfire` / `partial_burn` when true.
#[derive(Debug, Clone, PartialEq)]
pub struct Burn {
    /// Net heat released in the window, `Q_max − Q_min` [J].
    pub heat_release_j: f64,
    /// Whether the cycle fired (see [`FIRED_FRACTION`]).
    pub fired: bool,
    /// Each burn fraction asked for [%] and its angle [deg ATDC] (fired cycles).
    pub mfb_deg: Vec<(f64, Option<f64>)>,
    /// The largest pressure rise in the window [Pa/deg] …
    pub dp_max_pa_per_deg: f64,
    /// … and its angle [deg ATDC].
    pub dp_max_deg: f64,
    /// Not fired while the engine is firing ([`BurnHistory`]).
    pub misfire: bool,
    /// Fired, releasing less than [`PARTIAL_FRACTION`] of the recent fired cycles' heat.
    pub partial_burn: bool,
    /// The peak mean gas temperature in the window [K] (with [`GasTemperature`]).
    pub t_max_k: Option<f64>,
}

impl Burn {
    /// The angle where the burn reaches `pct` % [deg ATDC], when asked for and reached.
    pub fn mfb(&self, pct: f64) -> Option<f64> {
        self.mfb_deg
            .iter()
            .find(|(k, _)| *k == pct)
            .and_then(|(_, a)| *a)
    }
}

/// The name of burn fraction `pct`'s angle: `mfb50_deg`, `mfb5_deg`, `mfb2.5_deg`.
pub fn mfb_name(pct: f64) -> String {
    format!("mfb{pct}_deg")
}

impl Serialize for Burn {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut m = s.serialize_map(None)?;
        m.serialize_entry("heat_release_j", &self.heat_release_j)?;
        m.serialize_entry("fired", &self.fired)?;
        for (pct, deg) in &self.mfb_deg {
            if let Some(deg) = deg {
                m.serialize_entry(&mfb_name(*pct), deg)?;
            }
        }
        m.serialize_entry("dp_max_pa_per_deg", &self.dp_max_pa_per_deg)?;
        m.serialize_entry("dp_max_deg", &self.dp_max_deg)?;
        if self.misfire {
            m.serialize_entry("misfire", &true)?;
        }
        if self.partial_burn {
            m.serialize_entry("partial_burn", &true)?;
        }
        if let Some(t) = self.t_max_k {
            m.serialize_entry("t_max_k", &t)?;
        }
        m.end()
    }
}

/// A fired cycle releasing less than this fraction of the recent fired cycles' median heat is a
/// partial burn.
pub const PARTIAL_FRACTION: f64 = 0.6;

/// The fired cycles the reference heat is the median of, and the cycles after the last fired
/// one during which the engine still counts as firing (a cycle that does not fire then is a
/// misfire; after them, motored).
pub const REFERENCE_CYCLES: usize = 20;

/// What misfire and partial-burn flags compare a cycle with: the heat of the last
/// [`REFERENCE_CYCLES`] fully fired cycles, and how many cycles ago one fired. Sequential, so a
/// file and a stream flag the same cycles.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BurnHistory {
    heat: std::collections::VecDeque<f64>,
    since_fired: Option<usize>,
    scratch: Vec<f64>,
}

impl BurnHistory {
    /// Flag `b` against the history (a misfire: not fired within [`REFERENCE_CYCLES`] cycles of
    /// a fired one; a partial burn: fired below [`PARTIAL_FRACTION`] of the median heat), then
    /// count it in.
    pub fn flag(&mut self, b: &mut Burn) {
        let firing = self.since_fired.is_some_and(|n| n < REFERENCE_CYCLES);
        b.misfire = !b.fired && firing;
        b.partial_burn = false;
        if b.fired && !self.heat.is_empty() {
            self.scratch.clear();
            self.scratch.extend(self.heat.iter().copied());
            self.scratch.sort_by(f64::total_cmp);
            let n = self.scratch.len();
            let median = 0.5 * (self.scratch[(n - 1) / 2] + self.scratch[n / 2]);
            b.partial_burn = b.heat_release_j < PARTIAL_FRACTION * median;
        }
        if b.fired {
            self.since_fired = Some(0);
            if !b.partial_burn {
                if self.heat.len() == REFERENCE_CYCLES {
                    self.heat.pop_front();
                }
                self.heat.push_back(b.heat_release_j);
            }
        } else {
            self.since_fired = self.since_fired.map(|n| n + 1);
            if !firing {
                self.heat.clear();
            }
        }
    }
}

/// The apparent heat release over the window ([`HeatRelease`], Eq. 9.25): the window's first
/// sample `from`, `Q` [J] at each of its samples (0 at the first), the peak mean gas
/// temperature [K] when [`GasTemperature`] is given. `None` with fewer than three samples in
/// the window.
pub struct Apparent {
    /// The window's first sample in the cycle.
    pub from: usize,
    /// Q at each sample of the window [J].
    pub q: Vec<f64>,
    /// The peak mean gas temperature in the window [K].
    pub t_max_k: Option<f64>,
}

/// [`Apparent`] of a cycle: `atdc` its angles [deg ATDC] in increasing order, `p` the pressure
/// there [Pa], `v` the volume [m³]; `cyl` the engine, for the wall heat.
pub fn apparent_heat(
    hr: &HeatRelease,
    atdc: &[f64],
    p: &[f64],
    v: &[f64],
    cyl: &Cylinder,
) -> Option<Apparent> {
    let (lo, hi) = hr.window;
    let from = atdc.partition_point(|&a| a < lo);
    let to = atdc.partition_point(|&a| a <= hi);
    if to < from + 3 {
        return None;
    }
    // The state at IVC, and the trapped gas's `m·R` from it (`p·V = m·R·T`).
    let ivc = hr.temperature.map(|g| {
        (
            linear(atdc, p, g.ivc_deg),
            linear(atdc, v, g.ivc_deg),
            g.t_ivc_k,
        )
    });
    let (a, p, v) = (&atdc[from..to], &p[from..to], &v[from..to]);
    // Q at each sample of the window, 0 at its first (Eq. 9.25, the step's means), with the
    // coefficients γ/(γ−1) and 1/(γ−1).
    let coefficients = |g: f64| (g / (g - 1.0), 1.0 / (g - 1.0));
    let constant = coefficients(hr.gamma);
    let mut q = Vec::with_capacity(p.len());
    q.push(0.0);
    let (mut sum, mut t_max) = (0.0, f64::NEG_INFINITY);
    let Some((p_r, v_r, t_r)) = ivc else {
        // Constant γ, no wall heat: the same sum, without the per-step choices — the steps
        // first (independent of one another, in vector registers), then their running sum.
        let (c_pdv, c_vdp) = constant;
        q.extend((1..p.len()).map(|k| {
            let (pm, vm) = (0.5 * (p[k] + p[k - 1]), 0.5 * (v[k] + v[k - 1]));
            c_pdv * pm * (v[k] - v[k - 1]) + c_vdp * vm * (p[k] - p[k - 1])
        }));
        for dq in q.iter_mut() {
            sum += *dq;
            *dq = sum;
        }
        return Some(Apparent {
            from,
            q,
            t_max_k: None,
        });
    };
    // γ(T) at the step's mean gas temperature: the net steps, then (with the wall heat) the
    // wall's added — from the start of combustion with its combustion term, found from the net.
    let m_r = p_r * v_r / t_r;
    for k in 1..p.len() {
        let (pm, vm) = (0.5 * (p[k] + p[k - 1]), 0.5 * (v[k] + v[k - 1]));
        t_max = t_max.max(p[k] * v[k] / m_r);
        let (c_pdv, c_vdp) = coefficients(physid_models::air::gamma(pm * vm / m_r));
        sum += c_pdv * pm * (v[k] - v[k - 1]) + c_vdp * vm * (p[k] - p[k - 1]);
        q.push(sum);
    }
    if let Some(w) = hr.wall {
        let woschni = Woschni::new(&w, cyl, (p_r, v_r, t_r), hr.gamma);
        // The burn's start in the net heat release (its smallest before its largest).
        let start = if woschni.has_combustion_term() {
            argmin(&q[..=argmax(&q)])
        } else {
            usize::MAX
        };
        let mut lost = 0.0;
        for k in 1..p.len() {
            let (pm, vm) = (0.5 * (p[k] + p[k - 1]), 0.5 * (v[k] + v[k - 1]));
            lost += woschni.step(pm, vm, pm * vm / m_r, a[k] - a[k - 1], k > start);
            q[k] += lost;
        }
    }
    Some(Apparent {
        from,
        q,
        t_max_k: Some(t_max),
    })
}

/// The mass burned by Rassweiler & Withrow over the samples of a window (see the module docs):
/// 0 at the first, then the sum of `Δp_c·V_i` [Pa·m³] — proportional to the mass burned.
pub fn rassweiler_withrow(p: &[f64], v: &[f64], n: f64) -> Vec<f64> {
    let mut m = Vec::with_capacity(p.len());
    m.push(0.0);
    let mut sum = 0.0;
    for k in 1..p.len() {
        let dp_c = p[k] - p[k - 1] * (v[k - 1] / v[k]).powf(n);
        sum += dp_c * v[k - 1];
        m.push(sum);
    }
    m
}

/// The combustion figures of one cycle: `atdc` its angles [deg ATDC] in increasing order, `p`
/// the pressure there [Pa] and `v` the volume [m³]; `vd` the displacement [m³], `p_max` the
/// cycle's peak pressure [Pa], `cyl` the engine and the cycle's speed and compression exponent
/// (the wall heat's; Rassweiler–Withrow's when none is given). `None` with fewer than three
/// samples in the window.
pub fn burn(
    hr: &HeatRelease,
    atdc: &[f64],
    p: &[f64],
    v: &[f64],
    vd: f64,
    p_max: f64,
    cyl: &Cylinder,
) -> Option<Burn> {
    let Apparent { from, q, t_max_k } = apparent_heat(hr, atdc, p, v, cyl)?;
    let window = from..from + q.len();
    let (a, p, v) = (&atdc[window.clone()], &p[window.clone()], &v[window]);
    let (heat, fired) = {
        let k_max = argmax(&q);
        let heat = q[k_max] - q[argmin(&q[..=k_max])];
        (heat, heat >= FIRED_FRACTION * p_max * vd)
    };
    // The curve the burn angles are read from: the heat released, or the mass burned.
    let burned = match hr.method {
        BurnMethod::HeatRelease => q,
        BurnMethod::RassweilerWithrow { exponent } => {
            rassweiler_withrow(p, v, exponent.or(cyl.n_compression).unwrap_or(hr.gamma))
        }
    };
    let k_max = argmax(&burned);
    let k_min = argmin(&burned[..=k_max]);
    let total = burned[k_max] - burned[k_min];
    let mfb_deg = hr
        .mfb
        .iter()
        .map(|&pct| {
            let target = burned[k_min] + pct / 100.0 * total;
            let deg = (k_min + 1..=k_max).find(|&k| burned[k] >= target).map(|k| {
                a[k - 1]
                    + (target - burned[k - 1]) / (burned[k] - burned[k - 1]) * (a[k] - a[k - 1])
            });
            (pct, deg.filter(|_| fired))
        })
        .collect();
    // The steepest rise (the first of equals): its value, then where.
    let rise = |k: usize| (p[k + 1] - p[k - 1]) / (a[k + 1] - a[k - 1]);
    let rises = &mut Vec::with_capacity(a.len());
    rises.extend((1..a.len() - 1).map(rise));
    let dp_max = extreme(rises, |x, m| x > m);
    let dp_deg = rises
        .iter()
        .position(|&d| d == dp_max)
        .map_or(f64::NAN, |k| a[k + 1]);
    Some(Burn {
        heat_release_j: heat,
        fired,
        mfb_deg,
        dp_max_pa_per_deg: dp_max,
        dp_max_deg: dp_deg,
        misfire: false,
        partial_burn: false,
        t_max_k,
    })
}

/// `y` at `x0` over the increasing `x`, linearly between the samples around it (the end
/// sample's beyond the ends).
fn linear(x: &[f64], y: &[f64], x0: f64) -> f64 {
    let k = x.partition_point(|&a| a < x0);
    if k == 0 {
        return y[0];
    }
    if k == x.len() {
        return y[k - 1];
    }
    let f = (x0 - x[k - 1]) / (x[k] - x[k - 1]);
    y[k - 1] + f * (y[k] - y[k - 1])
}

/// The peak of `p` over the increasing angles `atdc`: the largest sample, and the angle of the
/// vertex of the parabola through it and its neighbours (the sample's own angle at either end,
/// or when the three do not bend down).
pub fn peak(atdc: &[f64], p: &[f64]) -> Option<(f64, f64)> {
    if p.is_empty() {
        return None;
    }
    let k = argmax(p);
    Some((p[k], peak_angle_at(atdc, p, k)))
}

/// The vertex's angle about sample `k` (see [`peak`]).
fn peak_angle_at(atdc: &[f64], p: &[f64], k: usize) -> f64 {
    if k == 0 || k + 1 == p.len() {
        return atdc[k];
    }
    let (x0, x1, x2) = (atdc[k - 1], atdc[k], atdc[k + 1]);
    let (y0, y1, y2) = (p[k - 1], p[k], p[k + 1]);
    // The vertex of the parabola through three points (any spacing).
    let d0 = (y1 - y0) / (x1 - x0);
    let d1 = (y2 - y1) / (x2 - x1);
    let curv = (d1 - d0) / (x2 - x0);
    if curv.is_nan() || curv >= 0.0 {
        return x1;
    }
    let vertex = 0.5 * (x0 + x1) - d0 / (2.0 * curv);
    vertex.clamp(x0, x2)
}

/// The index of the largest of finite `v` (the last of equals; 0 when empty).
fn argmax(v: &[f64]) -> usize {
    let m = extreme(v, |a, b| a > b);
    v.iter().rposition(|&x| x == m).unwrap_or(0)
}

/// The index of the smallest of finite `v` (the first of equals; 0 when empty).
fn argmin(v: &[f64]) -> usize {
    let m = extreme(v, |a, b| a < b);
    v.iter().position(|&x| x == m).unwrap_or(0)
}

/// The value of `v` that `beats` every other (`v[0]` of an empty or NaN-led `v`: never found),
/// in four running extremes — no comparison waits for the one before, and the compiler
/// vectorises them.
fn extreme(v: &[f64], beats: impl Fn(f64, f64) -> bool) -> f64 {
    let Some(&first) = v.first() else {
        return f64::NAN;
    };
    let mut lanes = [first; 4];
    let chunks = v.chunks_exact(4);
    let rest = chunks.remainder();
    for c in chunks {
        for (m, &x) in lanes.iter_mut().zip(c) {
            if beats(x, *m) {
                *m = x;
            }
        }
    }
    for &x in rest {
        if beats(x, lanes[0]) {
            lanes[0] = x;
        }
    }
    lanes
        .into_iter()
        .fold(first, |m, x| if beats(x, m) { x } else { m })
}
