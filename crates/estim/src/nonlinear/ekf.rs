//! The EKF (Alg. 5.6): the Kalman filter of Eq. 5.19 ([`LinearEstimator`]) fed with the exact
//! Jacobian `J = ∇_ϑ h(φ, ϑ̂)` (forward-mode dual numbers, [`GradientEngine`]) as its regressor
//! and `y − h(φ, ϑ̂)` as its innovation.

use super::*;

/// The extended Kalman filter over the free parameters of a [`ParamModel`]. Serialised whole
/// (its model too, when the model serialises): a copy restored from it continues bit for bit.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Ekf<M: ParamModel> {
    frame: Frame<M>,
    /// The Kalman filter over the state coordinates.
    kf: LinearEstimator,
    gradient: GradientEngine,
    /// Jacobian over the free parameters (state coordinates).
    jac: Vec<f64>,
}

impl<M: ParamModel> Ekf<M> {
    /// An EKF of the `free` parameters of `model`, starting from `params`' nominal values
    /// (which hold the fixed ones); `config.method` is not consulted.
    pub fn new(
        model: M,
        params: &ParamSet,
        free: &FreeSet,
        config: &NlConfig,
    ) -> Result<Self, EstimError> {
        let (frame, x0) = Frame::new(model, params, free, config)?;
        let l = x0.len();
        let names: Vec<String> = (0..l).map(|k| format!("x{k}")).collect();
        let inner =
            ParamSet::new(names, x0).map_err(|e| EstimError::InvalidConfig(e.to_string()))?;
        let cfg = EstimatorConfig {
            method: Method::Kalman {
                r1: config.r1.clone(),
                r2: config.r2,
            },
            p0: config.p0.clone(),
            guard: None,
        };
        Ok(Self {
            kf: LinearEstimator::new(&cfg, &inner, &inner.all_free())?,
            gradient: GradientEngine::new(params.len()),
            jac: vec![0.0; l],
            frame,
        })
    }
}

impl<M: ParamModel> ModelFilter for Ekf<M> {
    type Model = M;
    fn method(&self) -> NlMethod {
        NlMethod::Ekf
    }
    fn frame(&self) -> &Frame<M> {
        &self.frame
    }
    fn frame_mut(&mut self) -> &mut Frame<M> {
        &mut self.frame
    }
    fn state(&self) -> &[f64] {
        self.kf.estimate()
    }
    fn held(&self) -> &Cov {
        self.kf.held_covariance()
    }

    fn step(&mut self, inputs: &[f64], y: f64) -> Result<Step, EstimError> {
        self.frame.check(inputs, y)?;
        let scaled = self.frame.scaled();
        let (coords, model, theta, sample) = self.frame.parts();
        coords.load(theta, self.kf.estimate());
        let h = self
            .gradient
            .value_and_gradient(model, inputs, theta, coords.free, &mut self.jac);
        if !h.is_finite() {
            return Err(EstimError::NonFinite {
                sample,
                what: "model output h(φ, ϑ̂)".into(),
                value: h,
            });
        }
        if scaled {
            for (j, s) in self.jac.iter_mut().zip(self.frame.scale()) {
                *j *= s; // ∂h/∂x = ∂h/∂ϑ · ϑ0
            }
        }
        let step = self.kf.update_linearized(&self.jac, y - h)?;
        self.frame.accept(self.kf.estimate_mut());
        Ok(step)
    }

    fn restore_state(&mut self, s: &Snapshot) -> Result<(), EstimError> {
        let mut inner = Recursive::snapshot(&self.kf);
        inner.state.clone_from(&s.state);
        inner.cov = s.cov.clone();
        inner.samples = s.samples;
        Recursive::restore(&mut self.kf, &inner)
    }
}
