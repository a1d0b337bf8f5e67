//! Application 2 — adaptive characterisation of engine friction (thesis §7.3, SPEC §8).
//!
//! 1. **Cycle means** from a motored recording on a crank-angle basis (a time-basis recording is
//!    first resampled to one sample per crank degree from its engine encoder and TDC marker):
//!    speed N, manifold pressure p_int, ambient pressure p_atm, oil temperature T_oil and the
//!    motoring torque — `−torque_engine` (the engine's load cell) or `+torque_shaft` (the
//!    in-line transducer) — averaged over each 720° cycle. The crank-angle mean of a torque is
//!    the cycle's work over 4π, so the gas torque contributes exactly its pumping work: the
//!    motoring torque is the *total* friction the regression form models, pumping (c17 … c20)
//!    included, as the thesis's characterisation has it. A cycle whose speed changes by more than
//!    [`FrictionFitConfig::max_speed_change`] between its first and last sample is skipped (its
//!    mean carries the inertia torque J·α), and so is one whose mean manifold pressure moved by
//!    more than [`FrictionFitConfig::max_pressure_change`] from a neighbouring cycle's (the
//!    manifold filling or emptying after a throttle step is not quasi-steady).
//! 2. **Identifiability** of c1 … c20 on those cycles (Alg. 5.1 with the thesis's scaling
//!    `∂τ/∂c_i · c_i0/τ0`, Eq. 7.10): the estimable subset, ranked (Table 7.3).
//! 3. **DSFC** (Alg. 5.5) over the estimable subset from the nominal coefficients, the rest
//!    fixed (§7.3). It estimates relative deviations `x` with `c = c0·(1 + x)`, `x0 = 0`,
//!    `S0 = s0·I` (the thesis's `√100·I`): one covariance scale for coefficients that span
//!    1e-10 … 1e5. Forgetting λ (default 1: the engine's friction is characterised, not tracked).
//! 4. **Prediction error over time**: the one-step-ahead prediction `ψᵀ c(t−1)` — each cycle is
//!    predicted before the estimator sees it — against the measured cycle mean, and against
//!    the simulated truth when the recording carries it.

use crate::acquisition::{from_first_marker, to_crank_angle, AcquisitionOptions, TDC_MARKER};
use crate::error::AppError;
use physid_core::{Basis, FreeSet, ParamSet, Recording};
use physid_estim::metrics::nmse;
use physid_estim::{build_linear, CovSpec, EstimatorSpec, LinearEstimator, MethodName};
use physid_ident::{analyse, Cutoff, Data, IdentConfig, RankedParam, Selection};
use physid_models::friction::{
    Design, FrictionRegression, OperatingPoint, Settings, REGRESSION_PARAMS,
};
use physid_signal::cycles::{CycleStream, CycleSummary};
use serde::Serialize;
use std::collections::BTreeMap;

/// Where the motoring torque comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum TorqueSource {
    /// `−torque_engine`: the engine torque load cell (negative when motored).
    Engine,
    /// `+torque_shaft`: the in-line shaft torque transducer (dynamometer into the engine).
    Shaft,
}

impl TorqueSource {
    /// Parse `engine|shaft`.
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "engine" => Some(Self::Engine),
            "shaft" => Some(Self::Shaft),
            _ => None,
        }
    }

    fn channel(self) -> (&'static str, f64) {
        match self {
            Self::Engine => ("torque_engine", -1.0),
            Self::Shaft => ("torque_shaft", 1.0),
        }
    }
}

/// How to fit.
#[derive(Debug, Clone)]
pub struct FrictionFitConfig {
    /// The engine's design (mm) for the regressors.
    pub design: Design<f64>,
    /// Its discrete settings (oil, valvetrain, counts, model variant).
    pub settings: Settings,
    /// Motoring-torque channel.
    pub source: TorqueSource,
    /// How many of the ranked coefficients to estimate.
    pub selection: Selection,
    /// `S0 = s0·I` in relative coordinates (thesis: √100 = 10).
    pub s0: f64,
    /// DSFC forgetting factor λ ∈ (0, 1].
    pub lambda: f64,
    /// Skip cycles whose relative speed change first → last sample exceeds this.
    pub max_speed_change: f64,
    /// Skip cycles whose mean manifold pressure differs from the previous or the next cycle's
    /// by more than this (relative): the manifold filling or emptying after a throttle step is not the
    /// quasi-steady state the mean-value model describes.
    pub max_pressure_change: f64,
    /// Start-up transient excluded from the "after the transient" error [s from the first
    /// cycle used].
    pub transient_s: f64,
    /// Ambient pressure [kPa] when the recording has no `p_atm` channel.
    pub p_atm_kpa: Option<f64>,
}

impl FrictionFitConfig {
    /// The thesis's settings (§7.3) for an engine: motoring torque from the load cell, the
    /// repeat cut-off, `S0 = 10·I`, λ = 1, cycles steady within 1 % in speed and manifold
    /// pressure, 5 s start-up transient.
    pub fn new(design: Design<f64>, settings: Settings) -> Self {
        Self {
            design,
            settings,
            source: TorqueSource::Engine,
            selection: Selection::Rule(Cutoff::Repeat),
            s0: 10.0,
            lambda: 1.0,
            max_speed_change: 0.01,
            max_pressure_change: 0.01,
            transient_s: 5.0,
            p_atm_kpa: None,
        }
    }
}

/// Cycle means of a motored recording: the data of the characterisation.
#[derive(Debug, Clone, Default, Serialize)]
pub struct CycleMeans {
    /// Cycle index in the recording.
    pub cycle: Vec<i64>,
    /// Time at the cycle's start [s].
    pub t_s: Vec<f64>,
    /// Mean speed [rpm].
    pub n_rpm: Vec<f64>,
    /// Mean manifold pressure [kPa].
    pub p_int_kpa: Vec<f64>,
    /// Mean ambient pressure [kPa].
    pub p_atm_kpa: Vec<f64>,
    /// Mean oil temperature [°C].
    pub t_oil_c: Vec<f64>,
    /// Mean motoring (total friction) torque [N·m].
    pub tau_nm: Vec<f64>,
    /// The simulated total friction (`true_torque_friction − true_torque_indicated +
    /// true_torque_reciprocating`, cycle mean) when the recording carries it [N·m].
    pub truth_nm: Option<Vec<f64>>,
    /// Complete cycles skipped as not steady.
    pub skipped_unsteady: usize,
}

