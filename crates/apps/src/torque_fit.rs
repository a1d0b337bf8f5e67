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

use crate::acquisition::{to_crank_angle, AcquisitionOptions};
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
use physid_sim::params::CellParams;
use physid_sim::run::parameter_truth;
use serde::Serialize;
use std::collections::BTreeMap;

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
                    "channel '{name}' sample {i} is {}: the model needs finite data",
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

/// Run Application 3 on a crank-angle recording.
pub fn torque_fit(rec: &Recording, cfg: &TorqueFitConfig) -> Result<TorqueFit, AppError> {
    let data = TorqueData::from_recording(rec)?;
    let n = data.y.len();
    if n < 720 {
        return Err(AppError::Invalid(format!(
            "{n} samples: the fit needs at least one cycle (720 samples at one per crank degree)"
        )));
    }
    if !(cfg.p0.is_finite() && cfg.p0 > 0.0) {
        return Err(AppError::Invalid(format!(
            "P0 scale {} must be a positive number",
            cfg.p0
        )));
    }
    let (analysis, estimable) =
        torque_identifiability(&data, &cfg.nominal, &cfg.fixed, &cfg.selection)?;
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
    let mut est = NonlinearEstimator::new(model.clone(), &params, &free, &nl)
        .map_err(AppError::estim("estimator configuration"))?;
    let order: Vec<usize> = free.free().to_vec();
    let stride = n.div_ceil(4000).max(1);
    let mut out_t = Vec::with_capacity(n / stride + 1);
    let mut measured = Vec::with_capacity(n / stride + 1);
    let mut predicted = Vec::with_capacity(n / stride + 1);
    let mut tracks: Vec<Track> = order
        .iter()
        .map(|&j| Track {
            param: PARAMS[j].into(),
            value: Vec::new(),
            std_err: Vec::new(),
        })
        .collect();
    let mut u = [0.0; 6];
    for i in 0..n {
        data.row(i, &mut u);
        let step = est
            .update(&u, data.y[i])
            .map_err(|e| AppError::estim(format!("sample {i}"))(e))?;
        if i.is_multiple_of(stride) || i + 1 == n {
            out_t.push(data.t[i]);
            measured.push(data.y[i]);
            predicted.push(data.y[i] - step.prediction_error);
            let v = est.estimate();
            let se = est.std_errors();
            for (k, tr) in tracks.iter_mut().enumerate() {
                tr.value.push(v[k]);
                tr.std_err.push(se[k]);
            }
        }
    }
    let final_full = est.estimate_full();
    let se = est.std_errors();
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
    let before = predict(&cfg.nominal);
    let after = predict(&final_full);
    let w = n.saturating_sub(1440);
    let last_cycles = [
        data.t[w..].to_vec(),
        data.y[w..].to_vec(),
        before[w..].to_vec(),
        after[w..].to_vec(),
    ];
    Ok(TorqueFit {
        method: cfg.method.name(),
        ranking: analysis.ranked(estimable.len()),
        estimable: names.iter().map(|s| s.to_string()).collect(),
        nominal: cfg.nominal.to_vec(),
        params: final_full,
        std_err,
        r2,
        repairs: est.repairs(),
        t: out_t,
        tracks,
        measured,
        predicted,
        nmse_before: nmse(&data.y, &before).unwrap_or(f64::NAN),
        nmse_after: nmse(&data.y, &after).unwrap_or(f64::NAN),
        nrmse_before: nrmse(&data.y, &before).unwrap_or(f64::NAN),
        nrmse_after: nrmse(&data.y, &after).unwrap_or(f64::NAN),
        last_cycles,
        samples: n,
    })
}
