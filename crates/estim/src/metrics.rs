//! Prediction-quality metrics (thesis §6, Eq. 6.4).

/// The one-step prediction metrics of a run, accumulated a sample at a time ([`push`]
/// (Self::push)) so a stream of any length is summed in constant memory; [`nmse`], [`nrmse`] and
/// [`fit_percent`] over whole arrays are this, fed every sample.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Prediction {
    n: usize,
    /// Σ(Ym − Yp)², ΣYm, ΣYp, ΣYm².
    err: f64,
    sum_m: f64,
    sum_p: f64,
    sum_m2: f64,
    /// Welford's running mean of Ym and Σ(Ym − mean)².
    mean_m: f64,
    m2: f64,
    /// max 100·|Ym − Yp|/|Ym|.
    max_rel: f64,
}

impl Prediction {
    /// The metrics of `predicted` against `measured` (`None` for unequal lengths).
    pub fn of(measured: &[f64], predicted: &[f64]) -> Option<Self> {
        if measured.len() != predicted.len() {
            return None;
        }
        let mut m = Self::default();
        for (&y, &p) in measured.iter().zip(predicted) {
            m.push(y, p);
        }
        Some(m)
    }

    /// One sample: measured `y`, predicted `p`.
    pub fn push(&mut self, y: f64, p: f64) {
        self.n += 1;
        self.err += (y - p) * (y - p);
        self.sum_m += y;
        self.sum_p += p;
        self.sum_m2 += y * y;
        let d = y - self.mean_m;
        self.mean_m += d / self.n as f64;
        self.m2 += d * (y - self.mean_m);
        self.max_rel = self.max_rel.max(100.0 * (y - p).abs() / y.abs());
    }

    /// Samples taken.
    pub fn len(&self) -> usize {
        self.n
    }

    /// No sample taken.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Normalised mean square error exactly as the thesis defines it (Eq. 6.4):
    /// `NMSE = mean((Ym − Yp)²) / (mean(Ym)·mean(Yp))`; `None` with no sample or a zero
    /// denominator.
    pub fn nmse(&self) -> Option<f64> {
        let n = self.n as f64;
        let den = (self.sum_m / n) * (self.sum_p / n);
        (self.n > 0 && den != 0.0).then(|| (self.err / n) / den)
    }

    /// Normalised root mean square error `rms(Ym − Yp)/rms(Ym)`.
    pub fn nrmse(&self) -> Option<f64> {
        (self.n > 0 && self.sum_m2 != 0.0).then(|| (self.err / self.sum_m2).sqrt())
    }

    /// Fit in percent, `100·(1 − ‖Ym − Yp‖/‖Ym − mean(Ym)‖)`.
    pub fn fit_percent(&self) -> Option<f64> {
        (self.n > 0 && self.m2 != 0.0).then(|| 100.0 * (1.0 - (self.err / self.m2).sqrt()))
    }

    /// Largest relative error in per cent, `max 100·|Ym − Yp|/|Ym|` (∞ if a measured sample is
    /// 0 and mispredicted; a 0 predicted as 0 counts as no error); `None` with no sample.
    pub fn max_relative_percent(&self) -> Option<f64> {
        (self.n > 0).then_some(self.max_rel)
    }
}

/// Normalised mean square error exactly as the thesis defines it (Eq. 6.4):
/// `NMSE = mean((Ym − Yp)²) / (mean(Ym)·mean(Yp))`.
///
/// Ill-defined for signals whose mean is near zero (a cyclic torque): prefer [`nrmse`] there.
/// Returns `None` for empty or unequal-length inputs, or when the denominator is zero.
pub fn nmse(measured: &[f64], predicted: &[f64]) -> Option<f64> {
    Prediction::of(measured, predicted)?.nmse()
}

/// Normalised root mean square error `rms(Ym − Yp)/rms(Ym)`.
pub fn nrmse(measured: &[f64], predicted: &[f64]) -> Option<f64> {
    Prediction::of(measured, predicted)?.nrmse()
}

