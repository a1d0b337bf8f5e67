//! The chain on a motored pressure trace (`physid compression fit`): the motored-pressure model
//! ([`physid_models::motored`]: compression ratio, TDC offset, sensor offset, polytropic
//! exponent, BDC pressure, loss rate) fitted around every firing TDC of a crank-angle
//! recording.
//!
//! 1. The compression events: around each firing TDC, the samples in the window (default
//!    −120° … 120° ATDC, valves closed) — the compression at the end of one cycle, the expansion
//!    at the start of the next.
//! 2. Starting values from the data: `n = 1.3`, no offsets, no loss, the compression ratio from
//!    the ratio of the peak pressure to the pressure at the window's start
//!    (`p_max/p_a = (V_a/V_c)ⁿ`), the BDC pressure by the polytrope back from `p_a`.
//! 3. All the parameters not held (`--set`) fitted to every event at once (Gauss–Newton), the
//!    identifiability ranking at nominal values (Alg. 5.1, thesis scaling) and the estimable
//!    set (Wu et al. by default): which parameters the trace resolves and which trade off.
//! 4. The estimable ones, the rest held at their starting values:
//!    - fitted to all the events at once — the estimate, with 95 % intervals from the Fisher
//!      information of all of them (Eq. 5.12, σ² from the residuals);
//!    - fitted per event, with intervals from each event's information;
//!    - combined recursively over the events by Gauss–Newton — the first event's own fit,
//!      then each event linearised at the estimate so far (`J_k`, `r_k` there):
//!      `I_k = I_{k−1} + J_kᵀJ_k/σ_k²`, `ϑ̄_k = ϑ̄_{k−1} + I_k⁻¹·J_kᵀr_k/σ_k²` (the extended
//!      Kalman filter of a constant parameter): the on-line track. When one event resolves
//!      the parameters well it ends at the fit of all; when it does not (much noise), its
//!      first linearisations are poor and it lags — the fit of all is the estimate.
//!
//!    The spread of the per-event estimates is reported beside the interval: if it exceeds
//!    it, the parameters change from cycle to cycle or the model misses something.
//! 5. The thermodynamic loss angle: where the fitted trace peaks, `n·d ln V/dα = −k_loss`.
//!
//! Here: the configuration and the fit on windows in memory ([`compression_fit`]).
//! `events.rs`: the windows around each TDC; `passes.rs`: the windows in passes; `fit.rs`: the
//! fit over them; `result.rs`: the result; `tdc.rs`: the TDC from the pressure.

use crate::error::AppError;
use nalgebra::{DMatrix, DVector};
use physid_core::{Basis, GradientEngine, ParamModel, Recording, Recordings, Reopen};
use physid_ident::{
    analyse, fit_subset, quantify, Data, DataRows, IdentConfig, IdentError, RankedParam, Rows,
    Selection,
};
use physid_models::motored::{Motored, DESCRIPTIONS, PARAMS, UNITS};
use serde::Serialize;

mod events;
mod fit;
mod passes;
mod result;
mod tdc;

pub use events::*;
pub use fit::*;
pub use passes::*;
pub use result::*;
pub use tdc::*;

/// What to fit.
#[derive(Debug, Clone)]
pub struct CompressionConfig {
    /// The cylinder-pressure channel.
    pub channel: String,
    /// Stroke [m].
    pub stroke: f64,
    /// Connecting rod [m].
    pub rod: f64,
    /// The fitting window around TDC [deg ATDC].
    pub window_deg: (f64, f64),
    /// Parameters held at a value (not fitted): name and value.
    pub held: Vec<(String, f64)>,
    /// How many of the ranked parameters to fit.
    pub selection: Selection,
    /// Where a fitted parameter is physical, `(name, low, high)` ([`PLAUSIBLE`] unless
    /// widened): a fit outside is flagged with the reason ([`CompressionFit::implausible`]).
    pub plausible: Vec<(String, f64, f64)>,
}

/// Where the fit's parameters are physical: ε a piston engine's compression ratio, n the
/// polytropic exponent of compressing air with some heat loss (below its γ of 1.4 … 1.45 at
/// the gas temperatures of compression).
pub const PLAUSIBLE: [(&str, f64, f64); 2] = [("eps", 4.0, 25.0), ("n", 1.0, 1.45)];

impl CompressionConfig {
    /// The defaults for a channel and a geometry: window −120° … 120°, nothing held, the Wu
    /// criterion.
    pub fn new(channel: &str, stroke: f64, rod: f64) -> Self {
        Self {
            channel: channel.to_string(),
            stroke,
            rod,
            window_deg: DEFAULT_WINDOW,
            held: Vec::new(),
            selection: Selection::Wu { sigma2: None },
            plausible: PLAUSIBLE
                .iter()
                .map(|&(n, lo, hi)| (n.to_string(), lo, hi))
                .collect(),
        }
    }

