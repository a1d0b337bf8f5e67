//! [`LinearEstimator`] as a [`Recursive`](crate::recursive::Recursive) estimator: estimates,
//! standard errors, checkpoints.

use super::*;

impl crate::recursive::Recursive for LinearEstimator {
    fn method_name(&self) -> &'static str {
        self.config.method.name()
    }
    fn param_names(&self) -> &[String] {
        self.params.names()
    }
    fn update(&mut self, inputs: &[f64], y: f64) -> Result<Step, EstimError> {
        LinearEstimator::update(self, inputs, y)
    }
    fn free_names(&self) -> Vec<&str> {
        LinearEstimator::free_names(self)
    }
    fn estimate(&self) -> Vec<f64> {
        self.theta.as_slice().to_vec()
    }
    fn estimate_full(&self) -> Vec<f64> {
        LinearEstimator::estimate_full(self)
    }
    fn covariance(&self) -> DMatrix<f64> {
        self.cov.covariance()
    }
    fn initial_covariance(&self) -> DMatrix<f64> {
        self.cov0.covariance()
    }
    fn std_errors(&self) -> Option<Vec<f64>> {
        LinearEstimator::std_errors(self).ok()
    }
    fn samples(&self) -> u64 {
        self.samples
    }
    fn snapshot(&self) -> crate::recursive::Snapshot {
        crate::recursive::Snapshot {
            method: self.config.method.name().into(),
            free: self.free.free().to_vec(),
            params: LinearEstimator::estimate_full(self),
            state: self.theta.as_slice().to_vec(),
            cov: self.cov.clone(),
            samples: self.samples,
            memory: crate::recursive::Memory::Linear {
                lambda_t: self.lambda_t,
                noise_num: self.noise_num,
                noise_den: self.noise_den,
                noise_scale: self.noise_scale,
                guard_activations: self.guard_activations,
                frozen_variance: self
                    .frozen_variance
                    .iter()
                    .map(|v| v.is_finite().then_some(*v))
                    .collect(),
                last: self.last,
            },
        }
    }
    /// A snapshot taken with another free set (the excitation supervisor changed it) first
    /// moves this estimator to that set.
    fn restore(&mut self, s: &crate::recursive::Snapshot) -> Result<(), EstimError> {
        let crate::recursive::Memory::Linear {
            lambda_t,
            noise_num,
            noise_den,
            noise_scale,
            guard_activations,
            frozen_variance,
            last,
        } = &s.memory
        else {
            return Err(EstimError::InvalidConfig(format!(
                "checkpoint: taken of {}, restored into a linear estimator",
                s.memory.of()
            )));
        };
        if frozen_variance.len() != self.params.len() || s.params.len() != self.params.len() {
            return Err(EstimError::DimensionMismatch {
                what: "checkpoint: frozen variances (one per parameter)",
                expected: self.params.len(),
                got: frozen_variance.len(),
            });
        }
        let mut next = self.clone();
        if s.free != next.free.free() {
            let mut mask = vec![false; next.params.len()];
            for &i in &s.free {
                if i >= mask.len() {
                    return Err(EstimError::InvalidConfig(format!(
                        "checkpoint: free parameter index {i} beyond the {} parameters",
                        mask.len()
                    )));
                }
                mask[i] = true;
            }
            let free = FreeSet::from_mask(&mask)
                .map_err(|e| EstimError::InvalidConfig(format!("checkpoint: {e}")))?;
            next.set_free(&free)?;
        }
        s.check(
            self.config.method.name(),
            next.free.free(),
            next.params.len(),
            &next.cov,
        )?;
        next.params = ParamSet::new(next.params.names().to_vec(), s.params.clone())
            .map_err(|e| EstimError::InvalidConfig(format!("checkpoint: {e}")))?;
        next.theta.copy_from_slice(&s.state);
        next.cov = s.cov.clone();
        next.samples = s.samples;
        next.lambda_t = *lambda_t;
        next.noise_num = *noise_num;
        next.noise_den = *noise_den;
        next.noise_scale = *noise_scale;
        next.guard_activations = *guard_activations;
        next.frozen_variance = frozen_variance
            .iter()
            .map(|v| v.unwrap_or(f64::NAN))
            .collect();
        next.last = *last;
        *self = next;
        Ok(())
    }
}