/// Fit in percent, `100·(1 − ‖Ym − Yp‖/‖Ym − mean(Ym)‖)` (100 = perfect, 0 = no better than the
/// mean, negative = worse).
pub fn fit_percent(measured: &[f64], predicted: &[f64]) -> Option<f64> {
    Prediction::of(measured, predicted)?.fit_percent()
}

/// Largest relative error in per cent, `max 100·|y − ŷ|/|y|` — for a signal that keeps its
/// sign (a friction torque); `None` if empty or of different lengths (∞ if a measured sample
/// is 0 and mispredicted).
pub fn max_relative_percent(measured: &[f64], predicted: &[f64]) -> Option<f64> {
    Prediction::of(measured, predicted)?.max_relative_percent()
}

#[cfg(test)]
mod tests {
    use super::*;

    // Hand-computed: Ym = (1, 2, 3, 4), Yp = (1, 2, 3, 6): errors (0, 0, 0, −2).
    // mean sq err = 4/4 = 1; mean Ym = 2.5, mean Yp = 3 → NMSE = 1/7.5.
    // rms: ‖e‖² = 4, ‖Ym‖² = 30 → NRMSE = sqrt(4/30).
    // ‖Ym − mean‖² = 2.25 + 0.25 + 0.25 + 2.25 = 5 → fit = 100(1 − sqrt(4/5)).
    #[test]
    fn hand_computed_values() {
        let m = [1.0, 2.0, 3.0, 4.0];
        let p = [1.0, 2.0, 3.0, 6.0];
        assert!((nmse(&m, &p).unwrap() - 1.0 / 7.5).abs() < 1e-15);
        assert!((nrmse(&m, &p).unwrap() - (4.0f64 / 30.0).sqrt()).abs() < 1e-15);
        assert!((fit_percent(&m, &p).unwrap() - 100.0 * (1.0 - 0.8f64.sqrt())).abs() < 1e-12);
        assert_eq!(fit_percent(&m, &m), Some(100.0));
        // |4 − 6|/4 = 50 %; −2 predicted as −1: 50 % too (the sign of y does not matter).
        assert_eq!(max_relative_percent(&m, &p), Some(50.0));
        assert_eq!(max_relative_percent(&[-2.0], &[-1.0]), Some(50.0));
    }

    /// Welford's sum of squares against the two-pass one, on data with a large mean (where
    /// `Σy² − n·mean²` would lose every digit).
    #[test]
    fn the_running_sums_agree_with_two_passes() {
        let m: Vec<f64> = (0..10_000).map(|i| 1e6 + (i as f64 * 0.37).sin()).collect();
        let p: Vec<f64> = m.iter().map(|y| y + 0.01 * (y * 3.0).cos()).collect();
        let mean = m.iter().sum::<f64>() / m.len() as f64;
        let var: f64 = m.iter().map(|y| (y - mean) * (y - mean)).sum();
        let err: f64 = m.iter().zip(&p).map(|(y, q)| (y - q) * (y - q)).sum();
        let two_pass = 100.0 * (1.0 - (err / var).sqrt());
        let fit = fit_percent(&m, &p).unwrap();
        assert!(
            (fit - two_pass).abs() < 1e-9 * two_pass.abs(),
            "{fit} {two_pass}"
        );
    }

    #[test]
    fn degenerate_inputs_are_none() {
        assert_eq!(nmse(&[], &[]), None);
        assert_eq!(nmse(&[1.0], &[1.0, 2.0]), None);
        assert_eq!(nmse(&[1.0, -1.0], &[1.0, -1.0]), None);
        assert_eq!(nrmse(&[0.0], &[1.0]), None);
        assert_eq!(fit_percent(&[2.0, 2.0], &[1.0, 2.0]), None);
        assert_eq!(max_relative_percent(&[], &[]), None);
    }
}
