//! The events of the live service, one JSON object each with `"type"` and `"t_s"` (the
//! recording's time). The names are stable (docs/live.md).

use physid_apps::shaft_monitor::{PerParam, ShaftAlarm, ShaftSample};
use serde::Serialize;

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
    /// "relative_error": …}` (`t_s` when it was raised, `t_start_s` when the estimate left its
    /// bound).
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
    /// Something found in the stream (a gap in time or in the frames' `seq`):
    /// `{"type": "finding", "t_s": …, "message": …}`.
    Finding {
        /// Recording time of the last sample before it [s].
        t_s: f64,
        /// What.
        message: String,
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
        /// From a sample's time being due on the wall clock to its estimate being sent, when
        /// paced (absent at `--pace max`) [ms].
        #[serde(skip_serializing_if = "Option::is_none")]
        latency_ms: Option<LatencyMs>,
    },
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

    /// The shaft monitor's alarm event.
    pub fn shaft_alarm(a: &ShaftAlarm) -> Self {
        Event::Alarm {
            app: "shaft",
            param: a.param.clone(),
            t_s: a.t_raised_s,
            t_start_s: a.t_start_s,
            relative_error: a.relative_error,
        }
    }
}
