//! Prediction-quality metrics (thesis §6, Eq. 6.4).

/// Normalised mean square error exactly as the thesis defines it (Eq. 6.4):
/// `NMSE = mean((Ym − Yp)²) / (mean(Ym)·mean(Yp))`.
///
/// Ill-defined for signals whose mean is near zero (a cyclic torque): prefer [`nrmse`] there.
/// Returns `None` for empty or unequal-length inputs, or when the denominator is zero.
pub fn nmse(measured: &[f64], predicted: &[f64]) -> Option<f64> {
    if measured.is_empty() || measured.len() != predicted.len() {
        return None;
    }
    let n = measured.len() as f64;
    let mse = measured
        .iter()
        .zip(predicted)
        .map(|(m, p)| (m - p) * (m - p))
        .sum::<f64>()
        / n;
    let den = (measured.iter().sum::<f64>() / n) * (predicted.iter().sum::<f64>() / n);
    (den != 0.0).then(|| mse / den)
}

/// Normalised root mean square error `rms(Ym − Yp)/rms(Ym)`.
pub fn nrmse(measured: &[f64], predicted: &[f64]) -> Option<f64> {
    if measured.is_empty() || measured.len() != predicted.len() {
        return None;
    }
    let err: f64 = measured
        .iter()
        .zip(predicted)
        .map(|(m, p)| (m - p) * (m - p))
        .sum();
    let rms: f64 = measured.iter().map(|m| m * m).sum();
    (rms != 0.0).then(|| (err / rms).sqrt())
}

/// Fit in percent, `100·(1 − ‖Ym − Yp‖/‖Ym − mean(Ym)‖)` (100 = perfect, 0 = no better than the
/// mean, negative = worse).
pub fn fit_percent(measured: &[f64], predicted: &[f64]) -> Option<f64> {
    if measured.is_empty() || measured.len() != predicted.len() {
        return None;
    }
    let mean = measured.iter().sum::<f64>() / measured.len() as f64;
    let err: f64 = measured
        .iter()
        .zip(predicted)
        .map(|(m, p)| (m - p) * (m - p))
        .sum();
    let var: f64 = measured.iter().map(|m| (m - mean) * (m - mean)).sum();
    (var != 0.0).then(|| 100.0 * (1.0 - (err / var).sqrt()))
}

/// Largest relative error in per cent, `max 100·|y − ŷ|/|y|` — for a signal that keeps its
/// sign (a friction torque); `None` if empty or of different lengths (∞ if a measured sample
/// is 0 and mispredicted).
pub fn max_relative_percent(measured: &[f64], predicted: &[f64]) -> Option<f64> {
    if measured.is_empty() || measured.len() != predicted.len() {
        return None;
    }
    Some(
        measured
            .iter()
            .zip(predicted)
            .map(|(m, p)| 100.0 * (m - p).abs() / m.abs())
            .fold(0.0, f64::max),
    )
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
