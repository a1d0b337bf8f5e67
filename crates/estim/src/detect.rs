//! Change detection on recursive estimates and residuals.
//!
//! * [`RelativeErrorDetector`] — the thesis's fault detector (Eq. 6.3): the relative error
//!   `e_i = (ϑ_healthy,i − ϑ̂_i)/ϑ_healthy,i` of each parameter against its own bound, with a
//!   dwell: an alarm is raised after `k` consecutive samples beyond the bound, which isolates the
//!   parameter that moved.
//! * [`Cusum`] — the CUSUM test of Brown, Durbin & Evans (1975) on the standardised recursive
//!   residuals `w_t` ([`Step::standardized_residual`](crate::Step)), on-line.

use crate::EstimError;
use serde::{Deserialize, Serialize};

/// A raised alarm: which parameter moved, when, and by how much.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Alarm {
    /// Index of the parameter in the detector's order.
    pub param: usize,
    /// Its name.
    pub name: String,
    /// First sample of the run of samples beyond the bound.
    pub onset_sample: u64,
    /// Sample at which the dwell was completed and the alarm raised.
    pub raised_sample: u64,
    /// Relative error `e_i` (Eq. 6.3) when the alarm was raised.
    pub relative_error: f64,
}

/// The relative-error change detector of Eq. 6.3 with a per-parameter bound and a dwell.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct RelativeErrorDetector {
    names: Vec<String>,
    healthy: Vec<f64>,
    bounds: Vec<f64>,
    dwell: u64,
    run: Vec<u64>,
    active: Vec<bool>,
    last_error: Vec<f64>,
    sample: u64,
    alarms: Vec<Alarm>,
}

impl RelativeErrorDetector {
    /// A detector for parameters `names` with healthy values `healthy` (non-zero), bounds on
    /// `|e_i|` (positive; e.g. 0.1 for ±10 %) and a dwell of `dwell ≥ 1` consecutive samples.
    pub fn new(
        names: Vec<String>,
        healthy: Vec<f64>,
        bounds: Vec<f64>,
        dwell: u64,
    ) -> Result<Self, EstimError> {
        let n = names.len();
        for (what, len) in [("healthy values", healthy.len()), ("bounds", bounds.len())] {
            if len != n {
                return Err(EstimError::DimensionMismatch {
                    what,
                    expected: n,
                    got: len,
                });
            }
        }
        for (i, (&h, &b)) in healthy.iter().zip(&bounds).enumerate() {
            if !(h.is_finite() && h != 0.0) {
                return Err(EstimError::InvalidConfig(format!(
                    "healthy value of '{}' must be finite and non-zero (Eq. 6.3 divides by it), got {h}",
                    names[i]
                )));
            }
            if !(b.is_finite() && b > 0.0) {
                return Err(EstimError::InvalidConfig(format!(
                    "bound of '{}' must be positive, got {}",
                    names[i],
                    physid_core::Num(b)
                )));
            }
        }
        if dwell == 0 {
            return Err(EstimError::InvalidConfig(
                "dwell must be at least 1 sample".into(),
            ));
        }
        Ok(Self {
            names,
            healthy,
            bounds,
            dwell,
            run: vec![0; n],
            active: vec![false; n],
            last_error: vec![0.0; n],
            sample: 0,
            alarms: Vec::with_capacity(16),
        })
    }

    /// Feed one set of estimates (same order as the names). Returns how many alarms this sample
    /// raised; they are appended to [`alarms`](Self::alarms). A parameter whose error returns
    /// within its bound re-arms, so a later excursion raises a new alarm.
    pub fn update(&mut self, estimate: &[f64]) -> Result<usize, EstimError> {
        if estimate.len() != self.names.len() {
            return Err(EstimError::DimensionMismatch {
                what: "estimates for the detector",
                expected: self.names.len(),
                got: estimate.len(),
            });
        }
        if let Some(i) = estimate.iter().position(|v| !v.is_finite()) {
            return Err(EstimError::NonFinite {
                sample: self.sample,
                what: format!("estimate of '{}'", self.names[i]),
                value: estimate[i],
            });
        }
        let mut raised = 0;
        for (i, &est) in estimate.iter().enumerate() {
            let e = (self.healthy[i] - est) / self.healthy[i];
            self.last_error[i] = e;
            if e.abs() > self.bounds[i] {
                self.run[i] += 1;
                if self.run[i] == self.dwell && !self.active[i] {
                    self.active[i] = true;
                    raised += 1;
                    self.alarms.push(Alarm {
                        param: i,
                        name: self.names[i].clone(),
                        onset_sample: self.sample + 1 - self.dwell,
                        raised_sample: self.sample,
                        relative_error: e,
                    });
                }
            } else {
                self.run[i] = 0;
                self.active[i] = false;
            }
        }
        self.sample += 1;
        Ok(raised)
    }

    /// The latest relative errors `e_i` (Eq. 6.3).
    pub fn relative_errors(&self) -> &[f64] {
        &self.last_error
    }

    /// Which parameters are currently in alarm.
    pub fn active(&self) -> &[bool] {
        &self.active
    }

    /// All alarms raised so far.
    pub fn alarms(&self) -> &[Alarm] {
        &self.alarms
    }
}

/// The CUSUM test of the recursive residuals (Brown, Durbin & Evans 1975), on-line.
///
/// `W_t = (1/σ̂) Σ_{j=d+1..t} w_j`, with `σ̂` the sample standard deviation (ddof = 1) of the
/// residuals after the burn-in `d`. On-line, σ̂ is the one of the residuals seen so far; at the
/// end of a record it is the full-sample one, so the final statistic equals the batch statistic
/// (statsmodels' `RecursiveLSResults.cusum`).
#[derive(Debug, Clone, Default)]
pub struct Cusum {
    burn: u64,
    offered: u64,
    n: u64,
    sum: f64,
    mean: f64,
    m2: f64,
}

