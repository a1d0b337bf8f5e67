//! The information a recursive least-squares estimator with exponential forgetting gathers,
//! and the covariance of its estimate when the output's noise is coloured — what a designed
//! test is judged by (issue 45: "the information recursion, not only the batch FIM").
//!
//! RLS with forgetting λ (Alg. 5.2–5.3) keeps `P_k = A_k⁻¹` with
//! `A_k = λ·A_{k−1} + φ_k·φ_kᵀ`, `A_0 = P_0⁻¹`, and its estimate is
//! `ϑ̂_k = A_k⁻¹·(λᵏ·P_0⁻¹·ϑ_0 + Σ_i λ^{k−i}·φ_i·y_i)`. With `y_i = φ_iᵀϑ + e_i` the error is
//! `A_k⁻¹·Σ_i λ^{k−i}·φ_i·e_i` plus the start's `λᵏ·A_k⁻¹·P_0⁻¹·(ϑ_0 − ϑ)`. A design judges
//! what the *data* resolve, so the start is left out: with `D_k = A_k − λᵏ·P_0⁻¹` (the data's
//! information) and a noise of autocovariance `r(m) = E[e_i·e_{i−m}]`,
//!
//! ```text
//! Cov(ϑ̂_k) = D_k⁻¹ · S_k · D_k⁻¹,   S_k = Σ_i Σ_j λ^{2k−i−j}·r(i−j)·φ_i·φ_jᵀ.
//! ```
//!
//! With forgetting the start is gone after a few memories and this is the estimator's own
//! spread. Without (λ = 1, a characterisation) the start stays: in a direction the test does
//! not resolve, the estimator holds its start value — its noise spread is small there, its
//! error whatever the start's was — and `D_k` is singular there, so the design calls the
//! parameter unresolved rather than precise. Where the data resolve it, the two agree.
//!
//! and `S_k` follows its own recursion: with `u_k = Σ_{m≥1} r(m)·λᵐ·φ_{k−m}` (the past
//! regressors weighted by the noise's correlation with the present),
//! `S_k = λ²·S_{k−1} + r(0)·φ_k·φ_kᵀ + φ_k·u_kᵀ + u_k·φ_kᵀ` — `O(L·p + p²)` per sample for
//! `L` lags.
//!
//! A noise whose level changes along the test (`e_i = σ_i·ε_i`, `ε` of autocovariance `r`:
//! the cycle means of a sensor's noise over cycles of different lengths) enters `S_k` only:
//! its recursion takes `ψ_i = σ_i·φ_i` in place of `φ_i` ([`ForgettingInformation::push_scaled`]).
//!
//! For white noise (`r(m) = 0` for m ≥ 1) and λ = 1 this is the batch `σ²·(ΦᵀΦ)⁻¹`; with
//! forgetting the sandwich is smaller than `σ²·P_k` (≈ `σ²·P_k/(1 + λ)` for stationary
//! regressors). Allocation-free per sample.

use nalgebra::{DMatrix, DVector, SymmetricEigen};

/// The most lags of the noise's autocovariance carried ([`ForgettingInformation::new`]).
pub const MAX_LAGS: usize = 64;

/// Lags whose autocovariance is below this fraction of the variance are left out: each moves
/// a standard error by less than that fraction.
pub const LAG_CUT: f64 = 1e-6;

/// The information recursion of RLS with forgetting and the sandwich covariance of its
/// estimate under coloured noise (module docs).
#[derive(Debug, Clone)]
pub struct ForgettingInformation {
    p: usize,
    lambda: f64,
    /// `A_k` (row-major p×p).
    a: Vec<f64>,
    /// `r(0..=L)`.
    r: Vec<f64>,
    /// `r(m)·λᵐ` for m = 0..=L.
    w: Vec<f64>,
    /// `S_k` (row-major p×p).
    s: Vec<f64>,
    /// `u_k`.
    u: Vec<f64>,
    /// `ψ_k = σ_k·φ_k` (scratch).
    psi: Vec<f64>,
    /// The last L of `ψ`, a ring (`past[(head − m) mod L]` is `φ_{k−m}`).
    past: Vec<f64>,
    head: usize,
    /// Regressors taken.
    count: usize,
    /// `λᵏ/p0`: the start's part of `A_k`'s diagonal.
    start: f64,
}

