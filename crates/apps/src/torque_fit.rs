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

use crate::acquisition::{to_crank_angle, AcquisitionOptions, FirstMarker, TDC_MARKER};
use crate::compression::CrankPasses;
use crate::error::AppError;
use crate::recording_rows::{Column, RecordingRows};
use physid_core::{Basis, ParamModel, ParamSet, Recording};
use physid_estim::metrics::Prediction;
use physid_estim::{CovSpec, EstimatorSpec, MethodName, NonlinearEstimator};
use physid_ident::{
    analyse, fit_subset, Analysis, Cutoff, Data, IdentConfig, IdentError, RankedParam, Rows,
    Selection,
};
use physid_io::{ChunkReader, ReadOptions, CHUNK_ROWS};
use physid_models::cyclic_torque::{CyclicTorque, PARAMS};
use physid_models::friction::thesis_preset;
use physid_models::friction_fit::fit_friction_cubic;
use physid_signal::cycles::{CycleStream, CycleSummary};
use physid_sim::params::CellParams;
use physid_sim::run::parameter_truth;
use serde::Serialize;
use std::cell::Cell;
use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::path::Path;

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

    /// No samples, room for `n`.
    fn with_capacity(n: usize) -> Self {
        Self {
            inputs: (0..6).map(|_| Vec::with_capacity(n)).collect(),
            y: Vec::with_capacity(n),
            t: Vec::with_capacity(n),
        }
    }

    /// One sample: the inputs, the measured torque, the time.
    fn push(&mut self, u: &[f64; 6], y: f64, t: f64) {
        for (col, v) in self.inputs.iter_mut().zip(u) {
            col.push(*v);
        }
        self.y.push(y);
        self.t.push(t);
    }

    /// Every sample dropped, the room kept.
    fn clear(&mut self) {
        for col in &mut self.inputs {
            col.clear();
        }
        self.y.clear();
        self.t.clear();
    }
}

impl Rows for TorqueData {
    fn has_y(&self) -> bool {
        true
    }

    fn pass(
        &self,
        visit: &mut dyn FnMut(&Data) -> Result<(), IdentError>,
    ) -> Result<(), IdentError> {
        visit(&self.view())
    }
}

