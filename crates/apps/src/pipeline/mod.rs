//! The qualitative adaptive identification loop of thesis Fig. 5.7 (SPEC §6) from a file:
//! model → data → identifiability → estimation of the estimable subset (the rest fixed at
//! their nominal values) → is the objective met?
//!
//! ```toml
//! [model]
//! builtin = "cyclic-torque"          # or: expr = "K*dth + B*dw", params = { K = 1000, B = 1 }
//! output = "torque_engine"           # the measured channel the model predicts (CHANNEL[:UNIT])
//! inputs = { omega = "omega_en", alpha = "alpha_en", T_oil = "T_oil:degC" }
//! fixed = ["delta", "r"]             # known by design
//! params = { M_rec = 0.8 }           # nominal values (override the built-in's)
//! units = { K = "N·m/rad" }          # a formula's parameters: units and one-line meanings
//! descriptions = { K = "shaft stiffness" }   # for the report (a built-in's are known)
//!
//! [data]
//! scenario = "torque-ramp"           # or: file = "run.parquet"
//! basis = "crank"                    # crank (1°) or time (rate_hz)
//! set = { "engine.m_rec" = 0.84 }
//!
//! [identifiability]
//! cutoff = "rel:1e-6"                # repeat | wu | rel:FRACTION | absolute
//!
//! [estimator]
//! method = "ukf"                     # ekf | ukf | srukf | rls | rlsf | rlsvf | kf | dsfc
//!
//! [objective]
//! prediction_within_pct = 5.0
//! metric = "nrmse"                   # nrmse | max_relative
//! after_s = 1.0
//! ```
//!
//! The objective is checked on the one-step-ahead predictions — each sample predicted before
//! the estimator sees it — after `after_s` seconds: `nrmse` is `100·rms(y − ŷ)/rms(y)` (for
//! signals that cross zero, such as a cyclic torque), `max_relative` is `max 100·|y − ŷ|/|y|`
//! (for a signal that keeps its sign, such as a friction torque).
//!
//! The linear methods (RLS, RLSF, RLSVF, KF, DSFC) need a model linear in the estimated
//! parameters: its exact gradient is then the regressor ([`LinearInParams`]); linearity is
//! checked on every sample.

use crate::error::AppError;
use crate::model_choice::ModelChoice;
use crate::recording_rows::{Column, RecordingRows};
use physid_core::{ParamModel, ParamSet, Recording};
use physid_estim::{feed, metrics, CovSpec, EstimatorSpec, FeedError, MethodName, OnBad};
use physid_ident::{analyse, fit_subset, IdentConfig, IdentError, RankedParam};
use physid_sim::run::{simulate, OutputBasis, RunOptions};
use physid_sim::scenario::{Fault, Scenario};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

mod spec;

pub use spec::*;

/// A pipeline file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pipeline {
    /// The model.
    pub model: ModelSpec,
    /// The data.
    pub data: DataSpec,
    /// Identifiability settings.
    #[serde(default)]
    pub identifiability: IdentSpec,
    /// Estimator settings.
    #[serde(default)]
    pub estimator: EstimatorSection,
    /// The objective.
    #[serde(default)]
    pub objective: ObjectiveSpec,
}

impl Pipeline {
    /// Parse a pipeline file's text; `base` resolves relative data paths.
    pub fn parse(text: &str, base: &Path) -> Result<Self, AppError> {
        let mut p: Self = toml::from_str(text).map_err(|e| e.to_string())?;
        p.validate()?;
        if let Some(f) = &p.data.file {
            if f.is_relative() {
                p.data.file = Some(base.join(f));
            }
        }
        // A scenario file (not a built-in name) is relative to the pipeline file too.
        if let Some(s) = &p.data.scenario {
            let path = Path::new(s);
            if physid_sim::scenario::named(s).is_none() && path.is_relative() {
                p.data.scenario = Some(base.join(path).display().to_string());
            }
        }
        Ok(p)
    }

