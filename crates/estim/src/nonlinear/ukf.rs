//! The UKF (Alg. 5.7) and, with [`SqrtCov`], the SR-UKF: `2l+1` sigma points from the prior
//! covariance, the unscented mean and variance of the output, the cross-covariance, the update.

use super::*;

/// The unscented Kalman filter over the free parameters of a [`ParamModel`], holding its prior
/// covariance as `F` ([`FullCov`]: the UKF; [`SqrtCov`]: the SR-UKF). Serialised whole (its
/// model too, when the model serialises): a copy restored from it continues bit for bit.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Ukf<M: ParamModel, F: CovFactor> {
    frame: Frame<M>,
    points: SigmaPoints,
    x: DVector<f64>,
    /// The prior covariance of the next sample.
    pub(super) p: F,
    r2: f64,
    /// The factor of (l+ζ)·P.
    chol: DMatrix<f64>,
    w: SigmaWeights,
    /// Outputs of the 2l+1 sigma points.
    ys: Vec<f64>,
    /// The 2l+1 sigma points' full parameter vectors, one after another, evaluated in one
    /// [`ParamModel::eval_many`]. Scratch: not serialised (sized again on the first step after
    /// a restore).
    #[serde(skip, default)]
    points_theta: Vec<f64>,
    /// Cross-covariance / gain.
    pxy: DVector<f64>,
    /// Candidate state.
    x_new: DVector<f64>,
    /// Work matrix and vector (the projected prior, the rank-one updates).
    work: DMatrix<f64>,
    v: DVector<f64>,
    /// Deviations of the 2l outer sigma points from the mean, after projection onto bounds.
    dev: DMatrix<f64>,
}

impl<M: ParamModel, F: CovFactor> Ukf<M, F> {
    /// An unscented filter of the `free` parameters of `model` with sigma points `points`,
    /// starting from `params`' nominal values (which hold the fixed ones); `config.method` is
    /// not consulted.
    pub fn new(
        model: M,
        params: &ParamSet,
        free: &FreeSet,
        config: &NlConfig,
        points: SigmaPoints,
    ) -> Result<Self, EstimError> {
        let (frame, x0) = Frame::new(model, params, free, config)?;
        let l = x0.len();
        let w = SigmaWeights::new(&points, l)?;
        let (r1, r2) = kalman_noise(&config.r1, config.r2, l)?;
        let p = F::new(config.p0.to_matrix(l, "P0")?, r1)?;
        Ok(Self {
            frame,
            points,
            x: DVector::from_vec(x0),
            p,
            r2,
            chol: DMatrix::zeros(l, l),
            w,
            ys: vec![0.0; 2 * l + 1],
            points_theta: vec![0.0; (2 * l + 1) * params.len()],
            pxy: DVector::zeros(l),
            x_new: DVector::zeros(l),
            work: DMatrix::zeros(l, l),
            v: DVector::zeros(l),
            dev: DMatrix::zeros(l, 2 * l),
        })
    }

    /// Replace the prior by the covariance of the projected sigma points (constrained UKF):
    /// `P̄ = Wi·Σ d dᵀ` (the centre point has no deviation); the repairs it needed.
    fn projected_prior(&mut self, sample: u64) -> Result<u64, EstimError> {
        let l = self.x.len();
        for j in 0..l {
            for i in 0..l {
                let c: f64 = (0..2 * l)
                    .map(|k| self.dev[(i, k)] * self.dev[(j, k)])
                    .sum();
                self.work[(i, j)] = self.w.wi * c;
            }
        }
        self.p.set_prior(&self.work, sample)
    }

