//! The estimator's construction, its step (the engine of the module docs, and DSFC's
//! square-root form) and its accessors.

use super::kernels::*;
use super::lanes::Lanes;
#[cfg(avx2_copy)]
use super::lanes::{avx2, Avx};
use super::*;

impl LinearEstimator {
    /// Build an estimator of the `free` parameters of `params`, the others held at their nominal
    /// values; the estimate starts at the nominal values (ϑ0).
    pub fn new(
        config: &EstimatorConfig,
        params: &ParamSet,
        free: &FreeSet,
    ) -> Result<Self, EstimError> {
        check_view(params, free)?;
        let p = free.free().len();
        let p0 = config.p0.to_matrix(p, "P0")?;
        let chol = p0
            .clone()
            .cholesky()
            .ok_or(EstimError::NotPositiveDefinite { what: "P0" })?;
        let mut post = vec![1.0; p];
        let mut pre = vec![1.0; p];
        let mut lambda_t = 1.0;
        let kind = match &config.method {
            Method::Rls => Kind::Cov(CovKind::Rls),
            Method::Rlsf { lambda } => {
                let l = check_lambda("λ", *lambda)?;
                post.fill(l.sqrt().recip());
                Kind::Cov(CovKind::Rlsf {
                    lambda: l,
                    inv_lambda: l.recip(),
                })
            }
            Method::RlsfTv {
                lambda0,
                lambda_init,
            } => {
                let l0 = check_lambda("λ0", *lambda0)?;
                lambda_t = check_lambda("λ(0)", *lambda_init)?;
                Kind::Cov(CovKind::RlsfTv { lambda0: l0 })
            }
            Method::Rlsvf { lambdas, variant } => {
                if lambdas.len() != p {
                    return Err(EstimError::DimensionMismatch {
                        what: "vector forgetting factors (one per free parameter)",
                        expected: p,
                        got: lambdas.len(),
                    });
                }
                let mut min_lambda: f64 = 1.0;
                for (i, &l) in lambdas.iter().enumerate() {
                    let l = check_lambda(&format!("λ_{}", i + 1), l)?;
                    min_lambda = min_lambda.min(l);
                    match variant {
                        VfVariant::Published => post[i] = l.recip(),
                        VfVariant::Symmetric => {
                            post[i] = l.sqrt().recip();
                            pre[i] = post[i];
                        }
                    }
                }
                Kind::Cov(CovKind::Vf {
                    symmetric: *variant == VfVariant::Symmetric,
                    min_lambda,
                })
            }
            Method::Kalman { r1, r2 } => {
                let (r1, r2) = kalman_noise(r1, *r2, p)?;
                Kind::Cov(CovKind::Kalman { r1, r2 })
            }
            Method::Dsfc { lambda } => Kind::Dsfc {
                lambda: check_lambda("λ", *lambda)?,
            },
        };
        let cov0 = match kind {
            Kind::Dsfc { .. } => Cov::sqrt(chol.l()),
            Kind::Cov(_) => Cov::full(p0),
        };
        if let Some(g) = &config.guard {
            if !(g.max_trace.is_finite() && g.max_trace > 0.0) {
                return Err(EstimError::InvalidConfig(format!(
                    "wind-up guard bound {} must be positive",
                    physid_core::Num(g.max_trace)
                )));
            }
            let tr0 = cov0.trace();
            if g.action == GuardAction::Reset && g.max_trace <= tr0 {
                return Err(EstimError::InvalidConfig(format!(
                    "covariance resetting to P0 (trace {tr0}) needs a bound above it, got {}",
                    g.max_trace
                )));
            }
        }
        let mut theta = DVector::zeros(p);
        for (t, &i) in theta.iter_mut().zip(free.free()) {
            *t = params.nominal()[i];
        }
        Ok(Self {
            config: config.clone(),
            universe: free.clone(),
            frozen_variance: vec![f64::NAN; params.len()],
            kind,
            params: params.clone(),
            free: free.clone(),
            theta,
            cov: cov0.clone(),
            work: cov0.held().clone(),
            cov0,
            u: DVector::zeros(p),
            k: DVector::zeros(p),
            phi: vec![0.0; p],
            pre,
            post,
            lambda_t,
            noise_num: 0.0,
            noise_den: 0.0,
            noise_scale: 1.0,
            samples: 0,
            guard_activations: 0,
            last: None,
        })
    }

