//! The live loop: chunks from a [`Source`] through the applications' stages (the same stages
//! the file verbs run), events out — what `physid live --headless --json` prints and what the
//! panel shows.
//!
//! Here: the errors, the summary, [`run_live`] and the state of [`Stages`]. `config.rs`: what
//! the service is told; `stages.rs`: the stages' loop (a chunk, controls, checkpoints);
//! `latency.rs`: the delivery latency's histogram.

use crate::control::{Control, ControlRequest};
use crate::event::{quote, App, Event, Input, LatencyMs};
use crate::record::Recorder;
use crate::source::{Pace, Pacer, Source};
use crate::trace::TraceStage;
use physid_apps::acquisition::AcquisitionOptions;
use physid_apps::combustion_stage::CombustionStage;
use physid_apps::cycle_stage::{CycleOutput, CycleStage};
use physid_apps::error::AppError;
use physid_apps::friction_fit::{FrictionFitConfig, FrictionOutput, FrictionStage};
use physid_apps::per_cycle::PerCycleSettings;
use physid_apps::shaft_monitor::{MonitorConfig, ShaftOutput, ShaftParams, ShaftStage};
use physid_apps::stage::Stage;
use physid_apps::torque_fit::{TorqueFitConfig, TorqueOutput, TorqueStage};
use physid_apps::twin::live::{TwinConfig, TwinOut, TwinStage};
use physid_core::{Basis, Recording, RecordingError};
use physid_io::IoError;
use physid_models::friction::REGRESSION_PARAMS;
use physid_signal::crank::CrankError;
use physid_signal::integrity::{Finding as IntegrityFinding, IntegrityStream};
use physid_sim::run::SimError;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::sync::Arc;
use std::time::{Duration, Instant};
use thiserror::Error;

use slot::{At, Emit, Run, Slot};
use tell::Integrity;

mod config;
mod latency;
mod slot;
mod stages;
mod tell;

pub use config::*;
pub use latency::*;
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
    /// The cycle statistics.
    #[error(transparent)]
    Cycles(#[from] CrankError),
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

/// What a run did.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// Samples taken from the source.
    pub samples: usize,
    /// Frames refused.
    pub dropped: usize,
    /// The shaft's final K, B, τ0 and their standard errors (`None` when the shaft monitor
    /// stopped: a source without its channels, or an estimator error).
    pub shaft: Option<(ShaftParams, ShaftParams)>,
    /// Complete cycles reported.
    pub cycles: usize,
    /// Events sent.
    pub events: usize,
}

/// Run `source` to its end through the stages — the shaft monitor, the cycle statistics (when
/// the source has `theta_en` and a channel of [`CYCLE_CHANNELS`]) and, for the panel, the
/// time traces — applying the control messages that arrive on `controls` between chunks (each
/// answered on its reply channel and by an event), handing each event to `emit` (whose error,
/// e.g. a closed output, stops the run). An application stage that fails — a source without
/// the channels it needs, an estimator that loses positive definiteness — stops with a `finding`
/// saying why, and the run and the other stages go on; the source's own error (a file that
/// cannot be read, a cell that diverges) stops the run with the error (the events so far have
/// been sent).
pub fn run_live(
    source: &mut dyn Source,
    cfg: &LiveConfig,
    controls: Option<&Receiver<ControlRequest>>,
    emit: impl FnMut(&Event) -> Result<(), String>,
) -> Result<Summary, LiveError> {
    let mut live = Stages::new(cfg.clone(), source.rate_hz(), emit)?;
    loop {
        if live.stopping() {
            break;
        }
        let chunk = match source.next_chunk() {
            Ok(Some(c)) => c,
            Ok(None) => break,
            Err(LiveError::BadFrame { line, what }) => {
                live.refuse(Input::Frames, line, what)?;
                continue;
            }
            Err(e) => {
                // The source failed (a damaged file, the cell's simulation diverged): told as
                // an event, then the run ends as at its end — the stages' last outputs, a log
                // closed, `end` — and the error is returned. Before, the events just stopped.
                let told = live.send(&Event::Error {
                    t_s: live.st.last_t,
                    input: Input::Source,
                    line: live.samples(),
                    message: e.to_string(),
                });
                let _ = told.and_then(|()| live.finish());
                return Err(e);
            }
        };
        // Control messages that have arrived, applied between chunks; while paused, wait for
        // them (the pacer does not count the pause).
        if let Some(rx) = controls {
            live.controls(rx, source)?;
        }
        if let Some(message) = source.notice() {
            let t_s = live.st.last_t;
            live.send(&Event::finding(t_s, message))?;
        }
        live.chunk(&chunk)?;
    }
    live.finish()
}

