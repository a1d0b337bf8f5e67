//! `physid bench fleet`: N cells publishing at real time, workers processing them, measured.
//!
//! Each cell is a data-acquisition system at one sample per crank degree: the virtual cell's
//! shaft-steady scenario at a speed between the given limits (6·rpm samples/s), simulated
//! beforehand (a DAQ costs the host nothing), then published at real time (pace 1) with the
//! channels the stages use (`t`, `theta_en`, `theta_dy`, `omega_en`, `omega_dy`,
//! `torque_shaft`, `p_cyl`). Workers in the same process run the shaft monitor, the cycle
//! statistics and the integrity checks. Measured:
//!
//! * the event latency — from a sample being due on the wall clock (its cell's start plus its
//!   recording time) to its `estimate` event arriving at a subscriber on the server;
//! * how far each publisher fell behind the wall clock (real time held: no further than one
//!   chunk);
//! * every cell's samples published against those its `end` event counts, and the frames the
//!   workers processed and refused (none lost, none twice);
//! * messages and bytes through the server (`/varz` of a server this run started).

use super::local::LocalServer;
use super::publish::{publish, PublishConfig};
use super::worker::{run_worker, WorkerConfig, WorkerStats};
use super::{FleetError, NatsTarget};
use crate::service::{LatencyHistogram, LiveConfig};
use crate::source::{Pace, ReplaySource, ScenarioSource, Source};
use futures_util::StreamExt;
use physid_core::{Basis, Channel, Recording};
use physid_sim::run::{OutputBasis, RunOptions};
use physid_sim::scenario::{Profile, Scenario};
use serde::Serialize;
use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The channels a load cell publishes.
pub const LOAD_CHANNELS: [&str; 7] = [
    "t",
    "theta_en",
    "theta_dy",
    "omega_en",
    "omega_dy",
    "torque_shaft",
    "p_cyl",
];

/// Estimates of samples before this recording time [s] are the take-on, not steady
/// operation.
pub const SETTLE_S: f64 = 1.0;

/// A load run's settings.
#[derive(Debug, Clone)]
pub struct LoadConfig {
    /// Cells publishing.
    pub cells: usize,
    /// Recording seconds each cell publishes.
    pub seconds: f64,
    /// The cells' speeds spread evenly over this range [rpm].
    pub rpm: (f64, f64),
    /// Workers (in this process).
    pub workers: usize,
    /// Chunk length of a publisher [s].
    pub chunk_s: f64,
    /// The recording time a frame carries [s] ([`PublishConfig::frame_s`]).
    pub frame_s: f64,
}

/// What a load run measured.
#[derive(Debug, Clone, Serialize)]
pub struct LoadReport {
    /// Cells.
    pub cells: usize,
    /// Workers.
    pub workers: usize,
    /// Recording seconds per cell.
    pub seconds: f64,
    /// Samples per second of all cells together (their nominal rates).
    pub samples_per_s: f64,
    /// Samples published, all cells.
    pub samples_published: u64,
    /// Samples the cells' `end` events count.
    pub samples_processed: u64,
    /// Cells whose `end` event arrived.
    pub cells_ended: usize,
    /// Frames the workers refused (duplicates, out of order, malformed): 0 expected.
    pub frames_refused: u64,
    /// Frames published more than once after a lost acknowledgement (stored once).
    pub frames_resent: u64,
    /// Estimate events received.
    pub estimates: u64,
    /// Event latency [ms] in steady operation (estimates of samples from the second
    /// [`SETTLE_S`] on: a cell's take-on by a worker is counted in `first_estimate_ms`):
    /// median, 99th percentile, largest.
    pub latency_ms: [f64; 3],
    /// The longest wait from a cell's start to its first estimate event [ms] (a worker finding
    /// and taking the cell, the filters' start).
    pub first_estimate_ms: f64,
    /// The first few `error` and `finding` events, with their cell.
    pub notes: Vec<String>,
    /// How far behind real time a publisher got a chunk out at worst [s] (the DAQ side).
    pub publisher_lag_s: f64,
    /// The p99 latency ≤ 250 ms, no publisher more than 250 ms behind, every sample
    /// processed once.
    pub real_time: bool,
    /// CPU used by this process (publishers, workers, the bench's subscriber) over the run, in
    /// cores (CPU seconds per wall-clock second).
    pub cpu_physid: Option<f64>,
    /// CPU used by the nats-server this run started, in cores.
    pub cpu_server: Option<f64>,
    /// Through the server: messages in and out per second.
    pub msgs_per_s: Option<[f64; 2]>,
    /// Through the server: bytes in and out per second.
    pub bytes_per_s: Option<[f64; 2]>,
}

/// CPU seconds (user + system) a process has used, from `/proc/PID/stat` (Linux; its clock
/// ticks are USER_HZ = 100 per second); `None` elsewhere.
fn cpu_seconds(pid: &str) -> Option<f64> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // The fields after the command name (which may contain spaces) in parentheses.
    let rest = stat.rsplit_once(')')?.1;
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

