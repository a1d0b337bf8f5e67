//! The calibrated cell against a recording: each matched channel's NRMSE with the nominal
//! cell and with the calibrated one (the same replay, [`Replay`]).

use super::replay::Replay;
use crate::error::AppError;
use physid_sim::params::CellParams;
use serde::Serialize;

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
}

/// NRMSE `√(mean((y − ŷ)²)) / (max y − min y)` of each channel of `replay` for the cells
/// `nominal` and `calibrated`.
pub fn check(
    replay: &Replay,
    nominal: &CellParams,
    calibrated: &CellParams,
) -> Result<Vec<ChannelCheck>, AppError> {
    let (before, after) = std::thread::scope(|s| {
        let b = s.spawn(|| replay.simulate(nominal));
        let a = replay.simulate(calibrated);
        (b.join(), a)
    });
    let before = before.map_err(|_| AppError::Invalid("the nominal replay panicked".into()))??;
    let after = after?;
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
            ChannelCheck {
                name: name.clone(),
                unit: physid_core::standard_unit(name).unwrap_or("").to_string(),
                nrmse_before: rms(&before[c]) / range,
                nrmse_after: rms(&after[c]) / range,
                rms_after: rms(&after[c]),
            }
        })
        .collect())
}