/// The applications' stages on one cell's stream, chunk by chunk, each event handed to `emit`:
/// what [`run_live`] runs over a source and a fleet worker over a cell's NATS stream. The
/// state of the stages — the shaft monitor, the cycle statistics, the integrity checks, the
/// friction and torque stages — is plain data: [`checkpoint`](Self::checkpoint) writes it,
/// [`restore`](Self::restore) takes the run up where it was (a log being written is not
/// checkpointed: a checkpoint refuses while one is; the panel's traces start again).
pub struct Stages<E> {
    cfg: LiveConfig,
    rate_hz: f64,
    st: State,
    traces: Option<TraceStage>,
    recorder: Recorder,
    pacer: Pacer,
    emit: E,
    paused: bool,
    /// A `stop` control for a source that cannot end itself (a replay, frames): the loop ends
    /// before the next chunk.
    stop_requested: bool,
    latency: LatencyHistogram,
}

/// The checkpointed part of [`Stages`].
#[derive(Serialize, Deserialize)]
struct State {
    /// The rate the stages were built for [Hz] (a restore at another is refused).
    rate_hz: f64,
    /// The stages and what telling their outputs remembers.
    stages: StageSlots,
    /// The time of the stream's first sample [s].
    t_first: f64,
    events: usize,
    taken: usize,
    dropped: usize,
    control_line: usize,
    last_t: f64,
}

/// The applications' stages of a run. Each stops, with a finding, at its first error (a source
/// without the channels it needs, a value not finite, an estimator that fails); the run and the
/// other stages go on, and a `restart` brings it back.
#[derive(Serialize, Deserialize)]
struct StageSlots {
    /// The integrity checks on the stream (set up on the first chunk).
    integrity: Slot<Integrity>,
    /// The shaft monitor.
    shaft: Slot<ShaftStage>,
    /// The cycle statistics of the channels of [`CYCLE_CHANNELS`] the source has.
    cycles: Slot<CycleStage>,
    /// The friction characterisation (`--friction`).
    friction: Slot<FrictionStage>,
    /// The cyclic-torque estimation (`--torque`).
    torque: Slot<TorqueStage>,
    /// The combustion analysis (`--combustion`).
    combustion: Slot<CombustionStage>,
    /// The self-calibrated twin beside the stream (`--twin`).
    twin: Slot<TwinStage>,
}

impl StageSlots {
    /// The stages `cfg` asks for, for a stream at `rate_hz` [Hz].
    fn start(cfg: &LiveConfig, rate_hz: f64) -> Result<Self, LiveError> {
        Ok(Self {
            integrity: Slot::start(cfg, rate_hz)?,
            shaft: Slot::start(cfg, rate_hz)?,
            cycles: Slot::start(cfg, rate_hz)?,
            friction: Slot::start(cfg, rate_hz)?,
            torque: Slot::start(cfg, rate_hz)?,
            combustion: Slot::start(cfg, rate_hz)?,
            twin: Slot::start(cfg, rate_hz)?,
        })
    }

    /// The stages in the order a chunk goes through them.
    fn in_chunk_order(&mut self) -> [&mut dyn Run; 7] {
        [
            &mut self.integrity,
            &mut self.shaft,
            &mut self.cycles,
            &mut self.friction,
            &mut self.torque,
            &mut self.combustion,
            &mut self.twin,
        ]
    }

    /// The stages in the order their last outputs are told at the end of the stream (the
    /// order the events have always come in: the event stream is part of the output).
    fn in_finish_order(&mut self) -> [&mut dyn Run; 7] {
        [
            &mut self.torque,
            &mut self.integrity,
            &mut self.friction,
            &mut self.shaft,
            &mut self.cycles,
            &mut self.combustion,
            &mut self.twin,
        ]
    }
}

