//! Estimators for models non-linear in the parameters (thesis §5.3.2, Eq. 5.29–5.32):
//! random-walk parameters `ϑ(t) = ϑ(t−1) + w`, `w ~ N(0, R1)`, observed through
//! `y = h(φ(t), ϑ(t)) + ε`, `ε ~ N(0, R2)`, for any [`ParamModel`].
//!
//! * **EKF** (Alg. 5.6) — the Kalman filter of Eq. 5.19 ([`LinearEstimator`]) fed with the
//!   exact Jacobian `J = ∇_ϑ h(φ, ϑ̂)` (forward-mode dual numbers, [`GradientEngine`]) as its
//!   regressor and `y − h(φ, ϑ̂)` as its innovation: `K = PJᵀ/(R2 + JPJᵀ)`, `ϑ += K·e`,
//!   `P = P − KJP + R1`. On a linear model it *is* the Kalman filter.
//! * **UKF** (Alg. 5.7, Julier; Wan & van der Merwe) — `2l+1` sigma points from the prior
//!   covariance `P + R1`:
//!   `ζ = α²(l + κ) − l`, `W0m = ζ/(l+ζ)`, `W0c = W0m + 1 − α² + β`, `Wi = 1/(2(l+ζ))`
//!   (SPEC fix: the text prints `ζ/(2l+ζ)`); thesis defaults α = 1, β = 2, κ = 3 − l.
//!
//! Both keep P as the *prior* of the next sample, as Eq. 5.19 does (`P = P − KJP + R1`): `P0` is
//! the prior of the first sample. So on a linear model EKF, UKF and the Kalman filter agree.
//!
//! * **SR-UKF** (van der Merwe & Wan 2001) — the UKF carrying `S`, the lower Cholesky factor of
//!   the prior P: sigma points `x ± √(l+ζ)·S`, the update `S Sᵀ − U Uᵀ` with `U = Pxy/√S_y`
//!   as a rank-one Cholesky downdate, and R1 added as rank-one updates by its square-root
//!   columns. P stays positive semi-definite by construction; a downdate that fails numerically
//!   is repaired by re-factoring `SSᵀ − UUᵀ` with the jitter rule (1) and counted.
//!
//! **Repairs.** With the thesis defaults `W0 < 0` for l > 3, so the unscented covariance can
//! lose definiteness. The filter does not fail; it repairs by a fixed rule and counts:
//! (1) if the prior P has no Cholesky factor, it is symmetrised and `ε·I` is added with
//! `ε = 1e-12·(trace/l)`, ×10 per try, up to 12 tries; (2) if the predicted output variance
//! `S = Σ Wc_i (Y_i − ŷ)² + R2` is not positive, it is recomputed without the negative centre
//! weight. Anything beyond that refuses the sample (state untouched) with an error.
//!
//! **Scaled coordinates.** With [`NlConfig::scaled`], the filter estimates `x` with
//! `ϑ = ϑ0·(1 + x)`, so one covariance scale fits parameters of very different magnitudes
//! (thesis Table 8.2 mixes 1e-9 and 88 mm); estimates and standard errors are reported in
//! physical units. **Bounds** (e.g. a mass stays positive) are enforced by projection after each
//! update and counted.

use crate::cov::{chol_rank_one, factor_with_jitter, Cov, CovForm};
use crate::error::check_view;
use crate::linear::kalman_noise;
use crate::recursive::{Memory, Recursive, Snapshot};
use crate::{CovSpec, EstimError, EstimatorConfig, LinearEstimator, Method, Step};
use nalgebra::{DMatrix, DVector};
use physid_core::{FreeSet, GradientEngine, ParamModel, ParamSet};
use serde::{Deserialize, Serialize};

/// Sigma-point settings of the UKF.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SigmaPoints {
    /// Spread α (thesis: 1).
    pub alpha: f64,
    /// Prior-knowledge β (thesis: 2, Gaussian).
    pub beta: f64,
    /// κ; `None` = the thesis's 3 − l.
    pub kappa: Option<f64>,
}

impl Default for SigmaPoints {
    fn default() -> Self {
        Self {
            alpha: 1.0,
            beta: 2.0,
            kappa: None,
        }
    }
}