/// Identifiability of the cyclic-torque parameters on a recording's 1° samples (in memory,
/// [`TorqueData`], or gone over in passes, [`Degrees`]): the analysis over every parameter not
/// in `fixed`, and the indices (into [`PARAMS`]) of the estimable ones in rank order.
pub fn torque_identifiability<R: Rows + ?Sized>(
    data: &R,
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
    let a = analyse(&model, data, nominal, &free, IdentConfig::default())?;
    let (k, _) = selection.resolve(&model, data, &a)?;
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
    /// EKF, UKF or SR-UKF (with the thesis's sigma points).
    pub method: MethodName,
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
            method: MethodName::Ukf,
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

/// The channels resampled to one per crank degree from time-basis samples, in the model's
/// input order after θ, then the measured torque and the time, with their units.
const CURVE_CHANNELS: [(&str, &str); 7] = [
    ("omega_en", "rad/s"),
    ("alpha_en", "rad/s^2"),
    ("p_cyl", "Pa"),
    ("p_crank", "Pa"),
    ("T_oil", "K"),
    ("torque_engine", "N*m"),
    ("t", "s"),
];

/// Samples per chunk of 1° samples handed to the analyses and the filter.
const FILE_CHUNK: usize = 4096;

/// Points the tracks keep at least; beyond twice this, every other one is dropped (the tracks'
/// step doubles), so they take bounded memory however long the recording.
pub const TRACK_POINTS: usize = 4000;

/// Run Application 3 on a recording in memory: one sample per crank degree (a crank-angle
/// recording, or a time-basis one with `theta_en` resampled as it is gone over, cycles from its
/// first TDC marker; one with only the encoder count is converted first), the parameters chosen
/// on all of it ([`torque_fit_degrees`]).
pub fn torque_fit(rec: &Recording, cfg: &TorqueFitConfig) -> Result<TorqueFit, AppError> {
    if rec.basis == Basis::Time && rec.channel("theta_en").is_err() {
        let converted = to_crank_angle(rec, &AcquisitionOptions::default(), 1.0)?;
        return torque_fit_degrees(&Degrees::memory(&converted)?, cfg);
    }
    torque_fit_degrees(&Degrees::memory(rec)?, cfg)
}

/// Application 3 over a recording's 1° samples, gone over in passes: the parameters chosen on
/// all of them (the analyses and the batch fit fold them a chunk at a time), the filter run
/// through them once, the prediction of the nominal and the final model summed over them once.
/// Memory is that of the source ([`Degrees`]) and the bounded tracks, whatever the length.
pub fn torque_fit_degrees(src: &Degrees, cfg: &TorqueFitConfig) -> Result<TorqueFit, AppError> {
    let n = src.len()?;
    at_least_a_cycle(n)?;
    let mut filter = TorqueFilter::choose(cfg, src, true)?;
    let mut out = Vec::new();
    let mut u = [0.0; 6];
    src.samples::<AppError>(&mut |d| {
        for i in 0..d.y.len() {
            d.row(i, &mut u);
            filter.step(&u, d.y[i], d.t[i], &mut out)?;
        }
        Ok(())
    })?;
    let mut fit = filter.result(cfg, src, n)?;
    fit.cycles = out
        .into_iter()
        .filter_map(|o| match o {
            TorqueOutput::Cycle(c) => Some(c),
            TorqueOutput::Selected { .. } => None,
        })
        .collect();
    Ok(fit)
}

fn at_least_a_cycle(n: usize) -> Result<(), AppError> {
    if n < PER_CYCLE {
        return Err(AppError::Invalid(format!(
            "{n} samples: the fit needs at least one cycle (720 samples at one per crank degree)"
        )));
    }
    Ok(())
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

/// The channels the fit reads from a time-basis recording (physid names): those it needs, then
/// those it takes when they are there (the TDC marker).
pub fn sample_channels() -> (Vec<&'static str>, Vec<&'static str>) {
    let mut needed = vec!["theta_en"];
    needed.extend(CURVE_CHANNELS.iter().map(|c| c.0));
    (needed, vec![TDC_MARKER])
}

/// What takes each 1° sample: the model's inputs, the measured torque [N·m], the time [s].
type EachDegree<'f, E> = dyn FnMut(&[f64; 6], f64, f64) -> Result<(), E> + 'f;

/// A time-basis stream resampled to one sample per crank degree, cycles from a TDC angle on
/// `theta_en` (linear between samples, [`CycleStream`]'s crank-angle curves): what the live
/// stage and every pass of the file verb over a time-basis recording run.
struct DegreeCurves {
    theta_tdc: f64,
    curves: Option<CycleStream>,
    done: Vec<CycleSummary>,
    /// Time-basis samples taken so far.
    seen: usize,
}

impl DegreeCurves {
    fn new(theta_tdc: f64) -> Self {
        Self {
            theta_tdc,
            curves: None,
            done: Vec::new(),
            seen: 0,
        }
    }

    /// A chunk of time-basis samples with `t`, `theta_en` and [`CURVE_CHANNELS`]: every cycle
    /// it completes resampled, `each(u, y, t)` for each degree — the inputs in [`CyclicTorque`]'s
    /// order (θ [rad from the first TDC], ω, α, p_cyl, p_crank, T_oil [°C]), the measured torque
    /// [N·m], the time [s].
    fn push<E: From<AppError>>(
        &mut self,
        chunk: &Recording,
        each: &mut EachDegree<'_, E>,
    ) -> Result<(), E> {
        if chunk.is_empty() {
            return Ok(());
        }
        let invalid = |e: String| E::from(AppError::Invalid(e));
        if self.curves.is_none() {
            for (name, _) in CURVE_CHANNELS {
                chunk.channel(name).map_err(AppError::from)?;
            }
            chunk.channel("theta_en").map_err(AppError::from)?;
            self.curves = Some(
                CycleStream::new(CURVE_CHANNELS.len(), self.theta_tdc, Some(1.0))
                    .map_err(|e| invalid(e.to_string()))?,
            );
        }
        let cols = CURVE_CHANNELS
            .iter()
            .map(|(name, unit)| chunk.values_in(name, unit))
            .collect::<Result<Vec<_>, _>>()
            .map_err(AppError::from)?;
        for ((name, _), v) in CURVE_CHANNELS.iter().zip(&cols) {
            if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                return Err(invalid(format!(
                    "channel '{name}' sample {} is {}: the model needs finite data",
                    self.seen + i,
                    v[i]
                )));
            }
        }
        let views: Vec<&[f64]> = cols.iter().map(|c| c.as_slice()).collect();
        let theta = chunk.values_in("theta_en", "rad").map_err(AppError::from)?;
        let t = chunk.values("t").map_err(AppError::from)?;
        self.done.clear();
        if let Some(c) = self.curves.as_mut() {
            c.push(t, &theta, &views, &mut self.done)
                .map_err(|e| invalid(e.to_string()))?;
        }
        self.seen += chunk.len();
        let step = (1.0f64).to_radians();
        let mut u = [0.0; 6];
        for c in &self.done {
            let Some(curve) = &c.curve else { continue };
            for (k, (&y, &t)) in curve[5].iter().zip(&curve[6]).enumerate() {
                // θ from the first TDC in the stream, as the crank-angle conversion writes it.
                u[0] = c.cycle as f64 * 4.0 * PI + k as f64 * step;
                for (uj, col) in u[1..5].iter_mut().zip(curve) {
                    *uj = col[k];
                }
                u[5] = curve[4][k] - 273.15;
                each(&u, y, t)?;
            }
        }
        Ok(())
    }
}

/// How a [`Degrees`] makes its 1° samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Angle {
    /// The recording is on a crank-angle basis: its rows are the samples.
    Crank,
    /// A time basis with `theta_en`: resampled on every pass ([`DegreeCurves`]) from the
    /// first TDC marker (found by a first pass).
    Time,
}