    /// Process one sample: `phi` is the regressor over the *full* parameter set, `y` the
    /// measured output. A non-finite or wrong-length sample, or a step that would break the
    /// covariance, returns an error and leaves the state untouched. Allocation-free.
    pub fn update(&mut self, phi: &[f64], y: f64) -> Result<Step, EstimError> {
        check_sample(
            self.samples,
            "regressor φ",
            phi,
            self.params.len(),
            "y",
            y,
            |i| format!("phi[{i}] ({})", self.params.names()[i]),
        )?;
        // The free regressor: the caller's slice itself, or gathered into our buffer (taken out
        // of `self` for the step — a pointer swap, no allocation).
        let mut buf = std::mem::take(&mut self.phi);
        let (phi_free, y): (&[f64], f64) = if self.free.is_all_free() {
            (phi, y)
        } else {
            self.free.gather(phi, &mut buf);
            (
                &buf,
                y - self.free.fixed_contribution(phi, self.params.nominal()),
            )
        };
        // Summed in order, as a model's own `h(φ, ϑ) = Σ φ_i·ϑ_i` is: the EKF on a linear model
        // is this filter bit for bit.
        let e = y - phi_free
            .iter()
            .zip(self.theta.as_slice())
            .map(|(f, t)| f * t)
            .sum::<f64>();
        let result = self.step_sized(phi_free, e);
        self.phi = buf;
        self.commit(result)
    }

    /// One step of a *linearised* model (the EKF's use, Alg. 5.6): `j` is the regressor over
    /// the free parameters only — the exact Jacobian `∇h` at the current estimate — and
    /// `innovation` the prediction error `y − h(φ, ϑ̂)`. Same checks and guarantees as
    /// [`update`](Self::update).
    pub fn update_linearized(&mut self, j: &[f64], innovation: f64) -> Result<Step, EstimError> {
        check_sample(
            self.samples,
            "Jacobian over the free parameters",
            j,
            self.theta.len(),
            "innovation",
            innovation,
            |i| format!("Jacobian[{i}]"),
        )?;
        let result = self.step_sized(j, innovation);
        self.commit(result)
    }

    fn commit(&mut self, result: Result<Step, Breakdown>) -> Result<Step, EstimError> {
        let step = result.map_err(|b| EstimError::LostPositiveDefiniteness {
            sample: self.samples,
            detail: format!("{} = {}", b.what, b.value),
        })?;
        self.samples += 1;
        self.last = Some(step);
        Ok(step)
    }

    /// Run the step with the dimension known at compile time for p ≤ 20 — the same source,
    /// monomorphised, so the loops unroll and lose their bounds checks (p = 20: 8.4 against
    /// 7.3 M updates/s) — and at run time beyond. Where the build is for a CPU below AVX2 (the
    /// Python wheel: x86-64-v2) and this CPU has AVX2, the step's copy compiled for AVX2 runs
    /// (`avx2()`): the same source and the same results, in registers twice as wide.
    #[inline]
    fn step_sized(&mut self, phi: &[f64], e: f64) -> Result<Step, Breakdown> {
        macro_rules! sized {
            ($($n:literal)*) => {
                match phi.len() {
                    $($n => self.step_for_this_cpu(Const::<$n>, phi, e),)*
                    p => self.step_for_this_cpu(Dyn(p), phi, e),
                }
            };
        }
        sized!(1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20)
    }

    /// The step's AVX2 copy where there is one, this CPU has AVX2 and p is at least two blocks
    /// of four lanes; else the portable step. (Below, the wider registers buy nothing and the
    /// switch costs: RLS p = 2 from Python 31 against 32.5 M rows/s; p = 20 4.1 against 3.7.)
    #[inline(always)]
    #[allow(unsafe_code)] // the AVX2 copy's call, after asking the CPU
    fn step_for_this_cpu<D: Dim>(
        &mut self,
        dim: D,
        phi: &[f64],
        e: f64,
    ) -> Result<Step, Breakdown> {
        #[cfg(avx2_copy)]
        if dim.value() >= 8 && avx2() {
            // SAFETY: `avx2()` found AVX2 on this CPU.
            return unsafe { self.step_dim_avx2(dim, phi, e) };
        }
        self.step_dim_portable(dim, phi, e)
    }

