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

use crate::acquisition::{to_crank_angle, AcquisitionOptions};
use crate::error::AppError;
use physid_core::{Basis, ParamSet, Recording};
use physid_estim::metrics::nmse;
use physid_estim::{CovSpec, EstimatorConfig, LinearEstimator, Method};
use physid_ident::{analyse, Cutoff, Data, IdentConfig, RankedParam, Selection};
use physid_models::friction::{
    Design, FrictionRegression, OperatingPoint, Settings, REGRESSION_PARAMS,
};
use physid_signal::crank::cycle_stats;
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

/// Cycle means of a recording (see the module documentation).
pub fn cycle_means(rec: &Recording, cfg: &FrictionFitConfig) -> Result<CycleMeans, AppError> {
    let converted;
    let rec = if rec.basis == Basis::Time && rec.values("cycle").is_err() {
        converted = to_crank_angle(rec, &AcquisitionOptions::default(), 1.0)?;
        &converted
    } else {
        rec
    };
    let cycle = rec.values("cycle")?;
    let (tq_name, sign) = cfg.source.channel();
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
    for (name, v) in [
        ("omega_en", &omega),
        ("p_int", &p_int),
        ("T_oil", &t_oil),
        (tq_name, &tau),
        ("p_atm", &p_atm),
    ] {
        if let Some(i) = v.iter().position(|x| !x.is_finite()) {
            return Err(AppError::Invalid(format!(
                "channel '{name}' sample {i} is {} — the cycle means need finite data",
                v[i]
            )));
        }
    }
    // Samples per complete cycle: the most common count.
    let stats = cycle_stats(cycle, &omega);
    let mut counts: Vec<usize> = stats.iter().map(|s| s.samples).collect();
    counts.sort_unstable();
    let per_cycle = counts.get(counts.len() / 2).copied().unwrap_or(0);
    if per_cycle < 8 {
        return Err(AppError::Invalid(format!(
            "{} complete cycles with {per_cycle} samples each: the fit needs a crank-angle \
             recording with several samples per cycle",
            stats.len()
        )));
    }
    let mean = |x: &[f64], a: usize, b: usize| x[a..b].iter().sum::<f64>() / (b - a) as f64;
    let mut out = CycleMeans {
        truth_nm: truth.as_ref().map(|_| Vec::new()),
        ..Default::default()
    };
    // Complete cycles; `None` separates runs of consecutive complete cycles.
    let mut complete: Vec<Option<CycleSpan>> = Vec::new();
    let mut start = 0;
    while start < cycle.len() {
        let c = cycle[start];
        let mut end = start;
        while end < cycle.len() && cycle[end] == c {
            end += 1;
        }
        complete.push((c >= 0.0 && end - start == per_cycle).then(|| CycleSpan {
            cycle: c,
            start,
            end,
            p_int: mean(&p_int, start, end),
        }));
        start = end;
    }
    let moved = |a: &Option<CycleSpan>, p: f64| {
        a.map_or(0.0, |q| (p - q.p_int).abs() / q.p_int) > cfg.max_pressure_change
    };
    for (k, entry) in complete.iter().enumerate() {
        let Some(CycleSpan {
            cycle: c,
            start,
            end,
            p_int: p,
        }) = *entry
        else {
            continue;
        };
        let w = mean(&omega, start, end);
        let speed_change = (omega[end - 1] - omega[start]).abs() / w.abs().max(f64::MIN_POSITIVE);
        // A throttle step inside this cycle shows as a jump to the next cycle's pressure.
        let before = if k > 0 { &complete[k - 1] } else { &None };
        let after = complete.get(k + 1).unwrap_or(&None);
        if speed_change > cfg.max_speed_change || moved(before, p) || moved(after, p) {
            out.skipped_unsteady += 1;
            continue;
        }
        out.cycle.push(c as i64);
        out.t_s.push(t[start]);
        out.n_rpm.push(w * 30.0 / std::f64::consts::PI);
        out.p_int_kpa.push(p / 1e3);
        out.p_atm_kpa.push(mean(&p_atm, start, end) / 1e3);
        out.t_oil_c.push(mean(&t_oil, start, end) - 273.15);
        out.tau_nm.push(sign * mean(&tau, start, end));
        if let (Some(tr), Some(o)) = (&truth, out.truth_nm.as_mut()) {
            o.push(mean(tr, start, end));
        }
    }
    for k in 0..out.len() {
        OperatingPoint {
            n_rpm: out.n_rpm[k],
            p_int_kpa: out.p_int_kpa[k],
            p_atm_kpa: out.p_atm_kpa[k],
            t_oil_c: out.t_oil_c[k],
        }
        .validate()
        .map_err(|e| {
            AppError::Invalid(format!(
                "cycle {} (t = {:.3} s): {e} — the fit needs a motored, turning engine",
                out.cycle[k], out.t_s[k]
            ))
        })?;
    }
    Ok(out)
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

/// One complete cycle of a recording.
#[derive(Debug, Clone, Copy)]
struct CycleSpan {
    /// Its number.
    cycle: f64,
    /// Its first sample, and the one past its last.
    start: usize,
    end: usize,
    /// Its mean manifold pressure [Pa].
    p_int: f64,
}

/// Run the characterisation on a motored recording.
pub fn friction_fit(rec: &Recording, cfg: &FrictionFitConfig) -> Result<FrictionFit, AppError> {
    if !(cfg.s0.is_finite() && cfg.s0 > 0.0) {
        return Err(AppError::Invalid(format!(
            "S0 scale {} must be a positive number",
            cfg.s0
        )));
    }
    let data = cycle_means(rec, cfg)?;
    if data.len() < 20 {
        return Err(AppError::Invalid(format!(
            "{} steady cycles ({} skipped as not steady): the fit needs at least 20",
            data.len(),
            data.skipped_unsteady
        )));
    }
    let model = FrictionRegression::new(cfg.design, cfg.settings);
    let c0 = model.nominal();
    // Identifiability over the coefficients with a non-zero nominal value (a zero one — the
    // valvetrain's absent follower type — has no relative sensitivity and stays fixed).
    let free: Vec<usize> = (0..20).filter(|&j| c0[j] != 0.0).collect();
    let cols: Vec<Vec<f64>> = vec![
        data.n_rpm.clone(),
        data.p_int_kpa.clone(),
        data.p_atm_kpa.clone(),
        data.t_oil_c.clone(),
    ];
    let ident_data = Data {
        inputs: cols.iter().map(|c| c.as_slice()).collect(),
        y: Some(&data.tau_nm),
    };
    let analysis = analyse(&model, &ident_data, &c0, &free, IdentConfig::default())?;
    let (k, _) = cfg.selection.resolve(&model, &ident_data, &analysis)?;
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
    let est_idx: Vec<usize> = analysis.top(k).iter().map(|&i| free[i]).collect();
    let estimable: Vec<String> = est_idx
        .iter()
        .map(|&j| REGRESSION_PARAMS[j].to_string())
        .collect();
    // DSFC in relative coordinates: y − ψᵀc0 = Σ (c0_i ψ_i)·x_i.
    let rel = ParamSet::new(REGRESSION_PARAMS, vec![0.0; 20])
        .map_err(|e| AppError::Invalid(e.to_string()))?;
    let free_set = rel
        .free(&estimable)
        .map_err(|e| AppError::Invalid(e.to_string()))?;
    let config = EstimatorConfig {
        p0: CovSpec::Scaled(cfg.s0 * cfg.s0),
        ..EstimatorConfig::new(Method::Dsfc { lambda: cfg.lambda })
    };
    let mut est = LinearEstimator::new(&config, &rel, &free_set)
        .map_err(AppError::estim("estimator configuration"))?;
    let n = data.len();
    let mut predicted_nominal = Vec::with_capacity(n);
    let mut predicted = Vec::with_capacity(n);
    let mut scaled = [0.0; 20];
    let psi_at = |k: usize| {
        let u = data.inputs(k);
        model.regressor(&OperatingPoint {
            n_rpm: u[0],
            p_int_kpa: u[1],
            p_atm_kpa: u[2],
            t_oil_c: u[3],
        })
    };
    for k in 0..n {
        let psi = psi_at(k);
        let nominal: f64 = psi.iter().zip(&c0).map(|(p, c)| p * c).sum();
        for j in 0..20 {
            scaled[j] = c0[j] * psi[j];
        }
        let step = est
            .update(&scaled, data.tau_nm[k] - nominal)
            .map_err(|e| AppError::estim(format!("cycle {}", data.cycle[k]))(e))?;
        predicted_nominal.push(nominal);
        predicted.push(data.tau_nm[k] - step.prediction_error);
    }
    let x = est.estimate_full();
    let params: Vec<f64> = (0..20).map(|j| c0[j] * (1.0 + x[j])).collect();
    let se_x = est.std_errors().ok();
    let std_err: Vec<Option<f64>> = (0..20)
        .map(|j| {
            // The estimator's free parameters are in coefficient order.
            let pos = free_set.free().iter().position(|&i| i == j)?;
            se_x.as_ref().map(|s| c0[j].abs() * s[pos])
        })
        .collect();
    let predicted_final: Vec<f64> = (0..n)
        .map(|k| psi_at(k).iter().zip(&params).map(|(p, c)| p * c).sum())
        .collect();
    let pct = |pred: &[f64], reference: &[f64]| -> Vec<f64> {
        pred.iter()
            .zip(reference)
            .map(|(p, r)| 100.0 * (p - r) / r)
            .collect()
    };
    let error_pct = pct(&predicted, &data.tau_nm);
    let truth_error_pct = data.truth_nm.as_ref().map(|tr| pct(&predicted, tr));
    let after = data
        .t_s
        .iter()
        .position(|&t| t - data.t_s[0] >= cfg.transient_s)
        .unwrap_or(n);
    let max_abs = |v: &[f64]| v[after..].iter().fold(0.0f64, |m, e| m.max(e.abs()));
    Ok(FrictionFit {
        ranking,
        estimable,
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
        data,
    })
}