/// The events seen by the bench's subscriber.
#[derive(Default, Clone)]
struct Seen {
    latency: LatencyHistogram,
    estimates: u64,
    /// Cells whose first estimate has come, and the longest wait for one [ms].
    first: std::collections::HashSet<String>,
    first_ms: f64,
    /// Samples counted by each cell's `end` event.
    ends: HashMap<String, u64>,
    /// The first few errors and findings.
    notes: Vec<String>,
}

/// The load recordings: `distinct` speeds over `rpm`, `seconds` each, one sample per degree.
fn recordings(cfg: &LoadConfig, distinct: usize) -> Result<Vec<(f64, Recording)>, FleetError> {
    let mut out = Vec::new();
    for k in 0..distinct {
        let f = if distinct > 1 {
            k as f64 / (distinct - 1) as f64
        } else {
            0.0
        };
        let rpm = cfg.rpm.0 + f * (cfg.rpm.1 - cfg.rpm.0);
        let mut scenario =
            Scenario::load("shaft-steady").map_err(|e| FleetError::Invalid(e.to_string()))?;
        scenario.speed = Profile::constant(rpm, cfg.seconds);
        let opts = RunOptions {
            duration: Some(cfg.seconds),
            basis: OutputBasis::Time(6.0 * rpm),
            ..Default::default()
        };
        let mut src = ScenarioSource::new(&scenario, &opts, 1.0)?;
        let mut cols: Vec<Channel> = Vec::new();
        while let Some(chunk) = src.next_chunk()? {
            for (j, name) in LOAD_CHANNELS.iter().enumerate() {
                let c = chunk.channel(name).map_err(crate::LiveError::from)?;
                if cols.len() <= j {
                    cols.push(Channel {
                        name: c.name.clone(),
                        unit: c.unit.clone(),
                        values: Vec::new(),
                    });
                }
                cols[j].values.extend_from_slice(&c.values);
            }
        }
        let mut rec = Recording::new(Basis::Time);
        for c in cols {
            rec.push(c).map_err(crate::LiveError::from)?;
        }
        out.push((6.0 * rpm, rec));
    }
    Ok(out)
}

