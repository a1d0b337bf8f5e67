//! Application 3 — cyclic engine torque for end-of-line cold testing (thesis ch. 8, SPEC §9).
//!
//! The model is Eq. 8.2 ([`CyclicTorque`]): indicated, reciprocating and friction torque of a
//! motored engine from θ, ω, α, p_cyl, p_crank and T_oil, one sample per crank degree, with 15
//! parameters (M_rec, b, L, r, δ, c1 … c10).
//!
//! 1. **Identifiability** on the recording at the nominal values (Alg. 5.1, thesis scaling):
//!    which parameters the test supports (Table 8.1). Parameters known by design can be held
//!    out (`fixed`; δ by default — its nominal value is 0, so it has no relative sensitivity).
//!    Eq. 8.2 is invariant under `r → λr, L → λL, b → b/√λ, M_rec → M_rec/λ²`: at most three of
//!    those four are identifiable together, and the analysis finds which.
//! 2. **Estimation** of the estimable subset by EKF, UKF or SR-UKF (Alg. 5.6–5.7) in scaled
//!    coordinates `ϑ = ϑ0·(1 + x)`, the rest fixed at their nominal values. `R2` defaults to the
//!    residual variance of the batch fit of that subset (what the data says the model's error
//!    is), so that the reported ±3σ mean something; a random walk `R1` on chosen parameters
//!    lets the filter track a change (a reciprocating-mass fault).
//! 3. **Prediction quality** before (nominal) and after (final estimates): NMSE as the thesis
//!    defines it (Eq. 6.4 — ill-defined for a torque whose mean is near zero, SPEC §5.3), and
//!    NRMSE.

use crate::acquisition::{from_first_marker, to_crank_angle, AcquisitionOptions, TDC_MARKER};
use crate::error::AppError;
use physid_core::{Basis, ParamModel, ParamSet, Recording};
use physid_estim::metrics::{nmse, nrmse};
use physid_estim::{CovSpec, NlConfig, NlMethod, NonlinearEstimator};
use physid_ident::{
    analyse, fit_subset, Analysis, Cutoff, Data, IdentConfig, RankedParam, Selection,
};
use physid_models::cyclic_torque::{CyclicTorque, PARAMS};
use physid_models::friction::thesis_preset;
use physid_models::friction_fit::fit_friction_cubic;
use physid_signal::cycles::{CycleStream, CycleSummary};
use physid_sim::params::CellParams;
use physid_sim::run::parameter_truth;
use serde::Serialize;
use std::collections::BTreeMap;
use std::f64::consts::PI;

/// The relative cut-off of the cyclic-torque ranking: residuals below 1e-6 of the first are
/// at the level of the measured oil temperature's noise (0.1 K on 363 K, squared), which is all
/// that separates the temperature terms of the friction cubic at a constant oil temperature.
pub const TORQUE_CUTOFF: f64 = 1e-6;

/// The cyclic-torque model's nominal parameters for the virtual test cell's engine: its
/// geometry and reciprocating mass, the friction cubic fitted to the mean-value model (thesis
/// preset) over 500–1500 rpm and 20–100 °C (Fig. 8.1).
pub fn cyclic_torque_nominal(p: &CellParams) -> Result<[f64; 15], AppError> {
    let (d, st) = thesis_preset();
    let n: Vec<f64> = (0..11).map(|k| 500.0 + 100.0 * k as f64).collect();
    let t: Vec<f64> = (0..9).map(|k| 20.0 + 10.0 * k as f64).collect();
    let fit = fit_friction_cubic(&d, &st, 101.0, 101.0, &n, &t).map_err(|e| e.to_string())?;
    let e = &p.engine;
    let mut v = [0.0; 15];
    v[..5].copy_from_slice(&[e.m_rec, e.bore, e.rod, e.crank_radius, e.pin_offset]);
    v[5..].copy_from_slice(&fit.coefficients);
    Ok(v)
}

/// The model's data from a crank-angle recording: input columns θ (`theta_en`, rad from TDC),
/// ω, α, p_cyl, p_crank [Pa], T_oil [°C], the measured engine torque, and time.
#[derive(Debug, Clone)]
pub struct TorqueData {
    /// Input columns in [`CyclicTorque`]'s order.
    pub inputs: Vec<Vec<f64>>,
    /// Measured engine torque `torque_engine` [N·m].
    pub y: Vec<f64>,
    /// Time [s].
    pub t: Vec<f64>,
}

impl TorqueData {
    /// Read and check the channels (units converted to the model's). The crank angle is
    /// `theta` (rad from TDC, as the acquisition chain's crank-angle conversion writes it) or
    /// else `theta_en`; a time-basis recording is first resampled to one sample per crank
    /// degree from its engine encoder and TDC marker.
    pub fn from_recording(rec: &Recording) -> Result<Self, AppError> {
        let converted;
        let rec = if rec.basis == Basis::Time {
            converted = to_crank_angle(rec, &AcquisitionOptions::default(), 1.0)?;
            &converted
        } else {
            rec
        };
        Self::from_crank_angle(rec, 0)
    }

