//! The events of the live service, one JSON object each with `"type"` and `"t_s"` (the
//! recording's time). The names are stable (docs/live.md). One typed protocol: the service
//! writes these, and the fleet view, the tests and any Rust client read them back
//! (`Serialize + Deserialize`, tagged by `"type"`); the panel's own messages are
//! [`crate::wire::PanelMessage`].

use physid_apps::shaft_monitor::{PerParam, ShaftAlarm, ShaftSample};
use physid_core::nan_null;
use physid_signal::cycles::CycleSummary;
use physid_signal::integrity::FindingKind;
use serde::{Deserialize, Serialize};
use std::borrow::Cow;
use std::collections::BTreeMap;

/// A name the service mostly knows at compile time (a channel, a command) and a reader owns.
pub type Name = Cow<'static, str>;

/// The application an event is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum App {
    /// The coupling-shaft monitor (Application 1).
    Shaft,
    /// The friction characterisation (Application 2).
    Friction,
    /// The cyclic-torque estimation (Application 3).
    Torque,
    /// The self-calibrated twin (`--twin`, docs/twin.md).
    Twin,
}

/// Where a refused input came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Input {
    /// The frames from outside (`--frames`, NATS).
    Frames,
    /// The control messages.
    Controls,
    /// The live log.
    Record,
    /// The fleet's registry of cells.
    Registry,
    /// A cell's checkpoint in the fleet's store.
    Checkpoint,
    /// The run's source (a replayed file, the virtual cell), failed: `line` is the samples
    /// taken before it.
    Source,
}

/// A live log's state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LogState {
    /// Being written.
    Recording,
    /// Closed (readable in full).
    Closed,
    /// Stopped before any sample came: no file kept (the name claimed at the start is freed —
    /// an empty file would be readable by no reader).
    Empty,
}

