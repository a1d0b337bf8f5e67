//! Recursive estimators for models linear in the parameters, `y(t) = φ(t)ᵀϑ + ε(t)` (Eq. 5.14).
//!
//! One engine serves all of them. For the covariance-form methods a step is
//!
//! ```text
//! e   = y − φᵀϑ                          a-priori prediction error
//! φ̃   = D_pre·φ                          (vector forgetting, symmetric variant only)
//! u   = P·φ̃,   d = r + φ̃ᵀu               gain numerator and denominator
//! ϑ  += D_pre·u/d · e                    (K = D_pre·u/d)
//! P   = D_post·(P − u·uᵀ/d)·D_post + Q
//! ```
//!
//! | method | `r` | `D_pre` | `D_post` | `Q` | thesis |
//! |---|---|---|---|---|---|
//! | RLS | 1 | I | I | 0 | Alg. 5.2 |
//! | RLSF, constant λ | λ | I | λ^(−1/2)·I | 0 | Alg. 5.3 |
//! | RLSF, time-varying λ(t) = λ0·λ(t−1) + 1 − λ0 | λ(t) | I | λ(t)^(−1/2)·I | 0 | Eq. 5.24 |
//! | vector forgetting, published | 1 | I | Λ⁻¹ | 0 | Alg. 5.4 (Vahidi et al. 2005) |
//! | vector forgetting, symmetric | 1 | Λ^(−1/2) | Λ^(−1/2) | 0 | SPEC §5.1 note |
//! | Kalman, random-walk parameters | R2 | I | I | R1 | Eq. 5.19 |
//!
//! `u·uᵀ/d` is `K·φᵀ·P` written symmetrically; every entry is formed from commutative products
//! (`(u_i·u_j)·(1/d)`, `s_i·s_j`), so P stays bit-for-bit symmetric. The
//! update's loop over P runs in four-lane vectors down each column (the `wide` crate: AVX, or
//! two SSE2 halves), about 3p² operations for a p² of memory (BENCHMARKS.md has the
//! roofline). For p ≤ 20 the step is compiled for the exact size (one source, generic over
//! nalgebra's `Dim`), which unrolls its loops. DSFC forms `f = Sᵀφ` four columns at a time
//! from p = 8 on.
//!
//! The symmetric vector-forgetting variant is Alg. 5.3 with the discount applied per parameter before the gain (`M = Λ^(−1/2)PΛ^(−1/2)`); with `Λ = λI` it is
//! exactly RLSF(λ). The published variant discounts by `Λ⁻¹·…·Λ⁻¹`, i.e. by λ² per step when
//! `Λ = λI`: it then equals RLSF(λ²) started from `P0·λ²`.
//!
//! DSFC (Alg. 5.5, Isermann's square-root filter in covariance form) keeps `S` with `P = S·Sᵀ`:
//! `f = Sᵀφ`, `a = 1/(fᵀf + λ)`, `γ = a·S·f`, `ϑ += γ·e`, `S = (S − g·γ·fᵀ)/√λ`,
//! `g = 1/(1 + √(λa))`. P is positive semi-definite by construction.
//!
//! ## Noise scale and standard errors
//! The RLS family's P is in units of the noise variance σ² (the implied `R2 = 1`): the
//! innovation variance it reports is `d/r` in those units, and σ² is estimated from the
//! standardised recursive residuals `w = e/√(d/r)` as `σ̂² = Σρ^k w² / (Σρ^k − p)`, ρ the
//! forgetting factor (1 for RLS: then `σ̂²` is the residual sum of squares of the regularised
//! least-squares problem over `n − p`). Standard errors are `√(σ̂²·P_ii)` — exact for λ = 1, the
//! conventional approximation under forgetting (it overstates the spread of an exponentially
//! weighted estimate by up to √(1+λ)). The Kalman filter's P is absolute (R1, R2 are given):
//! its standard errors are `√P_ii`.
//!
//! ## Files
//! Here: the estimator's state ([`LinearEstimator`]). `config.rs`: the configuration as plain
//! data; `estimator.rs`: construction, the step and accessors; `recursive.rs`: the
//! [`Recursive`](crate::recursive::Recursive) face.

use crate::cov::{Cov, CovForm};
use crate::error::{check_sample, check_view};
use crate::EstimError;
use nalgebra::{Const, DMatrix, DVector, Dim, Dyn};
use physid_core::{FreeSet, ParamSet};
use serde::{Deserialize, Serialize};
use wide::f64x4;