impl ForgettingInformation {
    /// For `p` parameters, forgetting `lambda` ∈ (0, 1], the estimator's `P_0 = p0·I`, and the
    /// noise's autocovariance `r[m]` at the estimator's rate (`r[0]` its variance), cut where
    /// it falls below [`LAG_CUT`] of `r[0]` and at [`MAX_LAGS`].
    pub fn new(p: usize, lambda: f64, p0: f64, r: &[f64]) -> Result<Self, String> {
        if p == 0 {
            return Err("no parameters".into());
        }
        if !(lambda > 0.0 && lambda <= 1.0) {
            return Err(format!(
                "forgetting factor {}: expected in (0, 1]",
                physid_core::Num(lambda)
            ));
        }
        if !(p0.is_finite() && p0 > 0.0) {
            return Err(format!(
                "P0 = {}·I: expected a positive scale",
                physid_core::Num(p0)
            ));
        }
        match r.first() {
            Some(&r0) if r0.is_finite() && r0 > 0.0 => {}
            _ => return Err("the noise's variance must be positive and finite".into()),
        }
        if r.iter().any(|v| !v.is_finite()) {
            return Err("the noise's autocovariance has a non-finite value".into());
        }
        let lags = r
            .iter()
            .rposition(|v| v.abs() > LAG_CUT * r[0])
            .unwrap_or(0)
            .min(MAX_LAGS);
        let mut a = vec![0.0; p * p];
        for i in 0..p {
            a[i * p + i] = 1.0 / p0;
        }
        let r = r[..=lags].to_vec();
        let w = r
            .iter()
            .scan(1.0, |lm, &rm| {
                let v = rm * *lm;
                *lm *= lambda;
                Some(v)
            })
            .collect();
        Ok(Self {
            p,
            lambda,
            a,
            r,
            w,
            s: vec![0.0; p * p],
            u: vec![0.0; p],
            psi: vec![0.0; p],
            past: vec![0.0; lags.max(1) * p],
            head: 0,
            count: 0,
            start: 1.0 / p0,
        })
    }

    /// The lags carried (L).
    pub fn lags(&self) -> usize {
        self.r.len() - 1
    }

    /// Regressors taken.
    pub fn count(&self) -> usize {
        self.count
    }

    /// Take the regressor `φ_k` of the estimator's next update.
    pub fn push(&mut self, phi: &[f64]) {
        self.push_scaled(phi, 1.0);
    }

    /// Take `φ_k` whose output's noise is `sigma`·ε_k (module docs): `A` takes `φ_k`, `S` takes
    /// `ψ_k = sigma·φ_k`.
    pub fn push_scaled(&mut self, phi: &[f64], sigma: f64) {
        let p = self.p;
        debug_assert_eq!(phi.len(), p);
        let (l, l2) = (self.lambda, self.lambda * self.lambda);
        let lags = self.lags();
        for (q, &f) in self.psi.iter_mut().zip(phi) {
            *q = sigma * f;
        }
        // u_k = Σ_{m≥1} r(m)·λᵐ·ψ_{k−m} (the ring holds zeros before the first regressors).
        self.u.iter_mut().for_each(|v| *v = 0.0);
        for m in 1..=lags {
            let slot = (self.head + lags - m) % lags;
            let old = &self.past[slot * p..(slot + 1) * p];
            let wm = self.w[m];
            for (u, &o) in self.u.iter_mut().zip(old) {
                *u += wm * o;
            }
        }
        let r0 = self.r[0];
        for ((arow, srow), (&pi, (&qi, &ui))) in self
            .a
            .chunks_exact_mut(p)
            .zip(self.s.chunks_exact_mut(p))
            .zip(phi.iter().zip(self.psi.iter().zip(&self.u)))
        {
            for (((a, s), &pj), (&qj, &uj)) in arow
                .iter_mut()
                .zip(srow)
                .zip(phi)
                .zip(self.psi.iter().zip(&self.u))
            {
                *a = l * *a + pi * pj;
                *s = l2 * *s + r0 * qi * qj + qi * uj + ui * qj;
            }
        }
        if lags > 0 {
            self.past[self.head * p..(self.head + 1) * p].copy_from_slice(&self.psi);
            self.head = (self.head + 1) % lags;
        }
        self.count += 1;
        self.start *= l;
    }