/// The unscented transform's weights for `l` free parameters (Alg. 5.7, SPEC fix):
/// `ζ = α²(l + κ) − l`, `W0m = ζ/(l+ζ)`, `W0c = W0m + 1 − α² + β`, `Wi = 1/(2(l+ζ))`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SigmaWeights {
    /// Mean weight of the centre point, `W0m`.
    pub wm0: f64,
    /// Covariance weight of the centre point, `W0c`.
    pub wc0: f64,
    /// Weight of each of the 2l outer points, `Wi` (mean and covariance).
    pub wi: f64,
}

impl SigmaWeights {
    /// The weights of `points` for `l` parameters; refused unless α > 0 and `l + ζ > 0`.
    pub fn new(points: &SigmaPoints, l: usize) -> Result<Self, EstimError> {
        let lf = l as f64;
        let kappa = points.kappa.unwrap_or(3.0 - lf);
        let zeta = points.alpha * points.alpha * (lf + kappa) - lf;
        if !(points.alpha > 0.0 && lf + zeta > 0.0 && zeta.is_finite() && points.beta.is_finite()) {
            return Err(EstimError::InvalidConfig(format!(
                "sigma points need α > 0 and l + ζ > 0 (α = {}, κ = {kappa}, l = {l})",
                points.alpha
            )));
        }
        let wm0 = zeta / (lf + zeta);
        Ok(Self {
            wm0,
            wc0: wm0 + 1.0 - points.alpha * points.alpha + points.beta,
            wi: 1.0 / (2.0 * (lf + zeta)),
        })
    }

    /// `l + ζ`, the square of the sigma points' spread factor.
    pub fn spread2(&self) -> f64 {
        1.0 / (2.0 * self.wi)
    }
}

/// Which non-linear estimator.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum NlMethod {
    /// Extended Kalman filter (Alg. 5.6).
    Ekf,
    /// Unscented Kalman filter (Alg. 5.7).
    Ukf(SigmaPoints),
    /// Square-root UKF (van der Merwe & Wan 2001): the same filter carrying the Cholesky factor
    /// of P, updated by rank-one updates and downdates — the robust option.
    Srukf(SigmaPoints),
}

impl NlMethod {
    /// Short name (`ekf`, `ukf`).
    pub fn name(&self) -> &'static str {
        match self {
            NlMethod::Ekf => "ekf",
            NlMethod::Ukf(_) => "ukf",
            NlMethod::Srukf(_) => "srukf",
        }
    }
}

fn default_p0() -> CovSpec {
    CovSpec::Scaled(100.0)
}
fn default_r1() -> CovSpec {
    CovSpec::Scaled(0.0)
}
fn default_r2() -> f64 {
    1.0
}

/// Configuration of a non-linear estimator, as plain data.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NlConfig {
    /// EKF or UKF.
    pub method: NlMethod,
    /// Initial covariance over the free parameters (in scaled coordinates when `scaled`);
    /// default `100·I` (thesis ch. 8).
    #[serde(default = "default_p0")]
    pub p0: CovSpec,
    /// Random-walk covariance R1 (default 0).
    #[serde(default = "default_r1")]
    pub r1: CovSpec,
    /// Measurement-noise variance R2 (default 1).
    #[serde(default = "default_r2")]
    pub r2: f64,
    /// Estimate `x` with `ϑ = ϑ0·(1 + x)` (needs non-zero nominal values).
    #[serde(default)]
    pub scaled: bool,
    /// Bounds `(name, low, high)` enforced by projection.
    #[serde(default)]
    pub bounds: Vec<(String, f64, f64)>,
}

impl NlConfig {
    /// Defaults: P0 = 100·I, R1 = 0, R2 = 1, physical coordinates, no bounds.
    pub fn new(method: NlMethod) -> Self {
        Self {
            method,
            p0: default_p0(),
            r1: default_r1(),
            r2: default_r2(),
            scaled: false,
            bounds: Vec::new(),
        }
    }
}

/// The UKF's state and preallocated work space.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Ukf {
    x: DVector<f64>,
    /// The prior covariance: P (UKF), or its factor S (SR-UKF).
    p: Cov,
    r1: DMatrix<f64>,
    r2: f64,
    /// (l+ζ)·P (P the prior), then its Cholesky factor in place.
    chol: DMatrix<f64>,
    w: SigmaWeights,
    /// Outputs of the 2l+1 sigma points.
    ys: Vec<f64>,
    /// Cross-covariance / gain.
    pxy: DVector<f64>,
    /// Candidate state.
    x_new: DVector<f64>,
    /// Square-root columns of R1 (SR-UKF): R1 = Σ c cᵀ.
    r1_cols: Vec<DVector<f64>>,
    /// Work matrix and vector of the rank-one updates.
    work: DMatrix<f64>,
    v: DVector<f64>,
    /// Deviations of the 2l outer sigma points from the mean, after projection onto bounds.
    dev: DMatrix<f64>,
}