    /// The columns of a crank-angle recording, or of a chunk of one whose first sample is the
    /// recording's `offset`-th (an error names the sample in the recording).
    pub fn from_crank_angle(rec: &Recording, offset: usize) -> Result<Self, AppError> {
        let theta = if rec.values("theta").is_ok() {
            "theta"
        } else {
            "theta_en"
        };
        let t_oil_c: Vec<f64> = rec
            .values_in("T_oil", "K")?
            .iter()
            .map(|k| k - 273.15)
            .collect();
        let inputs = vec![
            rec.values_in(theta, "rad")?,
            rec.values_in("omega_en", "rad/s")?,
            rec.values_in("alpha_en", "rad/s^2")?,
            rec.values_in("p_cyl", "Pa")?,
            rec.values_in("p_crank", "Pa")?,
            t_oil_c,
        ];
        let y = rec.values_in("torque_engine", "N*m")?;
        let t = rec.values("t")?.to_vec();
        let names = [theta, "omega_en", "alpha_en", "p_cyl", "p_crank", "T_oil"];
        for (name, col) in names.iter().zip(&inputs).chain([(&"torque_engine", &y)]) {
            if let Some(i) = col.iter().position(|v| !v.is_finite()) {
                return Err(AppError::Invalid(format!(
                    "channel '{name}' sample {} is {}: the model needs finite data",
                    offset + i,
                    col[i]
                )));
            }
        }
        Ok(Self { inputs, y, t })
    }

    /// The identifiability data view.
    pub fn view(&self) -> Data<'_> {
        Data {
            inputs: self.inputs.iter().map(|c| c.as_slice()).collect(),
            y: Some(&self.y),
        }
    }

    fn row(&self, i: usize, u: &mut [f64; 6]) {
        for (k, col) in self.inputs.iter().enumerate() {
            u[k] = col[i];
        }
    }
}

/// Identifiability of the cyclic-torque parameters on a recording: the analysis over every
/// parameter not in `fixed`, and the indices (into [`PARAMS`]) of the estimable ones in rank
/// order.
pub fn torque_identifiability(
    data: &TorqueData,
    nominal: &[f64; 15],
    fixed: &[String],
    selection: &Selection,
) -> Result<(Analysis, Vec<usize>), AppError> {
    for f in fixed {
        if !PARAMS.contains(&f.as_str()) {
            return Err(AppError::Invalid(format!(
                "fixed parameter '{f}': the parameters are {}",
                PARAMS.join(", ")
            )));
        }
    }
    let free: Vec<usize> = (0..15)
        .filter(|&j| !fixed.iter().any(|f| f == PARAMS[j]))
        .collect();
    if free.is_empty() {
        return Err(AppError::Invalid(
            "every parameter is fixed: nothing to analyse".into(),
        ));
    }
    let model = CyclicTorque::default();
    let view = data.view();
    let a = analyse(&model, &view, nominal, &free, IdentConfig::default())?;
    let (k, _) = selection.resolve(&model, &view, &a)?;
    let estimable = a.top(k).iter().map(|&i| free[i]).collect();
    Ok((a, estimable))
}

/// How to fit.
#[derive(Debug, Clone)]
pub struct TorqueFitConfig {
    /// Initial (nominal) values ϑ0 of the 15 parameters.
    pub nominal: [f64; 15],
    /// Parameters known by design, held out of the analysis and the filter.
    pub fixed: Vec<String>,
    /// How many ranked parameters to estimate.
    pub selection: Selection,
    /// EKF, UKF or SR-UKF.
    pub method: NlMethod,
    /// `P0 = p0·I` over the scaled coordinates x (relative deviations).
    pub p0: f64,
    /// Measurement-noise variance R2 [N²·m²]; `None` = the batch fit's residual variance.
    pub r2: Option<f64>,
    /// Random-walk variance per sample (scaled coordinates) of chosen parameters, to track a
    /// change; the others are constant.
    pub track: Vec<(String, f64)>,
}

impl TorqueFitConfig {
    /// Defaults: UKF with the thesis's sigma points, δ fixed, the relative cut-off
    /// [`TORQUE_CUTOFF`], `P0 = 0.01·I` (a prior standard deviation of 10 % of each nominal
    /// value: the UKF's sigma points then stay within ±20 % — wider ones can reach a crank
    /// radius longer than the rod, where the slider-crank has no solution), R2 from the batch
    /// fit, no tracking.
    pub fn new(nominal: [f64; 15]) -> Self {
        Self {
            nominal,
            fixed: vec!["delta".into()],
            selection: Selection::Rule(Cutoff::Relative(TORQUE_CUTOFF)),
            method: NlMethod::Ukf(Default::default()),
            p0: 0.01,
            r2: None,
            track: Vec::new(),
        }
    }
}

