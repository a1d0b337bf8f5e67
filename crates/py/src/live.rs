//! The live service in Python: [`live`] starts a run on a thread of its own and
//! [`LiveStream`] hands its events over.

use crate::err;
use pyo3::prelude::*;
use std::collections::BTreeMap;

/// The live service's events (`physid live --headless --json`), one JSON object each, as a
/// run goes: the run on a thread of its own, its events handed over a bounded channel that
/// `__next__` waits on without the GIL. Dropping the stream (or `close`) stops the run.
#[pyclass(module = "physid._physid")]
pub struct LiveStream {
    events: Option<std::sync::Mutex<std::sync::mpsc::Receiver<String>>>,
    controls: Option<std::sync::mpsc::SyncSender<physid_live::ControlRequest>>,
    worker: Option<std::thread::JoinHandle<Result<(), String>>>,
}

#[pymethods]
impl LiveStream {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    /// The next event as JSON text; at the end, the run's error if it failed.
    fn __next__(&mut self, py: Python<'_>) -> PyResult<Option<String>> {
        let Some(rx) = &self.events else {
            return Ok(None);
        };
        let next = py.detach(|| match rx.lock() {
            Ok(r) => r.recv().ok(),
            Err(_) => None,
        });
        match next {
            Some(line) => Ok(Some(line)),
            None => {
                self.events = None;
                self.controls = None;
                match self.worker.take().map(|w| w.join()) {
                    Some(Ok(Err(e))) => Err(err(e)),
                    Some(Err(_)) => Err(err("the live run stopped unexpectedly")),
                    _ => Ok(None),
                }
            }
        }
    }

    /// Send a control message (one JSON object, as the panel's: `{"cmd": "speed", "rpm":
    /// 1200}`); its answer comes as an event.
    fn control(&self, text: String) -> PyResult<()> {
        match &self.controls {
            Some(tx) => tx
                .send(physid_live::ControlRequest::fire(text))
                .map_err(|_| err("the live run has ended")),
            None => Err(err("the live run has ended")),
        }
    }

    /// Stop the run (the events not yet taken are dropped).
    fn close(&mut self, py: Python<'_>) {
        self.events = None;
        self.controls = None;
        if let Some(w) = self.worker.take() {
            let _ = py.detach(|| w.join());
        }
    }
}

/// Start a live run: the virtual cell (`scenario`, `duration`, `faults`, `set`, sampled at
/// `rate` Hz) or a recording replayed (`replay`), at `pace` (`max` or a factor of real time),
/// in chunks of `chunk_s` seconds, an estimate event at most every `estimate_every_s`.
#[pyfunction]
#[pyo3(signature = (scenario, replay, duration, faults, set, pace, rate, chunk_s, estimate_every_s))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn live(
    scenario: Option<String>,
    replay: Option<std::path::PathBuf>,
    duration: Option<f64>,
    faults: Vec<String>,
    set: BTreeMap<String, f64>,
    pace: &str,
    rate: f64,
    chunk_s: f64,
    estimate_every_s: f64,
) -> PyResult<LiveStream> {
    use physid_live::{run_live, LiveConfig, Pace, ReplaySource, ScenarioSource, Source};
    use physid_sim::run::{OutputBasis, RunOptions};
    use physid_sim::scenario::{Fault, Scenario};
    let pace: Pace = pace.parse().map_err(|e| err(format!("pace {e}")))?;
    if !(chunk_s.is_finite()
        && chunk_s > 0.0
        && estimate_every_s.is_finite()
        && estimate_every_s > 0.0)
    {
        return Err(err("chunk_s and estimate_every_s: expected times > 0 [s]"));
    }
    // The source is built here, so that a bad scenario or file is an error now.
    let (source, theta_tdc): (Box<dyn Source + Send>, f64) = match replay {
        Some(path) => {
            let r = ReplaySource::open(&path, &Default::default(), chunk_s).map_err(err)?;
            let tdc = r.theta_tdc();
            (Box::new(r), tdc)
        }
        None => {
            let mut sc =
                Scenario::load(scenario.as_deref().unwrap_or("shaft-steady")).map_err(err)?;
            sc.set.extend(set);
            let faults = faults
                .iter()
                .map(|f| Fault::parse(f))
                .collect::<Result<Vec<_>, _>>()
                .map_err(err)?;
            let opts = RunOptions {
                duration,
                faults,
                basis: OutputBasis::Time(rate),
                ..Default::default()
            };
            (
                Box::new(ScenarioSource::new(&sc, &opts, chunk_s).map_err(err)?),
                0.0,
            )
        }
    };
    let cfg = LiveConfig {
        pace,
        theta_tdc,
        estimate_every_s,
        ..Default::default()
    };
    let (tx, rx) = std::sync::mpsc::sync_channel::<String>(1024);
    let (ctx, crx) = std::sync::mpsc::sync_channel(256);
    let worker = std::thread::spawn(move || {
        let mut source = source;
        run_live(source.as_mut(), &cfg, Some(&crx), |e| {
            let line = serde_json::to_string(e).map_err(|e| e.to_string())?;
            tx.send(line)
                .map_err(|_| "the stream was closed".to_string())
        })
        .map(|_| ())
        .or_else(|e| {
            let text = e.to_string();
            // Closed from Python: not an error.
            if text.contains("the stream was closed") {
                Ok(())
            } else {
                Err(text)
            }
        })
    });
    Ok(LiveStream {
        events: Some(std::sync::Mutex::new(rx)),
        controls: Some(ctx),
        worker: Some(worker),
    })
}