/// A recording's 1° samples as [`Rows`] — made again on every pass from the recording's
/// channels ([`RecordingRows`]: a file read again a chunk at a time, or its channels held after
/// the first pass within a limit): a crank-angle recording's rows, or a time-basis one's
/// resampled from its first TDC marker. The cyclic-torque model's analyses, batch fit, filter
/// and prediction each go over them in passes, so the fit keeps memory independent of the
/// recording's length.
pub struct Degrees<'a> {
    rows: DegreeSource<'a>,
    angle: Angle,
    /// The TDC angle on `theta_en` (time basis), once found.
    tdc: Cell<Option<f64>>,
    /// Samples in a pass, once one has been made.
    len: Cell<Option<usize>>,
}

impl<'a> Degrees<'a> {
    /// The 1° samples of the file `path` read with `options` (its channel selection replaced by
    /// the fit's channels), the channels held after the first pass within `hold_bytes`. A
    /// time-basis file needs `theta_en` (one whose angle is an encoder's counts: [`Degrees::crank`]
    /// over its crank-angle samples made as it is read).
    pub fn file(path: &Path, options: &ReadOptions, hold_bytes: usize) -> Result<Self, AppError> {
        let header = ChunkReader::open(path, options)?.header().clone();
        let (angle, needed, also) = Self::channels(&header)?;
        let rows = RecordingRows::file(
            path,
            options,
            needed.iter().map(|c| Column::named(c)).collect(),
            None,
            &also,
            hold_bytes,
        )?;
        Ok(Self::over(rows, angle))
    }

    /// The 1° samples of a recording in memory.
    pub fn memory(rec: &'a Recording) -> Result<Self, AppError> {
        let (angle, _, _) = Self::channels(rec)?;
        Ok(Self::over(
            RecordingRows::memory(rec, Vec::new(), None),
            angle,
        ))
    }

    /// The 1° samples of a crank-angle recording made again on every pass (a time-basis file
    /// whose angle is an encoder's counts, resampled as it is read: the CLI's `CrankFile`).
    pub fn crank(source: &'a dyn CrankPasses) -> Self {
        Self {
            rows: DegreeSource::Passes(source),
            angle: Angle::Crank,
            tdc: Cell::new(None),
            len: Cell::new(None),
        }
    }

