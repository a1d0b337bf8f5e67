//! On-line identifiability steering an estimator (thesis §9.2): a [`Steering`] runs the
//! recursive orthogonal ranking beside a [`LinearEstimator`] and freezes the
//! parameters the recent data no longer supports — under forgetting their covariance would
//! otherwise grow by 1/λ per sample (wind-up) — and releases them when excitation returns.
//!
//! "Supports" is judged per parameter against its own history: its residual sum of squares in
//! the current ranking (the information the remembered data holds about it beyond the
//! parameters ranked before it) relative to the largest it has had. Below `freeze_below` the
//! parameter is frozen, above `release_above` released (hysteresis). A comparison across
//! parameters (the ranking's relative cut-off) would not do: parameters of different units and
//! excitation levels would freeze each other.
//!
//! [`ExcitationSupervisor`] is the estimator with its steering, one [`Recursive`] estimator.
//!
//! [`lost_excitation`] is the demonstration on Example 5.2-style data (`z = A·sin(x) + B·y²`)
//! with a period where `y = 0`, so nothing excites B.

use nalgebra::DMatrix;
use physid_core::{FreeSet, ParamSet};
use physid_estim::{
    build_linear, EstimError, EstimatorSpec, LinearEstimator, MethodName, Recursive, Snapshot, Step,
};
use physid_ident::{IdentError, Memory, OnlineIdent, RankWorkspace};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use thiserror::Error;

/// Errors of the supervised estimator.
#[derive(Debug, Error)]
pub enum SupervisorError {
    /// From the estimator.
    #[error(transparent)]
    Estim(#[from] EstimError),
    /// From the identifiability analysis.
    #[error(transparent)]
    Ident(#[from] IdentError),
}

/// How the supervisor judges and acts.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
pub struct SupervisorConfig {
    /// What the ranking remembers (match the estimator's forgetting).
    pub memory: Memory,
    /// Freeze a parameter when its residual falls below this fraction of its largest.
    pub freeze_below: f64,
    /// Release it when its residual is back above this fraction.
    pub release_above: f64,
    /// Re-rank every this many samples.
    pub check_every: u64,
}

impl SupervisorConfig {
    /// Defaults for an estimator forgetting with λ: the same memory, freeze below 5 %, release
    /// above 20 %, re-rank every 10 samples.
    pub fn for_lambda(lambda: f64) -> Self {
        Self {
            memory: Memory::Forgetting(lambda),
            freeze_below: 0.05,
            release_above: 0.2,
            check_every: 10,
        }
    }
}

/// The supervisor's judgement of one estimator, apart from the estimator it steers: the
/// on-line ranking of its parameters and which of them are estimated now. The shaft monitor
/// steers its estimator with it directly; [`ExcitationSupervisor`] is the two together as one
/// [`Recursive`] estimator.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Steering {
    ident: OnlineIdent,
    config: SupervisorConfig,
    /// Universe: the parameters the estimator was built with (indices into the full set).
    universe: Vec<usize>,
    /// Per universe parameter: the scale of its sensitivity column (`φ_j·scale_j`).
    scale: Vec<f64>,
    /// Per universe parameter: the largest residual seen.
    reference: Vec<f64>,
    /// Per universe parameter: currently estimated.
    active: Vec<bool>,
    /// The ranking's row of the sample being taken.
    row: Vec<f64>,
    /// The ranking's working memory (re-ranking allocates nothing).
    ws: RankWorkspace,
    samples: u64,
    freezes: u64,
    releases: u64,
}

impl Steering {
    /// Steering for `estimator`: the ranking runs on the rows `φ_j·scale_j` of the estimator's
    /// free parameters (`scale`: one per free parameter, e.g. nominal magnitudes).
    pub fn new(
        estimator: &LinearEstimator,
        scale: Vec<f64>,
        config: SupervisorConfig,
    ) -> Result<Self, SupervisorError> {
        let universe = estimator.free_set().free().to_vec();
        if scale.len() != universe.len() {
            return Err(IdentError::Invalid(format!(
                "{} scales for {} free parameters",
                scale.len(),
                universe.len()
            ))
            .into());
        }
        if !(0.0 < config.freeze_below && config.freeze_below < config.release_above) {
            return Err(IdentError::Invalid(format!(
                "expected 0 < freeze_below ({}) < release_above ({})",
                config.freeze_below, config.release_above
            ))
            .into());
        }
        let p = universe.len();
        Ok(Self {
            ident: OnlineIdent::new(p, config.memory)?,
            config,
            universe,
            scale,
            reference: vec![0.0; p],
            active: vec![true; p],
            row: vec![0.0; p],
            ws: RankWorkspace::new(p),
            samples: 0,
            freezes: 0,
            releases: 0,
        })
    }