/// One estimated parameter's track.
#[derive(Debug, Clone, Serialize)]
pub struct Track {
    /// Parameter name.
    pub param: String,
    /// Estimates at [`TorqueFit::t`].
    pub value: Vec<f64>,
    /// Standard errors at [`TorqueFit::t`].
    pub std_err: Vec<f64>,
}

/// The test cell's parameter path of each cyclic-torque parameter that has one (the truth of
/// simulated data; the friction cubic's c1 … c10 have none).
pub const TRUTH_PATHS: [(&str, &str); 5] = [
    ("M_rec", "engine.m_rec"),
    ("b", "engine.bore"),
    ("L", "engine.rod"),
    ("r", "engine.crank_radius"),
    ("delta", "engine.pin_offset"),
];

/// The fit's result.
#[derive(Debug, Clone, Serialize)]
pub struct TorqueFit {
    /// Filter name.
    pub method: &'static str,
    /// The ranking of the analysed parameters.
    pub ranking: Vec<RankedParam>,
    /// The estimable parameters, in rank order.
    pub estimable: Vec<String>,
    /// Nominal values of all 15 parameters.
    pub nominal: Vec<f64>,
    /// Final values of all 15 (the fixed ones at nominal).
    pub params: Vec<f64>,
    /// Final standard errors (`None` for fixed parameters).
    pub std_err: Vec<Option<f64>>,
    /// R2 used [N²·m²].
    pub r2: f64,
    /// Covariance repairs by the filter.
    pub repairs: u64,
    /// Times of the tracks [s] (decimated to at most ~4000 points).
    pub t: Vec<f64>,
    /// Tracks of the estimated parameters.
    pub tracks: Vec<Track>,
    /// Measured torque at the track times [N·m].
    pub measured: Vec<f64>,
    /// One-step-ahead prediction at the track times [N·m].
    pub predicted: Vec<f64>,
    /// NMSE (Eq. 6.4) of the nominal model over the recording.
    pub nmse_before: f64,
    /// NMSE of the final estimates over the recording.
    pub nmse_after: f64,
    /// NRMSE of the nominal model.
    pub nrmse_before: f64,
    /// NRMSE of the final estimates.
    pub nrmse_after: f64,
    /// The last two cycles at full resolution: time [s], measured, nominal-model and
    /// final-estimate torque [N·m] (prediction against measurement, readable).
    pub last_cycles: [Vec<f64>; 4],
    /// Samples processed.
    pub samples: usize,
    /// Every cycle's worth (720 samples) through the filter, in order: the estimates' track
    /// (the file verb's `--tracks`).
    pub cycles: Vec<TorqueCycle>,
}

/// What `physid torque fit --json` prints (and the demo's summary holds).
#[derive(Debug, Clone, Serialize)]
pub struct TorqueSummary<'a> {
    /// The filter.
    pub method: &'static str,
    /// The estimated parameters, in rank order.
    pub estimable: &'a [String],
    /// The identifiability ranking.
    pub ranking: &'a [RankedParam],
    /// Every parameter's final value, by name.
    pub params: BTreeMap<&'static str, f64>,
    /// The standard errors of the estimated ones, by name.
    pub std_err: BTreeMap<&'static str, f64>,
    /// NMSE (Eq. 6.4) of the prediction with the nominal and the final values.
    pub nmse_before: f64,
    /// See `nmse_before`.
    pub nmse_after: f64,
    /// NRMSE of the same.
    pub nrmse_before: f64,
    /// See `nrmse_before`.
    pub nrmse_after: f64,
    /// R² of the batch fit.
    pub r2: f64,
    /// Covariance repairs.
    pub repairs: u64,
    /// Samples.
    pub samples: usize,
}

impl TorqueFit {
    /// The result without its tracks.
    pub fn summary(&self) -> TorqueSummary<'_> {
        TorqueSummary {
            method: self.method,
            estimable: &self.estimable,
            ranking: &self.ranking,
            params: PARAMS
                .iter()
                .copied()
                .zip(self.params.iter().copied())
                .collect(),
            std_err: PARAMS
                .iter()
                .zip(&self.std_err)
                .filter_map(|(&n, s)| s.map(|s| (n, s)))
                .collect(),
            nmse_before: self.nmse_before,
            nmse_after: self.nmse_after,
            nrmse_before: self.nrmse_before,
            nrmse_after: self.nrmse_after,
            r2: self.r2,
            repairs: self.repairs,
            samples: self.samples,
        }
    }

    /// The true value of each track over its times, where the recording is simulated and the
    /// parameter is one of the cell's ([`TRUTH_PATHS`]); `None` elsewhere.
    pub fn truths(&self, rec: &Recording) -> Vec<Option<Vec<f64>>> {
        self.tracks
            .iter()
            .map(|tr| {
                let path = TRUTH_PATHS.iter().find(|p| p.0 == tr.param)?.1;
                parameter_truth(rec, path, &self.t)
            })
            .collect()
    }
}

