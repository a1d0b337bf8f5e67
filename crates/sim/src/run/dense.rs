//! The cylinder between the solver's steps: its dense output. A step of the solver is a crank
//! degree or more, and the output grid falls between steps (a time basis at a higher rate, a
//! crank basis finer than the step); carried linearly, the cylinder's pressure — which the
//! piston compresses as `V^−γ` — is off by 2–9× the solver's own error at mid-step.
//!
//! Instead, `p·V = m·R·T` is carried: it moves only by the heat and the flows, not by the
//! piston's stroke. Between steps `j` and `j + 1` it is the cubic Hermite interpolant
//! through its values and its slopes `d(p·V)/dt = R·(ṁ·T + m·dT/dt)` (Eq. 3.20–3.27, from the
//! step's own evaluation: [`EngineOutputs::pv_rate`](crate::engine::EngineOutputs)), in the
//! fraction `f` of the way (the slopes times the step's duration), and the pressure is that
//! over the volume at the point's crank angle:
//!
//! ```text
//! p(f) = [h00(f)·y₀ + h10(f)·Δt·ẏ₀ + h01(f)·y₁ + h11(f)·Δt·ẏ₁] / V(θ(f)),    y = p·V
//! ```
//!
//! (`h00 = 2f³ − 3f² + 1`, `h10 = f³ − 2f² + f`, `h01 = −2f³ + 3f²`, `h11 = f³ − f²`). The gas
//! temperature is `T = y/(m·R)` with the mass carried linearly (`m·R = y/T` at each step).
//! From the pressure and the crank point at the point's angle follow, as the cell computes
//! them (SPEC §2.3), the indicated torque `(p − p_crank)·A_p·s′`, the engine's acceleration
//! `α = (τ_sh + τ_ind − m·s′·s″·ω² − τ_f)/(J + m·s′²)`, the reciprocating torque
//! `m·(s′·s″·ω² + s′²·α)` and the engine torque `τ_ind − τ_rec − τ_f` — with the shaft torque,
//! the friction and the speed (states, and smooth) carried linearly.
//!
//! Against RK4 at 0.05° (`crates/sim/tests/dense_output.rs`), between the steps every one of
//! these channels is then as close as at the steps themselves (0.7–1.1× their error there;
//! the pressure half-way between 1° steps 3.6e-5 of its peak, against 3.0e-4 carried linearly).

use super::acquisition::{Points, COLUMN};
use super::channels::{raw_index, Between, Dense, T};
use crate::engine::Engine;
use crate::numeric::SinCosTrack;
use crate::params::CellParams;

/// A point with `f·(1 − f)` below this counts as on its step, carried linearly: there the
/// linear error is under 4e-3 of its mid-step value (≈ 5e-6 of the peak pressure at 2° steps),
/// and a grid that falls on the steps (within their aim, ≈ 1e-6 rad) gives the samples it gave
/// before the dense output, bit for bit.
const ON_STEP: f64 = 1e-3;

/// The cylinder's dense output over a chunk's points (see the module docs).
#[derive(Clone)]
pub(super) struct Cylinder {
    engine: Engine,
    /// The engine's inertia `J` [kg·m²].
    inertia: f64,
    /// The raw columns read: p_cyl, T_cyl, V, d(p·V)/dt, m_rec, the shaft torque, the
    /// friction torque, ω_en.
    cols: [usize; 8],
    /// The crank angle's sine and cosine from point to point.
    sin_cos: SinCosTrack,
    /// Per point of the chunk: whether it has dense values, and they: `[p_cyl, T_cyl,
    /// τ_ind, τ_rec, τ_engine, α_en]`.
    on: Vec<bool>,
    values: Vec<[f64; 6]>,
}

