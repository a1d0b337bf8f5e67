//! The calibrated cell against a recording: each matched channel's NRMSE with the nominal
//! cell and with the calibrated one (the same replay, [`Replay`]), and the band the residual
//! is predicted to stay in — the channel's noise and the calibrated parameters' uncertainty
//! carried through the cell — with where it leaves it.
//!
//! The band: on a recording `y = ŷ(ϑ) + e`, the calibrated cell's residual is
//! `r = y − ŷ(ϑ̂) ≈ e − S·(ϑ̂ − ϑ)` with `S_k = ∂ŷ_k/∂ϑ` at the calibrated values, so
//! `var r_k = σ_c² + S_k·C·S_kᵀ` (`C` the calibration's covariance, `σ_c` the channel's noise
//! at the fit, the two independent: the recording checked is not the one calibrated on).
//! The 95 % band is `±1.96·√var r_k`.

use super::calibrate::{sensitivities, Calibration, Covariance, REL_STEP};
use super::replay::Replay;
use crate::error::AppError;
use physid_sim::params::CellParams;
use serde::{Deserialize, Serialize};

/// A two-sided 95 % band's half-width in standard deviations.
pub const Z95: f64 = 1.959_963_984_540_054;

/// An engine cycle in which more than this fraction of the residual's samples lie outside
/// the band (five times the 5 % expected) is one where the residual left it.
pub const LEFT_BAND: f64 = 0.25;

/// What a residual band is predicted from: a calibration's covariance and the noise of each
/// channel it matched.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct Uncertainty {
    /// The estimable parameters' covariance.
    pub covariance: Covariance,
    /// Each matched channel's noise σ at the fit: `(channel, σ)` [its unit].
    pub sigma: Vec<(String, f64)>,
}

impl Uncertainty {
    /// A calibration's.
    pub fn of(cal: &Calibration) -> Self {
        Self {
            covariance: cal.covariance.clone(),
            sigma: cal
                .channels
                .iter()
                .map(|c| (c.name.clone(), c.sigma))
                .collect(),
        }
    }

    /// From a calibration's JSON (`calibration.json` of `physid twin calibrate --out DIR`,
    /// `physid.twin_calibrate`): its `covariance` (`params`, `matrix`) and its `channels`
    /// (`name`, `sigma`).
    pub fn from_json(v: &serde_json::Value) -> Result<Self, AppError> {
        let covariance: Covariance =
            serde_json::from_value(v.get("covariance").cloned().ok_or_else(|| {
                AppError::Invalid(
                    "no 'covariance' (a calibration written before the band was: calibrate again)"
                        .into(),
                )
            })?)
            .map_err(|e| AppError::Invalid(format!("'covariance': {e}")))?;
        let p = covariance.params.len();
        if covariance.matrix.len() != p || covariance.matrix.iter().any(|r| r.len() != p) {
            return Err(AppError::Invalid(format!(
                "'covariance': a {p}×{p} matrix expected for its {p} parameters"
            )));
        }
        if let Some((i, _)) = covariance
            .matrix
            .iter()
            .enumerate()
            .find(|(i, r)| !r.iter().all(|x| x.is_finite()) || r[*i] < 0.0)
        {
            return Err(AppError::Invalid(format!(
                "'covariance': row {i} ({}) is not finite or has a negative variance",
                covariance.params[i]
            )));
        }
        let channels = v
            .get("channels")
            .and_then(|c| c.as_array())
            .ok_or_else(|| AppError::Invalid("no 'channels' list".into()))?;
        let mut sigma = Vec::with_capacity(channels.len());
        for (i, c) in channels.iter().enumerate() {
            let name = c.get("name").and_then(|n| n.as_str());
            let s = c.get("sigma").and_then(|s| s.as_f64());
            match (name, s) {
                (Some(n), Some(s)) if s.is_finite() && s >= 0.0 => sigma.push((n.to_string(), s)),
                _ => {
                    return Err(AppError::Invalid(format!(
                        "'channels'[{i}]: a 'name' and a 'sigma' ≥ 0 expected"
                    )))
                }
            }
        }
        Ok(Self { covariance, sigma })
    }
}

