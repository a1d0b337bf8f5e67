//! What the EKF and the unscented filters share ([`Frame`]): the model, its parameters and the
//! free view, the state coordinates (physical, or scaled `ϑ = ϑ0·(1 + x)`), the bounds and the
//! counters; and [`ModelFilter`], the one face each filter gives the rest of the crate (every
//! [`ModelFilter`] is a [`Recursive`] estimator).

use super::*;

/// How state coordinates map to physical parameter values, and the bounds on them.
pub(super) struct Coords<'a> {
    pub(super) free: &'a [usize],
    scale: &'a [f64],
    scaled: bool,
    pub(super) bounds: &'a [Option<(f64, f64)>],
}

impl Coords<'_> {
    /// Physical value of free parameter `k` at state coordinate `x`.
    #[inline]
    pub(super) fn physical(&self, k: usize, x: f64) -> f64 {
        if self.scaled {
            self.scale[k] * (1.0 + x)
        } else {
            x
        }
    }

    /// Write the physical values of state `x` into their places of the full vector `theta`.
    pub(super) fn load(&self, theta: &mut [f64], x: &[f64]) {
        for (k, (&i, &xk)) in self.free.iter().zip(x).enumerate() {
            theta[i] = self.physical(k, xk);
        }
    }

    /// State coordinate `x` of parameter `k` projected onto its bounds (unchanged without one).
    #[inline]
    pub(super) fn project(&self, k: usize, x: f64) -> f64 {
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

/// The part of a model-based filter that is not the filter (see the module docs).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Frame<M: ParamModel> {
    model: M,
    params: ParamSet,
    free: FreeSet,
    /// Full physical parameter vector at the current estimate (a step's work space).
    pub(super) theta: Vec<f64>,
    /// ϑ0 of the free parameters (the scale of scaled coordinates).
    scale: Vec<f64>,
    scaled: bool,
    bounds: Vec<Option<(f64, f64)>>,
    pub(super) repairs: u64,
    projections: u64,
    samples: u64,
    /// P0 in state coordinates (for [`Recursive::initial_covariance`]).
    p0: DMatrix<f64>,
}

impl<M: ParamModel> Frame<M> {
    /// The frame of a filter of the `free` parameters of `model` from `params`' nominal values
    /// (which hold the fixed ones), and its starting state: `x = 0` (scaled) or ϑ0.
    pub(super) fn new(
        model: M,
        params: &ParamSet,
        free: &FreeSet,
        config: &NlConfig,
    ) -> Result<(Self, Vec<f64>), EstimError> {
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
        let x0 = if config.scaled {
            vec![0.0; l]
        } else {
            scale.clone()
        };
        let frame = Self {
            theta: params.nominal().to_vec(),
            model,
            params: params.clone(),
            free: free.clone(),
            scale,
            scaled: config.scaled,
            bounds,
            repairs: 0,
            projections: 0,
            samples: 0,
            p0: config.p0.to_matrix(l, "P0")?,
        };
        Ok((frame, x0))
    }

    /// Field by field, so that a filter can borrow `theta` mutably beside them.
    pub(super) fn parts(&mut self) -> (Coords<'_>, &M, &mut [f64], u64) {
        (
            Coords {
                free: self.free.free(),
                scale: &self.scale,
                scaled: self.scaled,
                bounds: &self.bounds,
            },
            &self.model,
            &mut self.theta,
            self.samples,
        )
    }

    pub(super) fn coords(&self) -> Coords<'_> {
        Coords {
            free: self.free.free(),
            scale: &self.scale,
            scaled: self.scaled,
            bounds: &self.bounds,
        }
    }

    /// Whether the filter estimates `x` with `ϑ = ϑ0·(1 + x)`.
    pub(super) fn scaled(&self) -> bool {
        self.scaled
    }

    /// ϑ0 of the free parameters.
    pub(super) fn scale(&self) -> &[f64] {
        &self.scale
    }

    /// A sample's inputs and output, checked before they touch any state.
    pub(super) fn check(&self, inputs: &[f64], y: f64) -> Result<(), EstimError> {
        crate::error::check_model_sample(&self.model, self.samples, inputs, y)
    }

    /// After an accepted step: keep `state` within the bounds (each projection counted) and
    /// count the sample.
    pub(super) fn accept(&mut self, state: &mut [f64]) {
        if self.bounds.iter().any(Option::is_some) {
            let coords = self.coords();
            let mut moved = 0;
            for (k, x) in state.iter_mut().enumerate() {
                let p = coords.project(k, *x);
                if p != *x {
                    *x = p;
                    moved += 1;
                }
            }
            self.projections += moved;
        }
        self.samples += 1;
    }

    /// The physical values of `state` into `out` (one per free parameter).
    fn physical_into(&self, state: &[f64], out: &mut [f64]) {
        let c = self.coords();
        for (k, (o, &x)) in out.iter_mut().zip(state).enumerate() {
            *o = c.physical(k, x);
        }
    }

    /// Standard errors in physical units from the covariance `cov` as held: `√P_ii` (times
    /// `|ϑ0_i|` in scaled coordinates).
    fn std_errors_into(&self, cov: &Cov, out: &mut [f64]) {
        for (k, o) in out.iter_mut().enumerate().take(self.scale.len()) {
            let s = cov.variance(k).max(0.0).sqrt();
            *o = if self.scaled {
                s * self.scale[k].abs()
            } else {
                s
            };
        }
    }

    /// The full parameter vector at `state` (fixed ones at nominal), physical units.
    fn estimate_full(&self, state: &[f64]) -> Vec<f64> {
        let mut full = self.params.nominal().to_vec();
        self.coords().load(&mut full, state);
        full
    }
}

