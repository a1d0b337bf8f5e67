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
use physid_core::{Basis, ParamSet, Recording};
use physid_estim::{
    Alarm, CovSpec, EstimatorConfig, LinearEstimator, Method, RelativeErrorDetector, VfVariant,
};
use physid_models::shaft::{Shaft, NOMINAL};
use physid_signal::filter::{butter, Band};
use serde::Serialize;

/// The estimator.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum MonitorMethod {
    /// Recursive least squares with exponential forgetting λ.
    Rls,
    /// Vector forgetting: λ on K and B, 1 on the offset.
    Rlsvf,
    /// The square-root form (Alg. 5.5).
    Dsfc,
}

impl MonitorMethod {
    /// Parse `rls|rlsvf|dsfc`.
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "rls" => Some(Self::Rls),
            "rlsvf" => Some(Self::Rlsvf),
            "dsfc" => Some(Self::Dsfc),
            _ => None,
        }
    }

    /// The name (`rls`, `rlsvf`, `dsfc`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Rls => "rls",
            Self::Rlsvf => "rlsvf",
            Self::Dsfc => "dsfc",
        }
    }
}

impl std::str::FromStr for MonitorMethod {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::parse(s).ok_or_else(|| format!("'{s}': expected rls, rlsvf or dsfc"))
    }
}

/// How to monitor.
#[derive(Debug, Clone)]
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
}

impl Default for MonitorConfig {
    /// λ = 0.98, ϑ0 = 0, P0 = 1000·I (thesis ch. 6), healthy = Table 6.1's yellow spider,
    /// ±10 %, 0.1 s dwell, 500 Hz low-pass, 2 kHz estimator rate, 1 s settling.
    fn default() -> Self {
        Self {
            method: MonitorMethod::Rls,
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
        }
    }
}

/// The coupling shaft's parameters by name (JSON: `K`, `B`, `tau0`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
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
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
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
    /// The relative error then.
    pub relative_error: f64,
}

/// The monitor's result.
#[derive(Debug, Clone, Serialize)]
pub struct ShaftMonitor {
    /// The method.
    pub method: &'static str,
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
    /// Final standard errors of K, B, τ0 (NaN before they can be estimated).
    pub final_std_err: ShaftParams,
    /// Alarms.
    pub alarms: Vec<ShaftAlarm>,
    /// True K and B over time, when the recording carries them (simulated data).
    pub truth: Option<(Vec<f64>, Vec<f64>)>,
    /// NMSE of the K and B tracks against the truth after settling (thesis Fig. 6.9).
    pub nmse: Option<PerParam>,
    /// First time after which the estimates stay within ±5 % of the truth [s], per parameter.
    pub within_5pct_s: Option<[Option<f64>; 2]>,
}

/// What `physid monitor shaft --json` prints (and the demo's summary holds per method).
#[derive(Debug, Clone, Serialize)]
pub struct ShaftSummary<'a> {
    /// The method.
    pub method: &'static str,
    /// Final K, B, τ0.
    #[serde(rename = "final")]
    pub final_estimate: ShaftParams,
    /// Their standard errors (null before they can be estimated).
    pub std_err: ShaftParams,
    /// The alarms.
    pub alarms: &'a [ShaftAlarm],
    /// NMSE (Eq. 6.4) of the tracks against the truth (simulated data).
    pub nmse: Option<PerParam>,
}

impl ShaftMonitor {
    /// The result without its tracks.
    pub fn summary(&self) -> ShaftSummary<'_> {
        ShaftSummary {
            method: self.method,
            final_estimate: self.final_estimate,
            std_err: self.final_std_err,
            alarms: &self.alarms,
            nmse: self.nmse,
        }
    }
}