/// An event.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Event {
    /// An application's estimates now: `{"type": "estimate", "app": "shaft", "t_s": …,
    /// "params": {"K": …, "B": …}, "std_err": {"K": …, "B": …}}`.
    Estimate {
        /// The application (`shaft`).
        app: App,
        /// Recording time [s].
        #[serde(deserialize_with = "nan_null::f64")]
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
        app: App,
        /// The parameter that moved.
        param: String,
        /// When the alarm was raised [s].
        #[serde(deserialize_with = "nan_null::f64")]
        t_s: f64,
        /// When the estimate left its bound [s].
        #[serde(deserialize_with = "nan_null::f64")]
        t_start_s: f64,
        /// Its relative error (Eq. 6.3) then.
        #[serde(deserialize_with = "nan_null::f64")]
        relative_error: f64,
        /// The estimate's change from healthy then (−relative error; K fell 12 % → −0.12).
        #[serde(deserialize_with = "nan_null::f64")]
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
        app: App,
        /// Recording time [s].
        #[serde(deserialize_with = "nan_null::f64")]
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
        #[serde(deserialize_with = "nan_null::f64")]
        t_s: f64,
        /// Its mean motoring torque [N·m].
        #[serde(deserialize_with = "nan_null::f64")]
        measured: f64,
        /// Predicted before the estimator saw it [N·m].
        #[serde(deserialize_with = "nan_null::f64")]
        predicted: f64,
        /// The nominal model's prediction [N·m].
        #[serde(deserialize_with = "nan_null::f64")]
        nominal: f64,
        /// The simulated truth, when the source carries it [N·m].
        #[serde(skip_serializing_if = "Option::is_none")]
        truth: Option<f64>,
        /// The estimated coefficients after the cycle.
        #[serde(deserialize_with = "nan_null::map")]
        params: BTreeMap<String, f64>,
        /// Their standard errors (null before the estimator has them).
        #[serde(deserialize_with = "nan_null::map")]
        std_err: BTreeMap<String, f64>,
    },
    /// The cyclic-torque parameters after another cycle's worth of samples (720, one per crank
    /// degree) through the filter: `{"type": "torque", "t_s": …, "params": {"b": …, …},
    /// "std_err": {…}, "rms_error": …, "rms_measured": …}` — the estimates of the chosen
    /// parameters (SI units), and the RMS of the cycle's one-step prediction errors and of the
    /// measured engine torque [N·m].
    Torque {
        /// Time of the cycle's last sample [s].
        #[serde(deserialize_with = "nan_null::f64")]
        t_s: f64,
        /// The estimates.
        #[serde(deserialize_with = "nan_null::map")]
        params: BTreeMap<String, f64>,
        /// Their standard errors.
        #[serde(deserialize_with = "nan_null::map")]
        std_err: BTreeMap<String, f64>,
        /// RMS of the one-step prediction errors over the cycle [N·m].
        #[serde(deserialize_with = "nan_null::f64")]
        rms_error: f64,
        /// RMS of the measured torque over the cycle [N·m].
        #[serde(deserialize_with = "nan_null::f64")]
        rms_measured: f64,
    },
    /// A window of the twin beside the stream (`--twin`, docs/twin.md): `{"type": "twin",
    /// "t_s": …, "params": {"shaft.k": …, …}, "std_err": {…}, "frozen": [...], "residual":
    /// {"omega_en": …, …}, "measured": {"omega_en": …, …}, "twin": {…}}` — its live
    /// parameters' estimates (SI units; standard errors null while frozen or settling), each
    /// channel's residual RMS over the window in units of its noise (null before the noise is
    /// known) and each channel's mean over the window, measured and the twin's (SI units). A
    /// twin's alarm is an `alarm` event with `"app": "twin"` and the parameter's path.
    Twin {
        /// The window's end [s].
        #[serde(deserialize_with = "nan_null::f64")]
        t_s: f64,
        /// The estimates.
        #[serde(deserialize_with = "nan_null::map")]
        params: BTreeMap<String, f64>,
        /// Their standard errors.
        #[serde(deserialize_with = "nan_null::map")]
        std_err: BTreeMap<String, f64>,
        /// The parameters frozen in the window.
        frozen: Vec<String>,
        /// Each channel's residual RMS over its noise.
        #[serde(deserialize_with = "nan_null::map")]
        residual: BTreeMap<String, f64>,
        /// Each channel's mean over the window, measured.
        #[serde(default, deserialize_with = "nan_null::map")]
        measured: BTreeMap<String, f64>,
        /// The same of the twin.
        #[serde(default, deserialize_with = "nan_null::map")]
        twin: BTreeMap<String, f64>,
    },
    /// A frame from outside or a control message was refused (the run goes on; a refused frame
    /// is counted as dropped): `{"type": "error", "t_s": …, "input": "frames", "line": n,
    /// "message": …}` (`t_s` the last sample taken).
    Error {
        /// Recording time of the last sample taken [s] (null before any).
        #[serde(deserialize_with = "nan_null::f64")]
        t_s: f64,
        /// `frames`, `controls`, `record` or `registry`.
        input: Input,
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
        #[serde(deserialize_with = "nan_null::f64")]
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
        #[serde(deserialize_with = "nan_null::f64")]
        t_s: f64,
        /// When it began [s].
        #[serde(deserialize_with = "nan_null::f64")]
        t_start_s: f64,
        /// Crank-angle mean of each channel.
        #[serde(deserialize_with = "nan_null::map")]
        mean: BTreeMap<Name, f64>,
        /// Largest sample of each channel.
        #[serde(deserialize_with = "nan_null::map")]
        max: BTreeMap<Name, f64>,
        /// Crank angle of each channel's largest sample in the cycle [deg].
        #[serde(deserialize_with = "nan_null::map")]
        max_deg: BTreeMap<Name, f64>,
        /// The channels on a crank-angle grid (the panel's cyclic view).
        #[serde(skip_serializing_if = "Option::is_none")]
        curve: Option<Curve>,
    },
    /// A cycle's combustion figures (`physid cycles`' per cycle, on the stream; the cycle from
    /// 360° before its firing TDC to 360° after): `{"type": "combustion", "cycle": n, "t_s": …,
    /// "figures": {"imep": …, "mfb50_deg": …, "mapo": …, …}, "notes": […]}` — `figures` named
    /// and in the units of `physid cycles --tracks`' columns (null where not computed; flags
    /// 1/0), `t_s` the time of its firing TDC; with the panel, five cycles a second also carry
    /// `"curve": {"step_deg": …, "p": […], "hrr": […]}` — the pressure and the heat release rate
    /// [J/deg] from −360° ATDC (null outside the heat release's window).
    Combustion {
        /// Cycle index (the block of 720° its firing TDC starts, as `cycle` events count).
        cycle: i64,
        /// The time of its firing TDC [s].
        #[serde(deserialize_with = "nan_null::f64")]
        t_s: f64,
        /// The figures by their column names.
        #[serde(deserialize_with = "nan_null::map")]
        figures: BTreeMap<Name, f64>,
        /// What was left out of this cycle's figures, and why.
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        notes: Vec<String>,
        /// The pressure and heat release rate on a grid from −360° ATDC, when due.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        curve: Option<Curve>,
    },
    /// The panel's time traces, decimated (bin means): `{"type": "trace", "t_s": …, "t": […],
    /// "channels": {"omega_en": […], …}}`; not printed headless.
    Trace {
        /// Time of the last point [s].
        #[serde(deserialize_with = "nan_null::f64")]
        t_s: f64,
        /// The points' times [s] (each bin's middle).
        #[serde(deserialize_with = "nan_null::vec")]
        t: Vec<f64>,
        /// Each channel's bin means, SI units.
        #[serde(deserialize_with = "nan_null::map_vec")]
        channels: BTreeMap<Name, Vec<f64>>,
        /// Samples taken from the stream's start, up to this event (the panel's header).
        samples: u64,
    },
    /// The live data being logged: `{"type": "log", "t_s": …, "file": …, "samples": n,
    /// "bytes": n, "state": "recording" | "closed"}`.
    Log {
        /// Recording time [s].
        #[serde(deserialize_with = "nan_null::f64")]
        t_s: f64,
        /// The file.
        file: String,
        /// Samples written.
        samples: usize,
        /// Its size [bytes] (while recording: written and buffered).
        bytes: usize,
        /// `recording` or `closed`.
        state: LogState,
    },
    /// A control message applied: `{"type": "control", "t_s": …, "cmd": "fault", "line": n}`.
    Control {
        /// Recording time when it was applied [s].
        #[serde(deserialize_with = "nan_null::f64")]
        t_s: f64,
        /// The command.
        cmd: Name,
        /// Its line in the control input.
        line: usize,
    },
    /// The run ended (a replay's last sample, or the end of `--duration`): `{"type": "end",
    /// "t_s": …, "samples": n, "dropped": n}`.
    End {
        /// Recording time of the last sample [s].
        #[serde(deserialize_with = "nan_null::f64")]
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

/// A cycle's channels on a crank-angle grid of `step_deg`: from its start, 0 … < 720° (a
/// `cycle` event's, from a firing TDC), or −360° … < 360° ATDC (a `combustion` event's).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Curve {
    /// Grid step [deg].
    pub step_deg: f64,
    /// Each channel's values on the grid (NaN, `null` in JSON, where there is none).
    #[serde(flatten, deserialize_with = "nan_null::map_vec")]
    pub channels: BTreeMap<Name, Vec<f64>>,
}