impl Cusum {
    /// A CUSUM that ignores the first `burn` residuals (statsmodels: the number of regressors,
    /// or its diffuse/burn-in count).
    pub fn new(burn: u64) -> Self {
        Self {
            burn,
            ..Self::default()
        }
    }

    /// Offer the next standardised residual; returns `W_t` once two residuals are in.
    pub fn push(&mut self, w: f64) -> Option<f64> {
        self.offered += 1;
        if self.offered <= self.burn || !w.is_finite() {
            return None;
        }
        self.n += 1;
        self.sum += w;
        // Welford's update of mean and sum of squared deviations.
        let delta = w - self.mean;
        self.mean += delta / self.n as f64;
        self.m2 += delta * (w - self.mean);
        self.statistic()
    }

    /// `Σ w_j` after the burn-in (the un-normalised CUSUM path).
    pub fn cumulative_sum(&self) -> f64 {
        self.sum
    }

    /// Sample standard deviation (ddof = 1) of the residuals after the burn-in.
    pub fn std(&self) -> Option<f64> {
        (self.n >= 2).then(|| (self.m2 / (self.n - 1) as f64).sqrt())
    }

    /// The current statistic `W_t`.
    pub fn statistic(&self) -> Option<f64> {
        self.std().filter(|s| *s > 0.0).map(|s| self.sum / s)
    }

    /// Residuals counted (after the burn-in).
    pub fn count(&self) -> u64 {
        self.n
    }

    /// The Brown–Durbin–Evans significance line at this point of a record of `horizon` residuals
    /// after the burn-in: `a·√h + 2a·t/√h` with `t` = residuals so far, `a` = 0.850, 0.948 or
    /// 1.143 for the 10 %, 5 % or 1 % level. `|W_t|` beyond it signals a change.
    pub fn bound(&self, level: CusumLevel, horizon: u64) -> f64 {
        let a = level.constant();
        let h = (horizon.max(1) as f64).sqrt();
        a * h + 2.0 * a * self.n as f64 / h
    }
}

/// Significance level of the CUSUM lines.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum CusumLevel {
    /// 10 % (a = 0.850).
    P10,
    /// 5 % (a = 0.948).
    P5,
    /// 1 % (a = 1.143).
    P1,
}

impl CusumLevel {
    /// The constant `a` of Brown, Durbin & Evans (1975), Table 1.
    pub fn constant(self) -> f64 {
        match self {
            CusumLevel::P10 => 0.850,
            CusumLevel::P5 => 0.948,
            CusumLevel::P1 => 1.143,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dwell_isolates_and_rearms() {
        let mut d = RelativeErrorDetector::new(
            vec!["K".into(), "B".into()],
            vec![1000.0, 1.0],
            vec![0.1, 0.2],
            3,
        )
        .unwrap();
        // K at 1150 (e = −0.15) from sample 2; B stays at 0.9 (e = 0.1 < 0.2).
        let seq = [
            1000.0, 1000.0, 1150.0, 1150.0, 1150.0, 1150.0, 1000.0, 1200.0,
        ];
        let mut raised = vec![];
        for &k in &seq {
            raised.push(d.update(&[k, 0.9]).unwrap());
        }
        assert_eq!(raised, vec![0, 0, 0, 0, 1, 0, 0, 0]);
        let a = &d.alarms()[0];
        assert_eq!((a.param, a.onset_sample, a.raised_sample), (0, 2, 4));
        assert!((a.relative_error + 0.15).abs() < 1e-12);
        assert_eq!(d.active(), &[false, false]); // sample 7: back, then one sample out
        assert!((d.relative_errors()[0] + 0.2).abs() < 1e-12);
    }

    #[test]
    fn bad_configuration_is_refused() {
        let n = || vec!["K".to_string()];
        assert!(RelativeErrorDetector::new(n(), vec![0.0], vec![0.1], 1).is_err());
        assert!(RelativeErrorDetector::new(n(), vec![1.0], vec![-0.1], 1).is_err());
        assert!(RelativeErrorDetector::new(n(), vec![1.0], vec![0.1], 0).is_err());
        assert!(RelativeErrorDetector::new(n(), vec![1.0, 2.0], vec![0.1], 1).is_err());
        let mut d = RelativeErrorDetector::new(n(), vec![1.0], vec![0.1], 1).unwrap();
        assert!(d.update(&[f64::NAN]).is_err());
    }

    // Hand-computed: residuals 1, 2, 3, 6 after a burn of 1 (first value 100 ignored):
    // sum = 12, mean = 3, squared deviations 4+1+0+9 = 14, std = sqrt(14/3).
    #[test]
    fn cusum_hand_computed() {
        let mut c = Cusum::new(1);
        for w in [100.0, 1.0, 2.0, 3.0, 6.0] {
            c.push(w);
        }
        assert_eq!(c.count(), 4);
        assert!((c.statistic().unwrap() - 12.0 / (14.0f64 / 3.0).sqrt()).abs() < 1e-12);
        // Bound at t = 4 of a horizon of 4, 5 %: 0.948·2 + 2·0.948·4/2.
        assert!((c.bound(CusumLevel::P5, 4) - (0.948 * 2.0 + 0.948 * 4.0)).abs() < 1e-12);
    }
}