    /// How the samples are made from a recording with `header`'s channels, and the channels
    /// read: needed, and taken when there.
    fn channels(header: &Recording) -> Result<(Angle, Vec<&str>, Vec<&str>), AppError> {
        match header.basis {
            Basis::CrankAngle => Ok((Angle::Crank, crank_channels(header), Vec::new())),
            Basis::Time if header.channel("theta_en").is_ok() => {
                let (needed, also) = sample_channels();
                Ok((Angle::Time, needed, also))
            }
            Basis::Time => Err(AppError::Invalid(
                "a time-basis recording without 'theta_en': its crank-angle samples are made from the encoder's counts as it is read (`physid torque fit` does), or convert it with `physid convert --crank-angle` first".into(),
            )),
        }
    }

    fn over(rows: RecordingRows<'a>, angle: Angle) -> Self {
        Self {
            rows: DegreeSource::Rows(rows),
            angle,
            tdc: Cell::new(None),
            len: Cell::new(None),
        }
    }

    /// What the reader noticed but read all the same (a cut-short last line), once the file
    /// has been read to its end.
    pub fn warning(&self) -> Option<String> {
        self.rows.warning()
    }

    /// Whether the channels are held (after a first pass, within the limit).
    pub fn held(&self) -> bool {
        self.rows.held()
    }

    /// The number of 1° samples (a pass, the first time).
    pub fn len(&self) -> Result<usize, AppError> {
        if let Some(n) = self.len.get() {
            return Ok(n);
        }
        self.samples::<AppError>(&mut |_| Ok(()))?;
        Ok(self.len.get().unwrap_or(0))
    }

    /// Whether there are no 1° samples.
    pub fn is_empty(&self) -> Result<bool, AppError> {
        Ok(self.len()? == 0)
    }

    /// The firing TDC's angle on `theta_en` at the first marker (0 without one), found by a
    /// pass the first time — the rule of
    /// [`from_first_marker`](crate::acquisition::from_first_marker).
    fn tdc(&self) -> Result<f64, AppError> {
        if let Some(t) = self.tdc.get() {
            return Ok(t);
        }
        let mut scan = FirstMarker::default();
        let mut found = None;
        self.rows.chunks::<AppError>(&mut |chunk| {
            if found.is_none() {
                found = scan.scan(chunk, TDC_MARKER);
            }
            Ok(())
        })?;
        let t = found.flatten().unwrap_or(0.0);
        self.tdc.set(Some(t));
        Ok(t)
    }

    /// Go over every 1° sample once, in chunks of columns ([`TorqueData`], at most
    /// [`FILE_CHUNK`] samples from a time basis, [`CHUNK_ROWS`] from a crank-angle basis); an
    /// error of `visit` ends the pass and is returned. A pass that makes a different number of
    /// samples than the first is an error (the file changed).
    pub fn samples<E>(&self, visit: &mut dyn FnMut(&TorqueData) -> Result<(), E>) -> Result<(), E>
    where
        E: From<AppError> + From<IdentError>,
    {
        let mut n = 0;
        match self.angle {
            Angle::Crank => self.rows.chunks::<E>(&mut |chunk| {
                in_pieces(chunk, &mut |piece| {
                    let data = TorqueData::from_crank_angle(piece, n)?;
                    n += data.y.len();
                    visit(&data)
                })
            })?,
            Angle::Time => {
                let mut curves = DegreeCurves::new(self.tdc()?);
                let mut buf = TorqueData::with_capacity(FILE_CHUNK);
                self.rows.chunks::<E>(&mut |chunk| {
                    in_pieces(chunk, &mut |piece| {
                        curves.push::<E>(piece, &mut |u, y, t| {
                            buf.push(u, y, t);
                            if buf.y.len() == FILE_CHUNK {
                                n += buf.y.len();
                                visit(&buf)?;
                                buf.clear();
                            }
                            Ok(())
                        })
                    })
                })?;
                if !buf.y.is_empty() {
                    n += buf.y.len();
                    visit(&buf)?;
                }
            }
        }
        match self.len.get() {
            None => self.len.set(Some(n)),
            Some(m) if m != n => {
                return Err(E::from(AppError::Invalid(format!(
                    "the recording gave {n} samples at one per crank degree on a later pass, {m} on the first: was the file changed while it was read?"
                ))))
            }
            Some(_) => {}
        }
        Ok(())
    }
}