impl CycleMeans {
    /// The model inputs of cycle `k`: N, p_int, p_atm, T_oil.
    pub fn inputs(&self, k: usize) -> [f64; 4] {
        [
            self.n_rpm[k],
            self.p_int_kpa[k],
            self.p_atm_kpa[k],
            self.t_oil_c[k],
        ]
    }

    /// Number of cycles.
    pub fn len(&self) -> usize {
        self.cycle.len()
    }

    /// No cycles.
    pub fn is_empty(&self) -> bool {
        self.cycle.is_empty()
    }
}

/// One complete cycle's means: the characterisation's data point.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FrictionCycle {
    /// Cycle index.
    pub cycle: i64,
    /// Time at its start [s].
    pub t_s: f64,
    /// Mean speed [rpm].
    pub n_rpm: f64,
    /// Mean manifold pressure [kPa].
    pub p_int_kpa: f64,
    /// Mean ambient pressure [kPa].
    pub p_atm_kpa: f64,
    /// Mean oil temperature [°C].
    pub t_oil_c: f64,
    /// Mean motoring (total friction) torque [N·m].
    pub tau_nm: f64,
    /// The simulated total friction's mean, when the recording carries it [N·m].
    pub truth_nm: Option<f64>,
    /// `|ω_end − ω_start| / ω̄`: how much the speed changed over the cycle.
    pub speed_change: f64,
}

/// Cycle means of a recording (see the module documentation): what [`friction_fit`] runs on.
pub fn cycle_means(rec: &Recording, cfg: &FrictionFitConfig) -> Result<CycleMeans, AppError> {
    let mut stage = FrictionStage::new(cfg.clone(), None)?;
    feed(&mut stage, rec, cfg, &mut Vec::new())?;
    stage.push_gap(&mut Vec::new())?;
    Ok(stage.data)
}

/// Samples per chunk when a file is streamed through the stage.
const FILE_CHUNK: usize = 4096;

/// Whether a recording goes through the stage as a stream of samples: a time-basis one with
/// `theta_en` (the others are cycles of their crank-angle form).
pub fn streams(rec: &Recording) -> bool {
    rec.basis == Basis::Time && rec.channel("cycle").is_err() && rec.channel("theta_en").is_ok()
}

/// Feed a time-basis stream to a stage, cycles from its first TDC marker
/// ([`from_first_marker`]).
fn feed_stream<I, E>(
    stage: &mut FrictionStage,
    chunks: I,
    out: &mut Vec<FrictionOutput>,
) -> Result<(), AppError>
where
    I: IntoIterator<Item = Result<Recording, E>>,
    AppError: From<E>,
{
    let chunks = chunks.into_iter().map(|c| c.map_err(AppError::from));
    let (tdc, chunks) = from_first_marker(chunks, &AcquisitionOptions::default())?;
    let tdc = tdc.unwrap_or(0.0);
    stage.set_theta_tdc(tdc)?;
    for chunk in chunks {
        stage.push(&chunk?, out)?;
    }
    Ok(())
}

/// Feed a whole recording to a stage: a time-basis recording with `theta_en` as a stream of
/// chunks (cycles from its first TDC marker), any other one as the cycles of its crank-angle
/// form.
fn feed(
    stage: &mut FrictionStage,
    rec: &Recording,
    cfg: &FrictionFitConfig,
    out: &mut Vec<FrictionOutput>,
) -> Result<(), AppError> {
    if streams(rec) {
        let n = rec.len();
        let chunks = (0..n)
            .step_by(FILE_CHUNK)
            .map(|start| Ok::<_, AppError>(rec.slice(start..start + FILE_CHUNK)));
        return feed_stream(stage, chunks, out);
    }
    let converted;
    let rec = if rec.basis == Basis::Time && rec.values("cycle").is_err() {
        converted = to_crank_angle(rec, &AcquisitionOptions::default(), 1.0)?;
        &converted
    } else {
        rec
    };
    for c in crank_angle_cycles(rec, cfg)? {
        match c {
            Some(c) => stage.push_cycle(c, out)?,
            None => stage.push_gap(out)?,
        }
    }
    Ok(())
}

/// The cycles of a crank-angle recording (sample means over each complete cycle); `None`
/// where incomplete cycles interrupt the run of complete ones.
fn crank_angle_cycles(
    rec: &Recording,
    cfg: &FrictionFitConfig,
) -> Result<Vec<Option<FrictionCycle>>, AppError> {
    let mut runs = CrankRuns::default();
    runs.push(rec, cfg)?;
    runs.finish(cfg.source.channel().1)
}

/// Sums over each run of equal `cycle` values of a crank-angle recording, taken a chunk at a
/// time ([`crank_angle_cycles`] is one chunk): a few numbers per cycle, whatever the
/// recording's length. The sums run in sample order, so the means are those of the whole
/// recording bit for bit.
#[derive(Default)]
struct CrankRuns {
    /// Finished runs and the one still open (the last).
    runs: Vec<Run>,
    /// Samples per run of each non-negative whole cycle number (`cycle_stats`' counts), the
    /// last one open.
    counts: Vec<(i64, usize)>,
    samples: usize,
    truth: Option<bool>,
}

/// One run: its cycle value, its first time and speed, sums and its last speed.
struct Run {
    cycle: f64,
    t0: f64,
    n: usize,
    omega: (f64, f64, f64),
    p_int: f64,
    p_atm: f64,
    t_oil: f64,
    tau: f64,
    truth: f64,
}

