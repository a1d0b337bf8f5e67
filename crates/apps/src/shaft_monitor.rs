//! Application 1 — coupling-shaft health monitoring (thesis ch. 6, SPEC §7).
//!
//! `τ_sh = K·Δθ + B·Δω + τ_0` (Eq. 6.1), `Δθ = θ_dy − θ_en`, `Δω = ω_dy − ω_en`, with the torque
//! offset `τ_0` absorbing the encoders' unknown zero offset (SPEC §7). The three signals are
//! zero-phase low-pass filtered, decimated to the estimator's rate, and fed to a recursive
//! estimator (RLS, vector-forgetting RLS or DSFC; λ = 0.98 as in the thesis); the relative error
//! of each estimate from its healthy value (Eq. 6.3) raises an alarm when it stays beyond a
//! bound for a dwell — and names the parameter that moved (isolation).

use crate::acquisition::{to_time_basis, uniform_step};
use crate::error::AppError;
use crate::excitation::{ExcitationSupervisor, SupervisorConfig, SupervisorError};
use physid_core::{Basis, ParamSet, Recording};
use physid_estim::{
    build_linear, CovSpec, EstimatorSpec, LinearEstimator, MethodName, RelativeErrorDetector,
    VfVariant,
};
use physid_models::shaft::{Shaft, NOMINAL};
use physid_signal::filter::{butter, Band};
use physid_signal::integrity::NOMINAL_SAMPLES;
use physid_signal::speed_angle::SpeedAngle;
use physid_signal::stream::{settling_length, ZeroPhaseStream};
use serde::Serialize;
use std::collections::VecDeque;

/// The estimator.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MonitorMethod {
    /// Recursive least squares with exponential forgetting λ (`rlsf`, as in `physid estimate`;
    /// `rls` was its name here before the one vocabulary of docs/cli.md and is still read).
    #[serde(alias = "rls")]
    Rlsf,
    /// Vector forgetting: λ on K and B, 1 on the offset.
    Rlsvf,
    /// The square-root form (Alg. 5.5).
    Dsfc,
}

impl MonitorMethod {
    /// Parse `rlsf|rlsvf|dsfc` (and `rls`, the old name of `rlsf` here: see
    /// [`MonitorMethod::is_old_name`]).
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "rlsf" | "rls" => Some(Self::Rlsf),
            "rlsvf" => Some(Self::Rlsvf),
            "dsfc" => Some(Self::Dsfc),
            _ => None,
        }
    }

    /// `rls` meant RLS *with* forgetting in the shaft monitor, but RLS without it in
    /// `physid estimate`: it is still taken as `rlsf` for this release, with a warning.
    pub fn is_old_name(s: &str) -> bool {
        s == "rls"
    }

    /// The method in the one vocabulary of the estimators.
    pub fn method(self) -> MethodName {
        match self {
            Self::Rlsf => MethodName::Rlsf,
            Self::Rlsvf => MethodName::Rlsvf,
            Self::Dsfc => MethodName::Dsfc,
        }
    }

    /// The name (`rlsf`, `rlsvf`, `dsfc`).
    pub fn name(self) -> &'static str {
        self.method().as_str()
    }
}

impl std::str::FromStr for MonitorMethod {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::parse(s).ok_or_else(|| format!("'{s}': expected rlsf, rlsvf or dsfc"))
    }
}

/// How to monitor.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct MonitorConfig {
    /// Estimator.
    pub method: MonitorMethod,
    /// Forgetting factor.
    pub lambda: f64,
    /// `P0 = c·I`.
    pub p0: f64,
    /// Healthy K [N·m/rad] and B [N·m·s/rad]: the detector's reference.
    pub healthy: PerParam,
    /// Initial estimates of K, B, τ0 (the thesis's experiments start from 0; its fault
    /// simulations from the healthy values).
    pub theta0: ShaftParams,
    /// Relative-error bound (Eq. 6.3).
    pub bound: f64,
    /// Samples beyond the bound before an alarm.
    pub dwell: u64,
    /// Zero-phase low-pass cut-off [Hz] before estimation.
    pub cutoff_hz: f64,
    /// The estimator's sample rate [Hz] (the filtered signals are decimated to it).
    pub rate_hz: f64,
    /// Seconds of data before the detector starts (the estimator's start-up).
    pub settle_s: f64,
    /// Freeze K or B while the data no longer resolve them (the excitation supervisor, thesis
    /// §9.2: on-line identifiability over the last ≈ 0.1 s), release them when they do again.
    pub supervise: bool,
}

impl Default for MonitorConfig {
    /// λ = 0.98, ϑ0 = 0, P0 = 1000·I (thesis ch. 6), healthy = Table 6.1's yellow spider,
    /// ±10 %, 0.1 s dwell, 500 Hz low-pass, 2 kHz estimator rate, 1 s settling.
    fn default() -> Self {
        Self {
            method: MonitorMethod::Rlsf,
            lambda: 0.98,
            p0: 1000.0,
            healthy: PerParam {
                k: NOMINAL[0],
                b: NOMINAL[1],
            },
            theta0: ShaftParams {
                k: 0.0,
                b: 0.0,
                tau0: 0.0,
            },
            bound: 0.1,
            dwell: 200,
            cutoff_hz: 500.0,
            rate_hz: 2000.0,
            settle_s: 1.0,
            supervise: false,
        }
    }
}