/// Samples per cycle at one per crank degree.
const PER_CYCLE: usize = 720;

/// The channels a stage resamples to one per crank degree from time-basis samples, in the
/// model's input order after θ, then the measured torque and the time, with their units.
const CURVE_CHANNELS: [(&str, &str); 7] = [
    ("omega_en", "rad/s"),
    ("alpha_en", "rad/s^2"),
    ("p_cyl", "Pa"),
    ("p_crank", "Pa"),
    ("T_oil", "K"),
    ("torque_engine", "N*m"),
    ("t", "s"),
];

/// Run Application 3 on a recording: one sample per crank degree (a crank-angle recording, or
/// a time-basis one with `theta_en` resampled on the stream by the same [`TorqueStage`] the
/// live service runs, cycles from its first TDC marker; one with only the encoder count is
/// converted first), the parameters chosen on all of it.
pub fn torque_fit(rec: &Recording, cfg: &TorqueFitConfig) -> Result<TorqueFit, AppError> {
    let slices = |rec: &Recording| {
        let n = rec.len();
        (0..n.max(1))
            .step_by(FILE_CHUNK)
            .map(|start| Ok::<_, AppError>(rec.slice(start..start + FILE_CHUNK)))
            .collect::<Vec<_>>()
    };
    if rec.basis == Basis::Time && rec.channel("theta_en").is_ok() {
        return torque_fit_stream(slices(rec), cfg);
    }
    let converted;
    let rec = if rec.basis == Basis::Time {
        converted = to_crank_angle(rec, &AcquisitionOptions::default(), 1.0)?;
        &converted
    } else {
        rec
    };
    torque_fit_crank(slices(rec), cfg, &mut || {})
}

/// [`torque_fit`] on a crank-angle recording (one sample per degree) read a chunk at a time:
/// only the channels of [`crank_channels`] are read, and the stage keeps the 1° samples (the
/// parameters are chosen on all of them) — not the file's. `fitting` is called once the
/// recording has been read, as in [`torque_fit_phased`].
pub fn torque_fit_crank<I, E>(
    chunks: I,
    cfg: &TorqueFitConfig,
    fitting: &mut dyn FnMut(),
) -> Result<TorqueFit, AppError>
where
    I: IntoIterator<Item = Result<Recording, E>>,
    AppError: From<E>,
{
    let mut stage = TorqueStage::new(cfg.clone(), None, true)?;
    let mut out = Vec::new();
    let (mut seen, mut u) = (0, [0.0; 6]);
    for chunk in chunks {
        let data = TorqueData::from_crank_angle(&chunk?, seen)?;
        for i in 0..data.y.len() {
            data.row(i, &mut u);
            stage.push_sample(&u, data.y[i], data.t[i], &mut out)?;
        }
        seen += data.y.len();
    }
    fitting();
    finish(stage, out)
}

/// The channels the fit reads from a crank-angle recording with `header`'s channels (physid
/// names): the crank angle — `theta`, else `theta_en` — and the curves'.
pub fn crank_channels(header: &Recording) -> Vec<&'static str> {
    let theta = if header.channel("theta").is_ok() {
        "theta"
    } else {
        "theta_en"
    };
    let mut names = vec![theta];
    names.extend(CURVE_CHANNELS.iter().map(|c| c.0));
    names
}

/// The file verb's end: the result, with every cycle the stage put out.
fn finish(mut stage: TorqueStage, mut out: Vec<TorqueOutput>) -> Result<TorqueFit, AppError> {
    let mut fit = stage
        .finish(&mut out)?
        .ok_or_else(|| AppError::Invalid("the fit kept no data".into()))?;
    fit.cycles = out
        .into_iter()
        .filter_map(|o| match o {
            TorqueOutput::Cycle(c) => Some(c),
            TorqueOutput::Selected { .. } => None,
        })
        .collect();
    Ok(fit)
}

/// [`torque_fit`] on a time-basis recording with `theta_en` read a chunk at a time (a file, as
/// it comes; cycles from its first TDC marker): only the channels of
/// [`sample_channels`] are read, resampled to one per crank degree on the stream. The
/// parameters are chosen on all of the data, so the stage keeps the 1° samples (8 numbers a
/// degree: 46 kB a cycle) — not the file's.
pub fn torque_fit_stream<I, E>(chunks: I, cfg: &TorqueFitConfig) -> Result<TorqueFit, AppError>
where
    I: IntoIterator<Item = Result<Recording, E>>,
    AppError: From<E>,
{
    torque_fit_phased(chunks, cfg, &mut || {})
}