/// How state coordinates map to physical parameter values, and the bounds on them.
struct Coords<'a> {
    free: &'a [usize],
    scale: &'a [f64],
    scaled: bool,
    bounds: &'a [Option<(f64, f64)>],
}

impl Coords<'_> {
    /// Physical value of free parameter `k` at state coordinate `x`.
    #[inline]
    fn physical(&self, k: usize, x: f64) -> f64 {
        if self.scaled {
            self.scale[k] * (1.0 + x)
        } else {
            x
        }
    }

    /// Write the physical values of state `x` into their places of the full vector `theta`.
    fn load(&self, theta: &mut [f64], x: &[f64]) {
        for (k, (&i, &xk)) in self.free.iter().zip(x).enumerate() {
            theta[i] = self.physical(k, xk);
        }
    }

    /// State coordinate `x` of parameter `k` projected onto its bounds (unchanged without one).
    #[inline]
    fn project(&self, k: usize, x: f64) -> f64 {
        match self.bounds[k] {
            Some((lo, hi)) => {
                let phys = self.physical(k, x);
                let clamped = phys.clamp(lo, hi);
                if clamped == phys {
                    x
                } else if self.scaled {
                    clamped / self.scale[k] - 1.0
                } else {
                    clamped
                }
            }
            None => x,
        }
    }
}

#[derive(Debug, Clone, Serialize, Deserialize)]
enum Engine {
    Ekf(Box<LinearEstimator>),
    Ukf(Box<Ukf>),
}

/// EKF or UKF over the free parameters of a [`ParamModel`]. Serialised whole (its model
/// too, when the model serialises): a copy restored from it continues bit for bit.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct NonlinearEstimator<M: ParamModel> {
    model: M,
    method: NlMethod,
    params: ParamSet,
    free: FreeSet,
    engine: Engine,
    gradient: GradientEngine,
    /// Full physical parameter vector at the current estimate.
    theta: Vec<f64>,
    /// Jacobian over the free parameters (state coordinates).
    jac: Vec<f64>,
    /// ϑ0 of the free parameters (the scale of scaled coordinates).
    scale: Vec<f64>,
    scaled: bool,
    bounds: Vec<Option<(f64, f64)>>,
    repairs: u64,
    projections: u64,
    samples: u64,
    /// P0 in state coordinates (for [`Recursive::initial_covariance`]).
    p0: DMatrix<f64>,
}