/// The coupling shaft's parameters by name (JSON: `K`, `B`, `tau0`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct ShaftParams {
    /// Stiffness K [N·m/rad].
    #[serde(rename = "K")]
    pub k: f64,
    /// Damping B [N·m·s/rad].
    #[serde(rename = "B")]
    pub b: f64,
    /// Encoder-offset torque τ0 [N·m].
    pub tau0: f64,
}

/// A figure per monitored parameter (JSON: `K`, `B`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct PerParam {
    /// For K.
    #[serde(rename = "K")]
    pub k: f64,
    /// For B.
    #[serde(rename = "B")]
    pub b: f64,
}

/// A raised alarm, in time.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ShaftAlarm {
    /// `K` or `B`.
    pub param: String,
    /// When the relative error first left the bound [s].
    pub t_start_s: f64,
    /// When the dwell completed [s].
    pub t_raised_s: f64,
    /// The relative error then (Eq. 6.3: `(ϑ_healthy − ϑ̂)/ϑ_healthy`, positive when the
    /// estimate fell).
    pub relative_error: f64,
    /// The estimate's change from its healthy value then, `(ϑ̂ − ϑ_healthy)/ϑ_healthy =
    /// −relative_error` (K fell 12 % → −0.12): how a person reads it.
    pub change: f64,
}

/// The monitor's result.
#[derive(Debug, Clone, Serialize)]
pub struct ShaftMonitor {
    /// The method.
    pub method: &'static str,
    /// The recording's sample rate [Hz].
    pub input_rate_hz: f64,
    /// The zero-phase low-pass cut-off applied before estimation [Hz] (`None`: the cut-off was
    /// at or above the Nyquist frequency, and the signals went in unfiltered).
    pub lowpass_hz: Option<f64>,
    /// One input sample in `every` goes to the estimator.
    pub every: usize,
    /// Estimator sample times [s].
    pub t: Vec<f64>,
    /// K estimates.
    pub k: Vec<f64>,
    /// B estimates.
    pub b: Vec<f64>,
    /// Offset estimates [N·m].
    pub tau0: Vec<f64>,
    /// Standard errors of K and B at each sample.
    pub std_err: Vec<[f64; 2]>,
    /// Final K, B, τ0.
    pub final_estimate: ShaftParams,
    /// Final standard errors of K, B, τ0 (NaN before they can be estimated, and for those
    /// the data did not resolve).
    pub final_std_err: ShaftParams,
    /// The parameters the data did not resolve (their variance did not halve from P0): their
    /// final values are the estimator's start, not the shaft's.
    pub unresolved: Vec<&'static str>,
    /// What in the recording makes the estimates suspect: a speed that is not its angle's
    /// derivative ([`physid_signal::speed_angle`]: a units row that lies).
    pub warnings: Vec<String>,
    /// Alarms.
    pub alarms: Vec<ShaftAlarm>,
    /// True K and B over time, when the recording carries them (simulated data).
    pub truth: Option<(Vec<f64>, Vec<f64>)>,
    /// NMSE of the K and B tracks against the truth after settling (thesis Fig. 6.9).
    pub nmse: Option<PerParam>,
    /// First time after which the estimates stay within ±5 % of the truth [s], per parameter.
    pub within_5pct_s: Option<[Option<f64>; 2]>,
    /// With the excitation supervisor: how long K and B were frozen [s] (estimator samples
    /// frozen × the estimator's step).
    pub frozen_s: Option<PerParam>,
    /// With the excitation supervisor: K, B and τ0 frozen or not at each estimator sample.
    pub frozen: Vec<[bool; 3]>,
}

/// How long the excitation supervisor must hold a parameter frozen (or free) before the stage
/// reports the change [s]: longer than an engine cycle above 500 rpm, whose quiet part (no
/// compression near bottom dead centre) the estimator's own short memory (λ = 0.98 at 2 kHz:
/// 25 ms) cannot resolve K and B in — the estimator freezes them there (no wind-up), but that is
/// not a loss of excitation worth telling.
pub const FREEZE_HOLD_S: f64 = 0.25;

/// Samples per chunk when a file is streamed through the stage.
const FILE_CHUNK: usize = 4096;

/// A chunk of the monitor's input channels, all the same length.
#[derive(Debug, Clone, Copy)]
pub struct ShaftInputs<'a> {
    /// Time [s], uniformly spaced at the stage's rate.
    pub t: &'a [f64],
    /// Dynamometer angle [rad].
    pub theta_dy: &'a [f64],
    /// Engine angle [rad].
    pub theta_en: &'a [f64],
    /// Dynamometer speed [rad/s].
    pub omega_dy: &'a [f64],
    /// Engine speed [rad/s].
    pub omega_en: &'a [f64],
    /// Shaft torque [N·m].
    pub torque_shaft: &'a [f64],
}

impl<'a> ShaftInputs<'a> {
    /// The monitor's channels of a recording (on a uniform time basis).
    pub fn of(rec: &'a Recording) -> Result<Self, AppError> {
        Ok(Self {
            t: rec.values("t")?,
            theta_dy: rec.values("theta_dy")?,
            theta_en: rec.values("theta_en")?,
            omega_dy: rec.values("omega_dy")?,
            omega_en: rec.values("omega_en")?,
            torque_shaft: rec.values("torque_shaft")?,
        })
    }