/// [`torque_fit_stream`], `fitting` called once the recording has been read (the chunks
/// dropped), before the choice and the filter run over its samples — the longer part, for a
/// progress display.
pub fn torque_fit_phased<I, E>(
    chunks: I,
    cfg: &TorqueFitConfig,
    fitting: &mut dyn FnMut(),
) -> Result<TorqueFit, AppError>
where
    I: IntoIterator<Item = Result<Recording, E>>,
    AppError: From<E>,
{
    let mut stage = TorqueStage::new(cfg.clone(), None, true)?;
    let mut out = Vec::new();
    let chunks = chunks.into_iter().map(|c| c.map_err(AppError::from));
    let (tdc, chunks) = from_first_marker(chunks, &AcquisitionOptions::default())?;
    let tdc = tdc.unwrap_or(0.0);
    stage.set_theta_tdc(tdc)?;
    for chunk in chunks {
        stage.push(&chunk?, &mut out)?;
    }
    fitting();
    finish(stage, out)
}

/// The channels the fit reads from a time-basis recording (physid names): those it needs, then
/// those it takes when they are there (the TDC marker).
pub fn sample_channels() -> (Vec<&'static str>, Vec<&'static str>) {
    let mut needed = vec!["theta_en"];
    needed.extend(CURVE_CHANNELS.iter().map(|c| c.0));
    (needed, vec![TDC_MARKER])
}

/// Samples per chunk when a file is streamed through the stage.
const FILE_CHUNK: usize = 4096;

/// Points the tracks keep at least; beyond twice this, every other one is dropped (the tracks'
/// step doubles), so they take bounded memory however long the recording.
pub const TRACK_POINTS: usize = 4000;

/// What a [`TorqueStage`] reports.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum TorqueOutput {
    /// The estimable parameters were chosen (once), on the samples so far.
    Selected {
        /// Time of the last sample the choice saw [s].
        t_s: f64,
        /// The samples it saw.
        samples: usize,
        /// The estimable parameters, in rank order; the others stay at their nominal values.
        estimable: Vec<String>,
    },
    /// Another 720 samples (a cycle's worth) through the filter.
    Cycle(TorqueCycle),
}

/// A cycle's worth of samples through the filter.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TorqueCycle {
    /// Time of its last sample [s].
    pub t_s: f64,
    /// The estimates after it, in the order chosen ([`TorqueStage::estimable`]).
    pub params: Vec<f64>,
    /// Their standard errors.
    pub std_err: Vec<f64>,
    /// RMS of the one-step prediction errors over the cycle [N·m].
    pub rms_error_nm: f64,
    /// RMS of the measured torque over the cycle [N·m].
    pub rms_measured_nm: f64,
}

/// The filter once the parameters are chosen.
struct RunningTorque {
    est: NonlinearEstimator<CyclicTorque>,
    analysis: Analysis,
    /// The estimated parameters in rank order, and in the estimator's (index) order.
    estimable: Vec<usize>,
    order: Vec<usize>,
    r2: f64,
}

/// Application 3 as a stage: samples at one per crank degree in (or time-basis chunks,
/// resampled on the stream through [`CycleStream`]'s crank-angle curves), chosen parameters and
/// a cycle's estimates at a time out. The parameters are chosen on the first `select_after`
/// samples — live — or, with `None`, on all of them at [`finish`](Self::finish) — the file verb;
/// the filter then runs through the samples so far and every later one as it comes. With
/// `keep`, every sample is kept for the result's prediction figures ([`TorqueFit`]); without,
/// the samples are dropped once the filter has them, and memory stays bounded.
pub struct TorqueStage {
    cfg: TorqueFitConfig,
    select_after: Option<usize>,
    keep: bool,
    /// Every this many samples a point of the tracks.
    pub track_every: usize,
    theta_tdc: f64,
    curves: Option<CycleStream>,
    done: Vec<CycleSummary>,
    /// Samples taken (resampled) so far.
    seen: usize,
    data: TorqueData,
    running: Option<RunningTorque>,
    /// Samples through the filter.
    filtered: usize,
    out_t: Vec<f64>,
    measured: Vec<f64>,
    predicted: Vec<f64>,
    tracks: Vec<Track>,
    /// The cycle in progress: sums of squared errors and measurements.
    sse: f64,
    ssy: f64,
    /// The last sample filtered: its time, measurement and one-step prediction.
    last: (f64, f64, f64),
}