    /// The step for the instruction set the crate is built for (with `wide::f64x4`: AVX in a
    /// build for this machine, two SSE2 registers in a portable one).
    fn step_dim_portable<D: Dim>(
        &mut self,
        dim: D,
        phi: &[f64],
        e: f64,
    ) -> Result<Step, Breakdown> {
        self.step_dim::<D, wide::f64x4>(dim, phi, e)
    }

    /// The step compiled for AVX2 (the kernels' lanes in one register; no fused multiply-add,
    /// which would change the results).
    ///
    /// # Safety
    /// The CPU must have AVX2 (`avx2()`).
    #[cfg(avx2_copy)]
    #[target_feature(enable = "avx2")]
    fn step_dim_avx2<D: Dim>(&mut self, dim: D, phi: &[f64], e: f64) -> Result<Step, Breakdown> {
        self.step_dim::<D, Avx>(dim, phi, e)
    }

    /// The step, inlined into each of the copies above.
    #[cfg_attr(avx2_copy, inline(always))]
    fn step_dim<D: Dim, L: Lanes>(
        &mut self,
        dim: D,
        phi: &[f64],
        e: f64,
    ) -> Result<Step, Breakdown> {
        match self.kind {
            Kind::Dsfc { lambda } => self.step_sqrt::<D, L>(dim, phi, e, lambda),
            Kind::Cov(ref c) => {
                let step = c.step(self.lambda_t);
                self.step_cov::<D, L>(dim, phi, e, step)
            }
        }
    }

    /// Covariance-form step (see the module table). Writes the new P into `work`, checks it and
    /// only then commits (λ(t) of the time-varying method too).
    #[cfg_attr(avx2_copy, inline(always))]
    fn step_cov<D: Dim, L: Lanes>(
        &mut self,
        dim: D,
        phi: &[f64],
        e: f64,
        step: CovStep,
    ) -> Result<Step, Breakdown> {
        let p = dim.value();
        let phi = &phi[..p];
        let CovStep {
            r,
            r_inv,
            lambda_now,
            rho,
            symmetric_vf,
            time_varying,
            kalman,
        } = step;
        let pre = &self.pre[..p];
        let post = &self.post[..p];
        // φ̃ = D_pre φ (kept in k as scratch), u = P φ̃.
        let phit = &mut self.k.as_mut_slice()[..p];
        for ((t, &d), &f) in phit.iter_mut().zip(pre).zip(phi) {
            *t = d * f;
        }
        let pm = &self.cov.held().as_slice()[..p * p];
        let u = &mut self.u.as_mut_slice()[..p];
        columns_times(pm, phit, u);
        let d = r + dot(phit, u);
        if !(d.is_finite() && d > 0.0) {
            return Err(breakdown("innovation denominator r + φ̃ᵀu", d));
        }
        let dinv = d.recip();
        // Gain K = D_pre u / d.
        let k = &mut self.k.as_mut_slice()[..p];
        let mut ke = 0.0;
        for ((ki, &ui), &dp) in k.iter_mut().zip(u.iter()).zip(pre) {
            *ki = if symmetric_vf { dp } else { 1.0 } * ui * dinv;
            ke += (*ki * e).abs();
        }
        if !ke.is_finite() {
            return Err(breakdown("gain times prediction error", ke));
        }
        let u = &*u;
        // New P = D_post (P − u uᵀ/d) D_post · 1/λ(t) + Q. Every entry is a product of
        // commutative products — (s_i·s_j)·c·(P_ij − (u_i·u_j)·(1/d)) — which IEEE arithmetic
        // makes bit-identical for (i, j) and (j, i): a symmetric P stays exactly symmetric
        // without mirroring. (w = u/√d would save the multiplication by 1/d, but puts a square
        // root on the step's critical path: 12 % of the step at p = 2.)
        let scale = if time_varying {
            r_inv // 1/λ(t)
        } else {
            1.0
        };
        let q = match &self.kind {
            Kind::Cov(CovKind::Kalman { r1, .. }) => Some(&r1.as_slice()[..p * p]),
            _ => None,
        };
        let wm = &mut self.work.as_mut_slice()[..p * p];
        let uniform = match self.kind {
            Kind::Cov(CovKind::Vf { .. }) => None,
            _ => Some(post.first().map_or(1.0, |s0| s0 * s0) * scale),
        };
        let ww = RankOne {
            a: u,
            b: u,
            g: dinv,
        };
        let finite = match (uniform, q) {
            (Some(c), None) if c == 1.0 => downdate::<L, UNIT, false>(wm, pm, ww, post, c, &[]),
            (Some(c), Some(q)) if c == 1.0 => downdate::<L, UNIT, true>(wm, pm, ww, post, c, q),
            (Some(c), None) => downdate::<L, UNIFORM, false>(wm, pm, ww, post, c, &[]),
            (Some(c), Some(q)) => downdate::<L, UNIFORM, true>(wm, pm, ww, post, c, q),
            (None, None) => downdate::<L, PER_PARAM, false>(wm, pm, ww, post, scale, &[]),
            (None, Some(q)) => downdate::<L, PER_PARAM, true>(wm, pm, ww, post, scale, q),
        };
        if !finite {
            let bad = wm
                .iter()
                .copied()
                .find(|v| !v.is_finite())
                .unwrap_or(f64::NAN);
            return Err(breakdown(
                "an entry of the updated covariance (overflow or NaN)",
                bad,
            ));
        }
        if let Some(i) = (0..p).find(|&i| wm[i * p + i] <= 0.0) {
            return Err(breakdown(
                "a diagonal entry of the updated P",
                wm[i * p + i],
            ));
        }
        self.apply_guard_cov();
        std::mem::swap(self.cov.held_mut(), &mut self.work);
        for (t, &ki) in self.theta.as_mut_slice()[..p]
            .iter_mut()
            .zip(&self.k.as_slice()[..p])
        {
            *t += ki * e;
        }
        if time_varying {
            self.lambda_t = lambda_now;
        }
        // Innovation variance: d (Kalman, absolute), d/r in σ² units otherwise; 1/s = r/d.
        let (s, s_inv) = if kalman {
            (d, dinv)
        } else {
            (d * r_inv, r * dinv)
        };
        Ok(self.record(e, s, s_inv, rho))
    }