/// Latency quantiles [ms].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
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
            app: App::Shaft,
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
    pub fn cycle(c: &CycleSummary, channels: &[String], step_deg: f64) -> Self {
        let by_name = |v: &[f64]| {
            channels
                .iter()
                .map(|c| Name::Owned(c.clone()))
                .zip(v.iter().copied())
                .collect()
        };
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
                    .map(|c| Name::Owned(c.clone()))
                    .zip(curves.iter().cloned())
                    .collect(),
            }),
        }
    }

    /// The shaft monitor's alarm event.
    pub fn shaft_alarm(a: &ShaftAlarm) -> Self {
        Event::Alarm {
            app: App::Shaft,
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

#[cfg(test)]
mod tests {
    use super::*;

    fn map<K: Ord>(kv: impl IntoIterator<Item = (K, f64)>) -> BTreeMap<K, f64> {
        kv.into_iter().collect()
    }

    /// Every kind of event, written and read back, writes the same text again — NaN (`null`,
    /// "not known yet") included.
    #[test]
    fn every_event_reads_back_as_written() {
        let nan = f64::NAN;
        let events = [
            Event::Estimate {
                app: App::Shaft,
                t_s: 0.1,
                params: PerParam { k: 1250.0, b: 0.95 },
                std_err: PerParam { k: nan, b: nan },
            },
            Event::Alarm {
                app: App::Shaft,
                param: "K".into(),
                t_s: 12.5,
                t_start_s: 12.25,
                relative_error: 0.2,
                change: -0.2,
            },
            Event::Identifiability {
                app: App::Friction,
                t_s: 3.0,
                estimable: vec!["c1".into()],
                frozen: vec!["c2".into(), "c3".into()],
            },
            Event::Friction {
                cycle: 7,
                t_s: 1.0,
                measured: -3.5,
                predicted: -3.4,
                nominal: -3.0,
                truth: None,
                params: map([("c1".to_string(), 0.1)]),
                std_err: map([("c1".to_string(), nan)]),
            },
            Event::Torque {
                t_s: 2.0,
                params: map([("r".to_string(), 0.0457)]),
                std_err: map([("r".to_string(), 1e-4)]),
                rms_error: 1.5,
                rms_measured: 30.0,
            },
            Event::Twin {
                t_s: 30.35,
                params: map([("shaft.k".to_string(), 1000.0)]),
                std_err: map([("shaft.k".to_string(), nan)]),
                frozen: vec!["engine.m_rec".into()],
                residual: map([("omega_en".to_string(), 1.1)]),
                measured: map([("omega_en".to_string(), 104.7)]),
                twin: map([("omega_en".to_string(), nan)]),
            },
            Event::Error {
                t_s: nan,
                input: Input::Frames,
                line: 3,
                message: "column 't' is missing".into(),
            },
            Event::Finding {
                t_s: 0.5,
                message: "a pulse lost".into(),
                kind: Some(FindingKind::PulseLoss),
                sample: Some(42),
            },
            Event::finding(0.6, "the shaft monitor stopped".into()),
            Event::Cycle {
                cycle: 0,
                t_s: 0.17,
                t_start_s: 0.05,
                mean: map([(Name::Borrowed("p_cyl"), 2.9e5)]),
                max: map([(Name::Borrowed("p_cyl"), 2.1e6)]),
                max_deg: map([(Name::Borrowed("p_cyl"), 359.0)]),
                curve: Some(Curve {
                    step_deg: 360.0,
                    channels: [(Name::Borrowed("p_cyl"), vec![1e5, 2e6])]
                        .into_iter()
                        .collect(),
                }),
            },
            Event::Trace {
                t_s: 1.0,
                t: vec![0.95, 1.0],
                channels: [(Name::Borrowed("omega_en"), vec![104.7, nan])]
                    .into_iter()
                    .collect(),
                samples: 10_000,
            },
            Event::Log {
                t_s: 4.0,
                file: "run.parquet".into(),
                samples: 100,
                bytes: 4096,
                state: LogState::Closed,
            },
            Event::Control {
                t_s: 4.5,
                cmd: "fault".into(),
                line: 2,
            },
            Event::End {
                t_s: 30.0,
                samples: 300_001,
                dropped: 0,
                latency_ms: Some(LatencyMs {
                    p50: 0.4,
                    p99: 1.2,
                    max: 3.0,
                }),
            },
        ];
        for e in &events {
            let text = serde_json::to_string(e).unwrap();
            let back: Event = serde_json::from_str(&text).unwrap_or_else(|x| panic!("{text}: {x}"));
            assert_eq!(serde_json::to_string(&back).unwrap(), text);
        }
        let text = serde_json::to_string(&events[0]).unwrap();
        assert_eq!(
            text,
            r#"{"type":"estimate","app":"shaft","t_s":0.1,"params":{"K":1250.0,"B":0.95},"std_err":{"K":null,"B":null}}"#
        );
    }
}
