//! The events of the live service, one JSON object each with `"type"` and `"t_s"` (the
//! recording's time). The names are stable (docs/live.md).

use physid_apps::shaft_monitor::{PerParam, ShaftAlarm, ShaftSample};
use physid_signal::cycles::CycleSummary;
use physid_signal::integrity::FindingKind;
use serde::Serialize;
use std::collections::BTreeMap;

/// An event.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Event {
    /// An application's estimates now: `{"type": "estimate", "app": "shaft", "t_s": …,
    /// "params": {"K": …, "B": …}, "std_err": {"K": …, "B": …}}`.
    Estimate {
        /// The application (`shaft`).
        app: &'static str,
        /// Recording time [s].
        t_s: f64,
        /// The estimates by name.
        params: PerParam,
        /// Their standard errors (null before they can be estimated).
        std_err: PerParam,
    },
    /// An alarm: `{"type": "alarm", "app": "shaft", "param": "K", "t_s": …, "t_start_s": …,
    /// "relative_error": …, "change": …}` (`t_s` when it was raised, `t_start_s` when the
    /// estimate left its bound; `change` = −`relative_error`, the estimate's change).
    Alarm {
        /// The application.
        app: &'static str,
        /// The parameter that moved.
        param: String,
        /// When the alarm was raised [s].
        t_s: f64,
        /// When the estimate left its bound [s].
        t_start_s: f64,
        /// Its relative error (Eq. 6.3) then.
        relative_error: f64,
        /// The estimate's change from healthy then (−relative error; K fell 12 % → −0.12).
        change: f64,
    },
    /// Which of an application's parameters are estimated now and which are held (frozen):
    /// `{"type": "identifiability", "app": "friction", "t_s": …, "estimable": ["c1", …],
    /// "frozen": ["c2", …]}` — sent when it changes: the friction characterisation and the
    /// cyclic-torque estimation once, when they have chosen (the others stay at their nominal
    /// values); the shaft monitor with `--supervise` at the start and whenever the excitation
    /// supervisor has held a change for 0.25 s.
    Identifiability {
        /// The application.
        app: &'static str,
        /// Recording time [s].
        t_s: f64,
        /// The parameters estimated, in rank order.
        estimable: Vec<String>,
        /// The parameters held at their values.
        frozen: Vec<String>,
    },
    /// A steady engine cycle through the friction characterisation: `{"type": "friction",
    /// "cycle": n, "t_s": …, "measured": …, "predicted": …, "nominal": …, "truth": …,
    /// "params": {"c1": …}, "std_err": {"c1": …}}` — the cycle's mean motoring torque, its
    /// one-step-ahead prediction and the nominal model's [N·m], and the estimated coefficients
    /// after it (`t_s`: the cycle's start).
    Friction {
        /// Cycle index.
        cycle: i64,
        /// The cycle's start [s].
        t_s: f64,
        /// Its mean motoring torque [N·m].
        measured: f64,
        /// Predicted before the estimator saw it [N·m].
        predicted: f64,
        /// The nominal model's prediction [N·m].
        nominal: f64,
        /// The simulated truth, when the source carries it [N·m].
        #[serde(skip_serializing_if = "Option::is_none")]
        truth: Option<f64>,
        /// The estimated coefficients after the cycle.
        params: BTreeMap<String, f64>,
        /// Their standard errors (null before the estimator has them).
        std_err: BTreeMap<String, f64>,
    },
    /// The cyclic-torque parameters after another cycle's worth of samples (720, one per crank
    /// degree) through the filter: `{"type": "torque", "t_s": …, "params": {"b": …, …},
    /// "std_err": {…}, "rms_error": …, "rms_measured": …}` — the estimates of the chosen
    /// parameters (SI units), and the RMS of the cycle's one-step prediction errors and of the
    /// measured engine torque [N·m].
    Torque {
        /// Time of the cycle's last sample [s].
        t_s: f64,
        /// The estimates.
        params: BTreeMap<String, f64>,
        /// Their standard errors.
        std_err: BTreeMap<String, f64>,
        /// RMS of the one-step prediction errors over the cycle [N·m].
        rms_error: f64,
        /// RMS of the measured torque over the cycle [N·m].
        rms_measured: f64,
    },
    /// A frame from outside or a control message was refused (the run goes on; a refused frame
    /// is counted as dropped): `{"type": "error", "t_s": …, "input": "frames", "line": n,
    /// "message": …}` (`t_s` the last sample taken).
    Error {
        /// Recording time of the last sample taken [s] (null before any).
        t_s: f64,
        /// `frames` or `controls`.
        input: &'static str,
        /// Its line in that input.
        line: usize,
        /// What was wrong.
        message: String,
    },
    /// Something found in the stream: `{"type": "finding", "t_s": …, "message": …}` — a gap in
    /// the frames' `seq`, a stage that stopped, or an integrity finding, which also names its
    /// `kind` (as `physid inspect`: `pulse_loss`, `out_of_sync`, `lost_samples`, …) and the
    /// `sample` it is at (counted from the stream's first).
    Finding {
        /// Recording time [s]: of the sample it is at, or of the last sample before it.
        t_s: f64,
        /// What.
        message: String,
        /// The integrity finding's kind.
        #[serde(skip_serializing_if = "Option::is_none")]
        kind: Option<FindingKind>,
        /// The sample it is at.
        #[serde(skip_serializing_if = "Option::is_none")]
        sample: Option<usize>,
    },
    /// A complete engine cycle (720° from a firing TDC): the crank-angle mean of each channel,
    /// its largest sample and where in the cycle [deg] — `{"type": "cycle", "cycle": n,
    /// "t_s": …, "t_start_s": …, "mean": {"p_cyl": …, …}, "max": {…}, "max_deg": {…}}`, SI
    /// units; the panel's also carry `curve`, the channels on a crank-angle grid.
    Cycle {
        /// Cycle index (0: the first cycle that starts in the stream).
        cycle: i64,
        /// When it ended [s].
        t_s: f64,
        /// When it began [s].
        t_start_s: f64,
        /// Crank-angle mean of each channel.
        mean: BTreeMap<&'static str, f64>,
        /// Largest sample of each channel.
        max: BTreeMap<&'static str, f64>,
        /// Crank angle of each channel's largest sample in the cycle [deg].
        max_deg: BTreeMap<&'static str, f64>,
        /// The channels on a crank-angle grid (the panel's cyclic view).
        #[serde(skip_serializing_if = "Option::is_none")]
        curve: Option<Curve>,
    },
    /// The panel's time traces, decimated (bin means): `{"type": "trace", "t_s": …, "t": […],
    /// "channels": {"omega_en": […], …}}`; not printed headless.
    Trace {
        /// Time of the last point [s].
        t_s: f64,
        /// The points' times [s] (each bin's middle).
        t: Vec<f64>,
        /// Each channel's bin means, SI units.
        channels: BTreeMap<&'static str, Vec<f64>>,
        /// Samples taken from the stream's start, up to this event (the panel's header).
        samples: u64,
    },
    /// The live data being logged: `{"type": "log", "t_s": …, "file": …, "samples": n,
    /// "bytes": n, "state": "recording" | "closed"}`.
    Log {
        /// Recording time [s].
        t_s: f64,
        /// The file.
        file: String,
        /// Samples written.
        samples: usize,
        /// Its size [bytes] (while recording: written and buffered).
        bytes: usize,
        /// `recording` or `closed`.
        state: &'static str,
    },
    /// A control message applied: `{"type": "control", "t_s": …, "cmd": "fault", "line": n}`.
    Control {
        /// Recording time when it was applied [s].
        t_s: f64,
        /// The command.
        cmd: &'static str,
        /// Its line in the control input.
        line: usize,
    },
    /// The run ended (a replay's last sample, or the end of `--duration`): `{"type": "end",
    /// "t_s": …, "samples": n, "dropped": n}`.
    End {
        /// Recording time of the last sample [s].
        t_s: f64,
        /// Samples taken from the source.
        samples: usize,
        /// Frames refused (bad frames from outside).
        dropped: usize,
        /// From a sample's time being due on the wall clock to its estimate event handed to
        /// every output (stdout, the log, the panels' and the fleet's queues), when paced
        /// (absent at `--pace max`) [ms]: median, 99th percentile, largest, to 0.1 ms. A
        /// browser adds its network and rendering delay.
        #[serde(skip_serializing_if = "Option::is_none")]
        latency_ms: Option<LatencyMs>,
    },
}