mod config;
mod estimator;
mod recursive;

pub use config::*;

/// The method with its per-step constants resolved: a covariance-form method (the table
/// above) or DSFC's square-root form — two steps, chosen once by the type.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
enum Kind {
    Cov(CovKind),
    Dsfc { lambda: f64 },
}

/// A covariance-form method (the rows of the module table).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
enum CovKind {
    Rls,
    Rlsf { lambda: f64, inv_lambda: f64 },
    RlsfTv { lambda0: f64 },
    Vf { symmetric: bool, min_lambda: f64 },
    Kalman { r1: DMatrix<f64>, r2: f64 },
}

/// What one covariance-form step needs of its method, resolved before the step borrows the
/// estimator's state: `r`, `1/r` (the innovation variance in σ² units), λ(t) to commit on
/// success, the noise-scale decay ρ, and the table's switches.
#[derive(Debug, Clone, Copy)]
struct CovStep {
    r: f64,
    r_inv: f64,
    lambda_now: f64,
    rho: f64,
    /// `D_pre ≠ I` (vector forgetting, symmetric variant).
    symmetric_vf: bool,
    /// P is divided by λ(t) (time-varying forgetting).
    time_varying: bool,
    /// P is absolute and R1 is added (Kalman).
    kalman: bool,
}

impl CovKind {
    /// The step's constants, λ(t−1) = `lambda_t`.
    fn step(&self, lambda_t: f64) -> CovStep {
        let (r, r_inv, lambda_now, rho) = match self {
            CovKind::Rls => (1.0, 1.0, 1.0, 1.0),
            CovKind::Rlsf { lambda, inv_lambda } => (*lambda, *inv_lambda, *lambda, *lambda),
            CovKind::RlsfTv { lambda0 } => {
                let l = lambda0 * lambda_t + (1.0 - lambda0);
                (l, l.recip(), l, l)
            }
            CovKind::Vf { min_lambda, .. } => (1.0, 1.0, 1.0, *min_lambda),
            CovKind::Kalman { r2, .. } => (*r2, 1.0, 1.0, 1.0),
        };
        CovStep {
            r,
            r_inv,
            lambda_now,
            rho,
            symmetric_vf: matches!(
                self,
                CovKind::Vf {
                    symmetric: true,
                    ..
                }
            ),
            time_varying: matches!(self, CovKind::RlsfTv { .. }),
            kalman: matches!(self, CovKind::Kalman { .. }),
        }
    }
}

/// A recursive estimator for a model linear in the parameters: RLS, RLSF (constant or
/// time-varying λ), vector forgetting, Kalman or DSFC, over a free subset of a parameter set.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct LinearEstimator {
    /// The configuration as built, over `universe` (for [`set_free`](Self::set_free)).
    config: EstimatorConfig,
    /// The free set the estimator was built with: what `set_free` may choose from.
    universe: FreeSet,
    /// Per parameter (full set): its variance when `set_free` last froze it (NaN: never).
    frozen_variance: Vec<f64>,
    kind: Kind,
    params: ParamSet,
    free: FreeSet,
    /// Free-parameter estimates.
    theta: DVector<f64>,
    /// P, or S for DSFC.
    cov: Cov,
    /// Scratch of the same size as `cov`; swapped in on a successful step.
    work: DMatrix<f64>,
    /// P0 (or S0 for DSFC), for covariance resetting.
    cov0: Cov,
    /// Pφ̃, or f = Sᵀφ for DSFC.
    u: DVector<f64>,
    /// DSFC: γ. Covariance form: the gain K.
    k: DVector<f64>,
    /// φ of the free parameters.
    phi: Vec<f64>,
    /// D_pre (vector forgetting, symmetric).
    pre: Vec<f64>,
    /// D_post diagonal.
    post: Vec<f64>,
    /// Current forgetting factor λ(t) of the time-varying method (1 otherwise).
    lambda_t: f64,
    noise_num: f64,
    noise_den: f64,
    /// The power of two the residuals are divided by before they are squared into
    /// `noise_num` (1 unless the first residual's size is outside [`NOISE_RANGE`]): σ̂ of data
    /// scaled by 1e-300 or 1e150 neither underflows to 0 nor overflows.
    #[serde(default = "one")]
    noise_scale: f64,
    samples: u64,
    guard_activations: u64,
    last: Option<Step>,
}

fn one() -> f64 {
    1.0
}