/// A stretch of whole engine cycles in which the residual left its band.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Excursion {
    /// From [s] (the recording's time) …
    pub t_from_s: f64,
    /// … to [s].
    pub t_to_s: f64,
    /// The fraction of its samples outside the band.
    pub outside: f64,
    /// The largest `|r|` in units of the band's half-width.
    pub peak: f64,
}

/// A channel's residual band.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Band {
    /// The channel's noise σ at the calibration's fit [unit].
    pub sigma: f64,
    /// The parameters' part, `√(S_k·C·S_kᵀ)`, its RMS over the samples [unit].
    pub param_sd: f64,
    /// The fraction of samples whose residual lies outside the 95 % band (0.05 expected).
    pub outside: f64,
    /// Where the residual left the band (cycles with more than [`LEFT_BAND`] of their samples
    /// outside, consecutive ones joined).
    pub excursions: Vec<Excursion>,
    /// The band's half-width at each sample [unit].
    #[serde(skip)]
    pub half_width: Vec<f64>,
}

/// One channel's check.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ChannelCheck {
    /// Name.
    pub name: String,
    /// Unit (the recording's standard unit).
    pub unit: String,
    /// Residual RMS over the measured channel's range (max − min), the nominal cell.
    pub nrmse_before: f64,
    /// The same for the calibrated cell.
    pub nrmse_after: f64,
    /// Residual RMS of the calibrated cell [unit].
    pub rms_after: f64,
    /// The calibrated cell's residual band (none without an [`Uncertainty`], or for a channel
    /// the calibration did not match).
    pub band: Option<Band>,
    /// The nominal cell's output at each sample [unit].
    #[serde(skip)]
    pub before: Vec<f64>,
    /// The calibrated cell's [unit].
    #[serde(skip)]
    pub after: Vec<f64>,
}

/// NRMSE `√(mean((y − ŷ)²)) / (max y − min y)` of each channel of `replay` for the cells
/// `nominal` and `calibrated`; with `uncertainty`, the calibrated cell's residual band (module
/// docs) and where the residual leaves it.
pub fn check(
    replay: &Replay,
    nominal: &CellParams,
    calibrated: &CellParams,
    uncertainty: Option<&Uncertainty>,
) -> Result<Vec<ChannelCheck>, AppError> {
    let (before, after) = std::thread::scope(|s| {
        let b = s.spawn(|| replay.simulate(nominal));
        let a = replay.simulate(calibrated);
        (b.join(), a)
    });
    let before = before.map_err(|_| AppError::Invalid("the nominal replay panicked".into()))??;
    let after = after?;
    // The parameters' variance at each sample of each channel, `S_k·C·S_kᵀ`.
    let param_var: Option<Vec<Vec<f64>>> = match uncertainty {
        None => None,
        Some(u) => Some(param_variance(replay, calibrated, &u.covariance)?),
    };
    Ok(replay
        .channels
        .iter()
        .enumerate()
        .map(|(c, name)| {
            let m = &replay.measured[c];
            let range = m.iter().fold(f64::NEG_INFINITY, |a, &x| a.max(x))
                - m.iter().fold(f64::INFINITY, |a, &x| a.min(x));
            let rms = |y: &[f64]| {
                (m.iter().zip(y).map(|(a, b)| (a - b).powi(2)).sum::<f64>() / m.len() as f64).sqrt()
            };
            let range = if range > 0.0 { range } else { f64::NAN };
            let sigma = uncertainty
                .and_then(|u| u.sigma.iter().find(|s| s.0 == *name))
                .map(|s| s.1);
            let band = match (sigma, &param_var) {
                (Some(sigma), Some(v)) => Some(band(replay, m, &after[c], sigma, &v[c])),
                _ => None,
            };
            ChannelCheck {
                name: name.clone(),
                unit: physid_core::standard_unit(name).unwrap_or("").to_string(),
                nrmse_before: rms(&before[c]) / range,
                nrmse_after: rms(&after[c]) / range,
                rms_after: rms(&after[c]),
                band,
                before: before[c].clone(),
                after: after[c].clone(),
            }
        })
        .collect())
}