    /// Samples `r` of every channel.
    pub fn slice(&self, r: std::ops::Range<usize>) -> Self {
        Self {
            t: &self.t[r.clone()],
            theta_dy: &self.theta_dy[r.clone()],
            theta_en: &self.theta_en[r.clone()],
            omega_dy: &self.omega_dy[r.clone()],
            omega_en: &self.omega_en[r.clone()],
            torque_shaft: &self.torque_shaft[r],
        }
    }
}

/// One estimator sample of the monitor.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct ShaftSample {
    /// The input sample it was taken at (0 = the stream's first).
    pub index: usize,
    /// Its time [s].
    pub t_s: f64,
    /// K, B, τ0 after it.
    pub estimate: ShaftParams,
    /// Standard errors of K and B (NaN before they can be estimated).
    pub std_err: PerParam,
    /// Whether K, B and τ0 are frozen by the excitation supervisor: reported once the estimator
    /// has held one frozen (or free) for [`FREEZE_HOLD_S`] without a break.
    pub frozen: [bool; 3],
}

/// The monitor's estimator, supervised or not.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
enum Estimator {
    Plain(Box<LinearEstimator>),
    Supervised(Box<ExcitationSupervisor>),
}

impl Estimator {
    fn get(&self) -> &LinearEstimator {
        match self {
            Self::Plain(e) => e,
            Self::Supervised(s) => s.estimator(),
        }
    }

    fn update(&mut self, phi: &[f64], y: f64, at: usize) -> Result<(), AppError> {
        let estim = |source| AppError::Estim {
            at: format!("sample {at}"),
            source,
        };
        match self {
            Self::Plain(e) => e.update(phi, y).map(|_| ()).map_err(estim),
            Self::Supervised(s) => s.update(phi, y).map_err(|e| match e {
                SupervisorError::Estim(source) => estim(source),
                SupervisorError::Ident(e) => AppError::Invalid(format!("sample {at}: {e}")),
            }),
        }
    }

    /// Whether K, B and τ0 are frozen now.
    fn frozen(&self) -> [bool; 3] {
        match self {
            Self::Plain(_) => [false; 3],
            Self::Supervised(s) => {
                let a = s.active();
                [!a[0], !a[1], !a[2]]
            }
        }
    }
}

/// Below this engine speed [rad/s] (300 rpm, well under any test's operating point) the
/// engine is taken as stopping or standing still: the
/// estimator and the alarm detector are held (every parameter reported frozen) until it turns
/// again — a stopped cell raises no alarm and does not wind the estimator's covariance up.
pub const STANDSTILL_RAD_S: f64 = 300.0 * std::f64::consts::PI / 30.0;

/// The shaft monitor as a stage: chunks of samples in, estimator samples and alarms out, the
/// zero-phase low-pass done on the stream ([`ZeroPhaseStream`]). The file verb
/// ([`monitor_shaft`]) and the live service run this same code; its output does not depend on
/// how the input is chunked, and a sample's estimate leaves [`latency`](Self::latency) samples
/// after it arrived at the most. Allocation-free per sample once the output vectors have room.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct ShaftStage {
    cfg: MonitorConfig,
    every: usize,
    filters: Option<Box<[ZeroPhaseStream; 3]>>,
    /// Times of the inputs not yet out of the filters.
    times: VecDeque<f64>,
    /// The engine's speed [rad/s] at those times (the standstill hold).
    #[serde(default)]
    speeds: VecDeque<f64>,
    t0: Option<f64>,
    /// Index of the next filtered sample.
    next: usize,
    est: Estimator,
    det: RelativeErrorDetector,
    /// Times of the detector's last samples (an alarm's onset is at most a dwell back).
    det_times: VecDeque<f64>,
    /// The reported frozen state, and since when the estimator's has differed from it.
    held: [bool; 3],
    differs_since: [Option<f64>; 3],
    model: Shaft,
    raw: [Vec<f64>; 3],
    filtered: [Vec<f64>; 3],
}