/// Residuals whose size is within this range are squared as they are; outside it (data
/// scaled by 1e-300, or 1e150, whose squares underflow to 0 or overflow), they are first
/// divided by a power of two near the first one's size — exact, so the standard errors are
/// right to the last digit at any scale a double holds (issue 41, item 5).
pub const NOISE_RANGE: std::ops::RangeInclusive<f64> = 1e-100..=1e100;

fn check_lambda(name: &str, l: f64) -> Result<f64, EstimError> {
    if l.is_finite() && l > 0.0 && l <= 1.0 {
        Ok(l)
    } else {
        Err(EstimError::InvalidConfig(format!(
            "{name} = {l} is outside (0, 1]"
        )))
    }
}

/// Why a step was refused — small and `Copy`, so the success path carries no `String`; it
/// becomes an [`EstimError::LostPositiveDefiniteness`] only when it happens.
#[derive(Debug, Clone, Copy)]
struct Breakdown {
    what: &'static str,
    value: f64,
}

fn breakdown(what: &'static str, value: f64) -> Breakdown {
    Breakdown { what, value }
}

/// `aᵀb` in four lanes (each a running sum of every fourth product, added at the end): four
/// independent chains where one sum would be one chain of p additions.
#[inline]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut lanes = [0.0; 4];
    let (ac, bc) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ar, br) = (ac.remainder(), bc.remainder());
    for (x, y) in ac.zip(bc) {
        for l in 0..4 {
            lanes[l] += x[l] * y[l];
        }
    }
    for (l, (x, y)) in ar.iter().zip(br).enumerate() {
        lanes[l] += x * y;
    }
    (lanes[0] + lanes[1]) + (lanes[2] + lanes[3])
}

/// `u = M·x` for a column-major square `m`, as a sum of its columns four at a time: lanes run
/// down the columns (no reduction across them), and `u` is read and written once per four
/// columns. For a symmetric P this is `P·x` (RLS's `u = P·φ̃`).
#[inline]
fn columns_times(m: &[f64], x: &[f64], u: &mut [f64]) {
    let p = u.len();
    u.fill(0.0);
    let mut blocks = m[..p * p].chunks_exact(4 * p);
    let mut xs = x[..p].chunks_exact(4);
    for (block, f) in (&mut blocks).zip(&mut xs) {
        let (c0, rest) = block.split_at(p);
        let (c1, rest) = rest.split_at(p);
        let (c2, c3) = rest.split_at(p);
        for ((((ui, &a), &b), &c), &d) in u.iter_mut().zip(c0).zip(c1).zip(c2).zip(c3) {
            *ui += (a * f[0] + b * f[1]) + (c * f[2] + d * f[3]);
        }
    }
    for (col, &f) in blocks.remainder().chunks_exact(p).zip(xs.remainder()) {
        for (ui, &a) in u.iter_mut().zip(col) {
            *ui += a * f;
        }
    }
}

/// `f = Mᵀ·x` for a column-major square `m` (`f_j` = column j · x), four columns at a time:
/// each column's products in four lanes, summed `(l0 + l1) + (l2 + l3)` — the order written
/// out, the same on every CPU — as [`dot`] does. DSFC's `f = Sᵀφ`.
#[inline]
fn columns_dot(m: &[f64], x: &[f64], f: &mut [f64]) {
    let p = f.len();
    let split = p - p % 4;
    let (x4, xr) = x[..p].split_at(split);
    let sum = |v: f64x4| {
        let a = v.as_array();
        (a[0] + a[1]) + (a[2] + a[3])
    };
    let mut cols = m[..p * p].chunks_exact(4 * p);
    let mut out = f.chunks_exact_mut(4);
    for (block, fo) in (&mut cols).zip(&mut out) {
        let mut acc = [f64x4::ZERO; 4];
        let mut tail = [0.0; 4];
        for (k, col) in block.chunks_exact(p).enumerate() {
            let (c4, cr) = col.split_at(split);
            for (c, xc) in c4.chunks_exact(4).zip(x4.chunks_exact(4)) {
                acc[k] += lanes(c) * lanes(xc);
            }
            tail[k] = cr.iter().zip(xr).map(|(a, b)| a * b).sum::<f64>();
        }
        for k in 0..4 {
            fo[k] = sum(acc[k]) + tail[k];
        }
    }
    for (col, fj) in cols.remainder().chunks_exact(p).zip(out.into_remainder()) {
        *fj = dot(col, x);
    }
}

