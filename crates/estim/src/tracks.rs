//! An estimator over whole arrays, recording what it tracks after every row — the estimate,
//! its standard errors, the prediction error — into preallocated tracks: the Python package's
//! `run` (`crates/py`) and `physid bench`'s measure of it. The loop is compiled for each
//! estimator type (no dispatch per row) and allocates nothing per row.

use crate::nonlinear::ModelFilter;
use crate::{EstimError, LinearEstimator};

/// What [`track`] needs of an estimator, allocation-free.
pub trait Track {
    /// One row (the regressor φ or the model's inputs, and `y`); the prediction error.
    fn step(&mut self, x: &[f64], y: f64) -> Result<f64, EstimError>;
    /// The estimate of the free parameters into `out`.
    fn estimate_into(&self, out: &mut [f64]);
    /// Their standard errors into `out`, NaN while they cannot be estimated yet.
    fn std_err_into(&self, out: &mut [f64]);
}

impl Track for LinearEstimator {
    fn step(&mut self, x: &[f64], y: f64) -> Result<f64, EstimError> {
        Ok(self.update(x, y)?.prediction_error)
    }
    fn estimate_into(&self, out: &mut [f64]) {
        out.copy_from_slice(self.estimate());
    }
    fn std_err_into(&self, out: &mut [f64]) {
        if self.std_errors_into(out).is_err() {
            out.fill(f64::NAN);
        }
    }
}

impl<T: ModelFilter> Track for T {
    fn step(&mut self, x: &[f64], y: f64) -> Result<f64, EstimError> {
        Ok(ModelFilter::step(self, x, y)?.prediction_error)
    }
    fn estimate_into(&self, out: &mut [f64]) {
        ModelFilter::estimate_into(self, out);
    }
    fn std_err_into(&self, out: &mut [f64]) {
        ModelFilter::std_errors_into(self, out);
    }
}

/// The tracks of [`track`]: `theta` and `se` row-major n × k, `errors` n.
#[derive(Debug, Clone, PartialEq)]
pub struct Tracks {
    /// The estimate after each row.
    pub theta: Vec<f64>,
    /// Its standard errors (NaN while not estimable, or when not asked for).
    pub se: Vec<f64>,
    /// The a-priori prediction error of each row (NaN where the row was skipped).
    pub errors: Vec<f64>,
    /// Rows refused and skipped.
    pub skipped: Vec<usize>,
}

/// Every row of `x` (row-major, `w` columns) and `y` through `e`, whose estimate has `k`
/// values. A refused row is an error naming it, or with `skip_bad` is skipped (its track row
/// repeats the previous estimate). Without `std_err` the standard errors are not computed.
///
/// # Panics
/// If `w` is 0 (the caller's check) or `x` has fewer than `w·y.len()` values.
pub fn track<E: Track>(
    e: &mut E,
    x: &[f64],
    y: &[f64],
    w: usize,
    k: usize,
    skip_bad: bool,
    std_err: bool,
) -> Result<Tracks, String> {
    let n = y.len();
    assert!(w > 0 && x.len() >= n * w, "track: {n} rows of {w} columns");
    // Zeroed (pages the kernel hands out lazily), then every row written once.
    let mut t = Tracks {
        theta: vec![0.0; n * k],
        se: vec![if std_err { 0.0 } else { f64::NAN }; n * k],
        errors: vec![0.0; n],
        skipped: Vec::new(),
    };
    for (i, (row, &yi)) in x.chunks_exact(w).zip(y).enumerate() {
        match e.step(row, yi) {
            Ok(err) => t.errors[i] = err,
            Err(err) if !skip_bad => return Err(format!("row {i} of the arrays: {err}")),
            Err(_) => {
                t.errors[i] = f64::NAN;
                t.skipped.push(i);
            }
        }
        e.estimate_into(&mut t.theta[i * k..(i + 1) * k]);
        if std_err {
            e.std_err_into(&mut t.se[i * k..(i + 1) * k]);
        }
    }
    Ok(t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{EstimatorConfig, Method};
    use physid_core::ParamSet;

    /// The tracks are the estimator's state after each update; a bad row is named or skipped.
    #[test]
    fn the_tracks_are_the_updates() {
        let params = ParamSet::zeros(["a", "b"]).unwrap_or_else(|e| panic!("{e}"));
        let cfg = EstimatorConfig::new(Method::Rls);
        let new = || {
            LinearEstimator::new(&cfg, &params, &params.all_free())
                .unwrap_or_else(|e| panic!("{e}"))
        };
        let x = [1.0, 0.0, 0.0, 1.0, 1.0, 1.0, 2.0, -1.0];
        let y = [1.0, 2.0, 3.1, 0.1];
        let mut e = new();
        let t = track(&mut e, &x, &y, 2, 2, false, true).unwrap_or_else(|e| panic!("{e}"));
        let mut f = new();
        for i in 0..4 {
            let err = f
                .update(&x[2 * i..2 * i + 2], y[i])
                .map(|s| s.prediction_error);
            assert_eq!(Ok(t.errors[i]), err);
            assert_eq!(&t.theta[2 * i..2 * i + 2], f.estimate());
        }
        let mut bad = x;
        bad[3] = f64::NAN;
        let e2 = track(&mut new(), &bad, &y, 2, 2, false, true).err();
        assert!(e2.is_some_and(|m| m.starts_with("row 1 of the arrays")));
        let t = track(&mut new(), &bad, &y, 2, 2, true, false).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(t.skipped, [1]);
        assert_eq!(t.theta[2..4], t.theta[0..2]);
        assert!(t.errors[1].is_nan() && t.se.iter().all(|v| v.is_nan()));
    }
}