impl ShaftStage {
    /// A stage for inputs at `rate_hz` [Hz].
    pub fn new(cfg: &MonitorConfig, rate_hz: f64) -> Result<Self, AppError> {
        if !(rate_hz.is_finite() && rate_hz > 0.0) {
            return Err(AppError::Invalid(format!(
                "sample rate {rate_hz} Hz: expected > 0"
            )));
        }
        let filters = if cfg.cutoff_hz < rate_hz / 2.0 {
            let sos = butter(4, &[cfg.cutoff_hz], Band::Lowpass, rate_hz)
                .map_err(|e| AppError::Invalid(e.to_string()))?
                .to_sos();
            // Blocks of a quarter of the lookahead: the latency is 1.25 lookaheads (34 ms for
            // the default 500 Hz at 10 kHz) for 5 backward passes per sample instead of 2.
            let lookahead = settling_length(&sos);
            let f = ZeroPhaseStream::new(&sos, Some(lookahead), Some((lookahead / 4).max(1)));
            Some(Box::new([f.clone(), f.clone(), f]))
        } else {
            None
        };
        let t0 = cfg.theta0;
        let params = ParamSet::new(["K", "B", "tau0"], vec![t0.k, t0.b, t0.tau0])
            .map_err(|e| AppError::Invalid(e.to_string()))?;
        // Vector forgetting forgets K and B, not the offset, in its symmetric form.
        let spec = EstimatorSpec {
            lambda: cfg.lambda,
            lambdas: Some(vec![cfg.lambda, cfg.lambda, 1.0]),
            vf_variant: VfVariant::Symmetric,
            p0: CovSpec::Scaled(cfg.p0),
            ..EstimatorSpec::new(cfg.method.method())
        };
        let est = build_linear(&spec, &params, &params.all_free())
            .map_err(AppError::estim("estimator configuration"))?;
        let est = if cfg.supervise {
            // The estimator's own memory (λ): what it forgets, the ranking forgets; rows scaled
            // by the healthy values.
            let sup = SupervisorConfig::for_lambda(cfg.lambda);
            let scale = vec![
                cfg.healthy.k.abs().max(1e-12),
                cfg.healthy.b.abs().max(1e-12),
                1.0,
            ];
            let s = ExcitationSupervisor::new(est, scale, sup)
                .map_err(|e| AppError::Invalid(format!("excitation supervisor: {e}")))?;
            Estimator::Supervised(Box::new(s))
        } else {
            Estimator::Plain(Box::new(est))
        };
        let dwell = cfg.dwell.max(1);
        let det = RelativeErrorDetector::new(
            vec!["K".into(), "B".into()],
            vec![cfg.healthy.k, cfg.healthy.b],
            vec![cfg.bound, cfg.bound],
            dwell,
        )
        .map_err(AppError::estim("detector configuration"))?;
        let latency = filters.as_ref().map_or(0, |f| f[0].latency());
        Ok(Self {
            every: ((rate_hz / cfg.rate_hz).round() as usize).max(1),
            cfg: cfg.clone(),
            filters,
            times: VecDeque::with_capacity(latency + FILE_CHUNK),
            speeds: VecDeque::with_capacity(latency + FILE_CHUNK),
            t0: None,
            next: 0,
            est,
            det,
            det_times: VecDeque::with_capacity(dwell as usize + 1),
            held: [false; 3],
            differs_since: [None; 3],
            model: Shaft::new(true),
            raw: Default::default(),
            filtered: Default::default(),
        })
    }

    /// The reported frozen state at time `t` (see [`ShaftSample::frozen`]).
    fn held(&mut self, t: f64) -> [bool; 3] {
        let now = self.est.frozen();
        for ((held, since), now) in self.held.iter_mut().zip(&mut self.differs_since).zip(now) {
            if now == *held {
                *since = None;
            } else if t - *since.get_or_insert(t) >= FREEZE_HOLD_S {
                *held = now;
                *since = None;
            }
        }
        self.held
    }

    /// The most input samples between a sample's arrival and its estimate: the low-pass's
    /// block and lookahead ([`ZeroPhaseStream::latency`]), 0 without a low-pass.
    pub fn latency(&self) -> usize {
        self.filters.as_ref().map_or(0, |f| f[0].latency())
    }

    /// The current K, B, τ0 (a frozen one at its value when it was frozen).
    pub fn estimate(&self) -> ShaftParams {
        let e = self.est.get();
        let mut th = [0.0; 3];
        th.copy_from_slice(e.params().nominal());
        e.free_set().scatter(e.estimate(), &mut th);
        ShaftParams {
            k: th[0],
            b: th[1],
            tau0: th[2],
        }
    }

    /// Whether the data have resolved K, B and τ0 so far: the variance of each free one has
    /// at least halved from P0 ([`physid_estim::resolution`]); a frozen one keeps its value.
    /// Data of no information (every shaft channel scaled by 1e-300: φφᵀ underflows) leave
    /// the estimates at their start, which is no finding about the shaft. Allocation-free.
    pub fn resolved(&self) -> [bool; 3] {
        let e = self.est.get();
        let mut r = [true; 3];
        for (k, &i) in e.free_set().free().iter().enumerate() {
            r[i] = e.variance_ratio(k) < physid_estim::resolution::MAX_VARIANCE_RATIO;
        }
        r
    }

    /// Their standard errors (NaN before they can be estimated, and while frozen).
    pub fn std_err(&self) -> ShaftParams {
        let e = self.est.get();
        let n = e.free_set().free().len();
        let mut free = [0.0; 3];
        let mut se = [f64::NAN; 3];
        if e.std_errors_into(&mut free[..n]).is_ok() {
            e.free_set().scatter(&free[..n], &mut se);
        }
        ShaftParams {
            k: se[0],
            b: se[1],
            tau0: se[2],
        }
    }