impl CrankRuns {
    fn push(&mut self, rec: &Recording, cfg: &FrictionFitConfig) -> Result<(), AppError> {
        let cycle = rec.values("cycle")?;
        let (tq_name, _) = cfg.source.channel();
        let omega = rec.values_in("omega_en", "rad/s")?;
        let p_int = rec.values_in("p_int", "Pa")?;
        let t_oil = rec.values_in("T_oil", "K")?;
        let tau = rec.values_in(tq_name, "N*m")?;
        let t = rec.values("t")?;
        let p_atm = match (rec.values_in("p_atm", "Pa"), cfg.p_atm_kpa) {
            (Ok(v), _) => v,
            (Err(_), Some(kpa)) => vec![kpa * 1e3; cycle.len()],
            (Err(e), None) => return Err(e.into()),
        };
        let truth = match (
            rec.values("true_torque_friction"),
            rec.values("true_torque_indicated"),
            rec.values("true_torque_reciprocating"),
        ) {
            (Ok(f), Ok(i), Ok(r)) => Some(
                f.iter()
                    .zip(i)
                    .zip(r)
                    .map(|((f, i), r)| f - i + r)
                    .collect::<Vec<f64>>(),
            ),
            _ => None,
        };
        // The truth is there in every chunk or in none.
        if *self.truth.get_or_insert(truth.is_some()) != truth.is_some() {
            return Err(AppError::Invalid(
                "the simulated truth's channels come and go between chunks".into(),
            ));
        }
        for (name, v) in [
            ("omega_en", &omega),
            ("p_int", &p_int),
            ("T_oil", &t_oil),
            (tq_name, &tau),
            ("p_atm", &p_atm),
        ] {
            if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                return Err(AppError::Invalid(format!(
                    "channel '{name}' sample {} is {} — the cycle means need finite data",
                    self.samples + i,
                    v[i]
                )));
            }
        }
        for i in 0..cycle.len() {
            let c = cycle[i];
            if c >= 0.0 && c.is_finite() {
                let ci = c as i64;
                match self.counts.last_mut() {
                    Some((last, k)) if *last == ci => *k += 1,
                    _ => self.counts.push((ci, 1)),
                }
            }
            let tr = truth.as_ref().map_or(0.0, |v| v[i]);
            match self.runs.last_mut() {
                // NaN never equals itself: each NaN sample is a run of its own, as in
                // `cycle_runs`.
                Some(r) if r.cycle == c => {
                    r.n += 1;
                    r.omega.1 += omega[i];
                    r.omega.2 = omega[i];
                    r.p_int += p_int[i];
                    r.p_atm += p_atm[i];
                    r.t_oil += t_oil[i];
                    r.tau += tau[i];
                    r.truth += tr;
                }
                _ => self.runs.push(Run {
                    cycle: c,
                    t0: t[i],
                    n: 1,
                    omega: (omega[i], omega[i], omega[i]),
                    p_int: p_int[i],
                    p_atm: p_atm[i],
                    t_oil: t_oil[i],
                    tau: tau[i],
                    truth: tr,
                }),
            }
        }
        self.samples += cycle.len();
        Ok(())
    }

    /// The cycles, once every chunk is in: a complete cycle has the most common count of
    /// samples.
    /// `sign`: the torque source's sign (the motoring torque from the engine's load cell is
    /// its negative).
    fn finish(self, sign: f64) -> Result<Vec<Option<FrictionCycle>>, AppError> {
        let mut counts: Vec<usize> = self.counts.iter().map(|(_, k)| *k).collect();
        counts.sort_unstable();
        let per_cycle = counts.get(counts.len() / 2).copied().unwrap_or(0);
        if per_cycle < 8 {
            return Err(AppError::Invalid(format!(
                "{} complete cycles with {per_cycle} samples each: the fit needs a crank-angle \
                 recording with several samples per cycle",
                counts.len()
            )));
        }
        Ok(self
            .runs
            .iter()
            .map(|r| {
                (r.cycle >= 0.0 && r.n == per_cycle).then(|| {
                    let n = r.n as f64;
                    let w = r.omega.1 / n;
                    FrictionCycle {
                        cycle: r.cycle as i64,
                        t_s: r.t0,
                        n_rpm: w * 30.0 / std::f64::consts::PI,
                        p_int_kpa: r.p_int / n / 1e3,
                        p_atm_kpa: r.p_atm / n / 1e3,
                        t_oil_c: r.t_oil / n - 273.15,
                        tau_nm: sign * (r.tau / n),
                        truth_nm: self.truth.unwrap_or(false).then_some(r.truth / n),
                        speed_change: (r.omega.2 - r.omega.0).abs()
                            / w.abs().max(f64::MIN_POSITIVE),
                    }
                })
            })
            .collect())
    }
}

/// The characterisation's result.
#[derive(Debug, Clone, Serialize)]
pub struct FrictionFit {
    /// The cycle means the fit used.
    pub data: CycleMeans,
    /// The ranking of all 20 coefficients (selection order).
    pub ranking: Vec<RankedParam>,
    /// The estimable coefficients, in rank order.
    pub estimable: Vec<String>,
    /// Nominal coefficients c1 … c20.
    pub nominal: Vec<f64>,
    /// Final coefficients c1 … c20 (the non-estimable ones at nominal).
    pub params: Vec<f64>,
    /// Standard errors of the estimated coefficients (`None` for the fixed ones).
    pub std_err: Vec<Option<f64>>,
    /// The nominal model's prediction per cycle [N·m].
    pub predicted_nominal: Vec<f64>,
    /// One-step-ahead prediction per cycle [N·m].
    pub predicted: Vec<f64>,
    /// The final coefficients' prediction per cycle [N·m].
    pub predicted_final: Vec<f64>,
    /// `100·(predicted − measured)/measured` per cycle.
    pub error_pct: Vec<f64>,
    /// `100·(predicted − truth)/truth` per cycle, when the recording carries the truth.
    pub truth_error_pct: Option<Vec<f64>>,
    /// The last cycle's prediction error [%].
    pub final_error_pct: f64,
    /// The largest |prediction error| after the start-up transient [%].
    pub max_error_after_transient_pct: f64,
    /// The same against the truth, when known [%].
    pub max_truth_error_after_transient_pct: Option<f64>,
    /// NMSE (Eq. 6.4) of the nominal model and of the final coefficients against the measured
    /// cycle means.
    pub nmse_nominal: f64,
    /// See [`nmse_nominal`](Self::nmse_nominal).
    pub nmse_final: f64,
    /// Every steady cycle through the estimator, in order: the coefficients' track (the file
    /// verb's `--tracks`).
    #[serde(skip)]
    pub cycles: Vec<FrictionSample>,
}

