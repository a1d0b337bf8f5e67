//! What a designed test gives the shaft monitor (Application 1, Eq. 6.1): its regressors
//! `[Δθ, Δω, 1]` after the monitor's own low-pass and decimation, from the virtual cell run
//! without noise on the candidate, and the noise its output `τ_sh` carries after them.

use super::run::run_noiseless;
use super::{Design, Designed, Estimator, Evaluation};
use crate::error::AppError;
use crate::shaft_monitor::{
    lowpass, MonitorConfig, MonitorMethod, RegressorRow, ShaftInputs, ShaftStage, SHAFT_CHANNELS,
};
use physid_signal::filter::Sos;
use physid_sim::params::CellParams;
use physid_sim::run::OutputBasis;
use physid_sim::scenario::{named, Scenario};

/// The shaft monitor's parameters, in its estimator's order.
pub const PARAMS: [&str; 3] = ["K", "B", "tau0"];

/// A shaft monitor to design a test for: its configuration, the cell it runs on and the
/// recording's rate.
#[derive(Debug, Clone)]
pub struct ShaftDesign {
    /// The monitor as it will run on the test's recording (its λ, P0, low-pass, rate).
    pub monitor: MonitorConfig,
    /// The cell (its shaft's K and B are the nominal values; its sensors' noise the noise).
    pub cell: CellParams,
    /// The recording's sample rate [Hz].
    pub rate_hz: f64,
}

impl ShaftDesign {
    /// Refuse what the information recursion does not describe.
    pub fn check(&self) -> Result<(), AppError> {
        if self.monitor.method == MonitorMethod::Rlsvf {
            return Err(AppError::Invalid(
                "design: vector forgetting (rlsvf) forgets each parameter at its own rate, which the design's information recursion does not model; design with rlsf or dsfc (the same estimates)".into(),
            ));
        }
        if self.monitor.supervise {
            return Err(AppError::Invalid(
                "design: the excitation supervisor freezes parameters the data stop resolving, which a design is made to avoid; design without --supervise".into(),
            ));
        }
        super::check_rate(self.rate_hz)?;
        Ok(())
    }

    /// The nominal values the standard errors are relative to: the cell's K and B, and 1 N·m
    /// for the offset τ0 (whose value is 0).
    pub fn scales(&self) -> [f64; 3] {
        [self.cell.shaft.k, self.cell.shaft.b, 1.0]
    }

    /// The estimator's rate [Hz] and one input sample in how many.
    pub fn every(&self) -> usize {
        ((self.rate_hz / self.monitor.rate_hz).round() as usize).max(1)
    }

    /// The variance of the noise on `τ_sh` at the recording's rate [N²·m²]: the transducer's
    /// white noise and quantisation (`q²/12`), and the speed channels' noise through `B·Δω`
    /// (to first order; the encoders' angles carry none).
    pub fn noise_variance(&self) -> f64 {
        let s = &self.cell.sensors;
        let tq = &s.torque_shaft;
        tq.noise * tq.noise
            + tq.quantum * tq.quantum / 12.0
            + 2.0 * (self.cell.shaft.b * s.speed.noise).powi(2)
    }

    /// The noise's autocovariance at the estimator's rate, `r(m) = σ²·Σ_n g(n)·g(n + m·every)`
    /// with `g` the zero-phase low-pass's impulse response (the forward one correlated with
    /// itself: forwards then backwards), `m = 0..`[`MAX_LAGS`](super::information::MAX_LAGS).
    pub fn noise_autocovariance(&self) -> Result<Vec<f64>, AppError> {
        let var = self.noise_variance();
        if !(var.is_finite() && var > 0.0) {
            return Err(AppError::Invalid(
                "design: the shaft torque's noise is 0 (sensors.torque_shaft.noise): a noiseless output resolves every parameter at once, and no test is better than another — set the transducer's noise".into(),
            ));
        }
        let lags = super::information::MAX_LAGS;
        let every = self.every();
        Ok(match lowpass(&self.monitor, self.rate_hz)? {
            None => {
                let mut r = vec![0.0; lags + 1];
                r[0] = var;
                r
            }
            Some(sos) => {
                let g = zero_phase_impulse(&sos);
                (0..=lags)
                    .map(|m| {
                        let d = m * every;
                        var * g
                            .iter()
                            .zip(g.iter().skip(d))
                            .map(|(a, b)| a * b)
                            .sum::<f64>()
                    })
                    .collect()
            }
        })
    }