    /// Take a chunk; append the estimator samples and alarms it completes. A chunk with
    /// columns of different lengths or a non-finite sample is refused, naming the sample.
    pub fn push(
        &mut self,
        x: &ShaftInputs,
        samples: &mut Vec<ShaftSample>,
        alarms: &mut Vec<ShaftAlarm>,
    ) -> Result<(), AppError> {
        let n = x.t.len();
        let cols = [
            x.theta_dy,
            x.theta_en,
            x.omega_dy,
            x.omega_en,
            x.torque_shaft,
        ];
        if cols.iter().any(|c| c.len() != n) {
            return Err(AppError::Invalid(
                "a chunk's channels have different lengths".into(),
            ));
        }
        if self.t0.is_none() {
            self.t0 = x.t.first().copied();
        }
        for r in &mut self.raw {
            r.clear();
        }
        self.raw[0].extend(x.theta_dy.iter().zip(x.theta_en).map(|(a, b)| a - b));
        self.raw[1].extend(x.omega_dy.iter().zip(x.omega_en).map(|(a, b)| a - b));
        self.raw[2].extend_from_slice(x.torque_shaft);
        let first = self.next + self.times.len();
        if let Some(i) = self
            .raw
            .iter()
            .flat_map(|r| r.iter().enumerate())
            .find(|(_, v)| !v.is_finite())
            .map(|(i, _)| i)
        {
            return Err(AppError::Invalid(format!(
                "sample {}: a shaft signal is not finite",
                first + i
            )));
        }
        self.times.extend(x.t);
        self.speeds.extend(x.omega_en);
        for f in &mut self.filtered {
            f.clear();
        }
        match &mut self.filters {
            Some(filters) => {
                for ((f, r), o) in filters.iter_mut().zip(&self.raw).zip(&mut self.filtered) {
                    f.push(r, o).map_err(|e| AppError::Invalid(e.to_string()))?;
                }
            }
            None => {
                for (r, o) in self.raw.iter().zip(&mut self.filtered) {
                    o.extend_from_slice(r);
                }
            }
        }
        self.consume(samples, alarms)
    }

    /// The end of the stream: the last samples out of the filters.
    pub fn finish(
        &mut self,
        samples: &mut Vec<ShaftSample>,
        alarms: &mut Vec<ShaftAlarm>,
    ) -> Result<(), AppError> {
        for f in &mut self.filtered {
            f.clear();
        }
        if let Some(filters) = &mut self.filters {
            for (f, o) in filters.iter_mut().zip(&mut self.filtered) {
                f.finish(o).map_err(|e| AppError::Invalid(e.to_string()))?;
            }
        }
        self.consume(samples, alarms)
    }

    /// Estimator updates at the filtered samples on the estimator's grid.
    fn consume(
        &mut self,
        samples: &mut Vec<ShaftSample>,
        alarms: &mut Vec<ShaftAlarm>,
    ) -> Result<(), AppError> {
        let mut phi = [0.0; 3];
        let t0 = self.t0.unwrap_or(0.0);
        for k in 0..self.filtered[0].len() {
            let [dth, dw, tq] = &self.filtered;
            let i = self.next;
            self.next += 1;
            let t = self.times.pop_front().unwrap_or(f64::NAN);
            let speed = self.speeds.pop_front().unwrap_or(f64::NAN);
            if !i.is_multiple_of(self.every) {
                continue;
            }
            // A shaft that does not turn resolves no damping and drifts the estimator's
            // memory: the estimates and the alarm detector are held until it turns again.
            let standstill = speed.abs() < STANDSTILL_RAD_S;
            if !standstill {
                self.model.regressor(&[dth[k], 0.0, dw[k], 0.0], &mut phi);
                self.est.update(&phi, tq[k], i)?;
            }
            let (estimate, se) = (self.estimate(), self.std_err());
            samples.push(ShaftSample {
                index: i,
                t_s: t,
                estimate,
                std_err: PerParam { k: se.k, b: se.b },
                frozen: if standstill { [true; 3] } else { self.held(t) },
            });
            // The detector waits for data that resolve K and B (an unresolved estimate is its
            // starting value, not the shaft's).
            let [rk, rb, _] = self.resolved();
            if !standstill && t - t0 >= self.cfg.settle_s && rk && rb {
                if self.det_times.len() > self.cfg.dwell.max(1) as usize {
                    self.det_times.pop_front();
                }
                self.det_times.push_back(t);
                let before = self.det.alarms().len();
                self.det
                    .update(&[estimate.k, estimate.b])
                    .map_err(|e| AppError::Estim {
                        at: format!("sample {i}"),
                        source: e,
                    })?;
                for a in &self.det.alarms()[before..] {
                    let back = (a.raised_sample - a.onset_sample) as usize;
                    let at = self.det_times.len() - 1;
                    alarms.push(ShaftAlarm {
                        param: a.name.clone(),
                        t_start_s: self.det_times[at.saturating_sub(back)],
                        t_raised_s: t,
                        relative_error: a.relative_error,
                        change: -a.relative_error,
                    });
                }
            }
        }
        Ok(())
    }
}

/// What `physid monitor shaft --json` prints (and the demo's summary holds per method).
#[derive(Debug, Clone, Serialize)]
pub struct ShaftSummary<'a> {
    /// The method.
    pub method: &'static str,
    /// Final K, B, τ0.
    #[serde(rename = "final")]
    pub final_estimate: ShaftParams,
    /// Their standard errors (null before they can be estimated, and for those unresolved).
    pub std_err: ShaftParams,
    /// The parameters the data did not resolve (absent when all were).
    #[serde(skip_serializing_if = "<[_]>::is_empty")]
    pub unresolved: &'a [&'static str],
    /// What makes the estimates suspect (absent when nothing does).
    #[serde(skip_serializing_if = "<[_]>::is_empty")]
    pub warnings: &'a [String],
    /// The alarms.
    pub alarms: &'a [ShaftAlarm],
    /// NMSE (Eq. 6.4) of the tracks against the truth (simulated data).
    pub nmse: Option<PerParam>,
    /// With the excitation supervisor: how long K and B were frozen [s].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frozen_s: Option<PerParam>,
}