    /// `A_k` (the estimator's `P_k⁻¹`).
    pub fn information(&self) -> DMatrix<f64> {
        DMatrix::from_row_slice(self.p, self.p, &self.a)
    }

    /// `D_k = A_k − λᵏ·P0⁻¹`: the information the data gave, the start's left out.
    pub fn data_information(&self) -> DMatrix<f64> {
        let mut a = self.information();
        for i in 0..self.p {
            a[(i, i)] -= self.start;
        }
        a
    }

    /// `Cov(ϑ̂_k) = D⁻¹·S·D⁻¹` (module docs); `None` while the data's information `D` is
    /// singular to working precision (a direction not resolved).
    pub fn covariance(&self) -> Option<DMatrix<f64>> {
        let p = self.p;
        let a = self.data_information();
        let ainv = a.cholesky()?.inverse();
        let s = DMatrix::from_row_slice(p, p, &self.s);
        let cov = &ainv * s * &ainv;
        Some((&cov + cov.transpose()) * 0.5)
    }
}

/// How a design ranks the predicted covariance of the parameters it is asked for, in relative
/// terms (each parameter divided by its nominal value, so that units do not weigh).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Criterion {
    /// D-optimality: the smallest `log det` of the covariance (the confidence ellipsoid's
    /// volume).
    D,
    /// A-optimality: the smallest mean variance.
    A,
    /// E-optimality: the smallest largest eigenvalue (the worst direction).
    E,
    /// The shortest time until every standard error stays below its target.
    Time,
}

impl std::str::FromStr for Criterion {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "d" | "D" => Ok(Self::D),
            "a" | "A" => Ok(Self::A),
            "e" | "E" => Ok(Self::E),
            "time" => Ok(Self::Time),
            _ => Err(format!("'{s}': expected d, a, e or time")),
        }
    }
}

impl Criterion {
    /// The criterion's value of a relative covariance (smaller is better); `+∞` when it is
    /// not positive definite. [`Criterion::Time`] ranks by D here (its own figure is a time).
    pub fn value(self, rel_cov: &DMatrix<f64>) -> f64 {
        let eig = SymmetricEigen::new(rel_cov.clone()).eigenvalues;
        if eig.iter().any(|&v| !(v.is_finite() && v > 0.0)) {
            return f64::INFINITY;
        }
        match self {
            Self::D | Self::Time => eig.iter().map(|v| v.ln()).sum(),
            Self::A => eig.iter().sum::<f64>() / eig.len() as f64,
            Self::E => eig.max(),
        }
    }
}

/// The parameters no profile can reveal, by the orthogonal method (Alg. 5.1) on the summed
/// information of every candidate (`information` is `Σ φφᵀ` in relative coordinates): the
/// pivoted Cholesky factorisation of the information is the Gram–Schmidt of its columns, so a
/// parameter whose residual information, after the ones chosen before it, falls below `cut`
/// of the first parameter's is structurally unidentifiable on the admissible inputs — reported
/// as such, never given a huge σ. Returns the indices, in the order found.
pub fn structural_zeros(information: &DMatrix<f64>, cut: f64) -> Vec<usize> {
    let ranked = ranking(information);
    match ranked.iter().position(|&(_, r)| r.is_nan() || r <= cut) {
        Some(k) => ranked[k..].iter().map(|&(j, _)| j).collect(),
        None => Vec::new(),
    }
}