/// Where a [`Degrees`] reads its recording on each pass.
enum DegreeSource<'a> {
    /// The channels of a file or a recording in memory ([`RecordingRows`]).
    Rows(RecordingRows<'a>),
    /// A crank-angle recording made again on every pass.
    Passes(&'a dyn CrankPasses),
}

impl DegreeSource<'_> {
    /// `visit` every chunk in order; an error of `visit` ends the pass and is returned.
    fn chunks<E: From<IdentError> + From<AppError>>(
        &self,
        visit: &mut dyn FnMut(&Recording) -> Result<(), E>,
    ) -> Result<(), E> {
        match self {
            Self::Rows(rows) => rows.chunks(visit),
            Self::Passes(source) => {
                // `visit`'s error comes back as it is; the source's as an application error.
                let mut failed = None;
                let read = source.chunks(&mut |chunk| {
                    visit(chunk).map_err(|e| {
                        failed = Some(e);
                        AppError::Invalid(String::new())
                    })
                });
                match (read, failed) {
                    (Ok(()), _) => Ok(()),
                    (Err(_), Some(e)) => Err(e),
                    (Err(e), None) => Err(E::from(e)),
                }
            }
        }
    }

    fn warning(&self) -> Option<String> {
        match self {
            Self::Rows(rows) => rows.warning(),
            Self::Passes(_) => None,
        }
    }

    fn held(&self) -> bool {
        match self {
            Self::Rows(rows) => rows.held(),
            Self::Passes(_) => false,
        }
    }
}

/// `each` piece of at most [`CHUNK_ROWS`] rows of `chunk` in order: the channels held whole
/// are converted a reader chunk's worth at a time, not copied whole.
fn in_pieces<E>(
    chunk: &Recording,
    each: &mut dyn FnMut(&Recording) -> Result<(), E>,
) -> Result<(), E> {
    if chunk.len() <= CHUNK_ROWS {
        return each(chunk);
    }
    for start in (0..chunk.len()).step_by(CHUNK_ROWS) {
        each(&chunk.slice(start..start + CHUNK_ROWS))?;
    }
    Ok(())
}

impl Rows for Degrees<'_> {
    fn has_y(&self) -> bool {
        true
    }

    fn pass(
        &self,
        visit: &mut dyn FnMut(&Data) -> Result<(), IdentError>,
    ) -> Result<(), IdentError> {
        self.samples::<IdentError>(&mut |d| visit(&d.view()))
    }
}

/// An application's error met while a [`Rows`] source makes its rows: a reading error as
/// [`IdentError::Read`] (it names its file), an analysis' as itself, another explained.
impl From<AppError> for IdentError {
    fn from(e: AppError) -> Self {
        match e {
            AppError::Ident(e) => e,
            AppError::Io(e) => IdentError::Read(e.to_string()),
            e => IdentError::Invalid(e.to_string()),
        }
    }
}

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

/// The file verb's tracks: a point every `every` samples, thinned as they grow.
struct Tracks {
    every: usize,
    t: Vec<f64>,
    measured: Vec<f64>,
    predicted: Vec<f64>,
    params: Vec<Track>,
}

impl Tracks {
    /// A point: the sample's time, measurement and prediction, the estimates.
    fn push(&mut self, (t, y, predicted): (f64, f64, f64), v: &[f64], se: &[f64]) {
        self.t.push(t);
        self.measured.push(y);
        self.predicted.push(predicted);
        for (k, tr) in self.params.iter_mut().enumerate() {
            tr.value.push(v[k]);
            tr.std_err.push(se[k]);
        }
    }