/// `S_k·C·S_kᵀ` at each sample of each channel: the sensitivities to the covariance's
/// parameters at the calibrated cell (central differences of whole replays, as the calibration
/// takes them), `[channel][sample]`.
fn param_variance(
    replay: &Replay,
    calibrated: &CellParams,
    cov: &Covariance,
) -> Result<Vec<Vec<f64>>, AppError> {
    let p = cov.params.len();
    let mut var = vec![vec![0.0; replay.n]; replay.channels.len()];
    if p == 0 {
        return Ok(var);
    }
    // In scaled coordinates u = ϑ/ϑ̂: S is ∂ŷ/∂u, the covariance divided by ϑ̂_a·ϑ̂_b.
    let s = sensitivities(replay, calibrated, &cov.params, REL_STEP)?;
    let mut value = Vec::with_capacity(p);
    for path in &cov.params {
        value.push(calibrated.get(path).ok_or_else(|| {
            AppError::Invalid(format!(
                "the covariance's parameter '{path}' is not a cell parameter (physid simulate --list-params)"
            ))
        })?);
    }
    for (c, vc) in var.iter_mut().enumerate() {
        for (k, v) in vc.iter_mut().enumerate() {
            let mut acc = 0.0;
            for a in 0..p {
                for b in 0..p {
                    acc += s[a][c][k] * s[b][c][k] * cov.matrix[a][b] / (value[a] * value[b]);
                }
            }
            *v = acc.max(0.0);
        }
    }
    Ok(var)
}

/// The band of a channel measured `m`, replayed `y`, with noise `sigma` and parameter variance
/// `var` per sample; the cycles where the residual left it.
fn band(replay: &Replay, m: &[f64], y: &[f64], sigma: f64, var: &[f64]) -> Band {
    let half_width: Vec<f64> = var
        .iter()
        .map(|v| Z95 * (sigma * sigma + v).sqrt())
        .collect();
    let ratio: Vec<f64> = m
        .iter()
        .zip(y)
        .zip(&half_width)
        .map(|((a, b), h)| (a - b).abs() / h.max(f64::MIN_POSITIVE))
        .collect();
    let n = ratio.len().max(1);
    let outside = ratio.iter().filter(|r| **r > 1.0).count() as f64 / n as f64;
    // Per engine cycle (720° of the crank-angle grid).
    let per_cycle = ((720.0 / replay.step_deg).round() as usize).max(1);
    let mut excursions: Vec<Excursion> = Vec::new();
    let mut open: Option<(usize, usize, usize, f64)> = None; // first, last sample, outside, peak
    for (i, chunk) in ratio.chunks(per_cycle).enumerate() {
        let out = chunk.iter().filter(|r| **r > 1.0).count();
        let peak = chunk.iter().fold(0.0f64, |a, &r| a.max(r));
        let (first, last) = (i * per_cycle, i * per_cycle + chunk.len() - 1);
        if out as f64 > LEFT_BAND * chunk.len() as f64 {
            open = Some(match open {
                Some((f, _, o, p)) => (f, last, o + out, p.max(peak)),
                None => (first, last, out, peak),
            });
        } else if let Some(e) = open.take() {
            excursions.push(excursion(replay, e));
        }
    }
    if let Some(e) = open {
        excursions.push(excursion(replay, e));
    }
    let param_sd = (var.iter().sum::<f64>() / n as f64).sqrt();
    Band {
        sigma,
        param_sd,
        outside,
        excursions,
        half_width,
    }
}

fn excursion(replay: &Replay, (first, last, out, peak): (usize, usize, usize, f64)) -> Excursion {
    Excursion {
        t_from_s: replay.t[first],
        t_to_s: replay.t[last],
        outside: out as f64 / (last + 1 - first) as f64,
        peak,
    }
}