/// The model presets by name: the thesis's and the original model's
/// ([`physid_models::friction::PRESETS`]) and `cell`, the built-in virtual test cell's engine (its
/// geometry with the thesis's oil and valvetrain).
pub const FRICTION_PRESETS: [&str; 3] = ["thesis", "sandoval2002", "cell"];

/// A friction model preset by name ([`FRICTION_PRESETS`]); `None` for an unknown name.
pub fn friction_preset(name: &str) -> Option<(Design<f64>, Settings)> {
    match name {
        "cell" => Some(cell_friction_model()),
        other => physid_models::friction::preset(other),
    }
}

/// The `cell` preset: the friction model of the built-in virtual test cell's engine.
pub fn cell_friction_model() -> (Design<f64>, Settings) {
    let p = physid_sim::params::CellParams::default();
    physid_sim::engine::Engine::new(&p.engine, &p.ambient).friction_model()
}

/// The characterisation's objective (thesis §7.3): the prediction within ±5 % after the
/// start-up transient.
pub const OBJECTIVE_PCT: f64 = 5.0;

/// What `physid friction fit --json` prints (and the demo's summary holds).
#[derive(Debug, Clone, Serialize)]
pub struct FrictionSummary<'a> {
    /// The estimated coefficients, in rank order.
    pub estimable: &'a [String],
    /// The identifiability ranking.
    pub ranking: &'a [RankedParam],
    /// Every coefficient's final value, by name.
    pub params: BTreeMap<&'static str, f64>,
    /// Their nominal values.
    pub nominal: BTreeMap<&'static str, f64>,
    /// The standard errors of the estimated ones (null where the estimator has none yet).
    pub std_err: BTreeMap<&'a str, Option<f64>>,
    /// The prediction errors [%].
    pub prediction_error_pct: PredictionErrors,
    /// NMSE (Eq. 6.4) against the cycle means.
    pub nmse: NmseBeforeAfter,
    /// The cycles.
    pub cycles: CycleCount,
}

/// Prediction errors of a friction fit [%].
#[derive(Debug, Clone, Copy, Serialize)]
pub struct PredictionErrors {
    /// Of the last cycle.
    #[serde(rename = "final")]
    pub final_pct: f64,
    /// The largest after the start-up transient, against the cycle means.
    pub max_after_transient: f64,
    /// The same against the simulated truth.
    pub max_after_transient_vs_truth: Option<f64>,
}

/// NMSE of the nominal and of the fitted model.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct NmseBeforeAfter {
    /// The nominal coefficients.
    pub nominal: f64,
    /// The fitted ones.
    pub fitted: f64,
}

/// The cycles a friction fit used and skipped.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct CycleCount {
    /// Used.
    pub used: usize,
    /// Skipped as not steady.
    pub skipped_unsteady: usize,
}

impl FrictionFit {
    /// The result without its tracks.
    pub fn summary(&self) -> FrictionSummary<'_> {
        let by_name = |v: &[f64]| {
            REGRESSION_PARAMS
                .iter()
                .copied()
                .zip(v.iter().copied())
                .collect()
        };
        FrictionSummary {
            estimable: &self.estimable,
            ranking: &self.ranking,
            params: by_name(&self.params),
            nominal: by_name(&self.nominal),
            std_err: self
                .estimable
                .iter()
                .map(|n| {
                    let j = REGRESSION_PARAMS.iter().position(|p| p == n);
                    (n.as_str(), j.and_then(|j| self.std_err[j]))
                })
                .collect(),
            prediction_error_pct: PredictionErrors {
                final_pct: self.final_error_pct,
                max_after_transient: self.max_error_after_transient_pct,
                max_after_transient_vs_truth: self.max_truth_error_after_transient_pct,
            },
            nmse: NmseBeforeAfter {
                nominal: self.nmse_nominal,
                fitted: self.nmse_final,
            },
            cycles: CycleCount {
                used: self.data.len(),
                skipped_unsteady: self.data.skipped_unsteady,
            },
        }
    }

    /// The largest prediction error after the start-up transient [%], against the simulated
    /// truth when the recording carries it, else against the measured cycle means.
    pub fn error_after_transient_pct(&self) -> f64 {
        self.max_truth_error_after_transient_pct
            .unwrap_or(self.max_error_after_transient_pct)
    }

    /// Whether that error is within [`OBJECTIVE_PCT`].
    pub fn objective_met(&self) -> bool {
        self.error_after_transient_pct() <= OBJECTIVE_PCT
    }
}

/// Run the characterisation on a motored recording: the recording streamed through a
/// [`FrictionStage`] that chooses its coefficients on all the steady cycles (as the thesis's
/// off-line characterisation does).
pub fn friction_fit(rec: &Recording, cfg: &FrictionFitConfig) -> Result<FrictionFit, AppError> {
    let mut stage = FrictionStage::new(cfg.clone(), None)?;
    let mut out = Vec::new();
    feed(&mut stage, rec, cfg, &mut out)?;
    finish(stage, out)
}

/// [`friction_fit`] on a time-basis recording read a chunk at a time (a file, as it comes):
/// memory does not grow with its length — the stage keeps a few numbers per cycle.
pub fn friction_fit_stream<I, E>(
    chunks: I,
    cfg: &FrictionFitConfig,
) -> Result<FrictionFit, AppError>
where
    I: IntoIterator<Item = Result<Recording, E>>,
    AppError: From<E>,
{
    let mut stage = FrictionStage::new(cfg.clone(), None)?;
    let mut out = Vec::new();
    feed_stream(&mut stage, chunks, &mut out)?;
    finish(stage, out)
}