    /// Every other point dropped beyond twice [`TRACK_POINTS`]; the step doubles.
    fn bound(&mut self) {
        use crate::halve;
        if self.t.len() < 2 * TRACK_POINTS {
            return;
        }
        halve(&mut self.t);
        halve(&mut self.measured);
        halve(&mut self.predicted);
        for tr in &mut self.params {
            halve(&mut tr.value);
            halve(&mut tr.std_err);
        }
        self.every *= 2;
    }
}

/// Step 2, once the parameters are chosen: the filter over the estimable ones, a sample at a
/// time, a [`TorqueOutput::Cycle`] every 720 samples, and — for the file verb — bounded tracks.
struct TorqueFilter {
    est: NonlinearEstimator<CyclicTorque>,
    analysis: Analysis,
    /// The estimated parameters in rank order, and in the estimator's (index) order.
    estimable: Vec<usize>,
    order: Vec<usize>,
    r2: f64,
    tracks: Option<Tracks>,
    /// Samples through the filter.
    filtered: usize,
    /// The cycle in progress: sums of squared errors and measurements.
    sse: f64,
    ssy: f64,
    /// The last sample filtered: its time, measurement and one-step prediction.
    last: (f64, f64, f64),
}

impl TorqueFilter {
    /// Choose the parameters on `rows` (step 1: the analysis, the selection, and — without a
    /// given R2 — the batch fit of the chosen ones for its residual variance) and set up the
    /// filter on them; `tracks`: record the file verb's tracks.
    fn choose<R: Rows + ?Sized>(
        cfg: &TorqueFitConfig,
        rows: &R,
        tracks: bool,
    ) -> Result<Self, AppError> {
        let (analysis, estimable) =
            torque_identifiability(rows, &cfg.nominal, &cfg.fixed, &cfg.selection)?;
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
        let n = analysis.rows;
        let r2 = match cfg.r2 {
            Some(v) => v,
            None => {
                let fit = fit_subset(&model, rows, &cfg.nominal, &estimable, 20)?;
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
        let spec = EstimatorSpec {
            p0: CovSpec::Scaled(cfg.p0),
            r1: CovSpec::Diagonal(r1),
            r2,
            scaled: true,
            ..EstimatorSpec::new(cfg.method)
        };
        let est = spec
            .nl_config()
            .and_then(|nl| NonlinearEstimator::new(model, &params, &free, &nl))
            .map_err(AppError::estim("estimator configuration"))?;
        // The estimator's order is the parameters' (free set) order.
        let order: Vec<usize> = free.free().to_vec();
        let tracks = tracks.then(|| Tracks {
            every: 1,
            t: Vec::new(),
            measured: Vec::new(),
            predicted: Vec::new(),
            params: order
                .iter()
                .map(|&j| Track {
                    param: PARAMS[j].into(),
                    value: Vec::new(),
                    std_err: Vec::new(),
                })
                .collect(),
        });
        Ok(Self {
            est,
            analysis,
            estimable,
            order,
            r2,
            tracks,
            filtered: 0,
            sse: 0.0,
            ssy: 0.0,
            last: (f64::NAN, f64::NAN, f64::NAN),
        })
    }

    /// The estimable parameters' names, in rank order.
    fn names(&self) -> Vec<&'static str> {
        self.estimable.iter().map(|&j| PARAMS[j]).collect()
    }

    /// One sample through the filter (step 2); a track point every `every`, a
    /// [`TorqueOutput::Cycle`] every 720.
    fn step(
        &mut self,
        u: &[f64; 6],
        y: f64,
        t: f64,
        out: &mut Vec<TorqueOutput>,
    ) -> Result<(), AppError> {
        let i = self.filtered;
        let step = self
            .est
            .update(u, y)
            .map_err(|e| AppError::estim(format!("sample {i}"))(e))?;
        self.filtered += 1;
        self.sse += step.prediction_error * step.prediction_error;
        self.ssy += y * y;
        self.last = (t, y, y - step.prediction_error);
        // The tracks are the file verb's; live, the cycle outputs carry them.
        if let Some(tr) = self.tracks.as_mut() {
            if i.is_multiple_of(tr.every) {
                tr.push(self.last, &self.est.estimate(), &self.est.std_errors());
                tr.bound();
            }
        }
        if self.filtered.is_multiple_of(PER_CYCLE) {
            // In rank order, as chosen.
            let (v, se) = (self.est.estimate(), self.est.std_errors());
            let at = |j: usize| self.order.iter().position(|&i| i == j).unwrap_or(0);
            out.push(TorqueOutput::Cycle(TorqueCycle {
                t_s: t,
                params: self.estimable.iter().map(|&j| v[at(j)]).collect(),
                std_err: self.estimable.iter().map(|&j| se[at(j)]).collect(),
                rms_error_nm: (self.sse / PER_CYCLE as f64).sqrt(),
                rms_measured_nm: (self.ssy / PER_CYCLE as f64).sqrt(),
            }));
            self.sse = 0.0;
            self.ssy = 0.0;
        }
        Ok(())
    }

    /// The file verb's result once every sample has been filtered (step 3): the final
    /// estimates, and — a pass over `src`'s `n` samples — the prediction of the nominal and the
    /// final model (NMSE, NRMSE) and the last two cycles at full resolution.
    fn result(
        mut self,
        cfg: &TorqueFitConfig,
        src: &Degrees,
        n: usize,
    ) -> Result<TorqueFit, AppError> {
        let mut tracks = self
            .tracks
            .take()
            .ok_or_else(|| AppError::Invalid("the filter kept no tracks".into()))?;
        // The last point of the tracks is the last sample.
        if !(self.filtered - 1).is_multiple_of(tracks.every) {
            tracks.push(self.last, &self.est.estimate(), &self.est.std_errors());
        }
        let final_full = self.est.estimate_full();
        let se = self.est.std_errors();
        let std_err: Vec<Option<f64>> = (0..15)
            .map(|j| self.order.iter().position(|&i| i == j).map(|k| se[k]))
            .collect();
        let model = CyclicTorque::default();
        let (mut before, mut after) = (Prediction::default(), Prediction::default());
        let w = n.saturating_sub(2 * PER_CYCLE);
        let mut last_cycles: [Vec<f64>; 4] = Default::default();
        for v in &mut last_cycles {
            v.reserve_exact(n - w);
        }
        let (mut i, mut u) = (0, [0.0; 6]);
        src.samples::<AppError>(&mut |d| {
            for k in 0..d.y.len() {
                d.row(k, &mut u);
                let (y, b, a) = (
                    d.y[k],
                    model.eval::<f64>(&u, &cfg.nominal),
                    model.eval::<f64>(&u, &final_full),
                );
                before.push(y, b);
                after.push(y, a);
                if i >= w {
                    for (col, v) in last_cycles.iter_mut().zip([d.t[k], y, b, a]) {
                        col.push(v);
                    }
                }
                i += 1;
            }
            Ok(())
        })?;
        Ok(TorqueFit {
            method: cfg.method.as_str(),
            ranking: self.analysis.ranked(self.estimable.len()),
            estimable: self.names().iter().map(|s| s.to_string()).collect(),
            nominal: cfg.nominal.to_vec(),
            params: final_full,
            std_err,
            r2: self.r2,
            repairs: self.est.repairs(),
            t: tracks.t,
            tracks: tracks.params,
            measured: tracks.measured,
            predicted: tracks.predicted,
            nmse_before: before.nmse().unwrap_or(f64::NAN),
            nmse_after: after.nmse().unwrap_or(f64::NAN),
            nrmse_before: before.nrmse().unwrap_or(f64::NAN),
            nrmse_after: after.nrmse().unwrap_or(f64::NAN),
            last_cycles,
            samples: n,
            cycles: Vec::new(),
        })
    }
}

/// The samples a live stage keeps until it chooses, and the filter after.
struct Choosing {
    cfg: TorqueFitConfig,
    select_after: usize,
    data: TorqueData,
    filter: Option<TorqueFilter>,
}

impl Choosing {
    /// One sample: kept until the choice, filtered after.
    fn take(
        &mut self,
        u: &[f64; 6],
        y: f64,
        t: f64,
        out: &mut Vec<TorqueOutput>,
    ) -> Result<(), AppError> {
        if let Some(f) = self.filter.as_mut() {
            return f.step(u, y, t, out);
        }
        self.data.push(u, y, t);
        if self.data.y.len() >= self.select_after {
            self.select(out)?;
        }
        Ok(())
    }

