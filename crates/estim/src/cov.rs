//! The covariance as an estimator holds it, with its form explicit in the type: P itself
//! ([`CovForm::Full`]: RLS family, Kalman, EKF, UKF) or its lower Cholesky factor S with
//! `P = S·Sᵀ` ([`CovForm::Sqrt`]: DSFC, Alg. 5.5; SR-UKF). And the factorisations the
//! estimators share, written once: an in-place Cholesky factor, rank-one updates and downdates
//! of a factor, and the jitter repair (SPEC §5.2) — symmetrise, add `ε·I` with
//! `ε = 1e-12·(trace/l)`, ×10 per try, up to 12 tries.

use crate::EstimError;
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// How a covariance is held.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CovForm {
    /// P itself.
    Full,
    /// S, the lower Cholesky factor of P (`P = S·Sᵀ`).
    Sqrt,
}

/// A covariance in its held form (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Cov {
    form: CovForm,
    held: DMatrix<f64>,
}

impl Cov {
    /// P held as it is.
    pub fn full(p: DMatrix<f64>) -> Self {
        Self {
            form: CovForm::Full,
            held: p,
        }
    }

    /// P held as its lower Cholesky factor `s`.
    pub fn sqrt(s: DMatrix<f64>) -> Self {
        Self {
            form: CovForm::Sqrt,
            held: s,
        }
    }

    /// P, checked positive definite, in the form `form` (factored for [`CovForm::Sqrt`]); `what`
    /// names P in the error.
    pub fn from_covariance(
        form: CovForm,
        p: DMatrix<f64>,
        what: &'static str,
    ) -> Result<Self, EstimError> {
        let s = p
            .clone()
            .cholesky()
            .ok_or(EstimError::NotPositiveDefinite { what })?
            .l();
        Ok(match form {
            CovForm::Full => Self::full(p),
            CovForm::Sqrt => Self::sqrt(s),
        })
    }

    /// The form.
    pub fn form(&self) -> CovForm {
        self.form
    }

    /// The matrix as held: P, or S.
    pub fn held(&self) -> &DMatrix<f64> {
        &self.held
    }

    /// The matrix as held, to update in place.
    pub(crate) fn held_mut(&mut self) -> &mut DMatrix<f64> {
        &mut self.held
    }

    /// Side length.
    pub fn dim(&self) -> usize {
        self.held.nrows()
    }

    /// P (formed as `S·Sᵀ` from a factor).
    pub fn covariance(&self) -> DMatrix<f64> {
        match self.form {
            CovForm::Full => self.held.clone(),
            CovForm::Sqrt => &self.held * self.held.transpose(),
        }
    }

    /// `P_ii` without forming P.
    pub fn variance(&self, i: usize) -> f64 {
        match self.form {
            CovForm::Full => self.held[(i, i)],
            CovForm::Sqrt => self.held.row(i).norm_squared(),
        }
    }

    /// trace(P) without forming P (`‖S‖²_F` from a factor).
    pub fn trace(&self) -> f64 {
        match self.form {
            CovForm::Full => self.held.trace(),
            CovForm::Sqrt => self.held.norm_squared(),
        }
    }
}

/// Lower-triangular Cholesky factor written over `a` (its lower triangle read, the upper part
/// zeroed); false if `a` is not positive definite. Right-looking: each column, once final,
/// is taken off the trailing columns below their diagonal — contiguous column operations that
/// vectorise, where the dot-product form reads rows. Allocation-free.
pub(crate) fn cholesky_in_place(a: &mut DMatrix<f64>) -> bool {
    let n = a.nrows();
    let m = a.as_mut_slice();
    for j in 0..n {
        let (done, trailing) = m.split_at_mut((j + 1) * n);
        let col = &mut done[j * n..];
        let d = col[j];
        if !(d > 0.0 && d.is_finite()) {
            return false;
        }
        let d = d.sqrt();
        col[..j].fill(0.0);
        col[j] = d;
        for v in &mut col[j + 1..] {
            *v /= d;
        }
        let col = &*col;
        for (k, tcol) in (j + 1..n).zip(trailing.chunks_exact_mut(n)) {
            let f = col[k];
            for (t, &c) in tcol[k..].iter_mut().zip(&col[k..]) {
                *t -= c * f;
            }
        }
    }
    true
}