    /// One sample (`phi` over the full parameter set, as [`LinearEstimator::update`]) into
    /// `estimator` and the ranking, then — every `check_every` samples — the estimator's free
    /// set steered. A sample the estimator refuses, or whose scaled row is not finite, changes
    /// nothing.
    pub fn update(
        &mut self,
        estimator: &mut LinearEstimator,
        phi: &[f64],
        y: f64,
    ) -> Result<Step, SupervisorError> {
        // A row that overflows where φ is finite is refused before the estimator takes the
        // sample; a φ the estimator refuses is its to name.
        let well_formed = phi.len() == estimator.params().len();
        for (k, ((r, &j), s)) in self
            .row
            .iter_mut()
            .zip(&self.universe)
            .zip(&self.scale)
            .enumerate()
        {
            let v = if well_formed { phi[j] } else { 0.0 };
            *r = v * s;
            if v.is_finite() && !r.is_finite() {
                return Err(EstimError::NonFinite {
                    sample: estimator.samples(),
                    what: format!("the supervisor's ranking row φ_{k}·scale_{k}"),
                    value: *r,
                }
                .into());
            }
        }
        let step = estimator.update(phi, y)?;
        self.ident.update(&self.row)?;
        self.samples += 1;
        if self.samples.is_multiple_of(self.config.check_every.max(1)) {
            self.steer(estimator)?;
        }
        Ok(step)
    }

    fn steer(&mut self, estimator: &mut LinearEstimator) -> Result<(), SupervisorError> {
        let ranking = self.ident.ranking_into(&mut self.ws);
        let mut changed = false;
        for step in &ranking.steps {
            let j = step.param;
            let res = step.residual_ss;
            self.reference[j] = self.reference[j].max(res);
            let r = self.reference[j];
            if self.active[j] && res < self.config.freeze_below * r {
                self.active[j] = false;
                self.freezes += 1;
                changed = true;
            } else if !self.active[j] && res > self.config.release_above * r {
                self.active[j] = true;
                self.releases += 1;
                changed = true;
            }
        }
        if changed {
            let mut mask = vec![false; estimator.params().len()];
            for (&j, &a) in self.universe.iter().zip(&self.active) {
                mask[j] = a;
            }
            let free = FreeSet::from_mask(&mask).map_err(|e| IdentError::Invalid(e.to_string()))?;
            estimator.set_free(&free)?;
        }
        Ok(())
    }

    /// Per parameter the estimator was built with (in its order): whether it is estimated now
    /// (`false`: frozen).
    pub fn active(&self) -> &[bool] {
        &self.active
    }

    /// Parameters frozen so far (events).
    pub fn freezes(&self) -> u64 {
        self.freezes
    }

    /// Parameters released so far (events).
    pub fn releases(&self) -> u64 {
        self.releases
    }
}

/// A linear estimator whose free set follows the on-line identifiability of its parameters:
/// the estimator and its [`Steering`], one [`Recursive`] estimator (its checkpoint holds both).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct ExcitationSupervisor {
    estimator: LinearEstimator,
    steering: Steering,
}