impl<M: ParamModel> NonlinearEstimator<M> {
    /// Build an estimator of the `free` parameters of `model`, starting from `params`' nominal
    /// values (which hold the fixed ones).
    pub fn new(
        model: M,
        params: &ParamSet,
        free: &FreeSet,
        config: &NlConfig,
    ) -> Result<Self, EstimError> {
        crate::error::check_model_params(params, &model)?;
        check_view(params, free)?;
        let l = free.free().len();
        let scale: Vec<f64> = free.free().iter().map(|&i| params.nominal()[i]).collect();
        if config.scaled {
            if let Some(k) = scale.iter().position(|&s| s == 0.0) {
                return Err(EstimError::InvalidConfig(format!(
                    "scaled coordinates ϑ = ϑ0·(1 + x) need a non-zero nominal value for '{}'",
                    params.names()[free.free()[k]]
                )));
            }
        }
        let mut bounds = vec![None; l];
        for (name, lo, hi) in &config.bounds {
            let i = params
                .index_of(name)
                .map_err(|e| EstimError::InvalidConfig(e.to_string()))?;
            let k = free.free().iter().position(|&f| f == i).ok_or_else(|| {
                EstimError::InvalidConfig(format!("bound on '{name}', which is not free"))
            })?;
            if lo.is_nan() || hi.is_nan() || lo >= hi {
                return Err(EstimError::InvalidConfig(format!(
                    "bound on '{name}': low {lo} must be below high {hi}"
                )));
            }
            bounds[k] = Some((*lo, *hi));
        }
        // State coordinates: x = 0 (scaled) or ϑ0.
        let x0: Vec<f64> = if config.scaled {
            vec![0.0; l]
        } else {
            scale.clone()
        };
        let engine = match config.method {
            NlMethod::Ekf => {
                let names: Vec<String> = (0..l).map(|k| format!("x{k}")).collect();
                let inner_params = ParamSet::new(names, x0)
                    .map_err(|e| EstimError::InvalidConfig(e.to_string()))?;
                let cfg = EstimatorConfig {
                    method: Method::Kalman {
                        r1: config.r1.clone(),
                        r2: config.r2,
                    },
                    p0: config.p0.clone(),
                    guard: None,
                };
                Engine::Ekf(Box::new(LinearEstimator::new(
                    &cfg,
                    &inner_params,
                    &inner_params.all_free(),
                )?))
            }
            NlMethod::Ukf(sp) | NlMethod::Srukf(sp) => {
                let form = match config.method {
                    NlMethod::Srukf(_) => CovForm::Sqrt,
                    _ => CovForm::Full,
                };
                let w = SigmaWeights::new(&sp, l)?;
                let (r1, r2) = kalman_noise(&config.r1, config.r2, l)?;
                let p = Cov::from_covariance(form, config.p0.to_matrix(l, "P0")?, "P0")?;
                // SR-UKF: R1 = V Λ Vᵀ → columns √λ_k v_k.
                let r1_cols = match form {
                    CovForm::Sqrt => {
                        let eig = r1.clone().symmetric_eigen();
                        (0..l)
                            .filter(|&k| eig.eigenvalues[k] > 0.0)
                            .map(|k| eig.eigenvectors.column(k) * eig.eigenvalues[k].sqrt())
                            .collect()
                    }
                    CovForm::Full => Vec::new(),
                };
                Engine::Ukf(Box::new(Ukf {
                    x: DVector::from_vec(x0),
                    p,
                    r1,
                    r2,
                    chol: DMatrix::zeros(l, l),
                    w,
                    ys: vec![0.0; 2 * l + 1],
                    pxy: DVector::zeros(l),
                    x_new: DVector::zeros(l),
                    r1_cols,
                    work: DMatrix::zeros(l, l),
                    v: DVector::zeros(l),
                    dev: DMatrix::zeros(l, 2 * l),
                }))
            }
        };
        Ok(Self {
            gradient: GradientEngine::new(params.len()),
            theta: params.nominal().to_vec(),
            jac: vec![0.0; l],
            model,
            method: config.method,
            params: params.clone(),
            free: free.clone(),
            engine,
            scale,
            scaled: config.scaled,
            bounds,
            repairs: 0,
            projections: 0,
            samples: 0,
            p0: config.p0.to_matrix(l, "P0")?,
        })
    }

    fn state(&self) -> &[f64] {
        match &self.engine {
            Engine::Ekf(kf) => kf.estimate(),
            Engine::Ukf(u) => u.x.as_slice(),
        }
    }