impl ShaftMonitor {
    /// The result without its tracks.
    pub fn summary(&self) -> ShaftSummary<'_> {
        ShaftSummary {
            method: self.method,
            final_estimate: self.final_estimate,
            std_err: self.final_std_err,
            unresolved: &self.unresolved,
            warnings: &self.warnings,
            alarms: &self.alarms,
            nmse: self.nmse,
            frozen_s: self.frozen_s,
        }
    }
}

/// A crank-angle recording (one sample per crank step, so its time step follows the speed) on
/// a uniform time basis at its mean sample rate ([`mean_rate`]), as the monitor takes it;
/// `None` for a recording already on a time basis.
pub fn on_time_basis(rec: &Recording) -> Result<Option<Recording>, AppError> {
    if rec.basis != Basis::CrankAngle {
        return Ok(None);
    }
    let t = rec.values("t")?;
    let rate = mean_rate(
        t.len(),
        t.first().copied().unwrap_or(f64::NAN),
        t.last().copied().unwrap_or(f64::NAN),
    )?;
    Ok(Some(to_time_basis(rec, rate)?))
}

/// The mean sample rate [Hz] of a crank-angle recording's `n` samples of `t`, from `first` to
/// `last`: `(n − 1)/(last − first)` — what [`on_time_basis`] puts it on, and what a stream
/// takes from a first pass over `t` alone.
pub fn mean_rate(n: usize, first: f64, last: f64) -> Result<f64, AppError> {
    let span = last - first;
    if n < 2 || span.is_nan() || span <= 0.0 {
        return Err(AppError::Invalid(
            "a crank-angle recording whose time 't' does not advance cannot be put on a time basis"
                .into(),
        ));
    }
    Ok((n - 1) as f64 / span)
}

/// The mean sample rate ([`mean_rate`]) of the crank-angle file `path`, read with `opts`: a
/// pass over its `t` alone (and `anchor`, another of its channels — an MDF4 file finds `t`'s
/// channel group by it).
pub fn file_mean_rate(
    path: &std::path::Path,
    opts: &physid_io::ReadOptions,
    anchor: &str,
) -> Result<f64, AppError> {
    let opts = physid_io::ReadOptions {
        channels: Some(vec!["t".into(), anchor.into()]),
        ..opts.clone()
    };
    let (mut n, mut first, mut last) = (0, f64::NAN, f64::NAN);
    for chunk in physid_io::ChunkReader::open(path, &opts)? {
        let chunk = chunk?;
        let t = chunk.values("t")?;
        if n == 0 {
            first = t.first().copied().unwrap_or(f64::NAN);
        }
        last = t.last().copied().unwrap_or(last);
        n += t.len();
    }
    mean_rate(n, first, last)
}

/// The channels the monitor reads: its inputs, then the simulated truth when the recording
/// carries it.
pub const SHAFT_CHANNELS: [&str; 6] = [
    "t",
    "theta_dy",
    "theta_en",
    "omega_dy",
    "omega_en",
    "torque_shaft",
];
/// The true K and B of a simulated recording (optional).
pub const SHAFT_TRUTH: [&str; 2] = ["true_shaft_k", "true_shaft_b"];

/// Estimator samples kept in a [`ShaftMonitor`]'s tracks: beyond this, every other one is
/// dropped (the tracks' step doubles), so a long recording's tracks take bounded memory
/// (2¹⁷ samples: 65 s at the default 2 kHz in full). The alarms, the NMSE, the ±5 % times and
/// the frozen time are taken on every sample all the same.
pub const TRACK_MAX: usize = 1 << 17;

/// Run the monitor on a time-basis recording with `theta_dy`, `theta_en`, `omega_dy`,
/// `omega_en`, `torque_shaft` and `t` (and `true_shaft_k`/`true_shaft_b` if simulated).
///
/// A crank-angle recording (one sample per crank step, so its time step follows the speed) is
/// first resampled to a uniform time basis at its mean sample rate.
pub fn monitor_shaft(rec: &Recording, cfg: &MonitorConfig) -> Result<ShaftMonitor, AppError> {
    let resampled = on_time_basis(rec)?;
    let rec = resampled.as_ref().unwrap_or(rec);
    let n = rec.len();
    let chunks = (0..n.max(1))
        .step_by(FILE_CHUNK)
        .map(|start| Ok::<_, AppError>(rec.slice(start..start + FILE_CHUNK)));
    monitor_shaft_stream(chunks, cfg)
}

/// The monitor over a stream of time-basis chunks (a file read as it comes,
/// `physid_io::ChunkReader`): the stage the live service runs, with what the file verb reports
/// accumulated as the samples pass — memory bounded however long the stream ([`TRACK_MAX`]).
/// The sample rate is the mean step of the first [`NOMINAL_SAMPLES`] samples (held until they
/// have come, however the stream is chunked); every step is held to it within 0.1 %.
pub fn monitor_shaft_stream<E>(
    chunks: impl IntoIterator<Item = Result<Recording, E>>,
    cfg: &MonitorConfig,
) -> Result<ShaftMonitor, AppError>
where
    AppError: From<E>,
{
    monitor_shaft_tracked(chunks, cfg, &mut |_, _| Ok(()))
}