/// [`friction_fit`] on a crank-angle recording (with `cycle`) read a chunk at a time: the
/// cycle means are summed as the chunks come, a few numbers per cycle, so memory does not grow
/// with the samples; the coefficients are then chosen on all the steady cycles, as for the
/// whole recording (the same numbers bit for bit).
pub fn friction_fit_cycles<I, E>(
    chunks: I,
    cfg: &FrictionFitConfig,
) -> Result<FrictionFit, AppError>
where
    I: IntoIterator<Item = Result<Recording, E>>,
    AppError: From<E>,
{
    let mut cycles = FrictionCycles::new(cfg);
    for chunk in chunks {
        cycles.push(&chunk?)?;
    }
    cycles.fit()
}

/// [`friction_fit_cycles`] for chunks that are pushed (a crank-angle recording made as a
/// time-basis file is read): the cycle means summed as they come, the fit at the end.
pub struct FrictionCycles {
    runs: CrankRuns,
    cfg: FrictionFitConfig,
}

impl FrictionCycles {
    /// The fit `cfg`, no cycle yet.
    pub fn new(cfg: &FrictionFitConfig) -> Self {
        Self {
            runs: CrankRuns::default(),
            cfg: cfg.clone(),
        }
    }

    /// The next chunk of the crank-angle recording (with `cycle`).
    pub fn push(&mut self, chunk: &Recording) -> Result<(), AppError> {
        self.runs.push(chunk, &self.cfg)
    }

    /// The coefficients, chosen on all the steady cycles.
    pub fn fit(self) -> Result<FrictionFit, AppError> {
        let mut stage = FrictionStage::new(self.cfg.clone(), None)?;
        let mut out = Vec::new();
        for c in self.runs.finish(self.cfg.source.channel().1)? {
            match c {
                Some(c) => stage.push_cycle(c, &mut out)?,
                None => stage.push_gap(&mut out)?,
            }
        }
        finish(stage, out)
    }
}

/// The channels [`friction_fit_cycles`] reads from a crank-angle recording: those it needs,
/// then those it takes when they are there (ambient pressure when `p_atm_kpa` is set, the
/// simulated truth).
pub fn cycle_channels(cfg: &FrictionFitConfig) -> (Vec<&'static str>, Vec<&'static str>) {
    let mut needed = vec![
        "t",
        "cycle",
        "omega_en",
        "p_int",
        "T_oil",
        cfg.source.channel().0,
    ];
    let mut optional = Vec::new();
    if cfg.p_atm_kpa.is_none() {
        needed.push("p_atm");
    } else {
        optional.push("p_atm");
    }
    optional.extend(TRUTH_CHANNELS);
    (needed, optional)
}

/// The file verb's end: the result, with every cycle the stage put out.
fn finish(mut stage: FrictionStage, mut out: Vec<FrictionOutput>) -> Result<FrictionFit, AppError> {
    let mut fit = stage.finish(&mut out)?;
    fit.cycles = out
        .into_iter()
        .filter_map(|o| match o {
            FrictionOutput::Cycle(c) => Some(c),
            FrictionOutput::Selected { .. } => None,
        })
        .collect();
    Ok(fit)
}

/// The channels the characterisation reads from a time-basis recording (physid names): those
/// it needs, then those it takes when they are there (ambient pressure when `p_atm_kpa` is set,
/// the simulated truth, the TDC marker).
pub fn sample_channels(cfg: &FrictionFitConfig) -> (Vec<&'static str>, Vec<&'static str>) {
    let mut needed = vec![
        "t",
        "theta_en",
        "omega_en",
        "p_int",
        "T_oil",
        cfg.source.channel().0,
    ];
    let mut optional = vec![TDC_MARKER];
    if cfg.p_atm_kpa.is_none() {
        needed.push("p_atm");
    } else {
        optional.push("p_atm");
    }
    optional.extend(TRUTH_CHANNELS);
    (needed, optional)
}

/// What a [`FrictionStage`] reports.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum FrictionOutput {
    /// The estimable coefficients were chosen (once), on the steady cycles so far.
    Selected {
        /// Start time of the last cycle the choice saw [s].
        t_s: f64,
        /// The steady cycles it saw.
        cycles: usize,
        /// The estimable coefficients, in rank order; the others stay at their nominal values.
        estimable: Vec<String>,
    },
    /// A steady cycle through the estimator.
    Cycle(FrictionSample),
}

/// One steady cycle through the estimator.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrictionSample {
    /// Cycle index.
    pub cycle: i64,
    /// Its start time [s].
    pub t_s: f64,
    /// Its mean motoring torque [N·m].
    pub measured_nm: f64,
    /// The one-step-ahead prediction `ψᵀc(k−1)`, made before the estimator saw the cycle [N·m].
    pub predicted_nm: f64,
    /// The nominal model's prediction [N·m].
    pub nominal_nm: f64,
    /// The simulated total friction, when the recording carries it [N·m].
    pub truth_nm: Option<f64>,
    /// The estimable coefficients after the cycle, in the order chosen
    /// ([`FrictionStage::estimable`]).
    pub params: Vec<f64>,
    /// Their standard errors (NaN before the estimator has them).
    pub std_err: Vec<f64>,
}

/// The channels a stage sums over each cycle from samples: speed, manifold pressure, oil
/// temperature, the motoring torque, then (when present) ambient pressure and the truth.
#[derive(Debug, Clone)]
struct SampleMeans {
    cycles: CycleStream,
    /// Channel names and the units they are summed in.
    channels: Vec<(&'static str, &'static str)>,
    has_p_atm: bool,
    has_truth: bool,
    /// Samples taken so far.
    seen: usize,
    done: Vec<CycleSummary>,
}

/// The truth's channels: the total friction is `friction − indicated + reciprocating`.
const TRUTH_CHANNELS: [&str; 3] = [
    "true_torque_friction",
    "true_torque_indicated",
    "true_torque_reciprocating",
];