    fn coords(&self) -> Coords<'_> {
        Coords {
            free: self.free.free(),
            scale: &self.scale,
            scaled: self.scaled,
            bounds: &self.bounds,
        }
    }

    /// Process one sample: `inputs` in the model's input order, `y` the measured output.
    /// Bad samples, a model that returns NaN, or a step that cannot be repaired return an error
    /// and leave the state untouched. Allocation-free.
    pub fn update(&mut self, inputs: &[f64], y: f64) -> Result<Step, EstimError> {
        crate::error::check_model_sample(&self.model, self.samples, inputs, y)?;
        // Field by field, so that the engine and the parameter vector can be borrowed mutably.
        let coords = Coords {
            free: self.free.free(),
            scale: &self.scale,
            scaled: self.scaled,
            bounds: &self.bounds,
        };
        let step = match &mut self.engine {
            Engine::Ekf(kf) => {
                coords.load(&mut self.theta, kf.estimate());
                let h = self.gradient.value_and_gradient(
                    &self.model,
                    inputs,
                    &self.theta,
                    self.free.free(),
                    &mut self.jac,
                );
                if !h.is_finite() {
                    return Err(EstimError::NonFinite {
                        sample: self.samples,
                        what: "model output h(φ, ϑ̂)".into(),
                        value: h,
                    });
                }
                if self.scaled {
                    for (j, s) in self.jac.iter_mut().zip(&self.scale) {
                        *j *= s; // ∂h/∂x = ∂h/∂ϑ · ϑ0
                    }
                }
                kf.update_linearized(&self.jac, y - h)?
            }
            Engine::Ukf(u) => {
                let (step, repaired) = Self::ukf_step(
                    u,
                    &self.model,
                    &mut self.theta,
                    &coords,
                    inputs,
                    y,
                    self.samples,
                )?;
                self.repairs += repaired;
                step
            }
        };
        // Keep the estimate within its bounds.
        if coords.bounds.iter().any(Option::is_some) {
            let state: &mut [f64] = match &mut self.engine {
                Engine::Ekf(kf) => kf.estimate_mut(),
                Engine::Ukf(u) => u.x.as_mut_slice(),
            };
            for (k, x) in state.iter_mut().enumerate() {
                let p = coords.project(k, *x);
                if p != *x {
                    *x = p;
                    self.projections += 1;
                }
            }
        }
        self.samples += 1;
        Ok(step)
    }

    /// One UKF step (Alg. 5.7); returns the step and the number of repairs it needed. With
    /// bounds, the sigma points are projected onto them too (Kandepu, Foss & Imsland 2008) and
    /// the cross-covariance uses the projected deviations — projecting only the mean leaves
    /// sigma points where the model may not even be defined.
    fn ukf_step(
        u: &mut Ukf,
        model: &M,
        theta: &mut [f64],
        coords: &Coords,
        inputs: &[f64],
        y: f64,
        sample: u64,
    ) -> Result<(Step, u64), EstimError> {
        let l = u.x.len();
        let gamma2 = u.w.spread2(); // l + ζ
        let mut repairs = 0;
        // The factor of (l+ζ)·P (P the prior): γ·S directly in the square-root form; else a
        // Cholesky factorisation, repaired if needed.
        match u.p.form() {
            CovForm::Sqrt => {
                u.chol.copy_from(u.p.held());
                u.chol *= gamma2.sqrt();
            }
            CovForm::Full => {
                let p = u.p.held();
                let scale = p.trace().abs() / l as f64;
                let tries = factor_with_jitter(&mut u.chol, scale, |a, eps| {
                    for j in 0..l {
                        for i in 0..l {
                            let v = 0.5 * (p[(i, j)] + p[(j, i)]) + if i == j { eps } else { 0.0 };
                            a[(i, j)] = gamma2 * v;
                        }
                    }
                })
                .ok_or_else(|| EstimError::LostPositiveDefiniteness {
                    sample,
                    detail: "the prior covariance has no Cholesky factor after 12 jitter repairs"
                        .into(),
                })?;
                repairs = u64::from(tries > 0);
            }
        }
        // Outputs of the sigma points x, x ± column k of the factor.
        // Sigma point `col` (0-based among the 2l outer ones) is x + sign·(column k).
        let mut moved = false;
        let bounded = coords.bounds.iter().any(Option::is_some);
        let (x, chol) = (u.x.as_slice(), u.chol.as_slice());
        let dev = u.dev.as_mut_slice();
        // Sigma point x + sign·(column k of the factor), its deviation into column `col` of dev.
        let mut point = |sign: f64, k: Option<usize>, col: usize| -> f64 {
            for (idx, &i) in coords.free.iter().enumerate() {
                let step = k.map_or(0.0, |c| sign * chol[c * l + idx]);
                let raw = x[idx] + step;
                let xk = if bounded {
                    coords.project(idx, raw)
                } else {
                    raw
                };
                if k.is_some() {
                    // Exact deviation unless a bound moved the point.
                    dev[col * l + idx] = if xk == raw {
                        step
                    } else {
                        moved = true;
                        xk - x[idx]
                    };
                }
                theta[i] = coords.physical(idx, xk);
            }
            model.eval::<f64>(inputs, theta)
        };
        u.ys[0] = point(0.0, None, 0);
        for k in 0..l {
            u.ys[1 + k] = point(1.0, Some(k), k);
            u.ys[1 + l + k] = point(-1.0, Some(k), l + k);
        }
        if let Some(i) = u.ys.iter().position(|v| !v.is_finite()) {
            return Err(EstimError::NonFinite {
                sample,
                what: format!("model output at sigma point {i}"),
                value: u.ys[i],
            });
        }
        if moved {
            // The prior as the projected points represent it: P̄ = Wi·Σ d dᵀ (the centre point
            // has no deviation), factored again in the square-root form.
            repairs += Self::projected_prior(u, sample)?;
        }
        let SigmaWeights { wm0, wc0, wi } = u.w;
        let y_hat = wm0 * u.ys[0] + wi * u.ys[1..].iter().sum::<f64>();
        let spread: f64 = u.ys[1..].iter().map(|v| (v - y_hat) * (v - y_hat)).sum();
        let centre = (u.ys[0] - y_hat) * (u.ys[0] - y_hat);
        let mut s = wc0 * centre + wi * spread + u.r2;
        if s.is_nan() || s <= 0.0 {
            s = wi * spread + u.r2; // repair (2): drop the negative centre weight
            repairs += 1;
        }
        // Cross-covariance: the centre point has zero deviation in x.
        let dev = u.dev.as_slice();
        for (idx, pxy) in u.pxy.iter_mut().enumerate() {
            let mut c = 0.0;
            for k in 0..l {
                c += dev[k * l + idx] * (u.ys[1 + k] - y_hat)
                    + dev[(l + k) * l + idx] * (u.ys[1 + l + k] - y_hat);
            }
            *pxy = wi * c;
        }
        let e = y - y_hat;
        // K = Pxy/S; x += K e; next prior P = P − K S Kᵀ + R1 = P − Pxy Pxyᵀ/S + R1
        // (symmetric products keep P exactly symmetric).
        let sinv = 1.0 / s;
        for idx in 0..l {
            u.x_new[idx] = u.x[idx] + u.pxy[idx] * sinv * e;
        }
        if !u.x_new.iter().all(|v| v.is_finite()) {
            return Err(EstimError::LostPositiveDefiniteness {
                sample,
                detail: "non-finite state after the update".into(),
            });
        }
        if u.p.form() == CovForm::Sqrt {
            repairs += Self::sqrt_update(u, sinv, sample)?;
        } else {
            let pxy = u.pxy.as_slice();
            for ((pcol, rcol), &pj) in
                u.p.held_mut()
                    .as_mut_slice()
                    .chunks_exact_mut(l)
                    .zip(u.r1.as_slice().chunks_exact(l))
                    .zip(pxy)
            {
                for ((pij, &rij), &pi) in pcol.iter_mut().zip(rcol).zip(pxy) {
                    *pij += rij - (pi * pj) * sinv;
                }
            }
        }
        std::mem::swap(&mut u.x, &mut u.x_new);
        Ok((
            Step {
                prediction_error: e,
                innovation_variance: s,
            },
            repairs,
        ))
    }

    /// Replace the prior by the covariance of the projected sigma points (constrained UKF);
    /// returns the jitter repairs its factorisation needed (square-root form only).
    fn projected_prior(u: &mut Ukf, sample: u64) -> Result<u64, EstimError> {
        let l = u.x.len();
        for j in 0..l {
            for i in 0..l {
                let c: f64 = (0..2 * l).map(|k| u.dev[(i, k)] * u.dev[(j, k)]).sum();
                u.work[(i, j)] = u.w.wi * c;
            }
        }
        if u.p.form() == CovForm::Full {
            u.p.held_mut().copy_from(&u.work);
            return Ok(0);
        }
        let work = &u.work;
        let tries = factor_with_jitter(u.p.held_mut(), work.trace().abs() / l as f64, |a, eps| {
            a.copy_from(work);
            for i in 0..l {
                a[(i, i)] += eps;
            }
        })
        .ok_or_else(|| EstimError::LostPositiveDefiniteness {
            sample,
            detail: "covariance of the projected sigma points has no Cholesky factor".into(),
        })?;
        Ok(u64::from(tries > 0))
    }

    /// SR-UKF covariance update: `S ← chol(S Sᵀ − U Uᵀ + R1)`, `U = Pxy·√(1/S_y²)`, by a rank-one
    /// downdate and rank-one updates with R1's square-root columns, in `work` (committed on
    /// success). A failed downdate is repaired by re-factoring with jitter; returns the repairs.
    fn sqrt_update(u: &mut Ukf, sinv: f64, sample: u64) -> Result<u64, EstimError> {
        let l = u.x.len();
        let mut repairs = 0;
        u.work.copy_from(u.p.held());
        u.v.copy_from(&u.pxy);
        u.v *= sinv.sqrt();
        if !chol_rank_one(&mut u.work, &mut u.v, -1.0) {
            // Repair: P = S Sᵀ − U Uᵀ formed explicitly, symmetrised, jittered, re-factored.
            repairs += 1;
            let (s, pxy) = (u.p.held(), &u.pxy);
            let scale = s.norm_squared() / l as f64;
            factor_with_jitter(&mut u.work, scale, |a, eps| {
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
        for c in &u.r1_cols {
            u.v.copy_from(c);
            if !chol_rank_one(&mut u.work, &mut u.v, 1.0) {
                return Err(EstimError::LostPositiveDefiniteness {
                    sample,
                    detail: "rank-one update with R1 failed".into(),
                });
            }
        }
        std::mem::swap(u.p.held_mut(), &mut u.work);
        Ok(repairs)
    }

    /// The method.
    pub fn method(&self) -> NlMethod {
        self.method
    }

    /// The model.
    pub fn model(&self) -> &M {
        &self.model
    }

    /// Names of the free parameters.
    pub fn free_names(&self) -> Vec<&str> {
        self.params.free_names(&self.free)
    }

    /// The free parameters' estimates, physical units.
    pub fn estimate(&self) -> Vec<f64> {
        let mut out = vec![0.0; self.scale.len()];
        self.estimate_into(&mut out);
        out
    }

    /// [`estimate`](Self::estimate) into `out` (one value per free parameter), without
    /// allocating — for a caller that records it after every update.
    pub fn estimate_into(&self, out: &mut [f64]) {
        let c = self.coords();
        for (k, (o, &x)) in out.iter_mut().zip(self.state().iter()).enumerate() {
            *o = c.physical(k, x);
        }
    }

    /// The full parameter vector (fixed ones at nominal), physical units.
    pub fn estimate_full(&self) -> Vec<f64> {
        let mut full = self.params.nominal().to_vec();
        self.coords().load(&mut full, self.state());
        full
    }

    /// Covariance of the state (scaled coordinates when `scaled`).
    pub fn covariance(&self) -> DMatrix<f64> {
        match &self.engine {
            Engine::Ekf(kf) => kf.covariance(),
            Engine::Ukf(u) => u.p.covariance(),
        }
    }

    /// Standard errors of the free parameters in physical units: `√P_ii` (times `|ϑ0_i|` in
    /// scaled coordinates). R1 and R2 are taken as given (absolute).
    pub fn std_errors(&self) -> Vec<f64> {
        let mut out = vec![0.0; self.scale.len()];
        self.std_errors_into(&mut out);
        out
    }

    /// [`std_errors`](Self::std_errors) into `out` (one value per free parameter), without
    /// allocating.
    pub fn std_errors_into(&self, out: &mut [f64]) {
        let cov = match &self.engine {
            Engine::Ekf(kf) => kf.held_covariance(),
            Engine::Ukf(u) => &u.p,
        };
        for (k, o) in out.iter_mut().enumerate().take(self.scale.len()) {
            let s = cov.variance(k).max(0.0).sqrt();
            *o = if self.scaled {
                s * self.scale[k].abs()
            } else {
                s
            };
        }
    }

    /// How many covariance repairs the UKF needed (see the module docs).
    pub fn repairs(&self) -> u64 {
        self.repairs
    }

    /// How many times a bound was enforced.
    pub fn projections(&self) -> u64 {
        self.projections
    }

    /// Samples accepted.
    pub fn samples(&self) -> u64 {
        self.samples
    }
}

impl<M: ParamModel> Recursive for NonlinearEstimator<M> {
    fn method_name(&self) -> &'static str {
        self.method.name()
    }
    fn param_names(&self) -> &[String] {
        self.params.names()
    }
    fn update(&mut self, inputs: &[f64], y: f64) -> Result<Step, EstimError> {
        NonlinearEstimator::update(self, inputs, y)
    }
    fn free_names(&self) -> Vec<&str> {
        NonlinearEstimator::free_names(self)
    }
    fn estimate(&self) -> Vec<f64> {
        NonlinearEstimator::estimate(self)
    }
    fn estimate_full(&self) -> Vec<f64> {
        NonlinearEstimator::estimate_full(self)
    }
    fn covariance(&self) -> DMatrix<f64> {
        NonlinearEstimator::covariance(self)
    }
    fn initial_covariance(&self) -> DMatrix<f64> {
        self.p0.clone()
    }
    fn std_errors(&self) -> Option<Vec<f64>> {
        Some(NonlinearEstimator::std_errors(self))
    }
    fn samples(&self) -> u64 {
        self.samples
    }
    fn repairs(&self) -> Option<u64> {
        Some(self.repairs)
    }
    fn projections(&self) -> Option<u64> {
        Some(self.projections)
    }
    fn snapshot(&self) -> Snapshot {
        let (state, cov, inner_samples) = match &self.engine {
            Engine::Ekf(kf) => (
                kf.estimate().to_vec(),
                kf.held_covariance().clone(),
                kf.samples(),
            ),
            Engine::Ukf(u) => (u.x.as_slice().to_vec(), u.p.clone(), self.samples),
        };
        debug_assert_eq!(inner_samples, self.samples);
        Snapshot {
            method: self.method.name().into(),
            free: self.free.free().to_vec(),
            params: NonlinearEstimator::estimate_full(self),
            state,
            cov,
            samples: self.samples,
            memory: Memory::Model {
                repairs: self.repairs,
                projections: self.projections,
            },
        }
    }
    fn restore(&mut self, s: &Snapshot) -> Result<(), EstimError> {
        let Memory::Model {
            repairs,
            projections,
        } = s.memory
        else {
            return Err(EstimError::InvalidConfig(
                "checkpoint: taken of a linear estimator, restored into a model-based filter"
                    .into(),
            ));
        };
        match &mut self.engine {
            Engine::Ekf(kf) => {
                let mut inner = Recursive::snapshot(kf.as_ref());
                s.check(
                    self.method.name(),
                    self.free.free(),
                    self.params.len(),
                    kf.held_covariance(),
                )?;
                inner.state.clone_from(&s.state);
                inner.cov = s.cov.clone();
                inner.samples = s.samples;
                Recursive::restore(kf.as_mut(), &inner)?;
            }
            Engine::Ukf(u) => {
                s.check(
                    self.method.name(),
                    self.free.free(),
                    self.params.len(),
                    &u.p,
                )?;
                u.x.copy_from_slice(&s.state);
                u.p = s.cov.clone();
            }
        }
        self.params = ParamSet::new(self.params.names().to_vec(), s.params.clone())
            .map_err(|e| EstimError::InvalidConfig(format!("checkpoint: {e}")))?;
        self.theta.copy_from_slice(&s.params);
        self.samples = s.samples;
        self.repairs = repairs;
        self.projections = projections;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use physid_core::Scalar;

    #[derive(Debug, Clone)]
    struct Lin2 {
        p: Vec<String>,
        u: Vec<String>,
    }

    impl ParamModel for Lin2 {
        fn param_names(&self) -> &[String] {
            &self.p
        }
        fn input_names(&self) -> &[String] {
            &self.u
        }
        fn eval<T: Scalar>(&self, u: &[f64], p: &[T]) -> T {
            p[0] * u[0] + p[1] * u[1]
        }
    }

    fn ukf(method: NlMethod) -> NonlinearEstimator<Lin2> {
        let m = Lin2 {
            p: vec!["a".into(), "b".into()],
            u: vec!["x".into(), "y".into()],
        };
        let params = ParamSet::zeros(["a", "b"]).unwrap();
        NonlinearEstimator::new(m, &params, &params.all_free(), &NlConfig::new(method)).unwrap()
    }

    /// Repair (1): a prior with no Cholesky factor (here singular, P = v vᵀ) is jittered until
    /// it has one; the step succeeds and the repair is counted.
    #[test]
    fn singular_prior_is_repaired_and_counted() {
        let mut est = ukf(NlMethod::Ukf(SigmaPoints::default()));
        if let Engine::Ukf(u) = &mut est.engine {
            u.p = Cov::full(DMatrix::from_row_slice(2, 2, &[1.0, 1.0, 1.0, 1.0]));
        }
        est.update(&[1.0, 0.5], 2.0).unwrap();
        assert_eq!(est.repairs(), 1);
        assert!(est.estimate().iter().all(|v| v.is_finite()));
    }

    /// The square-root downdate `S Sᵀ − U Uᵀ` that is exactly singular fails as a rank-one
    /// downdate and is repaired by re-factoring with jitter.
    #[test]
    fn failed_square_root_downdate_is_repaired() {
        let mut est = ukf(NlMethod::Srukf(SigmaPoints::default()));
        let Engine::Ukf(u) = &mut est.engine else {
            panic!("SR-UKF engine")
        };
        u.p = Cov::sqrt(DMatrix::identity(2, 2));
        u.pxy = DVector::from_vec(vec![1.0, 0.0]);
        // S Sᵀ − U Uᵀ with U = Pxy·√(1/S_y²), S_y² = 1: I − e1 e1ᵀ, singular.
        let repairs = NonlinearEstimator::<Lin2>::sqrt_update(u, 1.0, 0).unwrap();
        assert_eq!(repairs, 1);
        let p = u.p.covariance();
        assert!(p[(0, 0)] > 0.0 && p[(0, 0)] < 1e-9 && (p[(1, 1)] - 1.0).abs() < 1e-9);
    }
}
