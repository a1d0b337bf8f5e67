//! How an unscented filter holds its prior covariance ([`CovFactor`]): P itself ([`FullCov`],
//! the UKF) or its lower Cholesky factor S ([`SqrtCov`], the SR-UKF) — the only places the two
//! filters differ: the spread of the sigma points, the prior the projected points give, and the
//! update `P ← P − Pxy Pxyᵀ/S_y + R1`.

use super::*;

/// The covariance of an unscented filter, in the form that names the filter.
pub trait CovFactor: Clone + std::fmt::Debug {
    /// The method with these sigma points.
    fn method(points: SigmaPoints) -> NlMethod;
    /// From P0 and R1 (both checked).
    fn new(p0: DMatrix<f64>, r1: DMatrix<f64>) -> Result<Self, EstimError>;
    /// The prior as held.
    fn held(&self) -> &Cov;
    /// The prior as held, to restore a checkpoint into.
    fn held_mut(&mut self) -> &mut Cov;
    /// A lower factor of `(l+ζ)·P` (`gamma2 = l+ζ`) into `chol`; the repairs it needed.
    fn spread(&self, gamma2: f64, chol: &mut DMatrix<f64>, sample: u64) -> Result<u64, EstimError>;
    /// The prior replaced by `prior` (the projected sigma points'); the repairs it needed.
    fn set_prior(&mut self, prior: &DMatrix<f64>, sample: u64) -> Result<u64, EstimError>;
    /// `P ← P − Pxy Pxyᵀ·sinv + R1` (`sinv = 1/S_y`), with `work` and `v` as scratch; the
    /// repairs it needed. Refused, the prior untouched, if it cannot be done.
    fn update(
        &mut self,
        pxy: &DVector<f64>,
        sinv: f64,
        work: &mut DMatrix<f64>,
        v: &mut DVector<f64>,
        sample: u64,
    ) -> Result<u64, EstimError>;
}

/// P itself: the UKF.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FullCov {
    p: Cov,
    r1: DMatrix<f64>,
}

impl CovFactor for FullCov {
    fn method(points: SigmaPoints) -> NlMethod {
        NlMethod::Ukf(points)
    }
    fn new(p0: DMatrix<f64>, r1: DMatrix<f64>) -> Result<Self, EstimError> {
        Ok(Self {
            p: Cov::from_covariance(CovForm::Full, p0, "P0")?,
            r1,
        })
    }
    fn held(&self) -> &Cov {
        &self.p
    }
    fn held_mut(&mut self) -> &mut Cov {
        &mut self.p
    }

    /// A Cholesky factorisation of the symmetrised `(l+ζ)·P`, with the jitter repair (1).
    fn spread(&self, gamma2: f64, chol: &mut DMatrix<f64>, sample: u64) -> Result<u64, EstimError> {
        let p = self.p.held();
        let l = p.nrows();
        let scale = p.trace().abs() / l as f64;
        let tries = factor_with_jitter(chol, scale, |a, eps| {
            for j in 0..l {
                for i in 0..l {
                    let v = 0.5 * (p[(i, j)] + p[(j, i)]) + if i == j { eps } else { 0.0 };
                    a[(i, j)] = gamma2 * v;
                }
            }
        })
        .ok_or_else(|| EstimError::LostPositiveDefiniteness {
            sample,
            detail: "the prior covariance has no Cholesky factor after 12 jitter repairs".into(),
        })?;
        Ok(u64::from(tries > 0))
    }

    fn set_prior(&mut self, prior: &DMatrix<f64>, _sample: u64) -> Result<u64, EstimError> {
        self.p.held_mut().copy_from(prior);
        Ok(0)
    }

    /// In place; symmetric products keep P exactly symmetric.
    fn update(
        &mut self,
        pxy: &DVector<f64>,
        sinv: f64,
        _work: &mut DMatrix<f64>,
        _v: &mut DVector<f64>,
        _sample: u64,
    ) -> Result<u64, EstimError> {
        let l = pxy.len();
        let pxy = pxy.as_slice();
        for ((pcol, rcol), &pj) in self
            .p
            .held_mut()
            .as_mut_slice()
            .chunks_exact_mut(l)
            .zip(self.r1.as_slice().chunks_exact(l))
            .zip(pxy)
        {
            for ((pij, &rij), &pi) in pcol.iter_mut().zip(rcol).zip(pxy) {
                *pij += rij - (pi * pj) * sinv;
            }
        }
        Ok(0)
    }
}