/// One filter over a model — [`Ekf`], [`Ukf`], or [`NonlinearEstimator`], the one chosen at run
/// time: how it steps, and where its state and covariance are. Everything else (estimates in
/// physical units, standard errors, checkpoints) is written once, here and in
/// [`Recursive`]'s implementation for every `ModelFilter`.
pub trait ModelFilter {
    /// The model filtered.
    type Model: ParamModel;
    /// The method with its settings.
    fn method(&self) -> NlMethod;
    /// The frame: model, parameters, coordinates, counters.
    fn frame(&self) -> &Frame<Self::Model>;
    /// The state in state coordinates (one per free parameter).
    fn state(&self) -> &[f64];
    /// The prior covariance of the next sample, as held.
    fn held(&self) -> &Cov;
    /// Process one sample: `inputs` in the model's input order, `y` the measured output. Bad
    /// samples, a model that returns NaN, or a step that cannot be repaired return an error and
    /// leave the state untouched. Allocation-free.
    fn step(&mut self, inputs: &[f64], y: f64) -> Result<Step, EstimError>;
    /// A checkpoint's state and covariance put in place, `s` checked against this filter
    /// first ([`Snapshot::check`]); the frame's part is [`restore`](Recursive::restore)'s.
    fn restore_state(&mut self, s: &Snapshot) -> Result<(), EstimError>;
    /// The frame, to restore a checkpoint's counters into.
    fn frame_mut(&mut self) -> &mut Frame<Self::Model>;

    /// The model.
    fn model(&self) -> &Self::Model {
        &self.frame().model
    }
    /// The free parameters' estimates into `out` (one each), physical units, allocation-free.
    fn estimate_into(&self, out: &mut [f64]) {
        self.frame().physical_into(self.state(), out);
    }
    /// Their standard errors into `out`, physical units, allocation-free. R1 and R2 are taken
    /// as given (absolute).
    fn std_errors_into(&self, out: &mut [f64]) {
        self.frame().std_errors_into(self.held(), out);
    }
    /// How many covariance repairs the filter needed (see the module docs).
    fn repairs(&self) -> u64 {
        self.frame().repairs
    }
    /// How many times a bound was enforced.
    fn projections(&self) -> u64 {
        self.frame().projections
    }
}

impl<T: ModelFilter> Recursive for T {
    fn method_name(&self) -> &'static str {
        self.method().name()
    }
    fn param_names(&self) -> &[String] {
        self.frame().params.names()
    }
    fn update(&mut self, inputs: &[f64], y: f64) -> Result<Step, EstimError> {
        self.step(inputs, y)
    }
    fn free_names(&self) -> Vec<&str> {
        let f = self.frame();
        f.params.free_names(&f.free)
    }
    fn estimate(&self) -> Vec<f64> {
        let mut out = vec![0.0; self.state().len()];
        self.estimate_into(&mut out);
        out
    }
    fn estimate_full(&self) -> Vec<f64> {
        self.frame().estimate_full(self.state())
    }
    fn covariance(&self) -> DMatrix<f64> {
        self.held().covariance()
    }
    fn initial_covariance(&self) -> DMatrix<f64> {
        self.frame().p0.clone()
    }
    fn std_errors(&self) -> Option<Vec<f64>> {
        let mut out = vec![0.0; self.state().len()];
        self.std_errors_into(&mut out);
        Some(out)
    }
    fn samples(&self) -> u64 {
        self.frame().samples
    }
    fn repairs(&self) -> Option<u64> {
        Some(self.frame().repairs)
    }
    fn projections(&self) -> Option<u64> {
        Some(self.frame().projections)
    }
    fn snapshot(&self) -> Snapshot {
        let f = self.frame();
        Snapshot {
            method: self.method().name().into(),
            free: f.free.free().to_vec(),
            params: f.estimate_full(self.state()),
            state: self.state().to_vec(),
            cov: self.held().clone(),
            samples: f.samples,
            memory: Memory::Model {
                repairs: f.repairs,
                projections: f.projections,
            },
        }
    }
    fn restore(&mut self, s: &Snapshot) -> Result<(), EstimError> {
        let Memory::Model {
            repairs,
            projections,
        } = s.memory
        else {
            return Err(EstimError::InvalidConfig(format!(
                "checkpoint: taken of {}, restored into a model-based filter",
                s.memory.of()
            )));
        };
        let f = self.frame();
        s.check(
            self.method().name(),
            f.free.free(),
            f.params.len(),
            self.held(),
        )?;
        let params = ParamSet::new(f.params.names().to_vec(), s.params.clone())
            .map_err(|e| EstimError::InvalidConfig(format!("checkpoint: {e}")))?;
        self.restore_state(s)?;
        let f = self.frame_mut();
        f.params = params;
        f.theta.copy_from_slice(&s.params);
        f.samples = s.samples;
        f.repairs = repairs;
        f.projections = projections;
        Ok(())
    }
}