/// Run the load: `server` started by the caller (its `/varz` is read), or `target` alone.
pub fn run_load(
    target: &NatsTarget,
    server: Option<&LocalServer>,
    cfg: &LoadConfig,
) -> Result<LoadReport, FleetError> {
    if cfg.cells == 0 || cfg.workers == 0 {
        return Err(FleetError::Invalid(
            "--cells and --workers: at least 1".into(),
        ));
    }
    let recs = recordings(cfg, cfg.cells.min(5))?;
    let samples_per_s: f64 = (0..cfg.cells).map(|k| recs[k % recs.len()].0).sum();
    let stop = Arc::new(AtomicBool::new(false));
    let stats = Arc::new(WorkerStats::default());
    let mut workers = Vec::new();
    for w in 0..cfg.workers {
        let (target, stop, stats) = (target.clone(), stop.clone(), stats.clone());
        let wcfg = WorkerConfig {
            name: format!("load-worker-{w}"),
            live: LiveConfig::default(),
            give_up: Duration::from_secs(60),
        };
        workers.push(std::thread::spawn(move || {
            run_worker(&target, &wcfg, stop, stats)
        }));
    }
    // The events of every cell, as they arrive.
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .map_err(|e| FleetError::Invalid(e.to_string()))?;
    let starts: Arc<Mutex<HashMap<String, Instant>>> = Arc::default();
    let seen = Arc::new(Mutex::new(Seen::default()));
    let client = rt.block_on(target.connect(
        "physid bench fleet",
        Duration::from_secs(10),
        Arc::default(),
    ))?;
    let mut sub = rt
        .block_on(client.subscribe("physid.cell.*.events"))
        .map_err(|e| super::nats("subscribing to the events")(e.into()))?;
    {
        let (starts, seen) = (starts.clone(), seen.clone());
        rt.spawn(async move {
            while let Some(msg) = sub.next().await {
                let now = Instant::now();
                let cell = msg
                    .subject
                    .as_str()
                    .trim_start_matches("physid.cell.")
                    .trim_end_matches(".events")
                    .to_string();
                let Ok(e) = serde_json::from_slice::<serde_json::Value>(&msg.payload) else {
                    continue;
                };
                let start = starts.lock().ok().and_then(|s| s.get(&cell).copied());
                let Ok(mut seen) = seen.lock() else { continue };
                match (e["type"].as_str(), e["t_s"].as_f64(), start) {
                    (Some("estimate"), Some(t), Some(start)) => {
                        seen.estimates += 1;
                        if seen.first.insert(cell) {
                            seen.first_ms = seen.first_ms.max(1e3 * (now - start).as_secs_f64());
                        }
                        if t >= SETTLE_S {
                            // An event's time from the server: saturated, never a panic.
                            let due = Duration::try_from_secs_f64(t)
                                .ok()
                                .and_then(|d| start.checked_add(d))
                                .unwrap_or(start);
                            seen.latency
                                .add(now.saturating_duration_since(due).as_secs_f64());
                        }
                    }
                    (Some("error" | "finding"), _, _) if seen.notes.len() < 5 => {
                        seen.notes.push(format!("{cell}: {}", e["message"]));
                    }
                    (Some("end"), _, _) => {
                        let n = e["samples"].as_u64().unwrap_or(0);
                        seen.ends.insert(cell, n);
                    }
                    _ => {}
                }
            }
        });
    }
    let varz0 = server.and_then(|s| s.varz().ok());
    let cpu0 = (
        cpu_seconds("self"),
        server
            .and_then(LocalServer::pid)
            .and_then(|p| cpu_seconds(&p.to_string())),
    );
    let t0 = Instant::now();
    let mut publishers = Vec::new();
    for k in 0..cfg.cells {
        let (rate, rec) = &recs[k % recs.len()];
        let cell = format!("load-{k}");
        let pcfg = PublishConfig {
            cell: cell.clone(),
            pace: Pace::Factor(1.0),
            source_name: format!("bench fleet, {:.0} rpm", rate / 6.0),
            theta_tdc: 0.0,
            give_up: Duration::from_secs(60),
            frame_s: cfg.frame_s,
        };
        let mut source = ReplaySource::new(rec.clone(), cfg.chunk_s)?;
        let (target, stop, starts) = (
            target.clone(),
            Arc::new(AtomicBool::new(false)),
            starts.clone(),
        );
        publishers.push(std::thread::spawn(move || {
            if let Ok(mut s) = starts.lock() {
                s.insert(cell, Instant::now());
            }
            let summary = publish(&mut source, &target, &pcfg, stop)?;
            Ok::<_, FleetError>((summary, summary.max_behind_s.unwrap_or(0.0)))
        }));
    }
    let mut published = 0;
    let mut resent = 0;
    let mut lag: f64 = 0.0;
    for p in publishers {
        let (summary, behind) = p
            .join()
            .map_err(|_| FleetError::Invalid("a publisher thread failed".into()))??;
        published += summary.samples;
        resent += summary.retries;
        lag = lag.max(behind);
    }
    // Every cell's end, or 60 s.
    let deadline = Instant::now() + Duration::from_secs(60);
    while Instant::now() < deadline {
        if seen.lock().map_or(0, |s| s.ends.len()) >= cfg.cells {
            break;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let wall = t0.elapsed().as_secs_f64();
    let varz1 = server.and_then(|s| s.varz().ok());
    let cpu1 = (
        cpu_seconds("self"),
        server
            .and_then(LocalServer::pid)
            .and_then(|p| cpu_seconds(&p.to_string())),
    );
    let cores = |a: Option<f64>, b: Option<f64>| Some((b? - a?) / wall);
    stop.store(true, Ordering::Relaxed);
    for w in workers {
        let _ = w.join();
    }
    let Seen {
        latency: hist,
        estimates,
        ends,
        first_ms,
        notes,
        ..
    } = seen
        .lock()
        .map_err(|_| FleetError::Invalid("the event counter failed".into()))?
        .clone();
    let processed: u64 = ends.values().sum();
    let latency_ms = hist.summary_ms().unwrap_or([f64::NAN; 3]);
    let refused = stats.refused.load(Ordering::Relaxed);
    let rate_of = |key: &str| match (&varz0, &varz1) {
        (Some(a), Some(b)) => {
            let d = |k: &str| b[k].as_f64().unwrap_or(0.0) - a[k].as_f64().unwrap_or(0.0);
            Some([
                d(&format!("in_{key}")) / wall,
                d(&format!("out_{key}")) / wall,
            ])
        }
        _ => None,
    };
    Ok(LoadReport {
        cells: cfg.cells,
        workers: cfg.workers,
        seconds: cfg.seconds,
        samples_per_s,
        samples_published: published,
        samples_processed: processed,
        cells_ended: ends.len(),
        frames_refused: refused,
        frames_resent: resent,
        estimates,
        latency_ms,
        first_estimate_ms: first_ms,
        notes,
        publisher_lag_s: lag,
        real_time: latency_ms[1] <= 250.0
            && lag <= 0.25
            && processed == published
            && ends.len() == cfg.cells
            && refused == 0,
        cpu_physid: cores(cpu0.0, cpu1.0),
        cpu_server: cores(cpu0.1, cpu1.1),
        msgs_per_s: rate_of("msgs"),
        bytes_per_s: rate_of("bytes"),
    })
}
