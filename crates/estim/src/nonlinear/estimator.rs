//! Construction and the step of the EKF (Alg. 5.6) and the UKF/SR-UKF (Alg. 5.7): coordinates,
//! the prior, the sigma points, the update, covariance repair and projection on the bounds.

use super::*;

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

    pub(super) fn state(&self) -> &[f64] {
        match &self.engine {
            Engine::Ekf(kf) => kf.estimate(),
            Engine::Ukf(u) => u.x.as_slice(),
        }
    }

    pub(super) fn coords(&self) -> Coords<'_> {
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
    pub(super) fn ukf_step(
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
    pub(super) fn projected_prior(u: &mut Ukf, sample: u64) -> Result<u64, EstimError> {
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
    pub(super) fn sqrt_update(u: &mut Ukf, sinv: f64, sample: u64) -> Result<u64, EstimError> {
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