/// The estimator once the coefficients are chosen.
#[derive(Debug, Clone)]
struct Running {
    ranking: Vec<RankedParam>,
    estimable: Vec<String>,
    free_set: FreeSet,
    est: LinearEstimator,
}

/// The characterisation as a stage (module documentation, steps 1–4): samples (or cycles) in,
/// chosen coefficients and per-cycle predictions out. A cycle is judged steady when the next
/// one has arrived (its manifold pressure is compared with both neighbours'). The coefficients
/// are chosen on the first `select_after` steady cycles — live — or, with `None`, on all of
/// them at [`finish`](Self::finish) — the file verb; the estimator then runs through the
/// cycles so far and every later one as it comes. The result does not depend on how the
/// samples were chunked.
#[derive(Debug, Clone)]
pub struct FrictionStage {
    cfg: FrictionFitConfig,
    select_after: Option<usize>,
    model: FrictionRegression,
    c0: [f64; 20],
    theta_tdc: f64,
    means: Option<SampleMeans>,
    /// The previous complete cycle's mean manifold pressure [kPa] (`None` after a gap).
    before: Option<f64>,
    /// The last cycle, judged when the next arrives.
    pending: Option<FrictionCycle>,
    data: CycleMeans,
    running: Option<Running>,
    predicted_nominal: Vec<f64>,
    predicted: Vec<f64>,
}

/// At least this many steady cycles before the coefficients are chosen.
pub const MIN_CYCLES: usize = 20;

impl FrictionStage {
    /// A stage; `select_after`: choose the coefficients after that many steady cycles (at least
    /// [`MIN_CYCLES`]), `None`: at the end.
    pub fn new(cfg: FrictionFitConfig, select_after: Option<usize>) -> Result<Self, AppError> {
        if !(cfg.s0.is_finite() && cfg.s0 > 0.0) {
            return Err(AppError::Invalid(format!(
                "S0 scale {} must be a positive number",
                cfg.s0
            )));
        }
        if let Some(n) = select_after.filter(|&n| n < MIN_CYCLES) {
            return Err(AppError::Invalid(format!(
                "choosing the coefficients after {n} cycles: the choice needs at least {MIN_CYCLES}"
            )));
        }
        let model = FrictionRegression::new(cfg.design, cfg.settings);
        Ok(Self {
            c0: model.nominal(),
            model,
            cfg,
            select_after,
            theta_tdc: 0.0,
            means: None,
            before: None,
            pending: None,
            data: CycleMeans::default(),
            running: None,
            predicted_nominal: Vec::new(),
            predicted: Vec::new(),
        })
    }

    /// Cycles start at this angle of `theta_en` + k·4π [rad] (default 0); before any sample.
    pub fn set_theta_tdc(&mut self, theta_tdc: f64) -> Result<(), AppError> {
        if self.means.is_some() {
            return Err(AppError::Invalid(
                "the TDC angle is set before the first sample".into(),
            ));
        }
        self.theta_tdc = theta_tdc;
        Ok(())
    }

    /// The estimable coefficients once chosen.
    pub fn estimable(&self) -> Option<&[String]> {
        self.running.as_ref().map(|r| r.estimable.as_slice())
    }

    /// The estimable coefficients' current values and standard errors (NaN before the
    /// estimator has them), in the order chosen.
    fn current(&self, r: &Running) -> (Vec<f64>, Vec<f64>) {
        let x = r.est.estimate_full();
        let se = r.est.std_errors().ok();
        r.estimable
            .iter()
            .filter_map(|name| {
                let j = REGRESSION_PARAMS.iter().position(|p| p == name)?;
                let pos = r.free_set.free().iter().position(|&i| i == j);
                let s = match (&se, pos) {
                    (Some(s), Some(pos)) => self.c0[j].abs() * s[pos],
                    _ => f64::NAN,
                };
                Some((self.c0[j] * (1.0 + x[j]), s))
            })
            .unzip()
    }