    /// Refuse, naming the key, every setting that has no valid value or would not be used —
    /// before any identification or estimation runs.
    pub fn validate(&self) -> Result<(), AppError> {
        let m = &self.model;
        match (&m.builtin, &m.expr) {
            (Some(_), Some(_)) => {
                return Err(AppError::Invalid(
                    "model: both builtin and expr are given: choose one".into(),
                ))
            }
            (None, None) => {
                return Err(AppError::Invalid(
                    "model: give builtin = \"…\" or expr = \"…\"".into(),
                ))
            }
            _ => {}
        }
        let d = &self.data;
        if let Some(r) = d.rate_hz {
            if !(r.is_finite() && r > 0.0) {
                return Err(AppError::Invalid(format!(
                    "data.rate_hz = {}: expected a rate > 0 Hz",
                    physid_core::Num(r)
                )));
            }
            if d.basis == Some(DataBasis::Crank) {
                return Err(AppError::Invalid("data.rate_hz: a crank-angle basis has no sample rate (one sample per degree): remove it, or basis = \"time\"".into()));
            }
        }
        if let Some(t) = d.duration {
            if !(t.is_finite() && t > 0.0) {
                return Err(AppError::Invalid(format!(
                    "data.duration = {}: expected a duration > 0 s",
                    physid_core::Num(t)
                )));
            }
        }
        match (&d.file, &d.scenario) {
            (Some(_), Some(_)) => {
                return Err(AppError::Invalid(
                    "data: both file and scenario are given: choose one".into(),
                ))
            }
            (None, None) => {
                return Err(AppError::Invalid(
                    "data: give file = \"…\" or scenario = \"…\"".into(),
                ))
            }
            (Some(_), None) => {
                // A file is read as it is: the simulation's settings would be ignored.
                let unused = [
                    ("duration", d.duration.is_some()),
                    ("basis", d.basis.is_some()),
                    ("rate_hz", d.rate_hz.is_some()),
                    ("set", !d.set.is_empty()),
                    ("faults", !d.faults.is_empty()),
                ];
                if let Some((k, _)) = unused.iter().find(|u| u.1) {
                    return Err(AppError::Invalid(format!(
                        "data.{k} applies to a simulated scenario, not to data.file (the file is read as it is)"
                    )));
                }
            }
            (None, Some(_)) => {}
        }
        let e = &self.estimator;
        let kalman = e.method.is_model_based() || e.method == MethodName::Kf;
        if let Some(r2) = e.r2 {
            if !kalman {
                return Err(AppError::Invalid(format!("estimator.r2 is the Kalman filters' noise variance: {} does not use it (kf, ekf, ukf, srukf do)", e.method)));
            }
            if !(r2.is_finite() && r2 > 0.0) {
                return Err(AppError::Invalid(format!(
                    "estimator.r2 = {}: expected a variance > 0",
                    physid_core::Num(r2)
                )));
            }
        }
        if let Some(p0) = e.p0 {
            if !(p0.is_finite() && p0 > 0.0) {
                return Err(AppError::Invalid(format!(
                    "estimator.p0 = {}: expected > 0",
                    physid_core::Num(p0)
                )));
            }
        }
        if let Some(l) = e.lambda {
            if !(l > 0.0 && l <= 1.0) {
                return Err(AppError::Invalid(format!(
                    "estimator.lambda = {}: a forgetting factor is in (0, 1]",
                    physid_core::Num(l)
                )));
            }
            if !matches!(
                e.method,
                MethodName::Rlsf | MethodName::Rlsvf | MethodName::Dsfc
            ) {
                return Err(AppError::Invalid(format!(
                    "estimator.lambda: {} does not forget (rlsf, rlsvf and dsfc do)",
                    e.method
                )));
            }
        }
        let o = &self.objective;
        if !(o.after_s.is_finite() && o.after_s >= 0.0) {
            return Err(AppError::Invalid(format!(
                "objective.after_s = {}: expected ≥ 0 s",
                physid_core::Num(o.after_s)
            )));
        }
        if !(o.prediction_within_pct.is_finite() && o.prediction_within_pct > 0.0) {
            return Err(AppError::Invalid(format!(
                "objective.prediction_within_pct = {}: expected > 0",
                physid_core::Num(o.prediction_within_pct)
            )));
        }
        Ok(())
    }