/// A cycle's channels on a crank-angle grid: 0, `step_deg`, … < 720°.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Curve {
    /// Grid step [deg].
    pub step_deg: f64,
    /// Each channel's values on the grid.
    #[serde(flatten)]
    pub channels: BTreeMap<&'static str, Vec<f64>>,
}

/// Latency quantiles [ms].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LatencyMs {
    /// Median.
    pub p50: f64,
    /// 99th percentile.
    pub p99: f64,
    /// Largest.
    pub max: f64,
}

impl Event {
    /// A finding that is not an integrity finding (no kind, no sample).
    pub fn finding(t_s: f64, message: String) -> Self {
        Event::Finding {
            t_s,
            message,
            kind: None,
            sample: None,
        }
    }

    /// The shaft monitor's estimate event of an estimator sample.
    pub fn shaft_estimate(s: &ShaftSample) -> Self {
        Event::Estimate {
            app: "shaft",
            t_s: s.t_s,
            params: PerParam {
                k: s.estimate.k,
                b: s.estimate.b,
            },
            std_err: s.std_err,
        }
    }

    /// The cycle event of a cycle summary over `channels` (the curve at `step_deg` when the
    /// summary has one).
    pub fn cycle(c: &CycleSummary, channels: &[&'static str], step_deg: f64) -> Self {
        let by_name = |v: &[f64]| channels.iter().copied().zip(v.iter().copied()).collect();
        Event::Cycle {
            cycle: c.cycle,
            t_s: c.t_end_s,
            t_start_s: c.t_start_s,
            mean: by_name(&c.mean),
            max: by_name(&c.max),
            max_deg: by_name(&c.max_deg),
            curve: c.curve.as_ref().map(|curves| Curve {
                step_deg,
                channels: channels
                    .iter()
                    .copied()
                    .zip(curves.iter().cloned())
                    .collect(),
            }),
        }
    }

    /// The shaft monitor's alarm event.
    pub fn shaft_alarm(a: &ShaftAlarm) -> Self {
        Event::Alarm {
            app: "shaft",
            param: a.param.clone(),
            t_s: a.t_raised_s,
            t_start_s: a.t_start_s,
            relative_error: a.relative_error,
            change: a.change,
        }
    }
}

/// At most `max` bytes of `text` (cut at a character), followed by how long it was: what an
/// error quotes of a client's input.
pub fn quote(text: &str, max: usize) -> std::borrow::Cow<'_, str> {
    if text.len() <= max {
        return text.into();
    }
    let mut end = max;
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    format!("{}… ({} bytes)", &text[..end], text.len()).into()
}