impl TorqueStage {
    /// A stage; `select_after`: choose after that many samples (at least a cycle), `None`: at
    /// the end; `keep`: keep every sample for the result.
    pub fn new(
        cfg: TorqueFitConfig,
        select_after: Option<usize>,
        keep: bool,
    ) -> Result<Self, AppError> {
        if !(cfg.p0.is_finite() && cfg.p0 > 0.0) {
            return Err(AppError::Invalid(format!(
                "P0 scale {} must be a positive number",
                cfg.p0
            )));
        }
        if let Some(n) = select_after.filter(|&n| n < PER_CYCLE) {
            return Err(AppError::Invalid(format!(
                "choosing the parameters after {n} samples: the choice needs at least one cycle ({PER_CYCLE})"
            )));
        }
        Ok(Self {
            cfg,
            select_after,
            keep,
            track_every: 1,
            theta_tdc: 0.0,
            curves: None,
            done: Vec::new(),
            seen: 0,
            data: TorqueData {
                inputs: vec![Vec::new(); 6],
                y: Vec::new(),
                t: Vec::new(),
            },
            running: None,
            filtered: 0,
            out_t: Vec::new(),
            measured: Vec::new(),
            predicted: Vec::new(),
            tracks: Vec::new(),
            sse: 0.0,
            ssy: 0.0,
            last: (f64::NAN, f64::NAN, f64::NAN),
        })
    }

    /// Cycles start at this angle of `theta_en` + k·4π [rad] (default 0); before any sample.
    pub fn set_theta_tdc(&mut self, theta_tdc: f64) -> Result<(), AppError> {
        if self.curves.is_some() {
            return Err(AppError::Invalid(
                "the TDC angle is set before the first sample".into(),
            ));
        }
        self.theta_tdc = theta_tdc;
        Ok(())
    }