/// The version of a [`Stages`] checkpoint's layout (a checkpoint of another is refused).
pub const CHECKPOINT_VERSION: u32 = 8;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::source::{ScenarioSource, Source};
    use physid_sim::run::{OutputBasis, RunOptions};
    use physid_sim::scenario::{Fault, Scenario};

    /// `scenario` run for `duration` s at 5 kHz (with `faults`), in chunks of 13 ms.
    fn run_chunks(scenario: &str, duration: f64, faults: &[&str]) -> (Vec<Recording>, f64) {
        let opts = RunOptions {
            duration: Some(duration),
            faults: faults.iter().map(|f| Fault::parse(f).unwrap()).collect(),
            basis: OutputBasis::Time(5000.0),
            ..Default::default()
        };
        let mut src =
            ScenarioSource::new(&Scenario::load(scenario).unwrap(), &opts, 0.013).unwrap();
        let mut out = Vec::new();
        while let Some(c) = src.next_chunk().unwrap() {
            out.push(c);
        }
        (out, src.rate_hz())
    }

    fn json(events: &[Event]) -> Vec<String> {
        events
            .iter()
            .map(|e| serde_json::to_string(e).unwrap())
            .collect()
    }

    /// `cfg`'s stages over `chunks`, checkpointed after chunk 1, a third of them and all but
    /// the last, and restored (through bytes): the events an uninterrupted run gives, bit for
    /// bit. Returns the uninterrupted run's events.
    fn restored_runs_equal_the_whole(
        cfg: &LiveConfig,
        chunks: &[Recording],
        rate: f64,
    ) -> Vec<Event> {
        let mut whole = Vec::new();
        let mut s = Stages::new(cfg.clone(), rate, |e: &Event| {
            whole.push(e.clone());
            Ok(())
        })
        .unwrap();
        for c in chunks {
            s.chunk(c).unwrap();
        }
        s.finish().unwrap();
        for cut in [1, chunks.len() / 3, chunks.len() - 1] {
            let mut first = Vec::new();
            let mut s = Stages::new(cfg.clone(), rate, |e: &Event| {
                first.push(e.clone());
                Ok(())
            })
            .unwrap();
            for c in &chunks[..cut] {
                s.chunk(c).unwrap();
            }
            let bytes = s.checkpoint().unwrap();
            drop(s);
            let mut second = Vec::new();
            let mut s = Stages::restore(cfg.clone(), &bytes, |e: &Event| {
                second.push(e.clone());
                Ok(())
            })
            .unwrap();
            for c in &chunks[cut..] {
                s.chunk(c).unwrap();
            }
            s.finish().unwrap();
            first.extend(second);
            assert_eq!(json(&first), json(&whole), "cut at chunk {cut}");
        }
        whole
    }

    /// The stages checkpointed at any chunk and restored (through bytes) give the events an
    /// uninterrupted run gives, bit for bit — the alarm of a stiffness fault, the estimates,
    /// the cycles, the end.
    #[test]
    fn a_restored_checkpoint_goes_on_exactly() {
        let (chunks, rate) = run_chunks("shaft-steady", 4.0, &["shaft.k=1000@2"]);
        let cfg = LiveConfig::default();
        let whole = restored_runs_equal_the_whole(&cfg, &chunks, rate);
        assert!(whole.iter().any(|e| matches!(e, Event::Alarm { .. })));
        // Another layout is refused with a reason, not misread — named as such even when its
        // state does not read as this layout's (it used to be "invalid type: integer …").
        let v = CHECKPOINT_VERSION + 1;
        let bad = rmp_serde::to_vec(&(v, 0u8)).unwrap();
        let e = Stages::restore(cfg, &bad, |_: &Event| Ok(()))
            .err()
            .unwrap();
        let layout =
            format!("a checkpoint of layout {v}: this physid reads layout {CHECKPOINT_VERSION}");
        assert!(e.to_string().contains(&layout), "{e}");
    }

    /// The friction characterisation and the cyclic-torque estimation checkpoint too: cut before
    /// their choice, after it and near the end, a restored run's events (the choice, every
    /// cycle's estimates) equal an uninterrupted one's, bit for bit.
    #[test]
    fn the_friction_and_torque_stages_checkpoint_too() {
        use physid_apps::friction_fit::friction_preset;
        let (d, st) = friction_preset("cell").unwrap();
        let friction = LiveConfig {
            friction: Some(config::FrictionLive {
                fit: FrictionFitConfig::new(d, st),
                select_after: 20,
            }),
            ..LiveConfig::default()
        };
        let (chunks, rate) = run_chunks("friction-sweep", 8.0, &[]);
        let whole = restored_runs_equal_the_whole(&friction, &chunks, rate);
        let n = whole
            .iter()
            .filter(|e| matches!(e, Event::Friction { .. }))
            .count();
        assert!(n > 20, "{n} friction cycles");
        let nominal =
            physid_apps::cell::cyclic_torque_nominal(&physid_sim::params::CellParams::default())
                .unwrap();
        let torque = LiveConfig {
            torque: Some(config::TorqueLive {
                fit: TorqueFitConfig::new(nominal),
                select_after_cycles: 2,
            }),
            ..LiveConfig::default()
        };
        let (chunks, rate) = run_chunks("torque-ramp", 2.0, &[]);
        let whole = restored_runs_equal_the_whole(&torque, &chunks, rate);
        let n = whole
            .iter()
            .filter(|e| matches!(e, Event::Torque { .. }))
            .count();
        assert!(n > 5, "{n} torque cycles");
    }

    /// Chunks lost mid-run (a DAQ's dropout, frames lost on a fleet: ≈ 0.5 s, several engine
    /// cycles) do not stop the stages that count cycles: the friction characterisation and the
    /// cyclic-torque estimation go on after the gap, as the cycle statistics do (their cycle
    /// in progress left out: `physid_signal::cycles`). Before, the crank angle's advance across
    /// the gap stopped each of them for the rest of the run.
    #[test]
    fn the_cycle_stages_go_on_after_a_gap() {
        use physid_apps::friction_fit::friction_preset;
        let (d, st) = friction_preset("cell").unwrap();
        let nominal =
            physid_apps::cell::cyclic_torque_nominal(&physid_sim::params::CellParams::default())
                .unwrap();
        let friction = LiveConfig {
            friction: Some(config::FrictionLive {
                fit: FrictionFitConfig::new(d, st),
                select_after: 20,
            }),
            ..LiveConfig::default()
        };
        let torque = LiveConfig {
            torque: Some(config::TorqueLive {
                fit: TorqueFitConfig::new(nominal),
                select_after_cycles: 2,
            }),
            ..LiveConfig::default()
        };
        for (cfg, scenario, seconds, gap) in [
            (friction, "friction-sweep", 8.0, 4.0..4.5),
            (torque, "torque-ramp", 3.0, 1.5..2.0),
        ] {
            let (chunks, rate) = run_chunks(scenario, seconds, &[]);
            let mut events = Vec::new();
            let mut s = Stages::new(cfg, rate, |e: &Event| {
                events.push(e.clone());
                Ok(())
            })
            .unwrap();
            for c in &chunks {
                let t = c.values("t").unwrap();
                if !(gap.contains(&t[0]) || gap.contains(&t[t.len() - 1])) {
                    s.chunk(c).unwrap();
                }
            }
            s.finish().unwrap();
            let stopped: Vec<&Event> = events
                .iter()
                .filter(
                    |e| matches!(e, Event::Finding { message, .. } if message.contains("stopped")),
                )
                .collect();
            assert!(stopped.is_empty(), "{scenario}: {stopped:?}");
            let after = |kind: fn(&Event) -> Option<f64>| {
                events
                    .iter()
                    .filter_map(kind)
                    .filter(|&t| t > gap.end)
                    .count()
            };
            let cycles = after(|e| match e {
                Event::Cycle { t_s, .. } => Some(*t_s),
                _ => None,
            });
            let fits = after(|e| match e {
                Event::Friction { t_s, .. } | Event::Torque { t_s, .. } => Some(*t_s),
                _ => None,
            });
            assert!(
                cycles >= 5 && fits >= 5,
                "{scenario}: {cycles} cycles, {fits} fits after the gap"
            );
        }
    }

    /// Quantiles of 1 … 1000 ms: the median's bin ends at 500 ms, the 99th percentile's at
    /// 990 ms (0.1 ms bins); beyond 2 s within 10 ms (the `bench fleet` run whose p99 stuck at
    /// 2000 ms while its max was 2729 ms); beyond 2 min the largest seen.
    #[test]
    fn histogram_quantiles() {
        let mut h = LatencyHistogram::default();
        assert_eq!(h.quantile(0.5), None);
        assert_eq!(h.summary_ms(), None);
        for k in 1..=1000 {
            h.add(k as f64 * 1e-3 - 5e-5);
        }
        assert!((h.quantile(0.5).unwrap() - 0.5).abs() < 1e-9);
        assert!((h.quantile(0.99).unwrap() - 0.99).abs() < 1e-9);
        h.add(5.0);
        assert_eq!(h.max(), 5.0);
        assert!((h.quantile(1.0).unwrap() - 5.0).abs() < 1e-9);
        // Latencies 1.5 … 3.0 s: the 99th percentile is 2.985 s, within one 10 ms bin.
        let mut slow = LatencyHistogram::default();
        for k in 0..=300 {
            slow.add(1.5 + k as f64 * 0.005 + 1e-6);
        }
        let p99 = slow.quantile(0.99).unwrap();
        assert!((2.985..=2.995 + 1e-9).contains(&p99), "{p99}");
        let [p50, p99_ms, max] = slow.summary_ms().unwrap();
        // The median 2.250001 s is in the 10 ms bin [2.25, 2.26): its upper edge.
        assert_eq!((p50, max), (2260.0, 3000.0));
        assert!((p99_ms * 10.0).fract() == 0.0 && p99_ms <= max);
        slow.add(500.0);
        assert_eq!(slow.quantile(1.0), Some(500.0));
    }
}