impl ExcitationSupervisor {
    /// Supervise `estimator` ([`Steering::new`]).
    pub fn new(
        estimator: LinearEstimator,
        scale: Vec<f64>,
        config: SupervisorConfig,
    ) -> Result<Self, SupervisorError> {
        let steering = Steering::new(&estimator, scale, config)?;
        Ok(Self {
            estimator,
            steering,
        })
    }

    /// One sample ([`Steering::update`]).
    pub fn update(&mut self, phi: &[f64], y: f64) -> Result<Step, SupervisorError> {
        self.steering.update(&mut self.estimator, phi, y)
    }

    /// Per parameter the estimator was built with (in its order): whether it is estimated now
    /// (`false`: frozen).
    pub fn active(&self) -> &[bool] {
        self.steering.active()
    }

    /// The supervised estimator.
    pub fn estimator(&self) -> &LinearEstimator {
        &self.estimator
    }

    /// Parameters frozen so far (events).
    pub fn freezes(&self) -> u64 {
        self.steering.freezes()
    }

    /// Parameters released so far (events).
    pub fn releases(&self) -> u64 {
        self.steering.releases()
    }
}

/// The supervised estimator as any other: a ranking error (which a finite sample the estimator
/// took cannot cause) is reported as an invalid configuration.
impl Recursive for ExcitationSupervisor {
    fn method_name(&self) -> &'static str {
        self.estimator.method_name()
    }
    fn update(&mut self, inputs: &[f64], y: f64) -> Result<Step, EstimError> {
        ExcitationSupervisor::update(self, inputs, y).map_err(|e| match e {
            SupervisorError::Estim(e) => e,
            SupervisorError::Ident(e) => {
                EstimError::InvalidConfig(format!("excitation supervisor: {e}"))
            }
        })
    }
    fn param_names(&self) -> &[String] {
        self.estimator.param_names()
    }
    fn free_names(&self) -> Vec<&str> {
        self.estimator.free_names()
    }
    fn estimate(&self) -> Vec<f64> {
        Recursive::estimate(&self.estimator)
    }
    fn estimate_full(&self) -> Vec<f64> {
        self.estimator.estimate_full()
    }
    fn covariance(&self) -> DMatrix<f64> {
        self.estimator.covariance()
    }
    fn initial_covariance(&self) -> DMatrix<f64> {
        Recursive::initial_covariance(&self.estimator)
    }
    fn std_errors(&self) -> Option<Vec<f64>> {
        Recursive::std_errors(&self.estimator)
    }
    fn samples(&self) -> u64 {
        self.estimator.samples()
    }
    /// The estimator's snapshot, its memory wrapped with the steering's state
    /// ([`physid_estim::Memory::Steered`]).
    fn snapshot(&self) -> Snapshot {
        let mut s = self.estimator.snapshot();
        s.memory = physid_estim::Memory::Steered {
            estimator: Box::new(s.memory),
            // Plain numbers into a Vec: MessagePack cannot fail on them; if it ever did, the
            // empty state is refused on restore, naming it.
            steering: rmp_serde::to_vec_named(&self.steering).unwrap_or_default(),
        };
        s
    }
    fn restore(&mut self, s: &Snapshot) -> Result<(), EstimError> {
        let physid_estim::Memory::Steered {
            estimator,
            steering,
        } = &s.memory
        else {
            return Err(EstimError::InvalidConfig(format!(
                "checkpoint: taken of {}, restored into a supervised estimator",
                s.memory.of()
            )));
        };
        let steering: Steering = rmp_serde::from_slice(steering).map_err(|e| {
            EstimError::InvalidConfig(format!("checkpoint: the supervisor's state: {e}"))
        })?;
        if steering.universe != self.steering.universe {
            return Err(EstimError::InvalidConfig(format!(
                "checkpoint: a supervisor of parameters {:?}, this one's are {:?}",
                steering.universe, self.steering.universe
            )));
        }
        let inner = Snapshot {
            memory: (**estimator).clone(),
            ..s.clone()
        };
        self.estimator.restore(&inner)?;
        self.steering = steering;
        Ok(())
    }
}