    /// Read a pipeline file.
    pub fn load(path: &Path) -> Result<Self, AppError> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        Self::parse(&text, path.parent().unwrap_or(Path::new(".")))
            .map_err(|e| AppError::Invalid(format!("{}: {e}", path.display())))
    }
}

/// Whether the objective was met.
#[derive(Debug, Clone, Serialize)]
pub struct Objective {
    /// `nrmse` or `max_relative`.
    pub metric: Metric,
    /// The value reached [%].
    pub value_pct: f64,
    /// The limit [%].
    pub limit_pct: f64,
    /// Samples evaluated (after the transient).
    pub samples: usize,
    /// Met.
    pub met: bool,
}

/// The pipeline's result.
#[derive(Debug, Clone, Serialize)]
pub struct PipelineResult {
    /// The model's parameters.
    pub names: Vec<String>,
    /// Data rows.
    pub rows: usize,
    /// The ranking (fixed parameters excluded).
    pub ranking: Vec<RankedParam>,
    /// The estimable parameters, in rank order.
    pub estimable: Vec<String>,
    /// The estimator.
    pub method: MethodName,
    /// Nominal values.
    pub nominal: Vec<f64>,
    /// Final values (non-estimable ones at nominal).
    pub params: Vec<f64>,
    /// Standard errors of the estimated ones (`None` for one the data do not resolve).
    pub std_err: Vec<Option<f64>>,
    /// The estimated parameters the data do not resolve ([`physid_estim::resolution`]).
    pub unresolved: Vec<String>,
    /// The objective.
    pub objective: Objective,
    /// Times of the plotted samples [s] (decimated to at most ~4000).
    pub t: Vec<f64>,
    /// Measured output at [`t`](Self::t).
    pub measured: Vec<f64>,
    /// One-step-ahead prediction at [`t`](Self::t).
    pub predicted: Vec<f64>,
    /// Estimates of the estimated parameters at [`t`](Self::t), in model order.
    pub tracks: Vec<(String, Vec<f64>)>,
}

/// What `physid run --json` prints.
#[derive(Debug, Clone, Serialize)]
pub struct PipelineSummary<'a> {
    /// Data rows.
    pub rows: usize,
    /// The ranking.
    pub ranking: &'a [RankedParam],
    /// The estimated parameters.
    pub estimable: &'a [String],
    /// The estimator.
    pub method: MethodName,
    /// Nominal values by name.
    pub nominal: BTreeMap<&'a str, f64>,
    /// Final values by name.
    pub params: BTreeMap<&'a str, f64>,
    /// Standard errors of the estimated ones by name (null where unresolved).
    pub std_err: BTreeMap<&'a str, Option<f64>>,
    /// The estimated parameters the data do not resolve.
    pub unresolved: &'a [String],
    /// The objective.
    pub objective: &'a Objective,
}

impl PipelineResult {
    /// The result without its tracks.
    pub fn summary(&self) -> PipelineSummary<'_> {
        let by_name = |v: &[f64]| {
            self.names
                .iter()
                .map(String::as_str)
                .zip(v.iter().copied())
                .collect()
        };
        PipelineSummary {
            rows: self.rows,
            ranking: &self.ranking,
            estimable: &self.estimable,
            method: self.method,
            nominal: by_name(&self.nominal),
            params: by_name(&self.params),
            std_err: self
                .names
                .iter()
                .zip(&self.std_err)
                .filter(|(n, _)| self.estimable.contains(n))
                .map(|(n, s)| (n.as_str(), *s))
                .collect(),
            unresolved: &self.unresolved,
            objective: &self.objective,
        }
    }
}