/// Run the monitor on a time-basis recording with `theta_dy`, `theta_en`, `omega_dy`,
/// `omega_en`, `torque_shaft` and `t` (and `true_shaft_k`/`true_shaft_b` if simulated).
///
/// A crank-angle recording (one sample per crank step, so its time step follows the speed) is
/// first resampled to a uniform time basis at its mean sample rate.
pub fn monitor_shaft(rec: &Recording, cfg: &MonitorConfig) -> Result<ShaftMonitor, AppError> {
    let resampled;
    let rec = if rec.basis == Basis::CrankAngle {
        let t = rec.values("t")?;
        let span = t.last().copied().unwrap_or(0.0) - t.first().copied().unwrap_or(0.0);
        if t.len() < 2 || span.is_nan() || span <= 0.0 {
            return Err(AppError::Invalid(
                "a crank-angle recording whose time 't' does not advance cannot be put on a time basis".into(),
            ));
        }
        resampled = to_time_basis(rec, (t.len() - 1) as f64 / span)?;
        &resampled
    } else {
        rec
    };
    let t = rec.values("t")?;
    let get = |n: &str| rec.values(n);
    let (thd, the, wd, we, tq) = (
        get("theta_dy")?,
        get("theta_en")?,
        get("omega_dy")?,
        get("omega_en")?,
        get("torque_shaft")?,
    );
    if t.len() < 100 {
        return Err(AppError::Invalid(format!(
            "{} samples: the monitor needs at least 100",
            t.len()
        )));
    }
    let dt = uniform_step(t)?;
    let fs = 1.0 / dt;
    let dth: Vec<f64> = thd.iter().zip(the).map(|(a, b)| a - b).collect();
    let dw: Vec<f64> = wd.iter().zip(we).map(|(a, b)| a - b).collect();
    // Zero-phase prefilter (if the cut-off is below Nyquist).
    let (dth, dw, tq) = if cfg.cutoff_hz < fs / 2.0 {
        let sos = butter(4, &[cfg.cutoff_hz], Band::Lowpass, fs)
            .map_err(|e| AppError::Invalid(e.to_string()))?
            .to_sos();
        let f = |x: &[f64]| {
            sos.sosfiltfilt(x)
                .map_err(|e| AppError::Invalid(e.to_string()))
        };
        (f(&dth)?, f(&dw)?, f(tq)?)
    } else {
        (dth, dw, tq.to_vec())
    };
    let every = ((fs / cfg.rate_hz).round() as usize).max(1);
    let t0 = cfg.theta0;
    let params = ParamSet::new(["K", "B", "tau0"], vec![t0.k, t0.b, t0.tau0])
        .map_err(|e| AppError::Invalid(e.to_string()))?;
    let method = match cfg.method {
        MonitorMethod::Rls => Method::Rlsf { lambda: cfg.lambda },
        MonitorMethod::Rlsvf => Method::Rlsvf {
            lambdas: vec![cfg.lambda, cfg.lambda, 1.0],
            variant: VfVariant::Symmetric,
        },
        MonitorMethod::Dsfc => Method::Dsfc { lambda: cfg.lambda },
    };
    let config = EstimatorConfig {
        p0: CovSpec::Scaled(cfg.p0),
        ..EstimatorConfig::new(method)
    };
    let mut est = LinearEstimator::new(&config, &params, &params.all_free())
        .map_err(AppError::estim("estimator configuration"))?;
    let mut det = RelativeErrorDetector::new(
        vec!["K".into(), "B".into()],
        vec![cfg.healthy.k, cfg.healthy.b],
        vec![cfg.bound, cfg.bound],
        cfg.dwell.max(1),
    )
    .map_err(AppError::estim("detector configuration"))?;
    let model = Shaft::new(true);
    let mut phi = [0.0; 3];
    let mut out = ShaftMonitor {
        method: cfg.method.name(),
        t: Vec::new(),
        k: Vec::new(),
        b: Vec::new(),
        tau0: Vec::new(),
        std_err: Vec::new(),
        final_estimate: ShaftParams {
            k: 0.0,
            b: 0.0,
            tau0: 0.0,
        },
        final_std_err: ShaftParams {
            k: f64::NAN,
            b: f64::NAN,
            tau0: f64::NAN,
        },
        alarms: Vec::new(),
        truth: None,
        nmse: None,
        within_5pct_s: None,
    };
    let mut se = [0.0; 3];
    let mut det_t0 = None;
    for i in (0..t.len()).step_by(every) {
        model.regressor(&[dth[i], 0.0, dw[i], 0.0], &mut phi);
        est.update(&phi, tq[i])
            .map_err(AppError::estim(format!("sample {i}")))?;
        let th = est.estimate();
        if est.std_errors_into(&mut se).is_err() {
            se = [f64::NAN; 3];
        }
        out.t.push(t[i]);
        out.k.push(th[0]);
        out.b.push(th[1]);
        out.tau0.push(th[2]);
        out.std_err.push([se[0], se[1]]);
        if t[i] - t[0] >= cfg.settle_s {
            if det_t0.is_none() {
                det_t0 = Some(out.t.len() - 1);
            }
            det.update(&th[..2])
                .map_err(AppError::estim(format!("sample {i}")))?;
        }
    }
    let th = est.estimate();
    out.final_estimate = ShaftParams {
        k: th[0],
        b: th[1],
        tau0: th[2],
    };
    if est.std_errors_into(&mut se).is_ok() {
        out.final_std_err = ShaftParams {
            k: se[0],
            b: se[1],
            tau0: se[2],
        };
    }
    let first = det_t0.unwrap_or(0);
    out.alarms = det
        .alarms()
        .iter()
        .map(|a: &Alarm| ShaftAlarm {
            param: a.name.clone(),
            t_start_s: out.t[(first + a.onset_sample as usize).min(out.t.len() - 1)],
            t_raised_s: out.t[(first + a.raised_sample as usize).min(out.t.len() - 1)],
            relative_error: a.relative_error,
        })
        .collect();
    if let (Ok(tk), Ok(tb)) = (rec.values("true_shaft_k"), rec.values("true_shaft_b")) {
        let idx: Vec<usize> = (0..t.len()).step_by(every).collect();
        let k_true: Vec<f64> = idx.iter().map(|&i| tk[i]).collect();
        let b_true: Vec<f64> = idx.iter().map(|&i| tb[i]).collect();
        let start = out
            .t
            .iter()
            .position(|&x| x - t[0] >= cfg.settle_s)
            .unwrap_or(0);
        // NMSE (Eq. 6.4) of each track against the truth after settling.
        let nmse = |truth: &[f64], est: &[f64]| {
            physid_estim::metrics::nmse(&truth[start..], &est[start..]).unwrap_or(f64::NAN)
        };
        let within = |truth: &[f64], est: &[f64]| {
            let last_out = truth
                .iter()
                .zip(est)
                .rposition(|(a, b)| ((b - a) / a).abs() > 0.05);
            match last_out {
                None => Some(out.t[0]),
                Some(j) if j + 1 < out.t.len() => Some(out.t[j + 1]),
                _ => None,
            }
        };
        out.nmse = Some(PerParam {
            k: nmse(&k_true, &out.k),
            b: nmse(&b_true, &out.b),
        });
        out.within_5pct_s = Some([within(&k_true, &out.k), within(&b_true, &out.b)]);
        out.truth = Some((k_true, b_true));
    }
    Ok(out)
}
