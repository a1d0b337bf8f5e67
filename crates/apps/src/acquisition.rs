//! The thesis's acquisition chain on a [`Recording`] (ch. 4, SPEC §2.7): inspection with the
//! post-run integrity check, conversion between a time basis and one sample per crank
//! degree, zero-phase filtering of chosen channels. The `physid inspect`, `convert` and
//! `filter` verbs are thin wrappers over these.

use physid_core::{Basis, Channel, Recording, RecordingError};
use physid_signal::crank::{crank_grid, interp};
use physid_signal::encoder::{first_marker, Encoder};
use physid_signal::filter::{butter, Band, FilterError};
use physid_signal::integrity::{check, median_step, Integrity, IntegrityOptions};
use serde::Serialize;
use std::f64::consts::PI;
use thiserror::Error;

/// Errors of the acquisition functions.
#[derive(Debug, Error)]
pub enum AcquisitionError {
    /// A channel problem.
    #[error(transparent)]
    Recording(#[from] RecordingError),
    /// A filter problem, with the channel.
    #[error("channel '{channel}': {source}")]
    Filter {
        /// The channel.
        channel: String,
        /// What went wrong.
        source: FilterError,
    },
    /// Anything else, explained.
    #[error("{0}")]
    Invalid(String),
}

/// Where the encoders and the TDC marker are.
#[derive(Debug, Clone)]
pub struct AcquisitionOptions {
    /// Encoder counter channels with their pulses per revolution; the TDC marker belongs to the
    /// first (the engine's).
    pub encoders: Vec<(String, u32)>,
    /// The TDC marker channel.
    pub marker: String,
}

impl Default for AcquisitionOptions {
    /// The thesis's test cell: `count_en` (360 pulses/rev), `count_dy` (1024), marker `tdc`.
    fn default() -> Self {
        Self {
            encoders: vec![("count_en".into(), 360), ("count_dy".into(), 1024)],
            marker: "tdc".into(),
        }
    }
}

/// One channel in the summary.
#[derive(Debug, Clone, Serialize)]
pub struct ChannelSummary {
    /// Name.
    pub name: String,
    /// Unit.
    pub unit: String,
    /// Samples.
    pub samples: usize,
}

/// What `physid inspect` reports.
#[derive(Debug, Clone, Serialize)]
pub struct Inspection {
    /// `time` or `crank_angle`.
    pub basis: &'static str,
    /// The channels.
    pub channels: Vec<ChannelSummary>,
    /// Duration [s] (from `t`), if known.
    pub duration_s: Option<f64>,
    /// Sample rate [Hz] (1 / median interval of `t`) on a time basis.
    pub sample_rate_hz: Option<f64>,
    /// Complete engine cycles (720°): counted from `cycle` on a crank-angle basis, from TDC
    /// markers (two per cycle) on a time basis.
    pub cycles: Option<usize>,
    /// The integrity check.
    pub integrity: Integrity,
}

/// Summarise a recording and check its integrity.
pub fn inspect(rec: &Recording, opts: &AcquisitionOptions) -> Inspection {
    let t = rec.values("t").ok();
    let duration_s = t.and_then(|t| Some(t.last()? - t.first()?));
    let sample_rate_hz = match (rec.basis, t) {
        (Basis::Time, Some(t)) => median_step(t).map(|d| 1.0 / d),
        _ => None,
    };
    let per_cycle = rec.values("crank_deg").ok().and_then(|d| {
        let step = d.windows(2).map(|w| w[1] - w[0]).find(|s| *s > 0.0)?;
        Some((720.0 / step).round() as usize)
    });
    let cycles = match rec.basis {
        Basis::CrankAngle => rec
            .values("cycle")
            .ok()
            .map(|c| complete_cycles(c, per_cycle)),
        Basis::Time => rec.values(&opts.marker).ok().map(|m| {
            let edges = physid_signal::encoder::marker_edges(m).len();
            edges.saturating_sub(1) / 2
        }),
    };
    let integrity = check(
        rec,
        &IntegrityOptions {
            encoders: opts
                .encoders
                .iter()
                .filter(|(n, _)| rec.channel(n).is_ok())
                .cloned()
                .collect(),
            marker: rec.channel(&opts.marker).ok().map(|_| opts.marker.clone()),
            // The marker is the first encoder's (the engine's, by default).
            marker_encoder: opts.encoders.first().map(|e| e.0.clone()),
            samples_per_cycle: per_cycle,
        },
    );
    Inspection {
        basis: match rec.basis {
            Basis::Time => "time",
            Basis::CrankAngle => "crank_angle",
        },
        channels: rec
            .channels()
            .iter()
            .map(|c| ChannelSummary {
                name: c.name.clone(),
                unit: c.unit.clone(),
                samples: c.values.len(),
            })
            .collect(),
        duration_s,
        sample_rate_hz,
        cycles,
        integrity,
    }
}

/// Runs of one cycle index with the full number of samples (or every run if unknown).
fn complete_cycles(cycle: &[f64], per: Option<usize>) -> usize {
    let mut n = 0;
    let mut start = 0;
    while start < cycle.len() {
        let mut end = start;
        while end < cycle.len() && cycle[end] == cycle[start] {
            end += 1;
        }
        if per.is_none_or(|p| end - start == p) {
            n += 1;
        }
        start = end;
    }
    n
}

/// The engine angle of a time-basis recording as strictly increasing `(t, θ)` pairs: from
/// `theta_en` if present, else from the engine encoder's counts at the samples where the count
/// moves on (event-based, as the thesis samples). Also the angle at the first TDC marker
/// (or, without a marker, the first multiple of 720° — the simulator's convention).
fn engine_angle(
    rec: &Recording,
    opts: &AcquisitionOptions,
) -> Result<(Vec<f64>, Vec<f64>, f64), AcquisitionError> {
    let t = rec.values("t")?;
    let (tt, th): (Vec<f64>, Vec<f64>) = if let Ok(theta) = rec.values("theta_en") {
        (t.to_vec(), theta.to_vec())
    } else {
        let (name, ppr) = opts
            .encoders
            .iter()
            .find(|(n, _)| rec.channel(n).is_ok())
            .ok_or_else(|| {
                AcquisitionError::Invalid(format!(
                    "no engine angle: the recording needs 'theta_en' [rad] or an encoder count channel ({}); the channels are {}",
                    opts.encoders.iter().map(|e| e.0.as_str()).collect::<Vec<_>>().join(", "),
                    rec.names().join(", ")
                ))
            })?;
        let counts = rec.values(name)?;
        let enc = Encoder { ppr: *ppr };
        let theta = enc.angle(counts, 0);
        let mut tt = vec![t[0]];
        let mut th = vec![theta[0]];
        for i in 1..counts.len() {
            if counts[i] > counts[i - 1] {
                tt.push(t[i]);
                th.push(theta[i]);
            }
        }
        (tt, th)
    };
    let tdc = match rec.values(&opts.marker).ok().and_then(first_marker) {
        Some(i) => interp(&tt, &th, &[t[i]])[0],
        None => {
            let first = th.first().copied().unwrap_or(0.0);
            (first / (4.0 * PI)).ceil() * 4.0 * PI
        }
    };
    Ok((tt, th, tdc))
}

/// The angle of a firing TDC on the recording's `theta_en` [rad]: its value at the first TDC
/// marker; `None` without `theta_en` or a marker (cycles then start at multiples of 4π, as
/// [`to_crank_angle`] starts them).
pub fn marker_tdc_angle(rec: &Recording, opts: &AcquisitionOptions) -> Option<f64> {
    let theta = rec.values("theta_en").ok()?;
    let i = first_marker(rec.values(&opts.marker).ok()?)?;
    theta.get(i).copied().filter(|v| v.is_finite())
}

/// Resample a time-basis recording to one sample every `step_deg` crank degrees from the
/// first TDC marker: channels `t`, `theta` [rad from TDC], `cycle`, `crank_deg`, then every
/// other channel interpolated (the encoder counts and the marker are left out).
pub fn to_crank_angle(
    rec: &Recording,
    opts: &AcquisitionOptions,
    step_deg: f64,
) -> Result<Recording, AcquisitionError> {
    if rec.basis != Basis::Time {
        return Err(AcquisitionError::Invalid(
            "the recording is already on a crank-angle basis".into(),
        ));
    }
    let t = rec.values("t")?;
    let (tt, th, tdc) = engine_angle(rec, opts)?;
    let grid = crank_grid(&tt, &th, tdc, step_deg)
        .map_err(|e| AcquisitionError::Invalid(e.to_string()))?;
    let mut out = Recording::new(Basis::CrankAngle);
    out.meta = rec.meta.clone();
    out.meta
        .insert("crank_step_deg".into(), format!("{step_deg}"));
    let skip: Vec<&str> = opts
        .encoders
        .iter()
        .map(|e| e.0.as_str())
        .chain([opts.marker.as_str(), "t", "theta_en"])
        .collect();
    for (name, unit, values) in [
        ("t", "s", grid.t.clone()),
        ("theta", "rad", grid.theta.clone()),
        ("cycle", "-", grid.cycle.clone()),
        ("crank_deg", "deg", grid.crank_deg.clone()),
    ] {
        out.push(Channel {
            name: name.into(),
            unit: unit.into(),
            values,
        })?;
    }
    for ch in rec
        .channels()
        .iter()
        .filter(|c| !skip.contains(&c.name.as_str()))
    {
        out.push(Channel {
            name: ch.name.clone(),
            unit: ch.unit.clone(),
            values: interp(t, &ch.values, &grid.t),
        })?;
    }
    Ok(out)
}

/// The sample period [s] of a time channel that must be uniform: the mean step, or an error at
/// the first step more than 0.1 % away from it (what to do about it included).
pub fn uniform_step(t: &[f64]) -> Result<f64, AcquisitionError> {
    if t.len() < 2 {
        return Err(AcquisitionError::Invalid("fewer than 2 samples".into()));
    }
    let dt = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
    match t
        .windows(2)
        .position(|w| ((w[1] - w[0]) - dt).abs() > 1e-3 * dt)
    {
        Some(i) => Err(AcquisitionError::Invalid(format!(
            "the time step is not uniform at sample {} ({} s, mean {dt} s): check with physid inspect, resample with physid convert --time-basis HZ",
            i + 1,
            t[i + 1] - t[i]
        ))),
        None => Ok(dt),
    }
}

/// Resample a crank-angle recording (with its `t` channel) to a uniform time basis at
/// `rate_hz`.
pub fn to_time_basis(rec: &Recording, rate_hz: f64) -> Result<Recording, AcquisitionError> {
    if !(rate_hz.is_finite() && rate_hz > 0.0) {
        return Err(AcquisitionError::Invalid(format!(
            "sample rate {rate_hz} Hz: expected > 0"
        )));
    }
    let t = rec.values("t")?;
    physid_signal::crank::check_increasing(t, "time")
        .map_err(|e| AcquisitionError::Invalid(e.to_string()))?;
    let (t0, t1) = (t[0], t[t.len() - 1]);
    let n = ((t1 - t0) * rate_hz).floor() as usize + 1;
    let grid: Vec<f64> = (0..n).map(|i| t0 + i as f64 / rate_hz).collect();
    let mut out = Recording::new(Basis::Time);
    out.meta = rec.meta.clone();
    out.push(Channel {
        name: "t".into(),
        unit: "s".into(),
        values: grid.clone(),
    })?;
    for ch in rec.channels().iter().filter(|c| c.name != "t") {
        out.push(Channel {
            name: ch.name.clone(),
            unit: ch.unit.clone(),
            values: interp(t, &ch.values, &grid),
        })?;
    }
    Ok(out)
}

/// A zero-phase Butterworth filter for [`filter_channels`].
#[derive(Debug, Clone)]
pub struct FilterSpec {
    /// Band type.
    pub band: Band,
    /// Cut-off(s) [Hz].
    pub cutoff_hz: Vec<f64>,
    /// Order.
    pub order: usize,
    /// Use the transfer function (scipy's `filtfilt`) instead of second-order sections
    /// (`sosfiltfilt`, better conditioned; the default).
    pub transfer_function: bool,
}

/// Filter `channels` of a time-basis recording in place (forward–backward, zero phase); the
/// sample rate is `1/Δt` of its `t` channel, which must be uniform (within 0.1 %).
pub fn filter_channels(
    rec: &mut Recording,
    channels: &[String],
    spec: &FilterSpec,
) -> Result<(), AcquisitionError> {
    if rec.basis != Basis::Time {
        return Err(AcquisitionError::Invalid(
            "zero-phase filtering in Hz needs a time basis: convert the recording first".into(),
        ));
    }
    let dt = uniform_step(rec.values("t")?)?;
    let zpk = butter(spec.order, &spec.cutoff_hz, spec.band, 1.0 / dt).map_err(|source| {
        AcquisitionError::Filter {
            channel: channels.join(", "),
            source,
        }
    })?;
    let (tf, sos) = (zpk.to_ba(), zpk.to_sos());
    let mut filtered = Vec::new();
    for name in channels {
        let x = rec.values(name)?;
        let y = if spec.transfer_function {
            tf.filtfilt(x)
        } else {
            sos.sosfiltfilt(x)
        }
        .map_err(|source| AcquisitionError::Filter {
            channel: name.clone(),
            source,
        })?;
        filtered.push((name.clone(), y));
    }
    for (name, y) in filtered {
        rec.replace_values(&name, y)?;
    }
    Ok(())
}