    /// DSFC step (Alg. 5.5).
    #[cfg_attr(avx2_copy, inline(always))]
    fn step_sqrt<D: Dim, L: Lanes>(
        &mut self,
        dim: D,
        phi: &[f64],
        e: f64,
        lambda: f64,
    ) -> Result<Step, Breakdown> {
        let p = dim.value();
        let phi = &phi[..p];
        let sm = &self.cov.held().as_slice()[..p * p];
        // f = Sᵀφ: f_j = column j of S · φ.
        let f = &mut self.u.as_mut_slice()[..p];
        if p >= 8 {
            columns_dot::<L>(sm, phi, f);
        } else {
            // Below two blocks of four the plain dot per column is faster (p = 6: 27 against
            // 19 M updates/s).
            for (fj, col) in f.iter_mut().zip(sm.chunks_exact(p)) {
                *fj = dot(col, phi);
            }
        }
        let f = &*f;
        let a = (dot(f, f) + lambda).recip();
        if !(a.is_finite() && a > 0.0) {
            return Err(breakdown("a = 1/(fᵀf + λ)", a));
        }
        // γ = a S f.
        let gamma = &mut self.k.as_mut_slice()[..p];
        columns_times(sm, f, gamma);
        for gi in gamma.iter_mut() {
            *gi *= a;
        }
        let gamma = &*gamma;
        let g = (1.0 + (lambda * a).sqrt()).recip();
        let inv_sqrt_l = lambda.sqrt().recip();
        // S = (S − (γ·fᵀ)·g)/√λ.
        let wm = &mut self.work.as_mut_slice()[..p * p];
        if !downdate::<L, UNIFORM, false>(
            wm,
            sm,
            RankOne { a: gamma, b: f, g },
            &[],
            inv_sqrt_l,
            &[],
        ) {
            let bad = wm
                .iter()
                .copied()
                .find(|v| !v.is_finite())
                .unwrap_or(f64::NAN);
            return Err(breakdown(
                "an entry of the updated square root (overflow or NaN)",
                bad,
            ));
        }
        let ke: f64 = gamma.iter().map(|v| (v * e).abs()).sum();
        if !ke.is_finite() {
            return Err(breakdown("gain times prediction error", ke));
        }
        self.apply_guard_sqrt();
        std::mem::swap(self.cov.held_mut(), &mut self.work);
        for (t, &gi) in self.theta.as_mut_slice()[..p]
            .iter_mut()
            .zip(&self.k.as_slice()[..p])
        {
            *t += gi * e;
        }
        // Innovation variance in σ² units: (fᵀf + λ)/λ = 1/(aλ).
        let s_inv = a * lambda;
        Ok(self.record(e, s_inv.recip(), s_inv, lambda))
    }

