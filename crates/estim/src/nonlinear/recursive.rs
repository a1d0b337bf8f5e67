//! [`NonlinearEstimator`] as a [`Recursive`] estimator: estimates, standard errors, checkpoints.

use super::*;

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