/// Rank-one update (`sign` = 1) or downdate (`sign` = −1) of a lower Cholesky factor in place:
/// `L Lᵀ ± x xᵀ` (`x` is overwritten). False if the result is not positive definite (then `l`
/// is partly modified: work on a copy). Allocation-free.
pub(crate) fn chol_rank_one(l: &mut DMatrix<f64>, x: &mut DVector<f64>, sign: f64) -> bool {
    let n = l.nrows();
    for k in 0..n {
        let lkk = l[(k, k)];
        let r2 = lkk * lkk + sign * x[k] * x[k];
        if r2.is_nan() || r2 <= 0.0 || lkk == 0.0 {
            return false;
        }
        let r = r2.sqrt();
        let (c, s) = (r / lkk, x[k] / lkk);
        l[(k, k)] = r;
        for i in k + 1..n {
            l[(i, k)] = (l[(i, k)] + sign * s * x[i]) / c;
            x[i] = c * x[i] - s * l[(i, k)];
        }
    }
    true
}

/// Tries of the jitter repair after the first, unjittered factorisation.
pub const JITTER_TRIES: u32 = 12;

/// The jitter repair: `fill(a, ε)` writes the matrix to factor with `ε` added to its diagonal
/// (first `ε = 0`, then `1e-12·scale`, ×10 per try, [`JITTER_TRIES`] tries), and `a` is factored
/// in place. Returns how many jittered tries were needed (0: none), or `None` when even the
/// last one has no factor. `scale` is the matrix's mean diagonal (`trace/l`). Allocation-free.
pub(crate) fn factor_with_jitter(
    a: &mut DMatrix<f64>,
    scale: f64,
    mut fill: impl FnMut(&mut DMatrix<f64>, f64),
) -> Option<u32> {
    let mut eps = 0.0;
    for tries in 0..=JITTER_TRIES {
        fill(a, eps);
        if cholesky_in_place(a) {
            return Some(tries);
        }
        eps = if eps == 0.0 {
            1e-12 * scale.max(f64::MIN_POSITIVE)
        } else {
            eps * 10.0
        };
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn in_place_cholesky_and_rank_one_updates_match_nalgebra() {
        let a = DMatrix::from_row_slice(3, 3, &[4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0]);
        let mut l = a.clone();
        assert!(cholesky_in_place(&mut l));
        let reference = a.clone().cholesky().unwrap().l();
        assert!((&l - &reference).norm() < 1e-14);
        let x = DVector::from_vec(vec![0.3, -0.2, 0.5]);
        for sign in [1.0, -1.0] {
            let mut l2 = l.clone();
            let mut w = x.clone();
            assert!(chol_rank_one(&mut l2, &mut w, sign));
            let expect = (&a + &x * x.transpose() * sign).cholesky().unwrap().l();
            assert!((&l2 - &expect).norm() < 1e-13, "sign {sign}");
        }
        // L Lᵀ − x xᵀ indefinite: refused.
        let mut l3 = l.clone();
        let mut big = DVector::from_vec(vec![3.0, 0.0, 0.0]);
        assert!(!chol_rank_one(&mut l3, &mut big, -1.0));
        let mut semi = DMatrix::from_row_slice(2, 2, &[1.0, 1.0, 1.0, 1.0]);
        assert!(!cholesky_in_place(&mut semi));
    }

    /// A singular matrix needs jitter: the first jittered try, ε = 1e-12·scale, factors
    /// [[1,1],[1,1]] + εI; a matrix with a negative eigenvalue of −1 needs ε > 1, beyond 12
    /// tries of 1e-12·10^k (k < 12) — refused.
    #[test]
    fn jitter_repair_counts_tries_and_gives_up() {
        let ones = DMatrix::from_element(2, 2, 1.0);
        let mut a = DMatrix::zeros(2, 2);
        let tries = factor_with_jitter(&mut a, 1.0, |m, eps| {
            m.copy_from(&ones);
            m[(0, 0)] += eps;
            m[(1, 1)] += eps;
        });
        assert_eq!(tries, Some(1));
        let s = &a * a.transpose();
        assert!((s[(0, 1)] - 1.0).abs() < 1e-15 && (s[(0, 0)] - (1.0 + 1e-12)).abs() < 1e-15);
        let indefinite = DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.0, -1.0]);
        let none = factor_with_jitter(&mut a, 1.0, |m, eps| {
            m.copy_from(&indefinite);
            m[(0, 0)] += eps;
            m[(1, 1)] += eps;
        });
        assert_eq!(none, None);
    }

    #[test]
    fn held_forms_give_the_same_covariance() {
        let p = DMatrix::from_row_slice(2, 2, &[4.0, 1.0, 1.0, 3.0]);
        let full = Cov::full(p.clone());
        let sqrt = Cov::from_covariance(CovForm::Sqrt, p.clone(), "P").unwrap();
        assert!((sqrt.covariance() - &p).norm() < 1e-14);
        for i in 0..2 {
            assert!((full.variance(i) - sqrt.variance(i)).abs() < 1e-14);
        }
        assert!((full.trace() - sqrt.trace()).abs() < 1e-14);
        assert!(Cov::from_covariance(CovForm::Sqrt, -p, "P").is_err());
    }
}