    /// The regressors the monitor's estimator would take from `scenario` run on the cell
    /// without noise (the noise is the covariance's, [`noise_autocovariance`](Self::noise_autocovariance)).
    pub fn regressors(&self, scenario: &Scenario) -> Result<Vec<RegressorRow>, AppError> {
        let mut stage = ShaftStage::for_regressors(&self.monitor, self.rate_hz)?;
        let n = (scenario.duration * self.rate_hz / self.every() as f64) as usize + 16;
        let mut rows = Vec::with_capacity(n);
        run_noiseless(
            &self.cell,
            &[
                "sensors.torque_shaft.noise",
                "sensors.torque_shaft.quantum",
                "sensors.speed.noise",
            ],
            scenario,
            OutputBasis::Time(self.rate_hz),
            &SHAFT_CHANNELS[1..],
            |chunk| stage.push_regressors(&ShaftInputs::of(chunk)?, &mut rows),
        )?;
        stage.finish_regressors(&mut rows)?;
        Ok(rows)
    }

    /// `scenario` evaluated for the parameters `selected` (indices into [`PARAMS`]).
    pub fn evaluate(
        &self,
        design: &Design,
        scenario: &Scenario,
        noise: &[f64],
    ) -> Result<Evaluation, AppError> {
        let rows = self.regressors(scenario)?;
        design.evaluate(
            rows.iter().map(|r| (r.t_s, &r.phi[..], 1.0)),
            &Estimator {
                scales: &self.scales(),
                units: &[1.0; 3],
                lambda: self.monitor.lambda,
                p0: self.monitor.p0,
                noise,
                settle_s: self.monitor.settle_s,
            },
        )
    }
}

/// The parameters a design is for ([`select`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Selection {
    /// Their indices in [`PARAMS`].
    pub selected: Vec<usize>,
    /// The cell settings their values make (`shaft.k`, `shaft.b`), for the designed
    /// scenario's `set`.
    pub set: Vec<(String, f64)>,
}

/// The parameters `items` (`K`, `B`, `tau0`, each optionally `NAME=VALUE`: the nominal value
/// to design at, set on the cell as `shaft.k`/`shaft.b`).
pub fn select(items: &[String], cell: &mut CellParams) -> Result<Selection, AppError> {
    let mut selected = Vec::new();
    let mut set = Vec::new();
    for item in items {
        let (name, value) = match item.split_once('=') {
            Some((n, v)) => {
                let v = v
                    .trim()
                    .parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| {
                        AppError::Invalid(format!("--params {item}: '{v}' is not a number"))
                    })?;
                (n.trim(), Some(v))
            }
            None => (item.trim(), None),
        };
        let i = PARAMS.iter().position(|n| *n == name).ok_or_else(|| {
            AppError::Invalid(format!(
                "--params {name}: the shaft monitor's parameters are {}",
                PARAMS.join(", ")
            ))
        })?;
        if let Some(v) = value {
            let path = match name {
                "K" => "shaft.k",
                "B" => "shaft.b",
                _ => {
                    return Err(AppError::Invalid(format!(
                        "--params {item}: the offset τ0 has no nominal value to set (it is 0)"
                    )))
                }
            };
            if let Some((_, before)) = set.iter().find(|(p, _)| p == path) {
                return Err(AppError::Invalid(format!(
                    "--params {item}: {name} is already given the value {before}"
                )));
            }
            cell.set_checked(path, v)?;
            set.push((path.to_string(), v));
        }
        if !selected.contains(&i) {
            selected.push(i);
        }
    }
    Ok(Selection { selected, set })
}