/// Load (or simulate) the pipeline's recording.
pub fn load_data(spec: &DataSpec) -> Result<Recording, AppError> {
    match (&spec.file, &spec.scenario) {
        (Some(f), None) => Ok(physid_io::read(f, &Default::default())?),
        (None, Some(name)) => {
            let mut s = Scenario::load(name)?;
            for f in &spec.faults {
                Fault::parse(f)?;
                s.faults.push(f.clone());
            }
            let opts = RunOptions {
                duration: spec.duration,
                basis: match spec.basis.unwrap_or(DataBasis::Time) {
                    DataBasis::Crank => OutputBasis::Crank(1.0),
                    DataBasis::Time => OutputBasis::Time(spec.rate_hz.unwrap_or(DEFAULT_RATE_HZ)),
                },
                ..Default::default()
            };
            // The pipeline's `set` wins over the scenario's own settings.
            s.set.extend(spec.set.iter().map(|(k, v)| (k.clone(), *v)));
            Ok(simulate(&s, &opts, |_| {})?)
        }
        _ => Err(AppError::Invalid(
            "[data] needs exactly one of file = \"…\" or scenario = \"…\"".into(),
        )),
    }
}

/// Run the loop on a recording in memory.
pub fn run_pipeline(p: &Pipeline, rec: &Recording) -> Result<PipelineResult, AppError> {
    let (model, nominal) = build_model(p)?;
    let (inputs, y) = columns(p, &model);
    run_with(
        &model,
        p,
        &RecordingRows::memory(rec, inputs, Some(y)),
        nominal,
    )
}

/// Run the loop on the pipeline's own data: of a file only the channels the run takes (the
/// model's inputs through `model.inputs`, its output, the time), gone over in passes — held
/// after the first when they fit `hold_bytes`, else read again on each; a scenario simulated
/// first. Also returns the channels read, without samples (their units).
pub fn run_pipeline_data(
    p: &Pipeline,
    hold_bytes: usize,
) -> Result<(PipelineResult, Recording), AppError> {
    let (model, nominal) = build_model(p)?;
    let (inputs, y) = columns(p, &model);
    match p.data.file.as_ref().filter(|_| p.data.scenario.is_none()) {
        Some(file) => {
            // A column the file lacks is named as the model's input or output.
            let header = physid_io::ChunkReader::open(file, &Default::default())?
                .header()
                .clone();
            check_columns(p, &model, &header)?;
            let rows = RecordingRows::file(
                file,
                &Default::default(),
                inputs,
                Some(y),
                &["t"],
                hold_bytes,
            )?;
            let r = run_with(&model, p, &rows, nominal)?;
            Ok((r, rows.header().clone()))
        }
        None => {
            let rec = load_data(&p.data)?;
            let rows = RecordingRows::memory(&rec, inputs, Some(y));
            let r = run_with(&model, p, &rows, nominal)?;
            Ok((r, rows.header().clone()))
        }
    }
}

/// The model's columns: each input through `model.inputs` (`CHANNEL` as recorded, or
/// `CHANNEL:UNIT` converted to the unit the model expects), and the output.
fn columns(p: &Pipeline, model: &ModelChoice) -> (Vec<Column>, Column) {
    let inputs = model
        .input_names()
        .iter()
        .map(|input| Column::parse(p.model.inputs.get(input).unwrap_or(input)))
        .collect();
    (inputs, Column::parse(&p.model.output))
}

/// Every column is in the recording (`header`: its channels, samples or not), in a unit that
/// converts to the one asked for; the error names the model's input or output.
fn check_columns(p: &Pipeline, model: &ModelChoice, header: &Recording) -> Result<(), AppError> {
    let (inputs, y) = columns(p, model);
    for (input, c) in model.input_names().iter().zip(&inputs) {
        c.values(header)
            .map_err(|e| format!("model input '{input}': {e}"))?;
    }
    y.values(header).map_err(|e| format!("model output: {e}"))?;
    Ok(())
}