/// S, the lower Cholesky factor of P: the SR-UKF (van der Merwe & Wan 2001).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SqrtCov {
    s: Cov,
    /// Square-root columns of R1: `R1 = V Λ Vᵀ = Σ c cᵀ`, `c = √λ_k v_k`.
    r1_cols: Vec<DVector<f64>>,
}

impl CovFactor for SqrtCov {
    fn method(points: SigmaPoints) -> NlMethod {
        NlMethod::Srukf(points)
    }
    fn new(p0: DMatrix<f64>, r1: DMatrix<f64>) -> Result<Self, EstimError> {
        let l = r1.nrows();
        let eig = r1.symmetric_eigen();
        Ok(Self {
            s: Cov::from_covariance(CovForm::Sqrt, p0, "P0")?,
            r1_cols: (0..l)
                .filter(|&k| eig.eigenvalues[k] > 0.0)
                .map(|k| eig.eigenvectors.column(k) * eig.eigenvalues[k].sqrt())
                .collect(),
        })
    }
    fn held(&self) -> &Cov {
        &self.s
    }
    fn held_mut(&mut self) -> &mut Cov {
        &mut self.s
    }

    /// `γ·S` directly.
    fn spread(
        &self,
        gamma2: f64,
        chol: &mut DMatrix<f64>,
        _sample: u64,
    ) -> Result<u64, EstimError> {
        chol.copy_from(self.s.held());
        *chol *= gamma2.sqrt();
        Ok(0)
    }

    /// `prior` factored again, with the jitter repair (1).
    fn set_prior(&mut self, prior: &DMatrix<f64>, sample: u64) -> Result<u64, EstimError> {
        let l = prior.nrows();
        let tries = factor_with_jitter(
            self.s.held_mut(),
            prior.trace().abs() / l as f64,
            |a, eps| {
                a.copy_from(prior);
                for i in 0..l {
                    a[(i, i)] += eps;
                }
            },
        )
        .ok_or_else(|| EstimError::LostPositiveDefiniteness {
            sample,
            detail: "covariance of the projected sigma points has no Cholesky factor".into(),
        })?;
        Ok(u64::from(tries > 0))
    }

    /// `S ← chol(S Sᵀ − U Uᵀ + R1)`, `U = Pxy·√sinv`: a rank-one downdate and rank-one updates
    /// with R1's square-root columns, in `work` (committed on success). A failed downdate is
    /// repaired by re-factoring `S Sᵀ − U Uᵀ` with jitter.
    fn update(
        &mut self,
        pxy: &DVector<f64>,
        sinv: f64,
        work: &mut DMatrix<f64>,
        v: &mut DVector<f64>,
        sample: u64,
    ) -> Result<u64, EstimError> {
        let l = pxy.len();
        let mut repairs = 0;
        work.copy_from(self.s.held());
        v.copy_from(pxy);
        *v *= sinv.sqrt();
        if !chol_rank_one(work, v, -1.0) {
            // Repair: P = S Sᵀ − U Uᵀ formed explicitly, symmetrised, jittered, re-factored.
            repairs += 1;
            let s = self.s.held();
            let scale = s.norm_squared() / l as f64;
            factor_with_jitter(work, scale, |a, eps| {
                for j in 0..l {
                    for i in 0..l {
                        let sst: f64 = (0..l).map(|k| s[(i, k)] * s[(j, k)]).sum();
                        a[(i, j)] = sst - (pxy[i] * pxy[j]) * sinv + if i == j { eps } else { 0.0 };
                    }
                }
            })
            .ok_or_else(|| EstimError::LostPositiveDefiniteness {
                sample,
                detail: "square-root downdate could not be repaired".into(),
            })?;
        }
        for c in &self.r1_cols {
            v.copy_from(c);
            if !chol_rank_one(work, v, 1.0) {
                return Err(EstimError::LostPositiveDefiniteness {
                    sample,
                    detail: "rank-one update with R1 failed".into(),
                });
            }
        }
        std::mem::swap(self.s.held_mut(), work);
        Ok(repairs)
    }
}