/// The parameters in the orthogonal method's order (Alg. 5.1) on an information matrix in
/// relative coordinates: each the one with the most information left after those before it
/// (the pivoted Cholesky factorisation, the Gram–Schmidt of the regressors' columns), with
/// that residual information relative to the first's (1 for the first; 0 once none is left).
pub fn ranking(information: &DMatrix<f64>) -> Vec<(usize, f64)> {
    let p = information.nrows();
    let mut m = information.clone();
    let mut left: Vec<usize> = (0..p).collect();
    let mut first = None;
    let mut out = Vec::with_capacity(p);
    while !left.is_empty() {
        // The parameter with the most residual information.
        let (pos, &j) = match left
            .iter()
            .enumerate()
            .max_by(|a, b| m[(*a.1, *a.1)].total_cmp(&m[(*b.1, *b.1)]))
        {
            Some(x) => x,
            None => break,
        };
        let d = m[(j, j)];
        let top = *first.get_or_insert(d);
        if !(d > 0.0 && top > 0.0) {
            // None is left: the rest in their order, with nothing.
            out.extend(left.iter().map(|&j| (j, 0.0)));
            break;
        }
        out.push((j, d / top));
        left.remove(pos);
        // Project j out of the rest (the Schur complement).
        let col: DVector<f64> = m.column(j).into_owned();
        for &a in &left {
            for &b in &left {
                m[(a, b)] -= col[a] * col[b] / d;
            }
        }
    }
    out
}