    fn validate(&self) -> Result<(), AppError> {
        let (a, b) = self.window_deg;
        if !(self.stroke.is_finite()
            && self.stroke > 0.0
            && self.rod.is_finite()
            && self.rod > 0.5 * self.stroke)
        {
            return Err(AppError::Invalid(format!(
                "stroke {} m, rod {} m: expected lengths > 0 in metres and a rod longer than half the stroke",
                physid_core::Num(self.stroke),
                physid_core::Num(self.rod)
            )));
        }
        if !((-180.0..-10.0).contains(&a) && b > 10.0 && b <= 180.0) {
            return Err(AppError::Invalid(format!(
                "window {}° … {}° ATDC: expected from −180° … −10° to 10° … 180° (the valves closed, TDC inside)",
                physid_core::Num(a),
                physid_core::Num(b)
            )));
        }
        for (name, lo, hi) in &self.plausible {
            if !PARAMS.contains(&name.as_str()) || lo.is_nan() || hi.is_nan() || lo >= hi {
                return Err(AppError::Invalid(format!(
                    "--plausible {name}={},{}: expected one of {} and a low below a high",
                    physid_core::Num(*lo),
                    physid_core::Num(*hi),
                    PARAMS.join(", ")
                )));
            }
        }
        for (name, v) in &self.held {
            if !PARAMS.contains(&name.as_str()) {
                return Err(AppError::Invalid(format!(
                    "--set {name}: the motored model's parameters are {}",
                    PARAMS.join(", ")
                )));
            }
            if !v.is_finite() {
                return Err(AppError::Invalid(format!("--set {name}={v}: not a number")));
            }
        }
        Ok(())
    }
}

/// The default fitting window [deg ATDC].
pub const DEFAULT_WINDOW: (f64, f64) = (-120.0, 120.0);

/// Starting values (see the module's doc) from the median over the TDCs of the pressure at the
/// window's start, `p_a`, and of its peak, `p_max`; the window starts at `a0` [deg ATDC].
fn start_values(p_a: Vec<f64>, p_max: Vec<f64>, a0: f64, model: &Motored) -> Vec<f64> {
    let median = |mut v: Vec<f64>| {
        v.sort_unstable_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (p_a, p_max) = (median(p_a), median(p_max));
    let a = a0.to_radians();
    let n0 = 1.3;
    // V_a/V_c = (p_max/p_a)^(1/n) = 1 + (ε − 1)·s(a)/S.
    let crank = model.crank();
    let s_a = crank.s_at(a);
    let ratio = (p_max / p_a).max(1.0 + 1e-6).powf(1.0 / n0);
    let eps = (1.0 + (ratio - 1.0) * crank.stroke() / s_a).clamp(1.5, 100.0);
    let p_bdc = p_a / model.volume_ratio(eps, a).powf(n0);
    vec![eps, 0.0, 0.0, n0, p_bdc, 0.0]
}

/// The angle [deg ATDC, true] where the model's trace peaks: `n·d ln(V(−π)/V)/dα = k` between
/// −30° and TDC (bisection); `None` outside.
pub fn peak_angle(model: &Motored, theta: &[f64]) -> Option<f64> {
    let (eps, n, k) = (theta[0], theta[3], theta[5]);
    let crank = model.crank();
    let s_total = crank.stroke();
    // d ln p/dα = −n·(ε − 1)·s'(α)/(S + (ε − 1)·s(α)) − k.
    let slope = |a: f64| {
        let (s, ds, _) = crank.motion(a);
        -n * (eps - 1.0) * ds / (s_total + (eps - 1.0) * s) - k
    };
    let (mut lo, mut hi) = (-30f64.to_radians(), 0.0);
    if !(slope(lo) > 0.0 && slope(hi) <= 0.0) {
        return None;
    }
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if slope(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some(0.5 * (lo + hi).to_degrees())
}

/// Typical sizes of the parameters that start at 0, for the ranking's relative sensitivities
/// (thesis scaling, Eq. 5.11): a TDC error of 1°, a sensor offset of a tenth of the BDC
/// pressure, a loss of 2 %/rad.
fn nominal_values(start: &[f64], held: &[usize]) -> Vec<f64> {
    let mut v = start.to_vec();
    for (j, typical) in [(1, 1.0), (2, 0.1 * start[4]), (5, 0.02)] {
        if !held.contains(&j) && v[j] == 0.0 {
            v[j] = typical;
        }
    }
    v
}

fn data<'a>(atdc: &'a [f64], p: &'a [f64]) -> Data<'a> {
    Data {
        inputs: vec![atdc],
        y: Some(p),
    }
}

/// Fit the motored model to a crank-angle recording (see the module's doc):
/// [`compression_fit_events`] on its TDCs' windows, held.
pub fn compression_fit(
    rec: &Recording,
    cfg: &CompressionConfig,
) -> Result<CompressionFit, AppError> {
    let events = TdcEvents::new(rec, &cfg.channel, cfg.window_deg, usize::MAX);
    compression_fit_events(&events, cfg)
}