    /// One step (Alg. 5.7); the repairs it needed. With bounds, the sigma points are projected
    /// onto them too (Kandepu, Foss & Imsland 2008) and the cross-covariance uses the projected
    /// deviations — projecting only the mean leaves sigma points where the model may not even
    /// be defined.
    fn ukf_step(&mut self, inputs: &[f64], y: f64) -> Result<(Step, u64), EstimError> {
        let l = self.x.len();
        let gamma2 = self.w.spread2(); // l + ζ
        let (coords, model, theta, sample) = self.frame.parts();
        let mut repairs = self.p.spread(gamma2, &mut self.chol, sample)?;
        // Outputs of the sigma points x, x ± column k of the factor.
        // Sigma point `col` (0-based among the 2l outer ones) is x + sign·(column k).
        let mut moved = false;
        let bounded = coords.bounds.iter().any(Option::is_some);
        let (x, chol) = (self.x.as_slice(), self.chol.as_slice());
        let dev = self.dev.as_mut_slice();
        let n = theta.len();
        if self.points_theta.len() != (2 * l + 1) * n {
            self.points_theta = vec![0.0; (2 * l + 1) * n];
        }
        for block in self.points_theta.chunks_exact_mut(n) {
            block.copy_from_slice(theta); // the fixed parameters' values
        }
        let (centre, outer) = self.points_theta.split_at_mut(n);
        let (plus, minus) = outer.split_at_mut(l * n);
        // Sigma point x + sign·(column k of the factor) into `theta`, its deviation into column
        // `col` of dev.
        let mut point = |theta: &mut [f64], sign: f64, k: Option<usize>, col: usize| {
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
        };
        point(centre, 0.0, None, 0);
        let outer = plus.chunks_exact_mut(n).zip(minus.chunks_exact_mut(n));
        if bounded {
            for (k, (p, m)) in outer.enumerate() {
                point(p, 1.0, Some(k), k);
                point(m, -1.0, Some(k), l + k);
            }
        } else {
            // Nothing projected: the same points, x ± column k, both in one pass down the
            // column; the deviations are the column itself.
            let (dev_plus, dev_minus) = self.dev.as_mut_slice().split_at_mut(l * l);
            for ((((p, m), ck), dp), dm) in outer
                .zip(chol.chunks_exact(l))
                .zip(dev_plus.chunks_exact_mut(l))
                .zip(dev_minus.chunks_exact_mut(l))
            {
                for (idx, (((&i, &c), &xi), (dpi, dmi))) in coords
                    .free
                    .iter()
                    .zip(ck)
                    .zip(x)
                    .zip(dp.iter_mut().zip(dm.iter_mut()))
                    .enumerate()
                {
                    (*dpi, *dmi) = (c, -c);
                    p[i] = coords.physical(idx, xi + c);
                    m[i] = coords.physical(idx, xi + -c);
                }
            }
        }
        // Their outputs in one batch: y_0 the centre's, y_{1+k} x + column k's, y_{1+l+k} x −
        // column k's.
        model.eval_many(inputs, &self.points_theta, &mut self.ys);
        if let Some(i) = self.ys.iter().position(|v| !v.is_finite()) {
            return Err(EstimError::NonFinite {
                sample,
                what: format!("model output at sigma point {i}"),
                value: self.ys[i],
            });
        }
        if moved {
            // The prior as the projected points represent it.
            repairs += self.projected_prior(sample)?;
        }
        let SigmaWeights { wm0, wc0, wi } = self.w;
        let ys = &self.ys;
        let y_hat = wm0 * ys[0] + wi * ys[1..].iter().sum::<f64>();
        let spread: f64 = ys[1..].iter().map(|v| (v - y_hat) * (v - y_hat)).sum();
        let centre = (ys[0] - y_hat) * (ys[0] - y_hat);
        let mut s = wc0 * centre + wi * spread + self.r2;
        if s.is_nan() || s <= 0.0 {
            s = wi * spread + self.r2; // repair (2): drop the negative centre weight
            repairs += 1;
        }
        // Cross-covariance: the centre point has zero deviation in x.
        let dev = self.dev.as_slice();
        for (idx, pxy) in self.pxy.iter_mut().enumerate() {
            let mut c = 0.0;
            for k in 0..l {
                c += dev[k * l + idx] * (ys[1 + k] - y_hat)
                    + dev[(l + k) * l + idx] * (ys[1 + l + k] - y_hat);
            }
            *pxy = wi * c;
        }
        let e = y - y_hat;
        // K = Pxy/S; x += K e; next prior P = P − K S Kᵀ + R1 = P − Pxy Pxyᵀ/S + R1.
        let sinv = 1.0 / s;
        for idx in 0..l {
            self.x_new[idx] = self.x[idx] + self.pxy[idx] * sinv * e;
        }
        if !self.x_new.iter().all(|v| v.is_finite()) {
            return Err(EstimError::LostPositiveDefiniteness {
                sample,
                detail: "non-finite state after the update".into(),
            });
        }
        repairs += self
            .p
            .update(&self.pxy, sinv, &mut self.work, &mut self.v, sample)?;
        std::mem::swap(&mut self.x, &mut self.x_new);
        Ok((
            Step {
                prediction_error: e,
                innovation_variance: s,
            },
            repairs,
        ))
    }
}

impl<M: ParamModel, F: CovFactor> ModelFilter for Ukf<M, F> {
    type Model = M;
    fn method(&self) -> NlMethod {
        F::method(self.points)
    }
    fn frame(&self) -> &Frame<M> {
        &self.frame
    }
    fn frame_mut(&mut self) -> &mut Frame<M> {
        &mut self.frame
    }
    fn state(&self) -> &[f64] {
        self.x.as_slice()
    }
    fn held(&self) -> &Cov {
        self.p.held()
    }

    fn step(&mut self, inputs: &[f64], y: f64) -> Result<Step, EstimError> {
        self.frame.check(inputs, y)?;
        let (step, repairs) = self.ukf_step(inputs, y)?;
        self.frame.repairs += repairs;
        self.frame.accept(self.x.as_mut_slice());
        Ok(step)
    }

    fn restore_state(&mut self, s: &Snapshot) -> Result<(), EstimError> {
        self.x.copy_from_slice(&s.state);
        *self.p.held_mut() = s.cov.clone();
        Ok(())
    }
}