    /// Noise-scale statistics from `w² = e²/s`, and the step.
    fn record(&mut self, e: f64, s: f64, s_inv: f64, rho: f64) -> Step {
        if self.noise_num == 0.0 && e != 0.0 && !NOISE_RANGE.contains(&e.abs()) {
            // The first residual that is not 0 sets the scale: 2^⌊log2 |e|⌋.
            self.noise_scale = 2f64.powi(e.abs().log2().floor() as i32);
        }
        let mut e = e / self.noise_scale;
        if !(e * e).is_finite() && e.is_finite() {
            // A residual far beyond the scale chosen (the first one was far smaller): the sum
            // so far moved to a scale near this one (what it loses is below its last digit).
            let next = self.noise_scale * 2f64.powi(e.abs().log2().floor() as i32);
            let f = self.noise_scale / next;
            self.noise_num = self.noise_num * f * f;
            e = e * self.noise_scale / next;
            self.noise_scale = next;
        }
        self.noise_num = rho * self.noise_num + e * e * s_inv;
        self.noise_den = rho * self.noise_den + 1.0;
        Step {
            prediction_error: e,
            innovation_variance: s,
        }
    }

    /// Wind-up guard on the candidate P in `work`.
    #[inline(always)]
    fn apply_guard_cov(&mut self) {
        let Some(g) = self.config.guard else { return };
        let tr = self.work.trace();
        if tr > g.max_trace {
            self.guard_activations += 1;
            match g.action {
                GuardAction::Scale => self.work *= g.max_trace / tr,
                GuardAction::Reset => self.work.copy_from(self.cov0.held()),
            }
        }
    }

    /// Wind-up guard on the candidate S in `work` (trace P = ‖S‖²_F).
    #[inline(always)]
    fn apply_guard_sqrt(&mut self) {
        let Some(g) = self.config.guard else { return };
        let tr = self.work.norm_squared();
        if tr > g.max_trace {
            self.guard_activations += 1;
            match g.action {
                GuardAction::Scale => self.work *= (g.max_trace / tr).sqrt(),
                GuardAction::Reset => self.work.copy_from(self.cov0.held()),
            }
        }
    }

    /// Covariance resetting: P (or S) back to P0, keeping the estimate. The way out after a
    /// [`EstimError::LostPositiveDefiniteness`] — which on nearly collinear data is the
    /// covariance form reaching its numerical limit: DSFC is the method for such data.
    pub fn reset_covariance(&mut self) {
        self.cov.held_mut().copy_from(self.cov0.held());
    }