/// What a [`monitor_shaft_tracked`] run hands on as it goes: the estimator samples just taken
/// (every one, not thinned) and the alarms raised so far; an `Err` stops the run with it.
pub type ShaftSink<'a> = dyn FnMut(&[ShaftSample], &[ShaftAlarm]) -> Result<(), String> + 'a;

/// [`monitor_shaft_stream`], every estimator sample handed to `sink` as it is taken (the
/// tracks written to a file as they come: `monitor shaft --tracks`).
pub fn monitor_shaft_tracked<E>(
    chunks: impl IntoIterator<Item = Result<Recording, E>>,
    cfg: &MonitorConfig,
    sink: &mut ShaftSink,
) -> Result<ShaftMonitor, AppError>
where
    AppError: From<E>,
{
    let mut chunks = chunks.into_iter();
    // The first samples, enough to know the rate.
    let mut first: Option<Recording> = None;
    while first.as_ref().map_or(0, Recording::len) < NOMINAL_SAMPLES {
        let Some(next) = chunks.next() else {
            break;
        };
        let next = next?;
        first = Some(match first.take() {
            None => next,
            Some(mut f) => {
                f.append(&next)?;
                f
            }
        });
    }
    let first = first.unwrap_or_else(|| Recording::new(Basis::Time));
    let t = ShaftInputs::of(&first)?.t;
    if t.len() < 100 {
        return Err(AppError::Invalid(format!(
            "{} samples: the monitor needs at least 100",
            t.len()
        )));
    }
    let dt = uniform_step(&t[..t.len().min(NOMINAL_SAMPLES)])?;
    let mut acc = Accumulated::new(cfg, t[0], dt)?;
    acc.push(&first, sink)?;
    for chunk in chunks {
        acc.push(&chunk?, sink)?;
    }
    acc.finish(sink)
}

/// Whether an estimate has stayed within ±5 % of the truth, as the samples pass.
#[derive(Debug, Clone, Copy)]
enum Within {
    /// Never outside so far.
    Always,
    /// Outside at the last sample.
    Out,
    /// Inside since this time [s].
    Since(f64),
}

impl Within {
    fn step(self, t: f64, inside: bool) -> Self {
        match (self, inside) {
            (_, false) => Self::Out,
            (Self::Out, true) => Self::Since(t),
            (s, true) => s,
        }
    }

    fn time(self, t_first: f64) -> Option<f64> {
        match self {
            Self::Always => Some(t_first),
            Self::Out => None,
            Self::Since(t) => Some(t),
        }
    }
}

/// The file verb's view of a stage's samples, accumulated as they pass.
struct Accumulated {
    cfg: MonitorConfig,
    stage: ShaftStage,
    t0: f64,
    dt: f64,
    /// Input samples seen; the previous input time.
    seen: usize,
    t_prev: Option<f64>,
    samples: Vec<ShaftSample>,
    alarms: Vec<ShaftAlarm>,
    out: ShaftMonitor,
    /// Estimator samples taken; one in `stride` is kept in the tracks.
    taken: usize,
    stride: usize,
    /// Truth of the input samples not yet reached by the stage's output: `(first index, K, B)`.
    truth: Option<(usize, VecDeque<(f64, f64)>)>,
    /// Sums for the NMSE (Eq. 6.4) after settling: n, Σ(y−ŷ)², Σy, Σŷ per parameter.
    sums: [(f64, f64, f64, f64); 2],
    within: [Within; 2],
    t_first: Option<f64>,
    frozen_count: [usize; 2],
    /// Each angle and its speed, checked as they pass (from the first chunk).
    speed_angle: Option<Vec<SpeedAngle>>,
}

impl Accumulated {
    fn new(cfg: &MonitorConfig, t0: f64, dt: f64) -> Result<Self, AppError> {
        let stage = ShaftStage::new(cfg, 1.0 / dt)?;
        Ok(Self {
            cfg: cfg.clone(),
            t0,
            dt,
            seen: 0,
            t_prev: None,
            samples: Vec::with_capacity(FILE_CHUNK),
            alarms: Vec::new(),
            out: ShaftMonitor {
                method: cfg.method.name(),
                input_rate_hz: 1.0 / dt,
                lowpass_hz: stage.filters.is_some().then_some(cfg.cutoff_hz),
                every: stage.every,
                t: Vec::new(),
                k: Vec::new(),
                b: Vec::new(),
                tau0: Vec::new(),
                std_err: Vec::new(),
                final_estimate: cfg.theta0,
                final_std_err: cfg.theta0,
                unresolved: Vec::new(),
                warnings: Vec::new(),
                alarms: Vec::new(),
                truth: None,
                nmse: None,
                within_5pct_s: None,
                frozen_s: None,
                frozen: Vec::new(),
            },
            stage,
            taken: 0,
            stride: 1,
            truth: None,
            sums: [(0.0, 0.0, 0.0, 0.0); 2],
            within: [Within::Always; 2],
            t_first: None,
            frozen_count: [0; 2],
            speed_angle: None,
        })
    }