    /// A chunk of time-basis samples with `t`, `theta_en` [rad], `omega_en`, `p_int`, `T_oil`,
    /// the motoring torque, `p_atm` (or the configured constant) and, optionally, the truth.
    pub fn push(
        &mut self,
        chunk: &Recording,
        out: &mut Vec<FrictionOutput>,
    ) -> Result<(), AppError> {
        if chunk.is_empty() {
            return Ok(());
        }
        if self.means.is_none() {
            self.means = Some(self.sample_means(chunk)?);
        }
        let Some(m) = self.means.as_mut() else {
            return Ok(());
        };
        let cols = m
            .channels
            .iter()
            .map(|(name, unit)| chunk.values_in(name, unit))
            .collect::<Result<Vec<_>, _>>()?;
        for ((name, _), v) in m.channels.iter().zip(&cols) {
            if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                return Err(AppError::Invalid(format!(
                    "channel '{name}' sample {} is {} — the cycle means need finite data",
                    m.seen + i,
                    v[i]
                )));
            }
        }
        let views: Vec<&[f64]> = cols.iter().map(|c| c.as_slice()).collect();
        m.done.clear();
        m.cycles
            .push(
                chunk.values("t")?,
                chunk.values("theta_en")?,
                &views,
                &mut m.done,
            )
            .map_err(|e| AppError::Invalid(e.to_string()))?;
        m.seen += chunk.len();
        let sign = self.cfg.source.channel().1;
        let p_atm_default = self.cfg.p_atm_kpa.map(|kpa| kpa * 1e3);
        let done = std::mem::take(&mut m.done);
        let (has_p_atm, has_truth) = (m.has_p_atm, m.has_truth);
        for c in &done {
            let w = c.mean[0];
            let mut k = 4;
            let p_atm = if has_p_atm {
                k += 1;
                c.mean[4]
            } else {
                p_atm_default.unwrap_or(f64::NAN)
            };
            let truth = has_truth.then(|| c.mean[k] - c.mean[k + 1] + c.mean[k + 2]);
            self.push_cycle(
                FrictionCycle {
                    cycle: c.cycle,
                    t_s: c.t_start_s,
                    n_rpm: w * 30.0 / std::f64::consts::PI,
                    p_int_kpa: c.mean[1] / 1e3,
                    p_atm_kpa: p_atm / 1e3,
                    t_oil_c: c.mean[2] - 273.15,
                    tau_nm: sign * c.mean[3],
                    truth_nm: truth,
                    speed_change: (c.end[0] - c.start[0]).abs() / w.abs().max(f64::MIN_POSITIVE),
                },
                out,
            )?;
        }
        if let Some(m) = self.means.as_mut() {
            m.done = done;
        }
        Ok(())
    }

    /// The channels to sum, from the first chunk.
    fn sample_means(&self, chunk: &Recording) -> Result<SampleMeans, AppError> {
        let (tq, _) = self.cfg.source.channel();
        let mut channels = vec![
            ("omega_en", "rad/s"),
            ("p_int", "Pa"),
            ("T_oil", "K"),
            (tq, "N*m"),
        ];
        for (name, _) in &channels {
            chunk.channel(name)?;
        }
        chunk.channel("theta_en")?;
        let has_p_atm = chunk.channel("p_atm").is_ok();
        if has_p_atm {
            channels.push(("p_atm", "Pa"));
        } else if self.cfg.p_atm_kpa.is_none() {
            chunk.channel("p_atm")?;
        }
        let has_truth = TRUTH_CHANNELS.iter().all(|c| chunk.channel(c).is_ok());
        if has_truth {
            channels.extend(TRUTH_CHANNELS.map(|c| (c, "N*m")));
        }
        Ok(SampleMeans {
            cycles: CycleStream::new(channels.len(), self.theta_tdc, None)
                .map_err(|e| AppError::Invalid(e.to_string()))?,
            channels,
            has_p_atm,
            has_truth,
            seen: 0,
            done: Vec::new(),
        })
    }

    /// One complete cycle (the one before it judged now).
    pub fn push_cycle(
        &mut self,
        c: FrictionCycle,
        out: &mut Vec<FrictionOutput>,
    ) -> Result<(), AppError> {
        if let Some(p) = self.pending.take() {
            self.judge(p, Some(c.p_int_kpa), out)?;
        }
        self.pending = Some(c);
        Ok(())
    }

    /// An incomplete cycle: the last one is judged without a successor.
    pub fn push_gap(&mut self, out: &mut Vec<FrictionOutput>) -> Result<(), AppError> {
        if let Some(p) = self.pending.take() {
            self.judge(p, None, out)?;
        }
        self.before = None;
        Ok(())
    }

    /// Keep a steady cycle (module documentation, step 1), skip another.
    fn judge(
        &mut self,
        c: FrictionCycle,
        after: Option<f64>,
        out: &mut Vec<FrictionOutput>,
    ) -> Result<(), AppError> {
        let moved = |q: Option<f64>| {
            q.is_some_and(|q| (c.p_int_kpa - q).abs() / q > self.cfg.max_pressure_change)
        };
        // A throttle step inside this cycle shows as a jump to the next cycle's pressure.
        let steady =
            c.speed_change <= self.cfg.max_speed_change && !moved(self.before) && !moved(after);
        self.before = Some(c.p_int_kpa);
        if !steady {
            self.data.skipped_unsteady += 1;
            return Ok(());
        }
        OperatingPoint {
            n_rpm: c.n_rpm,
            p_int_kpa: c.p_int_kpa,
            p_atm_kpa: c.p_atm_kpa,
            t_oil_c: c.t_oil_c,
        }
        .validate()
        .map_err(|e| {
            AppError::Invalid(format!(
                "cycle {} (t = {:.3} s): {e} — the fit needs a motored, turning engine",
                c.cycle, c.t_s
            ))
        })?;
        let d = &mut self.data;
        if d.is_empty() {
            d.truth_nm = c.truth_nm.map(|_| Vec::new());
        }
        d.cycle.push(c.cycle);
        d.t_s.push(c.t_s);
        d.n_rpm.push(c.n_rpm);
        d.p_int_kpa.push(c.p_int_kpa);
        d.p_atm_kpa.push(c.p_atm_kpa);
        d.t_oil_c.push(c.t_oil_c);
        d.tau_nm.push(c.tau_nm);
        if let Some(v) = d.truth_nm.as_mut() {
            v.push(c.truth_nm.unwrap_or(f64::NAN));
        }
        let kept = d.len();
        if self.running.is_some() {
            self.step(kept - 1, out)
        } else if self.select_after.is_some_and(|n| kept >= n) {
            self.select(out)
        } else {
            Ok(())
        }
    }

    /// The regressor of kept cycle `k`.
    fn psi(&self, k: usize) -> [f64; 20] {
        let u = self.data.inputs(k);
        self.model.regressor(&OperatingPoint {
            n_rpm: u[0],
            p_int_kpa: u[1],
            p_atm_kpa: u[2],
            t_oil_c: u[3],
        })
    }

    /// Choose the estimable coefficients on the cycles so far (steps 2–3), then run the
    /// estimator through them.
    fn select(&mut self, out: &mut Vec<FrictionOutput>) -> Result<(), AppError> {
        let data = &self.data;
        if data.len() < MIN_CYCLES {
            return Err(AppError::Invalid(format!(
                "{} steady cycles ({} skipped as not steady): the fit needs at least {MIN_CYCLES}",
                data.len(),
                data.skipped_unsteady
            )));
        }
        let c0 = self.c0;
        let model = &self.model;
        // Identifiability over the coefficients with a non-zero nominal value (a zero one — the
        // valvetrain's absent follower type — has no relative sensitivity and stays fixed).
        let free: Vec<usize> = (0..20).filter(|&j| c0[j] != 0.0).collect();
        let cols: [&[f64]; 4] = [&data.n_rpm, &data.p_int_kpa, &data.p_atm_kpa, &data.t_oil_c];
        let ident_data = Data {
            inputs: cols.to_vec(),
            y: Some(&data.tau_nm),
        };
        let analysis = analyse(model, &ident_data, &c0, &free, IdentConfig::default())?;
        let (k, _) = self.cfg.selection.resolve(model, &ident_data, &analysis)?;
        let mut ranking = analysis.ranked(k);
        for j in (0..20).filter(|j| !free.contains(j)) {
            ranking.push(RankedParam {
                param: REGRESSION_PARAMS[j].into(),
                rank: ranking.len() + 1,
                relative_residual: 0.0,
                estimable: false,
            });
        }
        if k == 0 {
            return Err(AppError::Invalid(
                "no coefficient is estimable on this data: another experiment is needed (speeds and manifold pressures varied)".into(),
            ));
        }
        let estimable: Vec<String> = analysis
            .top(k)
            .iter()
            .map(|&i| REGRESSION_PARAMS[free[i]].to_string())
            .collect();
        // DSFC in relative coordinates: y − ψᵀc0 = Σ (c0_i ψ_i)·x_i.
        let rel = ParamSet::new(REGRESSION_PARAMS, vec![0.0; 20])
            .map_err(|e| AppError::Invalid(e.to_string()))?;
        let free_set = rel
            .free(&estimable)
            .map_err(|e| AppError::Invalid(e.to_string()))?;
        let spec = EstimatorSpec {
            lambda: self.cfg.lambda,
            p0: CovSpec::Scaled(self.cfg.s0 * self.cfg.s0),
            ..EstimatorSpec::new(MethodName::Dsfc)
        };
        let est = build_linear(&spec, &rel, &free_set)
            .map_err(AppError::estim("estimator configuration"))?;
        let n = data.len();
        out.push(FrictionOutput::Selected {
            t_s: data.t_s[n - 1],
            cycles: n,
            estimable: estimable.clone(),
        });
        self.running = Some(Running {
            ranking,
            estimable,
            free_set,
            est,
        });
        for k in 0..n {
            self.step(k, out)?;
        }
        Ok(())
    }

    /// Kept cycle `k` through the estimator (step 4: predicted before the update).
    fn step(&mut self, k: usize, out: &mut Vec<FrictionOutput>) -> Result<(), AppError> {
        let psi = self.psi(k);
        let c0 = &self.c0;
        let nominal: f64 = psi.iter().zip(c0).map(|(p, c)| p * c).sum();
        let mut scaled = [0.0; 20];
        for j in 0..20 {
            scaled[j] = c0[j] * psi[j];
        }
        let d = &self.data;
        let Some(r) = self.running.as_mut() else {
            return Ok(());
        };
        let step = r
            .est
            .update(&scaled, d.tau_nm[k] - nominal)
            .map_err(|e| AppError::estim(format!("cycle {}", d.cycle[k]))(e))?;
        let predicted = d.tau_nm[k] - step.prediction_error;
        let (params, std_err) = match &self.running {
            Some(r) => self.current(r),
            None => Default::default(),
        };
        let d = &self.data;
        self.predicted_nominal.push(nominal);
        self.predicted.push(predicted);
        out.push(FrictionOutput::Cycle(FrictionSample {
            params,
            std_err,
            cycle: d.cycle[k],
            t_s: d.t_s[k],
            measured_nm: d.tau_nm[k],
            predicted_nm: predicted,
            nominal_nm: nominal,
            truth_nm: d.truth_nm.as_ref().map(|v| v[k]),
        }));
        Ok(())
    }

    /// The end of the stream: the last cycle judged, the coefficients chosen if they were not,
    /// and the result (once: the stage has given its predictions up to it).
    pub fn finish(&mut self, out: &mut Vec<FrictionOutput>) -> Result<FrictionFit, AppError> {
        self.push_gap(out)?;
        if self.running.is_none() {
            self.select(out)?;
        }
        let Some(r) = self.running.as_ref() else {
            return Err(AppError::Invalid("no coefficients were chosen".into()));
        };
        let (c0, data) = (self.c0, &self.data);
        let n = data.len();
        let x = r.est.estimate_full();
        let params: Vec<f64> = (0..20).map(|j| c0[j] * (1.0 + x[j])).collect();
        let se_x = r.est.std_errors().ok();
        let std_err: Vec<Option<f64>> = (0..20)
            .map(|j| {
                // The estimator's free parameters are in coefficient order.
                let pos = r.free_set.free().iter().position(|&i| i == j)?;
                se_x.as_ref().map(|s| c0[j].abs() * s[pos])
            })
            .collect();
        let predicted_final: Vec<f64> = (0..n)
            .map(|k| self.psi(k).iter().zip(&params).map(|(p, c)| p * c).sum())
            .collect();
        let pct = |pred: &[f64], reference: &[f64]| -> Vec<f64> {
            pred.iter()
                .zip(reference)
                .map(|(p, r)| 100.0 * (p - r) / r)
                .collect()
        };
        let predicted = std::mem::take(&mut self.predicted);
        let predicted_nominal = std::mem::take(&mut self.predicted_nominal);
        let error_pct = pct(&predicted, &data.tau_nm);
        let truth_error_pct = data.truth_nm.as_ref().map(|tr| pct(&predicted, tr));
        let after = data
            .t_s
            .iter()
            .position(|&t| t - data.t_s[0] >= self.cfg.transient_s)
            .unwrap_or(n);
        let max_abs = |v: &[f64]| v[after..].iter().fold(0.0f64, |m, e| m.max(e.abs()));
        Ok(FrictionFit {
            ranking: r.ranking.clone(),
            estimable: r.estimable.clone(),
            nominal: c0.to_vec(),
            std_err,
            final_error_pct: error_pct[n - 1],
            max_error_after_transient_pct: max_abs(&error_pct),
            max_truth_error_after_transient_pct: truth_error_pct.as_deref().map(max_abs),
            nmse_nominal: nmse(&data.tau_nm, &predicted_nominal).unwrap_or(f64::NAN),
            nmse_final: nmse(&data.tau_nm, &predicted_final).unwrap_or(f64::NAN),
            params,
            predicted_nominal,
            predicted,
            predicted_final,
            error_pct,
            truth_error_pct,
            data: data.clone(),
            cycles: Vec::new(),
        })
    }
}
