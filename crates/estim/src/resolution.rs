//! Whether the data resolved each estimated parameter — the thesis's identifiability question
//! (§5.5: which parameters can the data determine?) put to the estimator's own covariance
//! after a run, so that an estimate the data cannot support is flagged instead of reported
//! with a false certainty (a standard error of 0 on data scaled by 1e-300, wild values on
//! collinear regressors).
//!
//! The data's information about the parameters is what the run added to the prior's:
//! `I = P⁻¹ − P0⁻¹` (for RLS exactly `ΦᵀΦ`, the normal-equations matrix; for the filters its
//! linearised counterpart). A parameter is **resolved** when both
//!
//! * its variance fell: `P_jj / P0_jj < ½` (the data halved at least the prior's
//!   uncertainty), and
//! * it is distinguishable from the others: its *independence* `1/VIF_j = 1 − R²_j`, the part
//!   of its information no combination of the other parameters' carries
//!   (`1 / (I_jj · (I⁻¹)_jj)`), is above `1e-6` — zero for exactly collinear regressors.
//!
//! With forgetting, or process noise, the prior is forgotten too; the variance test then
//! compares with the starting covariance all the same, which flags a parameter whose
//! uncertainty wound back up when the excitation stopped.

use nalgebra::DMatrix;

/// The variance ratio `P_jj/P0_jj` at or above which a parameter is unresolved.
pub const MAX_VARIANCE_RATIO: f64 = 0.5;
/// The independence `1/VIF` at or below which a parameter is unresolved.
pub const MIN_INDEPENDENCE: f64 = 1e-6;

/// Per-parameter resolution of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct Resolution {
    /// `P_jj / P0_jj`.
    pub variance_ratio: Vec<f64>,
    /// `1/VIF_j` from the data's information `P⁻¹ − P0⁻¹` (0 when the data carry none).
    pub independence: Vec<f64>,
    /// Both tests passed.
    pub resolved: Vec<bool>,
}

impl Resolution {
    /// The indices of the unresolved parameters.
    pub fn unresolved(&self) -> Vec<usize> {
        (0..self.resolved.len())
            .filter(|&j| !self.resolved[j])
            .collect()
    }
}

/// The resolution of a run that started from covariance `p0` and ended at `p` (same
/// coordinates, square, the same size).
pub fn resolution(p: &DMatrix<f64>, p0: &DMatrix<f64>) -> Resolution {
    let n = p.nrows();
    let variance_ratio: Vec<f64> = (0..n).map(|j| p[(j, j)] / p0[(j, j)]).collect();
    let independence = independence(p, p0);
    let resolved = (0..n)
        .map(|j| {
            variance_ratio[j] < MAX_VARIANCE_RATIO
                && independence[j] > MIN_INDEPENDENCE
                && variance_ratio[j].is_finite()
        })
        .collect();
    Resolution {
        variance_ratio,
        independence,
        resolved,
    }
}

/// `1/VIF_j` of the information `I = P⁻¹ − P0⁻¹`, from the eigen-decomposition of its
/// correlation form `R = D^{-1/2} I D^{-1/2}`: `VIF_j = Σ_k V_jk²/λ_k`, an eigenvalue below
/// `1e-12·λ_max` counting as zero (an exact dependence).
fn independence(p: &DMatrix<f64>, p0: &DMatrix<f64>) -> Vec<f64> {
    let n = p.nrows();
    let (Some(pi), Some(p0i)) = (
        p.clone().cholesky().map(|c| c.inverse()),
        p0.clone().cholesky().map(|c| c.inverse()),
    ) else {
        return vec![0.0; n];
    };
    let info = pi - &p0i;
    // A diagonal at round-off of the prior's own is no information at all.
    let d: Vec<f64> = (0..n)
        .map(|j| {
            let floor = 1e-9 * p0i[(j, j)].abs();
            if info[(j, j)] > floor {
                info[(j, j)]
            } else {
                0.0
            }
        })
        .collect();
    let live: Vec<usize> = (0..n).filter(|&j| d[j] > 0.0).collect();
    let mut out = vec![0.0; n];
    if live.is_empty() {
        return out;
    }
    let m = live.len();
    let r = DMatrix::from_fn(m, m, |a, b| {
        let (i, j) = (live[a], live[b]);
        info[(i, j)] / (d[i] * d[j]).sqrt()
    });
    let eig = nalgebra::SymmetricEigen::new(r);
    let lmax = eig.eigenvalues.iter().cloned().fold(0.0, f64::max);
    for (a, &j) in live.iter().enumerate() {
        let mut vif = 0.0;
        for k in 0..m {
            let v2 = eig.eigenvectors[(a, k)].powi(2);
            let l = eig.eigenvalues[k];
            if l <= 1e-12 * lmax {
                if v2 > 1e-12 {
                    vif = f64::INFINITY;
                    break;
                }
            } else {
                vif += v2 / l;
            }
        }
        out[j] = if vif.is_finite() && vif > 0.0 {
            (1.0 / vif).min(1.0)
        } else {
            0.0
        };
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// RLS's covariance after regressors `x` with prior `p0·I`: `(I/p0 + XᵀX)⁻¹`.
    fn after(x: &DMatrix<f64>, p0: f64) -> (DMatrix<f64>, DMatrix<f64>) {
        let n = x.ncols();
        let prior = DMatrix::identity(n, n) * p0;
        let info = x.transpose() * x;
        let p = (DMatrix::identity(n, n) / p0 + info).try_inverse().unwrap();
        (p, prior)
    }

    #[test]
    fn independence_is_one_minus_r_squared_and_collinearity_is_zero() {
        // Two regressors at angle φ: 1/VIF = 1 − cos²φ = sin²φ (the R² of one on the other).
        let phi: f64 = 0.3;
        let rows = 400;
        let x = DMatrix::from_fn(rows, 2, |i, j| {
            let t = i as f64 * 0.05;
            let (a, b) = (t.sin(), t.cos());
            if j == 0 {
                a
            } else {
                a * phi.cos() + b * phi.sin()
            }
        });
        // With a vanishing prior the information is XᵀX itself.
        let (p, p0) = after(&x, 1e12);
        let r = resolution(&p, &p0);
        let xtx = x.transpose() * &x;
        let cos2 = xtx[(0, 1)].powi(2) / (xtx[(0, 0)] * xtx[(1, 1)]);
        for j in 0..2 {
            assert!((r.independence[j] - (1.0 - cos2)).abs() < 1e-6, "{r:?}");
            assert!(r.resolved[j]);
        }
        // Exactly collinear: no independence, both unresolved, whatever the variance did.
        let y = DMatrix::from_fn(rows, 2, |i, _| (i as f64 * 0.05).sin());
        let (p, p0) = after(&y, 1000.0);
        let r = resolution(&p, &p0);
        assert_eq!(r.independence, [0.0, 0.0], "{r:?}");
        assert_eq!(r.unresolved(), [0, 1]);
        // Data scaled by 1e-300: XᵀX underflows to 0, P stays P0.
        let tiny = x.map(|v| v * 1e-300);
        let (p, p0) = after(&tiny, 1000.0);
        let r = resolution(&p, &p0);
        assert!(
            r.variance_ratio.iter().all(|&v| (v - 1.0).abs() < 1e-12),
            "{r:?}"
        );
        assert_eq!(r.unresolved(), [0, 1]);
    }
}