    fn push(&mut self, chunk: &Recording, sink: &mut ShaftSink) -> Result<(), AppError> {
        let x = ShaftInputs::of(chunk)?;
        for p in self
            .speed_angle
            .get_or_insert_with(|| SpeedAngle::pairs(chunk, &[]))
        {
            p.push(chunk);
        }
        // The step held to the first chunks' rate, across chunk boundaries too.
        for (i, &now) in x.t.iter().enumerate() {
            if let Some(before) = self.t_prev {
                if ((now - before) - self.dt).abs() > 1e-3 * self.dt {
                    return Err(AppError::Invalid(format!(
                        "the time step is not uniform at sample {} ({} s, mean {} s): check with physid inspect, resample with physid convert --time-basis HZ",
                        self.seen + i,
                        now - before,
                        self.dt
                    )));
                }
            }
            self.t_prev = Some(now);
        }
        if let (Ok(tk), Ok(tb)) = (chunk.values(SHAFT_TRUTH[0]), chunk.values(SHAFT_TRUTH[1])) {
            let (_, q) = self
                .truth
                .get_or_insert_with(|| (self.seen, VecDeque::new()));
            q.extend(tk.iter().copied().zip(tb.iter().copied()));
        }
        self.seen += x.t.len();
        self.stage.push(&x, &mut self.samples, &mut self.alarms)?;
        sink(&self.samples, &self.alarms).map_err(AppError::Invalid)?;
        self.take();
        Ok(())
    }

    /// The stage's new samples into the tracks and sums.
    fn take(&mut self) {
        let samples = std::mem::take(&mut self.samples);
        for s in &samples {
            self.t_first.get_or_insert(s.t_s);
            for j in 0..2 {
                if s.frozen[j] {
                    self.frozen_count[j] += 1;
                }
            }
            let truth = self.truth.as_mut().and_then(|(base, q)| {
                while *base < s.index && !q.is_empty() {
                    q.pop_front();
                    *base += 1;
                }
                q.front().copied().filter(|_| *base == s.index)
            });
            if let Some((k, b)) = truth {
                let est = [s.estimate.k, s.estimate.b];
                for (j, truth) in [k, b].into_iter().enumerate() {
                    let outside = ((est[j] - truth) / truth).abs() > 0.05;
                    self.within[j] = self.within[j].step(s.t_s, !outside);
                    if s.t_s - self.t0 >= self.cfg.settle_s {
                        let m = &mut self.sums[j];
                        m.0 += 1.0;
                        m.1 += (truth - est[j]) * (truth - est[j]);
                        m.2 += truth;
                        m.3 += est[j];
                    }
                }
            }
            if self.taken.is_multiple_of(self.stride) {
                let o = &mut self.out;
                o.t.push(s.t_s);
                o.k.push(s.estimate.k);
                o.b.push(s.estimate.b);
                o.tau0.push(s.estimate.tau0);
                o.std_err.push([s.std_err.k, s.std_err.b]);
                if self.cfg.supervise {
                    o.frozen.push(s.frozen);
                }
                if let Some((k, b)) = truth {
                    let (tk, tb) = o.truth.get_or_insert_with(Default::default);
                    tk.push(k);
                    tb.push(b);
                }
                if o.t.len() > TRACK_MAX {
                    self.thin();
                }
            }
            self.taken += 1;
        }
        self.samples = samples;
        self.samples.clear();
    }

    /// Every other sample of the tracks dropped; the step doubles.
    fn thin(&mut self) {
        use crate::halve;
        let o = &mut self.out;
        halve(&mut o.t);
        halve(&mut o.k);
        halve(&mut o.b);
        halve(&mut o.tau0);
        halve(&mut o.std_err);
        halve(&mut o.frozen);
        if let Some((tk, tb)) = &mut o.truth {
            halve(tk);
            halve(tb);
        }
        self.stride *= 2;
    }

    fn finish(mut self, sink: &mut ShaftSink) -> Result<ShaftMonitor, AppError> {
        self.stage.finish(&mut self.samples, &mut self.alarms)?;
        sink(&self.samples, &self.alarms).map_err(AppError::Invalid)?;
        self.take();
        let mut out = self.out;
        out.final_estimate = self.stage.estimate();
        out.final_std_err = self.stage.std_err();
        let resolved = self.stage.resolved();
        for ((name, r), se) in ["K", "B", "tau0"].into_iter().zip(resolved).zip([
            &mut out.final_std_err.k,
            &mut out.final_std_err.b,
            &mut out.final_std_err.tau0,
        ]) {
            if !r {
                out.unresolved.push(name);
                *se = f64::NAN;
            }
        }
        out.alarms = self.alarms;
        out.warnings = self
            .speed_angle
            .iter()
            .flatten()
            .filter_map(SpeedAngle::finding)
            .collect();
        if self.cfg.supervise {
            let step = 1.0 / self.cfg.rate_hz;
            out.frozen_s = Some(PerParam {
                k: self.frozen_count[0] as f64 * step,
                b: self.frozen_count[1] as f64 * step,
            });
        }
        if out.truth.is_some() {
            // NMSE (Eq. 6.4) of each track against the truth after settling.
            let nmse = |(n, sq, y, p): (f64, f64, f64, f64)| {
                let den = (y / n) * (p / n);
                if n > 0.0 && den != 0.0 {
                    (sq / n) / den
                } else {
                    f64::NAN
                }
            };
            out.nmse = Some(PerParam {
                k: nmse(self.sums[0]),
                b: nmse(self.sums[1]),
            });
            let t_first = self.t_first.unwrap_or(self.t0);
            out.within_5pct_s = Some([self.within[0].time(t_first), self.within[1].time(t_first)]);
        }
        Ok(out)
    }
}