    /// Change which parameters are estimated, among those the estimator was built with:
    /// parameters leaving the free set are frozen at their current estimates; parameters
    /// entering it start from their frozen value with the variance they had when frozen (their
    /// P0 variance if never estimated) and no correlation — nothing was learnt about them
    /// meanwhile; the covariance block of parameters that stay free is kept. This is how an estimator
    /// stops a parameter that has lost excitation from winding up (the on-line identifiability
    /// signal decides which), and releases it when excitation returns. Allocates (an event,
    /// not a per-sample operation).
    pub fn set_free(&mut self, free: &FreeSet) -> Result<(), EstimError> {
        if free.free() == self.free.free() {
            return Ok(());
        }
        let universe = self.universe.free();
        if free.full_len() != self.params.len() {
            return Err(EstimError::DimensionMismatch {
                what: "free set over the parameters",
                expected: self.params.len(),
                got: free.full_len(),
            });
        }
        let pos: Vec<usize> = free
            .free()
            .iter()
            .map(|j| {
                universe.iter().position(|u| u == j).ok_or_else(|| {
                    EstimError::InvalidConfig(format!(
                        "parameter {} was fixed when the estimator was built; it cannot be freed",
                        self.params.names()[*j]
                    ))
                })
            })
            .collect::<Result<_, _>>()?;
        let names = self.params.names().to_vec();
        let params = ParamSet::new(names, self.estimate_full())
            .map_err(|e| EstimError::InvalidConfig(e.to_string()))?;
        let n = universe.len();
        let subset = |spec: &CovSpec, what: &'static str| -> Result<CovSpec, EstimError> {
            let m = spec.to_matrix(n, what)?;
            Ok(CovSpec::Full(
                pos.iter()
                    .map(|&a| pos.iter().map(|&b| m[(a, b)]).collect())
                    .collect(),
            ))
        };
        let mut config = self.config.clone();
        config.p0 = subset(&self.config.p0, "P0")?;
        match &mut config.method {
            Method::Rlsvf { lambdas, .. } => *lambdas = pos.iter().map(|&a| lambdas[a]).collect(),
            Method::Kalman { r1, .. } => *r1 = subset(r1, "R1")?,
            _ => {}
        }
        let mut next = LinearEstimator::new(&config, &params, free)?;
        // Covariance: entering parameters at P0 (diagonal block, no cross terms), staying ones
        // keep their block.
        let old = self.covariance();
        let was: Vec<Option<usize>> = free
            .free()
            .iter()
            .map(|j| self.free.free().iter().position(|f| f == j))
            .collect();
        let mut frozen_variance = self.frozen_variance.clone();
        for (i, &j) in self.free.free().iter().enumerate() {
            if !free.free().contains(&j) {
                frozen_variance[j] = old[(i, i)];
            }
        }
        let p0 = next.covariance();
        let k = pos.len();
        let cov = DMatrix::from_fn(k, k, |a, b| match (was[a], was[b]) {
            (Some(i), Some(j)) => old[(i, j)],
            (None, None) if a == b => {
                let v = frozen_variance[free.free()[a]];
                if v.is_finite() {
                    v
                } else {
                    p0[(a, a)]
                }
            }
            _ => 0.0,
        });
        next.cov = Cov::from_covariance(
            next.cov.form(),
            cov,
            "covariance after changing the free set",
        )?;
        next.work = next.cov.held().clone();
        next.config = self.config.clone();
        next.universe = self.universe.clone();
        next.frozen_variance = frozen_variance;
        next.lambda_t = self.lambda_t;
        next.noise_num = self.noise_num;
        next.noise_den = self.noise_den;
        next.noise_scale = self.noise_scale;
        next.samples = self.samples;
        next.guard_activations = self.guard_activations;
        next.last = self.last;
        *self = next;
        Ok(())
    }

    /// The method and its tuning.
    pub fn method(&self) -> &Method {
        &self.config.method
    }

    /// The parameter set (all parameters, free and fixed).
    pub fn params(&self) -> &ParamSet {
        &self.params
    }

    /// The free/fixed view.
    pub fn free_set(&self) -> &FreeSet {
        &self.free
    }

    /// Names of the free parameters, in order.
    pub fn free_names(&self) -> Vec<&str> {
        self.params.free_names(&self.free)
    }

    /// Estimates of the free parameters.
    pub fn estimate(&self) -> &[f64] {
        self.theta.as_slice()
    }

    /// Mutable access to the free estimates, for projection onto bounds by a wrapping
    /// estimator (the covariance is left as it is).
    pub fn estimate_mut(&mut self) -> &mut [f64] {
        self.theta.as_mut_slice()
    }

    /// The full parameter vector: free estimates, fixed parameters at their nominal values.
    pub fn estimate_full(&self) -> Vec<f64> {
        let mut full = self.params.nominal().to_vec();
        self.free.scatter(self.theta.as_slice(), &mut full);
        full
    }

    /// Covariance P of the free parameters (DSFC: `S·Sᵀ`). In σ² units for the RLS family.
    pub fn covariance(&self) -> DMatrix<f64> {
        self.cov.covariance()
    }

    /// The covariance as held: P, or DSFC's square root S (`P = S·Sᵀ`).
    pub fn held_covariance(&self) -> &Cov {
        &self.cov
    }

    /// DSFC's square root S (`P = S·Sᵀ`); `None` for the covariance-form methods.
    pub fn sqrt_covariance(&self) -> Option<&DMatrix<f64>> {
        match self.cov.form() {
            CovForm::Sqrt => Some(self.cov.held()),
            CovForm::Full => None,
        }
    }

    /// trace(P), without forming P.
    pub fn covariance_trace(&self) -> f64 {
        self.cov.trace()
    }

    /// Estimated measurement-noise variance σ̂² (see the module docs); the Kalman filter's is
    /// its given R2. (Of data scaled by 1e-300 it underflows to 0: the standard errors are
    /// computed without it, from [`noise_scale`](Self::noise_scale).)
    pub fn noise_variance(&self) -> Result<f64, EstimError> {
        if let Kind::Cov(CovKind::Kalman { r2, .. }) = self.kind {
            return Ok(r2);
        }
        let scale = self.noise_scale;
        Ok(self.scaled_noise_variance()? * scale * scale)
    }

    /// `σ̂²` divided by the square of [`noise_scale`](Self::noise_scale): it neither
    /// underflows nor overflows when σ̂² would.
    fn scaled_noise_variance(&self) -> Result<f64, EstimError> {
        let p = self.phi.len() as f64;
        if self.noise_den <= p {
            return Err(EstimError::NotEnoughData {
                needed: self.phi.len() + 1,
                seen: self.noise_den.floor() as usize,
            });
        }
        Ok(self.noise_num / (self.noise_den - p))
    }

    /// The power of two the residuals are divided by before they are squared (1 for data of
    /// ordinary size): see [`NOISE_RANGE`].
    pub fn noise_scale(&self) -> f64 {
        self.noise_scale
    }

    /// `P_ii / P0_ii` of the `i`-th free parameter: how far the data have narrowed its
    /// uncertainty (≥ ½: not resolved, [`crate::resolution`]). Allocation-free.
    pub fn variance_ratio(&self, i: usize) -> f64 {
        self.cov.variance(i) / self.cov0.variance(i)
    }

    /// Standard errors of the free estimates, written into `out` (allocation-free):
    /// `√(σ̂²·P_ii)`, or `√P_ii` for the Kalman filter.
    pub fn std_errors_into(&self, out: &mut [f64]) -> Result<(), EstimError> {
        let p = self.phi.len();
        if out.len() != p {
            return Err(EstimError::DimensionMismatch {
                what: "standard-error buffer",
                expected: p,
                got: out.len(),
            });
        }
        let (scale, factor) = match self.kind {
            Kind::Cov(CovKind::Kalman { .. }) => (1.0, 1.0),
            _ => (self.scaled_noise_variance()?, self.noise_scale),
        };
        for (i, o) in out.iter_mut().enumerate() {
            *o = factor * (scale * self.cov.variance(i)).sqrt();
        }
        Ok(())
    }

    /// Standard errors of the free estimates.
    pub fn std_errors(&self) -> Result<Vec<f64>, EstimError> {
        let mut v = vec![0.0; self.phi.len()];
        self.std_errors_into(&mut v)?;
        Ok(v)
    }

    /// Current forgetting factor: λ(t) for the time-varying method, the constant λ for RLSF and
    /// DSFC, 1 for RLS and Kalman, the smallest λ_i for vector forgetting.
    pub fn lambda(&self) -> f64 {
        match &self.kind {
            Kind::Cov(CovKind::Rlsf { lambda, .. }) | Kind::Dsfc { lambda } => *lambda,
            Kind::Cov(CovKind::RlsfTv { .. }) => self.lambda_t,
            Kind::Cov(CovKind::Vf { min_lambda, .. }) => *min_lambda,
            Kind::Cov(CovKind::Rls | CovKind::Kalman { .. }) => 1.0,
        }
    }

    /// Number of samples accepted.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// How many times the wind-up guard acted.
    pub fn guard_activations(&self) -> u64 {
        self.guard_activations
    }

    /// The last accepted step.
    pub fn last_step(&self) -> Option<Step> {
        self.last
    }
}
