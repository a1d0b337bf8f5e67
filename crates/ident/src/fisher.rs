//! Quantitative identifiability (thesis Eq. 5.12–5.13 and §9.2): Fisher information, standard
//! errors, confidence intervals, t-values, correlations; the collinearity index of Brun et al.
//! (2001); the D-, A-, E- and modified-E design criteria.

use crate::IdentError;
use nalgebra::{DMatrix, SymmetricEigen};
use serde::Serialize;
use statrs::distribution::{ContinuousCDF, StudentsT};

/// Precision of a parameter subset from its Fisher information.
#[derive(Debug, Clone, Serialize)]
pub struct Quantitative {
    /// Fisher information `I_F = JᵀΣ⁻¹J = JᵀJ/σ²` (Eq. 5.12).
    pub fim: DMatrix<f64>,
    /// Covariance `I_F⁻¹` (Cramér–Rao bound).
    pub covariance: DMatrix<f64>,
    /// Standard errors `√diag(I_F⁻¹)`.
    pub std_err: Vec<f64>,
    /// `ϑ/σ_ϑ`.
    pub t_values: Vec<f64>,
    /// 95 % confidence intervals `ϑ ± t(0.975, n − K)·σ_ϑ` (normal quantile if n − K is 0).
    pub ci95: Vec<(f64, f64)>,
    /// Correlation matrix of the estimates.
    pub correlation: DMatrix<f64>,
    /// The Student-t quantile used.
    pub t_quantile: f64,
}

/// Quantify the subset with Gram matrix `gram = JᵀJ` (unscaled sensitivities), noise variance
/// `sigma2`, centre values `theta` and `n` data rows.
pub fn quantify(
    gram: &DMatrix<f64>,
    sigma2: f64,
    theta: &[f64],
    n: usize,
) -> Result<Quantitative, IdentError> {
    let k = gram.ncols();
    if !(sigma2.is_finite() && sigma2 > 0.0) {
        return Err(IdentError::Invalid(format!(
            "noise variance {sigma2}: expected a finite value > 0"
        )));
    }
    let fim = gram / sigma2;
    let covariance = fim
        .clone()
        .cholesky()
        .ok_or(IdentError::Singular {
            what: "Fisher information of the selected parameters",
        })?
        .inverse();
    let std_err: Vec<f64> = (0..k).map(|i| covariance[(i, i)].sqrt()).collect();
    let dof = n.saturating_sub(k);
    let t_quantile = if dof > 0 {
        StudentsT::new(0.0, 1.0, dof as f64)
            .map(|t| t.inverse_cdf(0.975))
            .unwrap_or(1.959963984540054)
    } else {
        1.959963984540054
    };
    let t_values = theta.iter().zip(&std_err).map(|(t, s)| t / s).collect();
    let ci95 = theta
        .iter()
        .zip(&std_err)
        .map(|(t, s)| (t - t_quantile * s, t + t_quantile * s))
        .collect();
    let correlation = DMatrix::from_fn(k, k, |i, j| covariance[(i, j)] / (std_err[i] * std_err[j]));
    Ok(Quantitative {
        fim,
        covariance,
        std_err,
        t_values,
        ci95,
        correlation,
        t_quantile,
    })
}

/// Collinearity index `γ_K = 1/√λ_min(S̃ᵀS̃)` of Brun, Reichert and Künsch (2001), `S̃` the
/// sensitivity columns of the subset normalised to unit length, from their Gram matrix. `∞`
/// when the columns are linearly dependent to rounding (and for a zero column).
pub fn collinearity_index(gram: &DMatrix<f64>) -> f64 {
    let k = gram.ncols();
    let d: Vec<f64> = (0..k).map(|i| gram[(i, i)].sqrt()).collect();
    if d.iter().any(|&v| !(v > 0.0 && v.is_finite())) {
        return f64::INFINITY;
    }
    let g = DMatrix::from_fn(k, k, |i, j| gram[(i, j)] / (d[i] * d[j]));
    let lmin = SymmetricEigen::new(g).eigenvalues.min();
    // The normalised Gram's eigenvalues sum to K; below K·ε they are rounding.
    if lmin <= k as f64 * 1e3 * f64::EPSILON {
        f64::INFINITY
    } else {
        1.0 / lmin.sqrt()
    }
}

/// Optimal-design criteria of a Fisher information (Eq. 5.13).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DesignCriteria {
    /// D: `det I_F` (maximise).
    pub d: f64,
    /// A: `trace I_F⁻¹` (minimise); `∞` if singular.
    pub a: f64,
    /// E: `λ_min(I_F)` (maximise).
    pub e: f64,
    /// Modified E: `λ_max/λ_min` (minimise; the condition number); `∞` if singular.
    pub modified_e: f64,
}

/// The criteria of `fim`.
pub fn design_criteria(fim: &DMatrix<f64>) -> DesignCriteria {
    let eig = SymmetricEigen::new(fim.clone()).eigenvalues;
    let (lmin, lmax) = (eig.min(), eig.max());
    let d = eig.iter().product();
    let singular = lmin <= lmax * fim.ncols() as f64 * f64::EPSILON;
    let a = if singular {
        f64::INFINITY
    } else {
        eig.iter().map(|l| 1.0 / l).sum()
    };
    DesignCriteria {
        d,
        a,
        e: lmin,
        modified_e: if singular { f64::INFINITY } else { lmax / lmin },
    }
}
