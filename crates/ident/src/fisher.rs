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
            "noise variance {sigma2}: expected a finite value > 0",
            sigma2 = physid_core::Num(sigma2)
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
    let t_quantile = t_quantile_975(n.saturating_sub(k));
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

/// The normal distribution's 97.5 % quantile.
const Z_975: f64 = 1.959963984540054;

/// Degrees of freedom from which [`t_quantile_975`] uses its expansion.
const T_EXPANSION_FROM: usize = 10_000;

/// The Student-t distribution's 97.5 % quantile for `dof` degrees of freedom (0: the normal
/// one). Up to 10⁴ degrees of freedom `statrs`'s inverse; beyond, the Cornish–Fisher expansion
/// in 1/ν (Abramowitz & Stegun 26.7.5), whose first neglected term is below 1e-19 there —
/// `statrs`'s inverse of the incomplete beta function takes minutes at 36 M degrees of freedom
/// (a one-hour recording at 10 kHz).
pub fn t_quantile_975(dof: usize) -> f64 {
    if dof == 0 {
        return Z_975;
    }
    if dof < T_EXPANSION_FROM {
        return StudentsT::new(0.0, 1.0, dof as f64)
            .map(|t| t.inverse_cdf(0.975))
            .unwrap_or(Z_975);
    }
    let (z, v) = (Z_975, dof as f64);
    let (z2, z3) = (z * z, z * z * z);
    let (z5, z7, z9) = (z3 * z2, z3 * z2 * z2, z3 * z3 * z3);
    let g1 = (z3 + z) / 4.0;
    let g2 = (5.0 * z5 + 16.0 * z3 + 3.0 * z) / 96.0;
    let g3 = (3.0 * z7 + 19.0 * z5 + 17.0 * z3 - 15.0 * z) / 384.0;
    let g4 = (79.0 * z9 + 776.0 * z7 + 1482.0 * z5 - 1920.0 * z3 - 945.0 * z) / 92160.0;
    z + (g1 + (g2 + (g3 + g4 / v) / v) / v) / v
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The quantile against scipy's `stats.t.ppf(0.975, ν)` (`tests/golden/gen_t_quantile.py`)
    /// on both sides of the switch to the expansion — where `statrs`'s inverse has already
    /// drifted (3e-7 at 5·10⁴) — up to a one-hour recording's degrees of freedom.
    #[test]
    fn the_t_quantile_equals_scipys() {
        for (dof, scipy) in [
            (30, 2.0422724563012378),
            (10_000, 1.960201239890626),
            (20_000, 1.9600826051581348),
            (50_000, 1.9600114310936798),
            (1_000_000, 1.959966356814107),
            (36_000_000, 1.9599640504364788),
        ] {
            let t = t_quantile_975(dof);
            assert!((t - scipy).abs() < 1e-12, "{dof}: {t} vs {scipy}");
        }
        // Just below the switch, statrs's inverse agrees with the expansion's first terms.
        let below = t_quantile_975(T_EXPANSION_FROM - 1);
        let v = (T_EXPANSION_FROM - 1) as f64;
        let z = Z_975;
        let first_two = z + (z * z * z + z) / 4.0 / v;
        assert!((below - first_two).abs() < 1e-7, "{below} vs {first_two}");
        assert_eq!(t_quantile_975(0), Z_975);
    }
}