    /// Choose the parameters on the samples kept, filter them, and drop them.
    fn select(&mut self, out: &mut Vec<TorqueOutput>) -> Result<(), AppError> {
        let n = self.data.y.len();
        at_least_a_cycle(n)?;
        let mut f = TorqueFilter::choose(&self.cfg, &self.data, false)?;
        out.push(TorqueOutput::Selected {
            t_s: self.data.t[n - 1],
            samples: n,
            estimable: f.names().iter().map(|s| s.to_string()).collect(),
        });
        let data = std::mem::replace(&mut self.data, TorqueData::with_capacity(0));
        let mut u = [0.0; 6];
        for i in 0..n {
            data.row(i, &mut u);
            f.step(&u, data.y[i], data.t[i], out)?;
        }
        self.filter = Some(f);
        Ok(())
    }
}

/// Application 3 live: time-basis chunks in, resampled on the stream to one sample per crank
/// degree (the same [`DegreeCurves`] every pass of the file verb runs), the parameters chosen
/// on the first `select_after` samples ([`TorqueFilter::choose`], as the file verb chooses on
/// all), then a cycle's estimates at a time out. The samples are kept until the choice and
/// dropped after it: memory stays bounded.
pub struct TorqueStage {
    curves: DegreeCurves,
    choosing: Choosing,
}

impl TorqueStage {
    /// A stage that chooses after `select_after` samples (at least a cycle).
    pub fn new(cfg: TorqueFitConfig, select_after: usize) -> Result<Self, AppError> {
        if !(cfg.p0.is_finite() && cfg.p0 > 0.0) {
            return Err(AppError::Invalid(format!(
                "P0 scale {} must be a positive number",
                cfg.p0
            )));
        }
        if select_after < PER_CYCLE {
            return Err(AppError::Invalid(format!(
                "choosing the parameters after {select_after} samples: the choice needs at least one cycle ({PER_CYCLE})"
            )));
        }
        Ok(Self {
            curves: DegreeCurves::new(0.0),
            choosing: Choosing {
                cfg,
                select_after,
                data: TorqueData::with_capacity(0),
                filter: None,
            },
        })
    }