/// Cubic Hermite interpolation at `f` ∈ [0, 1] through `y0`, `y1` with slopes `d0`, `d1` per
/// unit of `f`.
fn hermite(y0: f64, d0: f64, y1: f64, d1: f64, f: f64) -> f64 {
    let (f2, f3) = (f * f, f * f * f);
    (2.0 * f3 - 3.0 * f2 + 1.0) * y0
        + (f3 - 2.0 * f2 + f) * d0
        + (-2.0 * f3 + 3.0 * f2) * y1
        + (f3 - f2) * d1
}

impl Cylinder {
    /// The dense output of the engine of `params`.
    pub(super) fn new(params: &CellParams) -> Self {
        Self {
            engine: Engine::new(&params.engine, &params.ambient),
            inertia: params.engine.inertia,
            cols: [
                "p_cyl",
                "true_T_cyl",
                "v_cyl",
                "pv_rate",
                "m_rec",
                "torque_shaft",
                "true_torque_friction",
                "omega_en",
            ]
            .map(raw_index),
            sin_cos: SinCosTrack::default(),
            on: Vec::new(),
            values: Vec::new(),
        }
    }

    /// The dense values at the chunk's `points`, from its raw columns `cols`; `theta_en` is
    /// the engine angle at each point [rad].
    pub(super) fn prepare(&mut self, cols: &[[f64; COLUMN]], points: &Points, theta_en: &[f64]) {
        let [c_p, c_t, c_v, c_rate, c_m, c_sh, c_f, c_w] = self.cols.map(|c| &cols[c]);
        let (time, n) = (&cols[T], points.j.len());
        self.on.clear();
        self.on.resize(n, false);
        self.values.clear();
        self.values.resize(n, [0.0; 6]);
        let lin = |c: &[f64; COLUMN], j: usize, f: f64| Between::Linear.carry(c[j], c[j + 1], f);
        for (k, (&j, &f)) in points.j.iter().zip(&points.f).enumerate() {
            let j = j.min(COLUMN - 2);
            let (v0, v1) = (c_v[j], c_v[j + 1]);
            if f * (1.0 - f) < ON_STEP || !(v0 > 0.0 && v1 > 0.0) {
                continue;
            }
            let dt = time[j + 1] - time[j];
            let (y0, y1) = (c_p[j] * v0, c_p[j + 1] * v1);
            let y = hermite(y0, dt * c_rate[j], y1, dt * c_rate[j + 1], f);
            let theta = theta_en[k];
            let at = self
                .engine
                .crank_point_sin_cos(theta, self.sin_cos.at(theta));
            let p = y / self.engine.volume_at(&at);
            let mr = Between::Linear.carry(y0 / c_t[j], y1 / c_t[j + 1], f);
            let indicated = self.engine.torque_at(&at, 0.0, p, 0.0).indicated;
            let m = Between::Hold.carry(c_m[j], c_m[j + 1], f);
            let (w, friction) = (lin(c_w, j, f), lin(c_f, j, f));
            let rec_velocity = m * at.ds * at.dds * w * w;
            let alpha = (lin(c_sh, j, f) + indicated - rec_velocity - friction)
                / (self.inertia + m * at.ds * at.ds);
            let rec = rec_velocity + m * at.ds * at.ds * alpha;
            self.on[k] = true;
            self.values[k] = [p, y / mr, indicated, rec, indicated - rec - friction, alpha];
        }
    }

    /// Channel `how` at the points [`prepare`](Self::prepare)d, appended to `out`; `col` is
    /// its raw column (carried linearly where a point has no dense value).
    pub(super) fn carry_into(
        &self,
        how: Dense,
        col: &[f64; COLUMN],
        points: &Points,
        out: &mut Vec<f64>,
    ) {
        let i = how as usize;
        for (k, (&j, &f)) in points.j.iter().zip(&points.f).enumerate() {
            let j = j.min(COLUMN - 2);
            out.push(if self.on[k] {
                self.values[k][i]
            } else {
                Between::Linear.carry(col[j], col[j + 1], f)
            });
        }
    }
}