/// Settings of the demonstration.
#[derive(Debug, Clone)]
pub struct LostExcitationConfig {
    /// Sample interval [s].
    pub dt: f64,
    /// Duration [s].
    pub duration: f64,
    /// The period without excitation of B (`y = 0`) [s].
    pub quiet: (f64, f64),
    /// Forgetting factor λ of the estimator (and of the ranking's memory).
    pub lambda: f64,
    /// Measurement noise standard deviation.
    pub noise_std: f64,
    /// Noise seed.
    pub seed: u64,
}

impl Default for LostExcitationConfig {
    fn default() -> Self {
        Self {
            dt: 0.001,
            duration: 6.0,
            quiet: (2.0, 3.0),
            lambda: 0.98,
            noise_std: 0.01,
            seed: 92,
        }
    }
}

/// Tracks of one estimator.
#[derive(Debug, Clone, Default)]
pub struct Track {
    /// Â.
    pub a: Vec<f64>,
    /// B̂.
    pub b: Vec<f64>,
    /// trace(P).
    pub trace: Vec<f64>,
    /// Whether B was being estimated (not frozen).
    pub b_free: Vec<bool>,
}

/// The demonstration's result.
#[derive(Debug, Clone)]
pub struct LostExcitation {
    /// Time [s].
    pub t: Vec<f64>,
    /// RLSF (λ) without protection.
    pub unguarded: Track,
    /// The same RLSF supervised by the on-line ranking.
    pub supervised: Track,
    /// Freeze events of the supervised estimator.
    pub freezes: u64,
    /// Release events.
    pub releases: u64,
}

/// Run RLSF with and without the supervisor on `z = 10·sin(x) + 0.5·y² + ε`, `x` and `y` as in
/// Example 5.2 except that `y = 0` during `quiet`.
pub fn lost_excitation(cfg: &LostExcitationConfig) -> Result<LostExcitation, SupervisorError> {
    let params = ParamSet::zeros(["A", "B"]).map_err(|e| IdentError::Invalid(e.to_string()))?;
    let spec = EstimatorSpec {
        lambda: cfg.lambda,
        ..EstimatorSpec::new(MethodName::Rlsf)
    };
    let mut plain = build_linear(&spec, &params, &params.all_free())?;
    let mut sup = ExcitationSupervisor::new(
        build_linear(&spec, &params, &params.all_free())?,
        vec![1.0, 1.0],
        SupervisorConfig::for_lambda(cfg.lambda),
    )?;
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let n = (cfg.duration / cfg.dt).round() as usize + 1;
    let mut out = LostExcitation {
        t: Vec::with_capacity(n),
        unguarded: Track::default(),
        supervised: Track::default(),
        freezes: 0,
        releases: 0,
    };
    let tau = std::f64::consts::TAU;
    for i in 0..n {
        let t = i as f64 * cfg.dt;
        let x = tau * 47.0 * t + 1.2 * (tau * 3.1 * t).sin();
        let y = if t >= cfg.quiet.0 && t < cfg.quiet.1 {
            0.0
        } else {
            2.0 + (tau * 0.23 * t + 0.4).sin()
        };
        let phi = [x.sin(), y * y];
        let noise: f64 = rng.sample(StandardNormal);
        let z = 10.0 * phi[0] + 0.5 * phi[1] + cfg.noise_std * noise;
        plain.update(&phi, z)?;
        sup.update(&phi, z)?;
        out.t.push(t);
        for (track, est) in [
            (&mut out.unguarded, &plain),
            (&mut out.supervised, sup.estimator()),
        ] {
            let full = est.estimate_full();
            track.a.push(full[0]);
            track.b.push(full[1]);
            track.trace.push(est.covariance_trace());
            track.b_free.push(est.free_set().free().contains(&1));
        }
    }
    out.freezes = sup.freezes();
    out.releases = sup.releases();
    Ok(out)
}