/// The most nearly collinear pairs of a covariance: `(i, j, ρ)` with `|ρ| ≥ threshold`, the
/// correlation of the two estimates.
pub fn collinear_pairs(cov: &DMatrix<f64>, threshold: f64) -> Vec<(usize, usize, f64)> {
    let p = cov.nrows();
    let mut out = Vec::new();
    for i in 0..p {
        for j in i + 1..p {
            let rho = cov[(i, j)] / (cov[(i, i)] * cov[(j, j)]).sqrt();
            if rho.abs() >= threshold {
                out.push((i, j, rho));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The recursion against its definition written out: `A = Σ λ^{k−i} φφᵀ + λᵏ/p0·I` and the
    /// double sum `Σ_i Σ_j λ^{2k−i−j} φ_i φ_jᵀ r(i−j)`, over random regressors and an MA(2)
    /// noise's autocovariance.
    #[test]
    fn recursion_is_the_double_sum() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let (p, n, lambda, p0) = (3, 40, 0.93, 50.0);
        let r = [1.3, 0.6, -0.2];
        let phis: Vec<Vec<f64>> = (0..n)
            .map(|_| (0..p).map(|_| rng.random_range(-1.0..1.0)).collect())
            .collect();
        let mut info = ForgettingInformation::new(p, lambda, p0, &r).unwrap();
        for ph in &phis {
            info.push(ph);
        }
        let k = n - 1;
        let mut a = DMatrix::<f64>::identity(p, p) * (lambda.powi(n as i32) / p0);
        let mut s = DMatrix::<f64>::zeros(p, p);
        for (i, pi) in phis.iter().enumerate() {
            let fi = DVector::from_column_slice(pi);
            a += &fi * fi.transpose() * lambda.powi((k - i) as i32);
            for (j, pj) in phis.iter().enumerate() {
                let m = i.abs_diff(j);
                if m < r.len() {
                    let fj = DVector::from_column_slice(pj);
                    s += &fi * fj.transpose() * (r[m] * lambda.powi((2 * k - i - j) as i32));
                }
            }
        }
        // The recursion's A starts at P0⁻¹ and forgets it too.
        let a_rec = info.information();
        assert!((&a_rec - &a).abs().max() < 1e-12 * a.abs().max(), "A");
        // The data's information: A less the start's λⁿ·P0⁻¹.
        let d = &a - DMatrix::<f64>::identity(p, p) * (lambda.powi(n as i32) / p0);
        let ainv = d.try_inverse().unwrap();
        let want = &ainv * s * &ainv;
        let got = info.covariance().unwrap();
        assert!(
            (&got - &want).abs().max() < 1e-10 * want.abs().max(),
            "{got} {want}"
        );
    }

    /// A noise level per row: the double sum with `σ_i·σ_j·r(i−j)`, over random regressors,
    /// levels and an MA(1) noise.
    #[test]
    fn scaled_noise_is_the_weighted_double_sum() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let (p, n, lambda) = (2, 30, 0.97);
        let r = [0.8, 0.3];
        let rows: Vec<(Vec<f64>, f64)> = (0..n)
            .map(|_| {
                (
                    (0..p).map(|_| rng.random_range(-1.0..1.0)).collect(),
                    rng.random_range(0.1..3.0),
                )
            })
            .collect();
        let mut info = ForgettingInformation::new(p, lambda, 1e6, &r).unwrap();
        for (ph, sg) in &rows {
            info.push_scaled(ph, *sg);
        }
        let k = n - 1;
        let mut s = DMatrix::<f64>::zeros(p, p);
        for (i, (pi, si)) in rows.iter().enumerate() {
            for (j, (pj, sj)) in rows.iter().enumerate() {
                let m = i.abs_diff(j);
                if m < r.len() {
                    let (fi, fj) = (
                        DVector::from_column_slice(pi),
                        DVector::from_column_slice(pj),
                    );
                    s += &fi
                        * fj.transpose()
                        * (si * sj * r[m] * lambda.powi((2 * k - i - j) as i32));
                }
            }
        }
        let d =
            info.information() - DMatrix::<f64>::identity(p, p) * (lambda.powi(n as i32) * 1e-6);
        let ainv = d.try_inverse().unwrap();
        let want = &ainv * s * &ainv;
        let got = info.covariance().unwrap();
        assert!(
            (&got - &want).abs().max() < 1e-10 * want.abs().max(),
            "{got} {want}"
        );
    }

    /// λ = 1, white noise: the batch least-squares covariance σ²·(ΦᵀΦ)⁻¹ (P0 huge).
    #[test]
    fn white_noise_without_forgetting_is_the_batch_covariance() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let (p, n) = (2, 500);
        let mut info = ForgettingInformation::new(p, 1.0, 1e12, &[0.25]).unwrap();
        let mut ftf = DMatrix::<f64>::zeros(p, p);
        for _ in 0..n {
            let ph = [1.0, rng.random_range(-2.0..2.0)];
            info.push(&ph);
            let f = DVector::from_column_slice(&ph);
            ftf += &f * f.transpose();
        }
        let want = ftf.try_inverse().unwrap() * 0.25;
        let got = info.covariance().unwrap();
        assert!((&got - &want).abs().max() < 1e-8 * want.abs().max());
    }

    /// A parameter with no information, or one whose column is another's multiple, is a
    /// structural zero; independent columns are not.
    #[test]
    fn structural_zeros_are_found() {
        // Columns: x, 2x (collinear), y, 0.
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut info = DMatrix::<f64>::zeros(4, 4);
        for _ in 0..200 {
            let (x, y): (f64, f64) = (rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
            let f = DVector::from_column_slice(&[x, 2.0 * x, y, 0.0]);
            info += &f * f.transpose();
        }
        let mut z = structural_zeros(&info, 1e-9);
        z.sort_unstable();
        assert_eq!(
            z,
            vec![0, 3],
            "x or 2x goes first; the other and the zero column left"
        );
        let id = DMatrix::<f64>::identity(3, 3);
        assert!(structural_zeros(&id, 1e-9).is_empty());
        assert_eq!(structural_zeros(&DMatrix::zeros(2, 2), 1e-9), vec![0, 1]);
    }

    /// D, A and E on a diagonal covariance: Σ ln, the mean, the largest.
    #[test]
    fn criteria_of_a_diagonal() {
        let c = DMatrix::from_diagonal(&DVector::from_column_slice(&[1e-4, 4e-4]));
        assert!((Criterion::D.value(&c) - (1e-4f64.ln() + 4e-4f64.ln())).abs() < 1e-12);
        assert!((Criterion::A.value(&c) - 2.5e-4).abs() < 1e-16);
        assert!((Criterion::E.value(&c) - 4e-4).abs() < 1e-16);
        let singular = DMatrix::from_diagonal(&DVector::from_column_slice(&[1e-4, 0.0]));
        assert_eq!(Criterion::D.value(&singular), f64::INFINITY);
    }
}