/// Design a test for the shaft monitor: `design`'s candidates judged for `shaft`, the thesis's
/// T01 and T02 alongside, the cell's `set` settings carried into the designed scenario (it
/// runs on the cell it was designed for). `progress` is told how many candidates are done.
pub fn design_shaft(
    shaft: &ShaftDesign,
    design: &Design,
    set: &[(String, f64)],
    progress: &(dyn Fn(usize) + Sync),
) -> Result<Designed, AppError> {
    shaft.check()?;
    design.check()?;
    let noise = shaft.noise_autocovariance()?;
    let baselines: Vec<Scenario> = ["shaft-steady", "shaft-ramp"]
        .iter()
        .filter_map(|n| named(n))
        .collect();
    let mut r = design.run(&|s| shaft.evaluate(design, s, &noise), &baselines, progress)?;
    r.scenario.set.extend(set.iter().cloned());
    Ok(r)
}

/// The impulse response of `sos` run forwards and backwards, `g(n) = Σ_j h(j)·h(j + |n|)`,
/// for n = 0.. (it is even): `h` taken until its tail holds less than 1e-16 of its energy.
fn zero_phase_impulse(sos: &Sos) -> Vec<f64> {
    let mut n = 256;
    let h = loop {
        let mut x = vec![0.0; n];
        x[0] = 1.0;
        let mut y = vec![0.0; n];
        let mut zi = vec![[0.0; 2]; sos.sections.len()];
        sos.sosfilt_into(&x, &mut zi, &mut y);
        let total: f64 = y.iter().map(|v| v * v).sum();
        let tail: f64 = y[n / 2..].iter().map(|v| v * v).sum();
        if tail <= 1e-16 * total || n >= 1 << 20 {
            break y;
        }
        n *= 2;
    };
    // g(n) for n ≥ 0; the full, even response is g(|n|).
    let half: Vec<f64> = (0..h.len())
        .map(|d| h.iter().zip(h.iter().skip(d)).map(|(a, b)| a * b).sum())
        .collect();
    // Σ_n g(n)·g(n + d) over all integers n needs both sides: lay g out in full.
    let mut full = Vec::with_capacity(2 * half.len() - 1);
    full.extend(half.iter().rev());
    full.extend(half.iter().skip(1));
    full
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use physid_signal::filter::{butter, Band};

    /// The noise's variance after the zero-phase low-pass, against the filtered noise itself:
    /// 200 000 samples of white noise through `sosfiltfilt`, the variance and the lag-5
    /// autocovariance within 2 % (a statistical witness that shares no code with the sums).
    #[test]
    fn filtered_noise_autocovariance_matches_a_filtered_noise() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let d = ShaftDesign {
            monitor: MonitorConfig::default(),
            cell: CellParams::default(),
            rate_hz: 10_000.0,
        };
        let r = d.noise_autocovariance().unwrap();
        let var = d.noise_variance();
        let sos = butter(4, &[500.0], Band::Lowpass, 10_000.0)
            .unwrap()
            .to_sos();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let normal = Normal::new(0.0, var.sqrt()).unwrap();
        let x: Vec<f64> = (0..200_000).map(|_| normal.sample(&mut rng)).collect();
        let y = sos.sosfiltfilt(&x).unwrap();
        let y = &y[1000..y.len() - 1000];
        let n = y.len() as f64;
        let c0 = y.iter().map(|v| v * v).sum::<f64>() / n;
        let c1 = y.iter().zip(&y[5..]).map(|(a, b)| a * b).sum::<f64>() / n;
        assert!((c0 / r[0] - 1.0).abs() < 0.02, "{c0} {}", r[0]);
        assert!((c1 / r[1] - 1.0).abs() < 0.05, "{c1} {}", r[1]);
        // The low-pass keeps ≈ the fraction of the band it passes (|H|⁴'s width, below 1/10).
        assert!(r[0] < 0.1 * var && r[0] > 0.05 * var, "{} {var}", r[0]);
    }
}
