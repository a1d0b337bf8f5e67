//! The live loop without a panel: chunks from a [`Source`] through the applications' stages,
//! events out — what `physid live --headless --json` runs.

use crate::control::Control;
use crate::event::Event;
use crate::event::LatencyMs;
use crate::source::{Pace, Pacer, Source};
use physid_apps::error::AppError;
use physid_apps::shaft_monitor::{MonitorConfig, ShaftInputs, ShaftParams, ShaftStage};
use physid_core::RecordingError;
use physid_io::IoError;
use physid_sim::run::SimError;
use std::sync::mpsc::Receiver;
use thiserror::Error;

/// Errors of the live service.
#[derive(Debug, Error)]
pub enum LiveError {
    /// An application's stage.
    #[error(transparent)]
    App(#[from] AppError),
    /// The virtual test cell.
    #[error(transparent)]
    Sim(#[from] SimError),
    /// Reading a recording.
    #[error(transparent)]
    Io(#[from] IoError),
    /// A chunk without a channel a stage needs.
    #[error(transparent)]
    Recording(#[from] RecordingError),
    /// Writing the events.
    #[error("writing the events: {0}")]
    Output(String),
    /// One frame from outside that is not valid: refused, the stream goes on.
    #[error("frame on line {line}: {what}")]
    BadFrame {
        /// Its line in the input.
        line: usize,
        /// What was wrong.
        what: String,
    },
    /// Anything else, explained.
    #[error("{0}")]
    Invalid(String),
}

/// How the live loop runs.
#[derive(Debug, Clone)]
pub struct LiveConfig {
    /// The shaft monitor's settings.
    pub monitor: MonitorConfig,
    /// At most one estimate event per this much recording time [s] (the last estimate is always
    /// sent at the end).
    pub estimate_every_s: f64,
    /// How fast against the wall clock.
    pub pace: Pace,
}

impl Default for LiveConfig {
    /// The monitor's defaults, 10 estimate events per second, as fast as it can.
    fn default() -> Self {
        Self {
            monitor: MonitorConfig::default(),
            estimate_every_s: 0.1,
            pace: Pace::Max,
        }
    }
}

/// What a run did.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// Samples taken from the source.
    pub samples: usize,
    /// Frames refused.
    pub dropped: usize,
    /// The shaft's final K, B, τ0 and their standard errors.
    pub shaft: (ShaftParams, ShaftParams),
    /// Events sent.
    pub events: usize,
}

/// Run `source` to its end through the shaft monitor's stage, applying the control messages
/// that arrive on `controls` between chunks, handing each event to `emit`
/// (whose error, e.g. a closed output, stops the run). A chunk missing a channel, or a stage's
/// error, stops the run with the error (the events so far have been sent).
pub fn run_headless(
    source: &mut dyn Source,
    cfg: &LiveConfig,
    controls: Option<&Receiver<String>>,
    mut emit: impl FnMut(&Event) -> Result<(), String>,
) -> Result<Summary, LiveError> {
    let mut stage = ShaftStage::new(&cfg.monitor, source.rate_hz())?;
    let mut pacer = Pacer::new(cfg.pace);
    let (mut samples, mut alarms) = (Vec::new(), Vec::new());
    let (mut taken, mut events) = (0usize, 0usize);
    let mut last_sent: Option<f64> = None;
    // The latest estimate not sent (throttled): sent at the end.
    let mut pending = None;
    let mut last_t = f64::NAN;
    let mut send = |e: &Event, events: &mut usize| -> Result<(), LiveError> {
        *events += 1;
        emit(e).map_err(LiveError::Output)
    };
    let mut dropped = 0;
    let mut control_line = 0;
    let mut latency = LatencyHistogram::default();
    loop {
        let chunk = match source.next_chunk() {
            Ok(Some(c)) => c,
            Ok(None) => break,
            Err(LiveError::BadFrame { line, what }) => {
                dropped += 1;
                send(
                    &Event::Error {
                        t_s: last_t,
                        input: "frames",
                        line,
                        message: what,
                    },
                    &mut events,
                )?;
                continue;
            }
            Err(e) => return Err(e),
        };
        // Control messages that have arrived, applied between chunks.
        while let Some(Ok(text)) = controls.map(Receiver::try_recv) {
            control_line += 1;
            let event = match Control::parse(&text).and_then(|c| {
                source.control(&c)?;
                Ok(c.name())
            }) {
                Ok(cmd) => Event::Control {
                    t_s: last_t,
                    cmd,
                    line: control_line,
                },
                Err(message) => Event::Error {
                    t_s: last_t,
                    input: "controls",
                    line: control_line,
                    message,
                },
            };
            send(&event, &mut events)?;
        }
        if let Some(message) = source.notice() {
            send(
                &Event::Finding {
                    t_s: last_t,
                    message,
                },
                &mut events,
            )?;
        }
        if chunk.is_empty() {
            continue;
        }
        let t = chunk.values("t")?;
        pacer.wait_until(t[t.len() - 1]);
        taken += t.len();
        last_t = t[t.len() - 1];
        samples.clear();
        alarms.clear();
        stage.push(&ShaftInputs::of(&chunk)?, &mut samples, &mut alarms)?;
        for s in &samples {
            // Every estimate is ready now, whether it is sent or thinned out.
            if let Some(l) = pacer.since_due(s.t_s) {
                latency.add(l);
            }
            if last_sent.is_none_or(|l| s.t_s - l >= cfg.estimate_every_s) {
                send(&Event::shaft_estimate(s), &mut events)?;
                last_sent = Some(s.t_s);
                pending = None;
            } else {
                pending = Some(*s);
            }
        }
        for a in &alarms {
            send(&Event::shaft_alarm(a), &mut events)?;
        }
    }
    samples.clear();
    alarms.clear();
    stage.finish(&mut samples, &mut alarms)?;
    for a in &alarms {
        send(&Event::shaft_alarm(a), &mut events)?;
    }
    if let Some(s) = samples.last().or(pending.as_ref()) {
        send(&Event::shaft_estimate(s), &mut events)?;
    }
    send(
        &Event::End {
            t_s: last_t,
            samples: taken,
            dropped,
            latency_ms: latency.quantile(0.5).map(|p50| LatencyMs {
                p50: 1e3 * p50,
                p99: 1e3 * latency.quantile(0.99).unwrap_or(f64::NAN),
                max: 1e3 * latency.max(),
            }),
        },
        &mut events,
    )?;
    Ok(Summary {
        samples: taken,
        dropped,
        shaft: (stage.estimate(), stage.std_err()),
        events,
    })
}

/// A latency histogram: 0.1 ms bins up to 2 s (no allocation after construction).
#[derive(Debug, Clone)]
pub struct LatencyHistogram {
    bins: Vec<u64>,
    count: u64,
    max_s: f64,
}

/// Width of a bin [s].
const BIN_S: f64 = 1e-4;

impl Default for LatencyHistogram {
    fn default() -> Self {
        Self {
            bins: vec![0; 20_000],
            count: 0,
            max_s: 0.0,
        }
    }
}

impl LatencyHistogram {
    /// Count one latency [s] (beyond 2 s in the last bin; negative as 0).
    pub fn add(&mut self, s: f64) {
        let k = ((s.max(0.0) / BIN_S) as usize).min(self.bins.len() - 1);
        self.bins[k] += 1;
        self.count += 1;
        self.max_s = self.max_s.max(s);
    }

    /// The `q`-quantile [s] (upper edge of its bin); `None` when empty.
    pub fn quantile(&self, q: f64) -> Option<f64> {
        if self.count == 0 {
            return None;
        }
        let want = (q * self.count as f64).ceil().max(1.0) as u64;
        let mut seen = 0;
        for (k, &n) in self.bins.iter().enumerate() {
            seen += n;
            if seen >= want {
                return Some((k + 1) as f64 * BIN_S);
            }
        }
        Some(self.max_s)
    }

    /// The largest [s].
    pub fn max(&self) -> f64 {
        self.max_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Quantiles of 1 … 1000 ms: the median's bin ends at 500 ms, the 99th percentile's at
    /// 990 ms (0.1 ms bins); beyond 2 s lands in the last bin.
    #[test]
    fn histogram_quantiles() {
        let mut h = LatencyHistogram::default();
        assert_eq!(h.quantile(0.5), None);
        for k in 1..=1000 {
            h.add(k as f64 * 1e-3 - 5e-5);
        }
        assert!((h.quantile(0.5).unwrap() - 0.5).abs() < 1e-9);
        assert!((h.quantile(0.99).unwrap() - 0.99).abs() < 1e-9);
        h.add(5.0);
        assert_eq!(h.max(), 5.0);
        assert!((h.quantile(1.0).unwrap() - 2.0).abs() < 1e-9);
    }
}