/// The pipeline's model and its nominal values (the built-in's, overridden by `model.params`).
fn build_model(p: &Pipeline) -> Result<(ModelChoice, Vec<f64>), AppError> {
    let params: Vec<(String, f64)> = p
        .model
        .params
        .iter()
        .map(|(k, v)| (k.clone(), *v))
        .collect();
    ModelChoice::build(p.model.expr.as_deref(), p.model.builtin.as_deref(), &params)
}

fn run_with(
    model: &ModelChoice,
    p: &Pipeline,
    rows: &RecordingRows,
    nominal: Vec<f64>,
) -> Result<PipelineResult, AppError> {
    let names = model.param_names().to_vec();
    check_columns(p, model, rows.header())?;
    for f in &p.model.fixed {
        if !names.contains(f) {
            return Err(AppError::Invalid(format!(
                "fixed parameter '{f}': the parameters are {}",
                names.join(", ")
            )));
        }
    }
    for (key, given) in [
        ("units", &p.model.units),
        ("descriptions", &p.model.descriptions),
    ] {
        if let Some(n) = given.keys().find(|n| !names.contains(n)) {
            return Err(AppError::Invalid(format!(
                "model.{key}: '{n}' is not a parameter; the parameters are {}",
                names.join(", ")
            )));
        }
    }
    let free: Vec<usize> = (0..names.len())
        .filter(|&j| !p.model.fixed.contains(&names[j]))
        .collect();
    if free.is_empty() {
        return Err(AppError::Invalid(format!(
            "model.fixed fixes every parameter ({}): nothing is left to identify or estimate",
            names.join(", ")
        )));
    }
    // 1. Identifiability (a non-finite value is found on its first pass).
    let config = IdentConfig {
        scaling: p.identifiability.scaling,
        ..IdentConfig::default()
    };
    let analysis = analyse(model, rows, &nominal, &free, config).map_err(|e| match e {
        IdentError::BadValue { row, column, value } => {
            let what = match model.input_names().iter().position(|c| *c == column) {
                Some(k) => format!(
                    "model input '{column}' ({})",
                    p.model
                        .inputs
                        .get(&column)
                        .unwrap_or(&model.input_names()[k])
                ),
                None if column == "output" => format!("model output ({})", p.model.output),
                None => column,
            };
            AppError::Invalid(format!(
                "{what}, sample {row}: {value} (expected a finite number)"
            ))
        }
        e => e.into(),
    })?;
    let n = analysis.rows;
    let (k, _) = p.identifiability.cutoff.resolve(model, rows, &analysis)?;
    let estimable: Vec<usize> = analysis.top(k).iter().map(|&i| free[i]).collect();
    if estimable.is_empty() {
        return Err(AppError::Invalid(
            "no parameter is estimable on this data: another experiment is needed".into(),
        ));
    }
    // 2. Estimation.
    let set = ParamSet::new(names.clone(), nominal.clone()).map_err(|e| e.to_string())?;
    let est_names: Vec<&str> = estimable.iter().map(|&j| names[j].as_str()).collect();
    let free_set = set.free(&est_names).map_err(|e| e.to_string())?;
    let order = free_set.free().to_vec();
    let stride = n.div_ceil(4000).max(1);
    let mut out = PipelineResult {
        names: names.clone(),
        rows: n,
        ranking: analysis.ranked(k),
        estimable: est_names.iter().map(|s| s.to_string()).collect(),
        method: p.estimator.method,
        nominal: nominal.clone(),
        params: nominal.clone(),
        std_err: vec![None; names.len()],
        unresolved: Vec::new(),
        objective: Objective {
            metric: p.objective.metric,
            value_pct: f64::NAN,
            limit_pct: p.objective.prediction_within_pct,
            samples: 0,
            met: false,
        },
        t: Vec::new(),
        measured: Vec::new(),
        predicted: Vec::new(),
        tracks: order
            .iter()
            .map(|&j| (names[j].clone(), Vec::new()))
            .collect(),
    };
    // R2 of the Kalman filters: given, or the batch fit's residual variance.
    let r2 = || -> Result<f64, AppError> {
        Ok(match p.estimator.r2 {
            Some(v) => v,
            None => {
                let fit = fit_subset(model, rows, &nominal, &estimable, 20)?;
                (fit.rss / (n.saturating_sub(estimable.len())).max(1) as f64).max(f64::MIN_POSITIVE)
            }
        })
    };
    // The pipeline's defaults: λ = 1; P(0) = 1000·I for a linear method, for a filter 0.01·I in
    // scaled coordinates (all nominals non-zero) or 100·I; R2 given or the batch fit's.
    let e = &p.estimator;
    let mut spec = EstimatorSpec::new(e.method);
    spec.lambda = e.lambda.unwrap_or(1.0);
    if e.method.is_model_based() {
        spec.scaled = estimable.iter().all(|&j| nominal[j] != 0.0);
        spec.p0 = CovSpec::Scaled(e.p0.unwrap_or(if spec.scaled { 0.01 } else { 100.0 }));
    } else if let Some(p0) = e.p0 {
        spec.p0 = CovSpec::Scaled(p0);
    }
    if e.method.is_model_based() || e.method == MethodName::Kf {
        spec.r2 = r2()?;
    }
    let mut est = physid_estim::build(&spec, model.clone(), &set, &free_set)
        .map_err(AppError::estim("estimator configuration"))?;
    // 3. The run, a chunk at a time; the objective on the one-step-ahead predictions after
    // the transient, summed as they come.
    let mut objective = metrics::Prediction::default();
    let (mut offset, mut t0, mut after, mut t_last) = (0, None, false, f64::NAN);
    rows.chunks(&mut |chunk: &Recording| -> Result<(), AppError> {
        let (cols, y) = rows.columns(chunk)?;
        let y = y.ok_or_else(|| AppError::Invalid("the output column is missing".into()))?;
        // The sample index stands for the time in a file without `t`.
        let t = chunk.values("t").ok();
        let columns: Vec<&[f64]> = cols.iter().map(|c| c.as_ref()).collect();
        feed(est.as_mut(), &columns, &y, OnBad::Error, |i, step, est| {
            let ti = t.map_or((offset + i) as f64, |t| t[i]);
            t_last = ti;
            let predicted = y[i] - step.prediction_error;
            after = after || ti - *t0.get_or_insert(ti) >= p.objective.after_s;
            if after {
                objective.push(y[i], predicted);
            }
            // The full estimate is assembled only for the plotted samples.
            if (offset + i).is_multiple_of(stride) || offset + i + 1 == n {
                let theta = est.estimate_full();
                out.t.push(ti);
                out.measured.push(y[i]);
                out.predicted.push(predicted);
                for (k, &j) in order.iter().enumerate() {
                    out.tracks[k].1.push(theta[j]);
                }
            }
        })
        .map_err(|FeedError { sample, error }| AppError::Estim {
            at: format!("sample {}", offset + sample),
            source: error,
        })?;
        offset += y.len();
        Ok(())
    })?;
    if offset != n {
        return Err(AppError::Invalid(format!(
            "the data gave {offset} rows to the estimator, {n} to the analysis"
        )));
    }
    let (final_full, se) = (est.estimate_full(), est.std_errors().unwrap_or_default());
    // What the data resolved: an unresolved parameter gets no standard error.
    let res = est.resolution();
    for (k, &j) in order.iter().enumerate() {
        out.std_err[j] = se.get(k).copied().filter(|_| res.resolved[k]);
    }
    out.unresolved = res
        .unresolved()
        .iter()
        .map(|&k| names[order[k]].clone())
        .collect();
    out.params = final_full;
    if objective.is_empty() {
        return Err(AppError::Invalid(format!(
            "objective.after_s = {} s: no prediction to judge after it — the data span {} s",
            p.objective.after_s,
            t0.map_or(0.0, |t0| t_last - t0)
        )));
    }
    let value = p.objective.metric.of(&objective);
    out.objective.value_pct = value;
    out.objective.samples = objective.len();
    out.objective.met = !objective.is_empty() && value <= p.objective.prediction_within_pct;
    Ok(out)
}