/// 0 if `v` is finite (`v − v` is +0, all bits clear), not 0 if it is infinite or NaN (then
/// `v − v` is NaN): or-ed over a matrix it is one subtraction and one `or` a lane, where a
/// running sum — one chain of p² additions — would not vectorise.
#[inline(always)]
#[allow(clippy::eq_op)] // v − v is the point: 0 or NaN
fn is_nonfinite(v: f64) -> u64 {
    (v - v).to_bits()
}

/// The rank-one term `(a·bᵀ)·g` a [`downdate`] takes off, each entry `(a_i·b_j)·g`: with
/// `a = b` it is bit-for-bit symmetric.
struct RankOne<'a> {
    a: &'a [f64],
    b: &'a [f64],
    g: f64,
}

/// How a [`downdate`] scales its entries: not at all (`c` = 1: RLS, Kalman), by one factor `c`
/// (D_post a multiple of I, or 1/λ(t): RLSF; DSFC's 1/√λ), or by `s_i·s_j·c` (D_post per
/// parameter: vector forgetting).
const UNIT: u8 = 0;
const UNIFORM: u8 = 1;
const PER_PARAM: u8 = 2;

/// The covariance update's loop over P (see the module table): column by column,
/// `W_ij = f_ij·(P_ij − (a_i·b_j)·g) [+ Q_ij]` ([`RankOne`]) with `f_ij` as `SCALE` says
/// ([`UNIT`], [`UNIFORM`], [`PER_PARAM`]). Returns whether every entry is finite
/// ([`is_nonfinite`]). Written in four-lane vectors down each column, so that it compiles to
/// whole-vector operations at any p (left to itself, the compiler vectorised a small fixed p
/// across the columns, with gathers, and a larger one with a scalar tail of up to 31 rows).
#[inline(always)]
fn downdate<const SCALE: u8, const WITH_Q: bool>(
    wm: &mut [f64],
    pm: &[f64],
    RankOne { a: w, b, g }: RankOne,
    s: &[f64],
    c: f64,
    q: &[f64],
) -> bool {
    let p = w.len();
    // Without D_post per parameter (or Q) the slice is not read: any of length p stands in, so
    // that one zip serves every case.
    let s = if SCALE == PER_PARAM { s } else { w };
    let split = p - p % 4;
    let (w4, wr) = w.split_at(split);
    let (s4, sr) = s.split_at(split);
    let cv = f64x4::splat(c);
    let mut bad = f64x4::ZERO;
    let mut bad_rest = 0u64;
    for (j, (wcol, pcol)) in wm.chunks_exact_mut(p).zip(pm.chunks_exact(p)).enumerate() {
        let (wj, gv) = (b[j], f64x4::splat(g));
        let sj = s[j];
        let (wjv, sjv) = (f64x4::splat(wj), f64x4::splat(sj));
        let qcol = if WITH_Q { &q[j * p..(j + 1) * p] } else { pcol };
        let (wo4, wor) = wcol.split_at_mut(split);
        let (p4, pr) = pcol.split_at(split);
        let (q4, qr) = qcol.split_at(split);
        for ((((wo, pi), wi), si), qi) in wo4
            .chunks_exact_mut(4)
            .zip(p4.chunks_exact(4))
            .zip(w4.chunks_exact(4))
            .zip(s4.chunks_exact(4))
            .zip(q4.chunks_exact(4))
        {
            let d = lanes(pi) - (lanes(wi) * wjv) * gv;
            let mut v = match SCALE {
                UNIT => d,
                UNIFORM => cv * d,
                _ => ((lanes(si) * sjv) * cv) * d,
            };
            if WITH_Q {
                v += lanes(qi);
            }
            wo.copy_from_slice(v.as_array());
            #[allow(clippy::eq_op)] // as in is_nonfinite
            {
                bad |= v - v;
            }
        }
        for ((((wo, &pij), &wi), &si), &qi) in wor.iter_mut().zip(pr).zip(wr).zip(sr).zip(qr) {
            let d = pij - (wi * wj) * g;
            let mut v = match SCALE {
                UNIT => d,
                UNIFORM => c * d,
                _ => ((si * sj) * c) * d,
            };
            if WITH_Q {
                v += qi;
            }
            *wo = v;
            bad_rest |= is_nonfinite(v);
        }
    }
    bad.as_array().iter().all(|b| b.to_bits() == 0) && bad_rest == 0
}

/// Four values of a slice as a vector.
#[inline(always)]
fn lanes(x: &[f64]) -> f64x4 {
    f64x4::new([x[0], x[1], x[2], x[3]])
}