    /// Cycles start at this angle of `theta_en` + k·4π [rad] (default 0); before any sample.
    pub fn set_theta_tdc(&mut self, theta_tdc: f64) -> Result<(), AppError> {
        if self.curves.curves.is_some() {
            return Err(AppError::Invalid(
                "the TDC angle is set before the first sample".into(),
            ));
        }
        self.curves.theta_tdc = theta_tdc;
        Ok(())
    }

    /// The estimable parameters once chosen, in rank order.
    pub fn estimable(&self) -> Option<Vec<&'static str>> {
        self.choosing.filter.as_ref().map(TorqueFilter::names)
    }

    /// A chunk of time-basis samples with `t`, `theta_en`, `omega_en`, `alpha_en`, `p_cyl`,
    /// `p_crank`, `T_oil` and `torque_engine`: each complete cycle resampled to one sample per
    /// crank degree and taken.
    pub fn push(&mut self, chunk: &Recording, out: &mut Vec<TorqueOutput>) -> Result<(), AppError> {
        let choosing = &mut self.choosing;
        self.curves
            .push::<AppError>(chunk, &mut |u, y, t| choosing.take(u, y, t, out))
    }

    /// The end of the stream: the parameters chosen on all of it if they were not yet.
    pub fn finish(&mut self, out: &mut Vec<TorqueOutput>) -> Result<(), AppError> {
        if self.choosing.filter.is_none() {
            self.choosing.select(out)?;
        }
        Ok(())
    }
}