    /// The estimable parameters once chosen, in rank order.
    pub fn estimable(&self) -> Option<Vec<&'static str>> {
        self.running
            .as_ref()
            .map(|r| r.estimable.iter().map(|&j| PARAMS[j]).collect())
    }

    /// A chunk of time-basis samples with `t`, `theta_en`, `omega_en`, `alpha_en`, `p_cyl`,
    /// `p_crank`, `T_oil` and `torque_engine`: each complete cycle resampled to one sample per
    /// crank degree (linear between samples) and taken.
    pub fn push(&mut self, chunk: &Recording, out: &mut Vec<TorqueOutput>) -> Result<(), AppError> {
        if chunk.is_empty() {
            return Ok(());
        }
        if self.curves.is_none() {
            for (name, _) in CURVE_CHANNELS {
                chunk.channel(name)?;
            }
            chunk.channel("theta_en")?;
            self.curves = Some(
                CycleStream::new(CURVE_CHANNELS.len(), self.theta_tdc, Some(1.0))
                    .map_err(|e| AppError::Invalid(e.to_string()))?,
            );
        }
        let cols = CURVE_CHANNELS
            .iter()
            .map(|(name, unit)| chunk.values_in(name, unit))
            .collect::<Result<Vec<_>, _>>()?;
        for ((name, _), v) in CURVE_CHANNELS.iter().zip(&cols) {
            if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                return Err(AppError::Invalid(format!(
                    "channel '{name}' sample {} is {}: the model needs finite data",
                    self.seen + i,
                    v[i]
                )));
            }
        }
        let views: Vec<&[f64]> = cols.iter().map(|c| c.as_slice()).collect();
        let mut done = std::mem::take(&mut self.done);
        done.clear();
        if let Some(c) = self.curves.as_mut() {
            c.push(
                chunk.values("t")?,
                &chunk.values_in("theta_en", "rad")?,
                &views,
                &mut done,
            )
            .map_err(|e| AppError::Invalid(e.to_string()))?;
        }
        self.seen += chunk.len();
        let step = (1.0f64).to_radians();
        let mut u = [0.0; 6];
        for c in &done {
            let Some(curve) = &c.curve else { continue };
            for (k, (&y, &t)) in curve[5].iter().zip(&curve[6]).enumerate() {
                // θ from the first TDC in the stream, as the crank-angle conversion writes it.
                u[0] = c.cycle as f64 * 4.0 * PI + k as f64 * step;
                for (uj, col) in u[1..5].iter_mut().zip(curve) {
                    *uj = col[k];
                }
                u[5] = curve[4][k] - 273.15;
                self.push_sample(&u, y, t, out)?;
            }
        }
        self.done = done;
        Ok(())
    }

    /// One sample at one per crank degree: the inputs in [`CyclicTorque`]'s order (θ [rad from
    /// TDC], ω, α, p_cyl, p_crank, T_oil [°C]), the measured torque [N·m], the time [s].
    pub fn push_sample(
        &mut self,
        u: &[f64; 6],
        y: f64,
        t: f64,
        out: &mut Vec<TorqueOutput>,
    ) -> Result<(), AppError> {
        if self.keep || self.running.is_none() {
            for (col, v) in self.data.inputs.iter_mut().zip(u) {
                col.push(*v);
            }
            self.data.y.push(y);
            self.data.t.push(t);
        }
        if self.running.is_some() {
            self.filter(u, y, t, out)
        } else if self.select_after.is_some_and(|n| self.data.y.len() >= n) {
            self.select(out)
        } else {
            Ok(())
        }
    }

    /// Choose the parameters on the samples so far (steps 1–2), then filter them.
    fn select(&mut self, out: &mut Vec<TorqueOutput>) -> Result<(), AppError> {
        let cfg = &self.cfg;
        let data = &self.data;
        let n = data.y.len();
        if n < PER_CYCLE {
            return Err(AppError::Invalid(format!(
                "{n} samples: the fit needs at least one cycle (720 samples at one per crank degree)"
            )));
        }
        let (analysis, estimable) =
            torque_identifiability(data, &cfg.nominal, &cfg.fixed, &cfg.selection)?;
        if estimable.is_empty() {
            return Err(AppError::Invalid(
                "no parameter is estimable on this recording".into(),
            ));
        }
        if let Some(&j) = estimable.iter().find(|&&j| cfg.nominal[j] == 0.0) {
            return Err(AppError::Invalid(format!(
                "'{}' has nominal value 0: scaled coordinates ϑ = ϑ0·(1 + x) cannot move it — give it a non-zero nominal value or fix it",
                PARAMS[j]
            )));
        }
        let model = CyclicTorque::default();
        let r2 = match cfg.r2 {
            Some(v) => v,
            None => {
                let fit = fit_subset(&model, &data.view(), &cfg.nominal, &estimable, 20)?;
                // An exact fit (noise-free data) leaves no residual: keep R2 positive.
                (fit.rss / (n - estimable.len()).max(1) as f64).max(f64::MIN_POSITIVE)
            }
        };
        let params = ParamSet::new(PARAMS, cfg.nominal.to_vec())
            .map_err(|e| AppError::Invalid(e.to_string()))?;
        let names: Vec<&str> = estimable.iter().map(|&j| PARAMS[j]).collect();
        let free = params
            .free(&names)
            .map_err(|e| AppError::Invalid(e.to_string()))?;
        let mut r1 = vec![0.0; free.free().len()];
        for (name, v) in &cfg.track {
            let pos = free
                .free()
                .iter()
                .position(|&j| PARAMS[j] == name.as_str())
                .ok_or_else(|| {
                    AppError::Invalid(format!(
                        "track {name}: it is not among the estimated parameters ({})",
                        names.join(", ")
                    ))
                })?;
            r1[pos] = *v;
        }
        let nl = NlConfig {
            p0: CovSpec::Scaled(cfg.p0),
            r1: CovSpec::Diagonal(r1),
            r2,
            scaled: true,
            bounds: Vec::new(),
            method: cfg.method,
        };
        let est = NonlinearEstimator::new(model, &params, &free, &nl)
            .map_err(AppError::estim("estimator configuration"))?;
        // The estimator's order is the parameters' (free set) order.
        let order: Vec<usize> = free.free().to_vec();
        self.tracks = order
            .iter()
            .map(|&j| Track {
                param: PARAMS[j].into(),
                value: Vec::new(),
                std_err: Vec::new(),
            })
            .collect();
        out.push(TorqueOutput::Selected {
            t_s: data.t[n - 1],
            samples: n,
            estimable: names.iter().map(|s| s.to_string()).collect(),
        });
        self.running = Some(RunningTorque {
            est,
            analysis,
            estimable,
            order,
            r2,
        });
        let mut u = [0.0; 6];
        for i in 0..n {
            self.data.row(i, &mut u);
            let (y, t) = (self.data.y[i], self.data.t[i]);
            self.filter(&u, y, t, out)?;
        }
        if !self.keep {
            for c in &mut self.data.inputs {
                *c = Vec::new();
            }
            self.data.y = Vec::new();
            self.data.t = Vec::new();
        }
        Ok(())
    }

    /// One sample through the filter (step 2); a track point every `track_every`, a
    /// [`TorqueOutput::Cycle`] every 720.
    fn filter(
        &mut self,
        u: &[f64; 6],
        y: f64,
        t: f64,
        out: &mut Vec<TorqueOutput>,
    ) -> Result<(), AppError> {
        let Some(r) = self.running.as_mut() else {
            return Ok(());
        };
        let i = self.filtered;
        let step = r
            .est
            .update(u, y)
            .map_err(|e| AppError::estim(format!("sample {i}"))(e))?;
        self.filtered += 1;
        self.sse += step.prediction_error * step.prediction_error;
        self.ssy += y * y;
        self.last = (t, y, y - step.prediction_error);
        // The tracks are the file verb's (kept samples); live, the cycle outputs carry them.
        if self.keep && i.is_multiple_of(self.track_every) {
            self.out_t.push(t);
            self.measured.push(y);
            self.predicted.push(y - step.prediction_error);
            let (v, se) = (r.est.estimate(), r.est.std_errors());
            for (k, tr) in self.tracks.iter_mut().enumerate() {
                tr.value.push(v[k]);
                tr.std_err.push(se[k]);
            }
        }
        if self.filtered.is_multiple_of(PER_CYCLE) {
            // In rank order, as chosen.
            let (v, se) = (r.est.estimate(), r.est.std_errors());
            let at = |j: usize| r.order.iter().position(|&i| i == j).unwrap_or(0);
            out.push(TorqueOutput::Cycle(TorqueCycle {
                t_s: t,
                params: r.estimable.iter().map(|&j| v[at(j)]).collect(),
                std_err: r.estimable.iter().map(|&j| se[at(j)]).collect(),
                rms_error_nm: (self.sse / PER_CYCLE as f64).sqrt(),
                rms_measured_nm: (self.ssy / PER_CYCLE as f64).sqrt(),
            }));
            self.sse = 0.0;
            self.ssy = 0.0;
        }
        if self.out_t.len() >= 2 * TRACK_POINTS {
            self.thin_tracks();
        }
        Ok(())
    }

    /// Every other point of the tracks dropped; their step doubles.
    fn thin_tracks(&mut self) {
        use crate::halve;
        halve(&mut self.out_t);
        halve(&mut self.measured);
        halve(&mut self.predicted);
        for tr in &mut self.tracks {
            halve(&mut tr.value);
            halve(&mut tr.std_err);
        }
        self.track_every *= 2;
    }

    /// The end of the stream: the parameters chosen if they were not, and — with `keep` — the
    /// result.
    pub fn finish(&mut self, out: &mut Vec<TorqueOutput>) -> Result<Option<TorqueFit>, AppError> {
        if self.running.is_none() {
            self.select(out)?;
        }
        if !self.keep {
            return Ok(None);
        }
        let (Some(r), data) = (self.running.as_ref(), &self.data) else {
            return Ok(None);
        };
        let n = data.y.len();
        let model = CyclicTorque::default();
        let order = &r.order;
        // The last point of the tracks is the last sample.
        if !(self.filtered - 1).is_multiple_of(self.track_every) {
            let (v, se) = (r.est.estimate(), r.est.std_errors());
            let (t, y, predicted) = self.last;
            self.out_t.push(t);
            self.measured.push(y);
            self.predicted.push(predicted);
            for (k, tr) in self.tracks.iter_mut().enumerate() {
                tr.value.push(v[k]);
                tr.std_err.push(se[k]);
            }
        }
        let final_full = r.est.estimate_full();
        let se = r.est.std_errors();
        let std_err: Vec<Option<f64>> = (0..15)
            .map(|j| order.iter().position(|&i| i == j).map(|k| se[k]))
            .collect();
        let predict = |p: &[f64]| -> Vec<f64> {
            let mut u = [0.0; 6];
            (0..n)
                .map(|i| {
                    data.row(i, &mut u);
                    model.eval::<f64>(&u, p)
                })
                .collect()
        };
        let before = predict(&self.cfg.nominal);
        let after = predict(&final_full);
        let w = n.saturating_sub(1440);
        let last_cycles = [
            data.t[w..].to_vec(),
            data.y[w..].to_vec(),
            before[w..].to_vec(),
            after[w..].to_vec(),
        ];
        Ok(Some(TorqueFit {
            method: self.cfg.method.name(),
            ranking: r.analysis.ranked(r.estimable.len()),
            estimable: r.estimable.iter().map(|&j| PARAMS[j].to_string()).collect(),
            nominal: self.cfg.nominal.to_vec(),
            params: final_full,
            std_err,
            r2: r.r2,
            repairs: r.est.repairs(),
            t: std::mem::take(&mut self.out_t),
            tracks: std::mem::take(&mut self.tracks),
            measured: std::mem::take(&mut self.measured),
            predicted: std::mem::take(&mut self.predicted),
            nmse_before: nmse(&data.y, &before).unwrap_or(f64::NAN),
            nmse_after: nmse(&data.y, &after).unwrap_or(f64::NAN),
            nrmse_before: nrmse(&data.y, &before).unwrap_or(f64::NAN),
            nrmse_after: nrmse(&data.y, &after).unwrap_or(f64::NAN),
            last_cycles,
            samples: n,
            cycles: Vec::new(),
        }))
    }
}
