//! `physid worker --nats URL`: the applications' stages for whichever cells need them.
//!
//! * **One worker per cell at a time.** A worker takes a cell by creating its key in
//!   [`LEASES_BUCKET`] (which fails while another holds it) and renews it every second; the
//!   bucket forgets a key not renewed for [`LEASE_TTL`], so a worker that dies — `kill -9`, a
//!   lost machine — frees its cells within that time.
//! * **In order, each frame once.** A cell's frames are read from its samples subject in stream
//!   order by an ordered consumer; a frame whose number is not the next is refused (a duplicate,
//!   out of order) or, ahead, taken with a finding naming the frames missing.
//! * **Failover without loss.** Every [`CHECKPOINT_EVERY`] (and when stopped) the worker writes
//!   the cell's checkpoint — the stages' state ([`Stages::checkpoint`]: estimator, detector,
//!   filter memory, cycle statistics), the run, the last frame and its stream sequence — after
//!   the events so far are stored. A worker taking a cell over restores the checkpoint and reads
//!   on from the next stream sequence: the frames after the checkpoint are processed again from
//!   the same state, so they give the same events, and the events' message ids
//!   (`<cell>/<run>/<stream sequence>/<k>`) make the stream store each once. The checkpoint is
//!   written only over the revision this worker wrote (compare and set): a worker that lost its
//!   cell cannot overwrite its successor's. A state larger than the server's message limit is
//!   stored in parts ([`checkpoint`](super::checkpoint)). A checkpoint this worker cannot take
//!   up (of another layout, or no checkpoint) is told as an `error` event (`"input":
//!   "checkpoint"`) and the cell is processed from its run's first frame — failing the cell's
//!   task instead would fail it again at every take, for ever.
//! * **Bad input** — a frame that is not a frame, another cell's frame, a wrong schema, frames on
//!   the subject of a cell nobody registered — is counted and reported as an `error` event with
//!   the reason, never absorbed into an estimate, and the worker goes on.

use super::checkpoint::{self, Checkpoint};
use super::{
    nats, send_until_acked, subject, CellInfo, Fleet, FleetError, NatsTarget, CELLS_BUCKET,
    CHECKPOINTS_BUCKET, LEASE_TTL,
};
use crate::event::{Event, Input};
use crate::service::{LiveConfig, Stages};
use crate::wire;
use async_nats::jetstream::consumer::{pull::OrderedConfig, DeliverPolicy};
use futures_util::StreamExt;
use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// How often a worker looks for cells that need a worker.
pub const DISCOVER_EVERY: Duration = Duration::from_millis(500);

/// How often a worker looks for frames of cells nobody registered.
pub const UNKNOWN_SCAN: Duration = Duration::from_secs(2);

/// How often a cell's checkpoint is written.
pub const CHECKPOINT_EVERY: Duration = Duration::from_secs(1);

/// How a worker runs.
#[derive(Debug, Clone)]
pub struct WorkerConfig {
    /// The worker's name (in leases and logs).
    pub name: String,
    /// The stages' settings (the shaft monitor's; headless, as fast as the frames come).
    pub live: LiveConfig,
    /// Give up an event the server has not acknowledged for this long.
    pub give_up: Duration,
}

/// What a worker did.
#[derive(Debug, Default)]
pub struct WorkerStats {
    /// Cells taken (a cell taken again after losing it counts again).
    pub taken: AtomicU64,
    /// Frames processed.
    pub frames: AtomicU64,
    /// Frames refused.
    pub refused: AtomicU64,
    /// Events published.
    pub events: AtomicU64,
}

/// Run a worker until `stop` (SIGTERM): take the cells that need one, process their frames,
/// checkpoint them; at `stop`, checkpoint every cell and free it for another worker.
pub fn run_worker(
    target: &NatsTarget,
    cfg: &WorkerConfig,
    stop: Arc<AtomicBool>,
    stats: Arc<WorkerStats>,
) -> Result<(), FleetError> {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .map_err(|e| FleetError::Invalid(format!("starting the NATS client: {e}")))?;
    rt.block_on(supervise(target, cfg, stop, stats))
}

/// A cell this worker has: its lease's revision and its task.
struct Owned {
    revision: u64,
    stop: Arc<AtomicBool>,
    task: tokio::task::JoinHandle<Result<(), FleetError>>,
}

async fn supervise(
    target: &NatsTarget,
    cfg: &WorkerConfig,
    stop: Arc<AtomicBool>,
    stats: Arc<WorkerStats>,
) -> Result<(), FleetError> {
    let connections = Arc::new(AtomicU64::new(0));
    let client = target
        .connect(
            &format!("physid worker {}", cfg.name),
            Duration::from_secs(10),
            connections.clone(),
        )
        .await?;
    let fleet = Arc::new(Fleet::open(client).await?);
    let mut owned: HashMap<String, Owned> = HashMap::new();
    let mut unknown_told: HashSet<String> = HashSet::new();
    let mut bad_told: HashSet<String> = HashSet::new();
    let mut tick = tokio::time::interval(DISCOVER_EVERY);
    // Runs known to be processed to their end (not looked up again).
    let mut done_runs: HashMap<String, u64> = HashMap::new();
    let mut renew_due = tokio::time::Instant::now();
    let mut scan_due = tokio::time::Instant::now();
    while !stop.load(Ordering::Relaxed) {
        tick.tick().await;
        // Cells whose task has ended (the run is done, or it failed): freed.
        let ended: Vec<String> = owned
            .iter()
            .filter(|(_, o)| o.task.is_finished())
            .map(|(c, _)| c.clone())
            .collect();
        for cell in ended {
            if let Some(o) = owned.remove(&cell) {
                if let Ok(Err(e)) = o.task.await {
                    eprintln!("physid worker {}: cell {cell}: {e}", cfg.name);
                }
                free_lease(&fleet, &cell, o.revision).await;
            }
        }
        // Renew the leases (a third of their life); one not renewed is lost: stop its task.
        // All at once, not one round trip after another: a loaded server answering in 20 ms
        // would otherwise take 3 s — a whole lease's life — to renew 150 cells.
        if tokio::time::Instant::now() >= renew_due {
            renew_due = tokio::time::Instant::now() + LEASE_TTL / 3;
            let renewals = owned.iter().map(|(cell, o)| {
                let (leases, name) = (&fleet.leases, cfg.name.clone());
                async move {
                    (
                        cell.clone(),
                        leases.update(cell, name.into(), o.revision).await,
                    )
                }
            });
            let mut lost = Vec::new();
            for (cell, renewed) in futures_util::future::join_all(renewals).await {
                match (renewed, owned.get_mut(&cell)) {
                    (Ok(r), Some(o)) => o.revision = r,
                    _ => lost.push(cell),
                }
            }
            for cell in lost {
                if let Some(o) = owned.remove(&cell) {
                    eprintln!("physid worker {}: lost the lease on cell {cell}", cfg.name);
                    o.stop.store(true, Ordering::Relaxed);
                    let _ = o.task.await;
                }
            }
        }
        // Subjects with frames, listed before the registry is read (a publisher registers
        // its cell before its first frame: a subject listed here whose cell is not in the
        // registry read after it has none).
        let scan = tokio::time::Instant::now() >= scan_due;
        let mut subjects = Vec::new();
        if scan {
            scan_due = tokio::time::Instant::now() + UNKNOWN_SCAN;
            if let Ok(mut list) = fleet
                .samples
                .clone()
                .info_with_subjects("physid.cell.*.samples")
                .await
            {
                while let Some(Ok(s)) = list.next().await {
                    subjects.push(s);
                }
            }
        }
        // The registered cells: take those nobody has.
        let Ok(registry) = registered(&fleet).await else {
            continue;
        };
        for (cell, info) in &registry {
            let info = match info {
                Ok(i) => i,
                Err(why) => {
                    // Told once per worker and reason; the cell is not processed.
                    if bad_told.insert(format!("{cell}: {why}")) && wire::valid_cell(cell) {
                        let e = Event::Error {
                            t_s: f64::NAN,
                            input: Input::Registry,
                            line: 0,
                            message: format!(
                                "the {CELLS_BUCKET} entry of '{cell}': {why}; the cell is not processed"
                            ),
                        };
                        let json = serde_json::to_vec(&e).unwrap_or_default();
                        let _ = send_until_acked(
                            &fleet.js,
                            subject(cell, "events"),
                            json.into(),
                            format!("{cell}/registry/{}", bad_told.len()),
                            cfg.give_up,
                        )
                        .await;
                    }
                    continue;
                }
            };
            if owned.contains_key(cell) || done_runs.get(cell) == Some(&info.run) {
                continue;
            }
            if checkpoint::finished(&fleet, &info.cell, info.run).await {
                done_runs.insert(cell.clone(), info.run);
                continue;
            }
            let Ok(revision) = fleet.leases.create(cell, cfg.name.clone().into()).await else {
                continue;
            };
            stats.taken.fetch_add(1, Ordering::Relaxed);
            let task_stop = Arc::new(AtomicBool::new(false));
            let task = tokio::spawn(process_cell(
                fleet.clone(),
                info.clone(),
                cfg.clone(),
                connections.clone(),
                task_stop.clone(),
                stats.clone(),
            ));
            owned.insert(
                cell.clone(),
                Owned {
                    revision,
                    stop: task_stop,
                    task,
                },
            );
        }
        // Frames on the subject of a cell nobody registered: told once per worker.
        for (subj, count) in subjects {
            let Some(cell) = subj
                .strip_prefix("physid.cell.")
                .and_then(|s| s.strip_suffix(".samples"))
            else {
                continue;
            };
            if registry.contains_key(cell) || !unknown_told.insert(cell.to_string()) {
                continue;
            }
            stats.refused.fetch_add(count as u64, Ordering::Relaxed);
            let e = Event::Error {
                t_s: f64::NAN,
                input: Input::Frames,
                line: 0,
                message: format!(
                    "unknown cell '{cell}': {count} frame(s) on {subj} but no entry in the \
                     {CELLS_BUCKET} bucket — a publisher registers its cell first \
                     (physid live --nats does); these frames are not processed"
                ),
            };
            let json = serde_json::to_vec(&e).unwrap_or_default();
            let _ = send_until_acked(
                &fleet.js,
                subject(cell, "events"),
                json.into(),
                format!("{cell}/unknown"),
                cfg.give_up,
            )
            .await;
        }
    }
    // Stopped: every cell checkpointed and freed at once (not after the lease's expiry).
    for (cell, o) in owned {
        o.stop.store(true, Ordering::Relaxed);
        if let Ok(Err(e)) = o.task.await {
            eprintln!("physid worker {}: cell {cell}: {e}", cfg.name);
        }
        free_lease(&fleet, &cell, o.revision).await;
    }
    Ok(())
}

/// Free this worker's lease on `cell` if it still holds it — the lease it last wrote, at
/// `revision`. A lease lost meanwhile (it expired while this worker stalled, and another worker
/// took the cell) is the other's: deleting it, as before, let a third worker take the cell
/// while the other still worked on it — the cell's events twice.
async fn free_lease(fleet: &Fleet, cell: &str, revision: u64) {
    let _ = fleet
        .leases
        .delete_expect_revision(cell, Some(revision))
        .await;
}

/// The registry: every entry, read and checked (an entry that is not a valid cell's: the
/// reason).
async fn registered(
    fleet: &Fleet,
) -> Result<HashMap<String, Result<CellInfo, String>>, FleetError> {
    let mut keys = fleet
        .cells
        .keys()
        .await
        .map_err(|e| nats(format!("listing {CELLS_BUCKET}"))(e.into()))?;
    let mut out = HashMap::new();
    while let Some(Ok(key)) = keys.next().await {
        if let Ok(Some(v)) = fleet.cells.get(&key).await {
            let info = serde_json::from_slice::<CellInfo>(&v)
                .map_err(|e| format!("not a registry entry ({e})"))
                .and_then(|i| {
                    if i.cell != key {
                        Err(format!("its 'cell' is '{}', its key '{key}'", i.cell))
                    } else if !(i.rate_hz.is_finite() && i.rate_hz > 0.0) {
                        Err(format!(
                            "'rate_hz' is {}: expected > 0",
                            physid_core::Num(i.rate_hz)
                        ))
                    } else if !i.theta_tdc.is_finite() {
                        Err(format!("'theta_tdc' is {}: expected a number", i.theta_tdc))
                    } else {
                        Ok(i)
                    }
                });
            out.insert(key, info);
        }
    }
    Ok(out)
}

type Emit = Box<dyn FnMut(&Event) -> Result<(), String> + Send>;

/// One cell's frames through the stages, from its checkpoint on, until its end frame or `stop`.
async fn process_cell(
    fleet: Arc<Fleet>,
    info: CellInfo,
    cfg: WorkerConfig,
    connections: Arc<AtomicU64>,
    stop: Arc<AtomicBool>,
    stats: Arc<WorkerStats>,
) -> Result<(), FleetError> {
    let cell = info.cell.clone();
    let (tx, rx) = std::sync::mpsc::channel::<Event>();
    let emit = || -> Emit {
        let tx = tx.clone();
        Box::new(move |e: &Event| tx.send(e.clone()).map_err(|e| e.to_string()))
    };
    let mut live = cfg.live.clone();
    live.theta_tdc = info.theta_tdc;
    live.panel = None;
    live.pace = crate::source::Pace::Max;
    let (previous, mut writer) = checkpoint::read(&fleet, &cell).await?;
    // The checkpoint of this run taken up: the stages, the last frame, the next stream
    // sequence (`Ok(None)`: there is none; `Err`: it cannot be taken up, and why).
    let taken_up = match previous {
        Ok(Some(c)) if c.run == info.run => {
            if c.done {
                return Ok(());
            }
            Stages::restore(live.clone(), &c.state, emit())
                .map(|st| Some((st, c.seq, c.stream_seq + 1)))
                .map_err(|e| e.to_string())
        }
        Ok(_) => Ok(None),
        Err(why) => Err(why),
    };
    let (stages, mut seq, start) = match taken_up {
        Ok(Some(s)) => s,
        Ok(None) => (Stages::new(live, info.rate_hz, emit())?, 0, 1),
        Err(why) => {
            // Failing the cell's task here would fail it again at every take, for ever.
            tell_unusable_checkpoint(&fleet, &info, &cfg, &why).await;
            (Stages::new(live, info.rate_hz, emit())?, 0, 1)
        }
    };
    let mut stages = Some(stages);
    eprintln!(
        "physid worker {}: took cell {cell} (run {}) at stream sequence {start}, after frame {seq}",
        cfg.name, info.run
    );
    let mut last_stream_seq = start - 1;
    let mut checkpoint_due = tokio::time::Instant::now() + CHECKPOINT_EVERY;
    let mut done = false;
    let events_subject = subject(&cell, "events");
    // The frames from `last_stream_seq + 1` on, read again after every reconnection (a
    // server restart) or consumer error.
    let mut frames = None;
    let mut opened_at = 0;
    while !stop.load(Ordering::Relaxed) && !done {
        let now = connections.load(Ordering::Relaxed);
        if frames.is_none() || opened_at != now {
            opened_at = now;
            frames = open_frames(&fleet, &cell, last_stream_seq + 1).await.ok();
            if frames.is_none() {
                tokio::time::sleep(Duration::from_millis(200)).await;
                continue;
            }
        }
        let Some(messages) = frames.as_mut() else {
            continue;
        };
        let msg = match tokio::time::timeout(Duration::from_millis(200), messages.next()).await {
            Ok(Some(Ok(m))) => Some(m),
            Ok(Some(Err(_)) | None) => {
                frames = None;
                None
            }
            Err(_) => None,
        };
        if let Some(msg) = msg {
            let stream_seq = msg
                .info()
                .map_or(last_stream_seq + 1, |i| i.stream_sequence);
            last_stream_seq = stream_seq;
            let Some(st) = stages.as_mut() else { break };
            let outcome = take_frame(st, &info, &mut seq, stream_seq, &msg.payload)?;
            match outcome {
                Outcome::Taken => {
                    stats.frames.fetch_add(1, Ordering::Relaxed);
                }
                Outcome::Refused => {
                    stats.refused.fetch_add(1, Ordering::Relaxed);
                }
                Outcome::OldRun => {}
                Outcome::NewerRun(run) if registered_run(&fleet, &cell).await == Some(run) => {
                    // The publisher started a new run without ending this one (it was killed,
                    // its machine restarted): this run ends here, and the cell's next take
                    // processes the new one. Refusing its frames would refuse them for ever.
                    st.send(&Event::finding(
                        f64::NAN,
                        format!(
                            "the cell's publisher started run {run} without ending run {}: run \
                             {} ends here, after frame {seq}; run {run} is processed next",
                            info.run, info.run
                        ),
                    ))?;
                    done = true;
                    if let Some(st) = stages.take() {
                        st.finish()?;
                    }
                }
                Outcome::NewerRun(run) => {
                    stats.refused.fetch_add(1, Ordering::Relaxed);
                    st.refuse(
                        Input::Frames,
                        stream_seq as usize,
                        format!(
                            "frame at stream sequence {stream_seq}: a frame of run {run} while \
                             the registry's run is {}",
                            info.run
                        ),
                    )?;
                }
                Outcome::End => {
                    stats.frames.fetch_add(1, Ordering::Relaxed);
                    done = true;
                    // The stages' last output and the `end` event.
                    if let Some(st) = stages.take() {
                        st.finish()?;
                    }
                }
            }
            let mut k = 0;
            while let Ok(e) = rx.try_recv() {
                let json = serde_json::to_vec(&e)
                    .map_err(|e| FleetError::Invalid(format!("an event as JSON: {e}")))?;
                let id = format!("{cell}/{}/{stream_seq}/{k}", info.run);
                send_until_acked(
                    &fleet.js,
                    events_subject.clone(),
                    json.into(),
                    id,
                    cfg.give_up,
                )
                .await?;
                stats.events.fetch_add(1, Ordering::Relaxed);
                k += 1;
            }
        }
        if let (Some(st), true) = (&stages, tokio::time::Instant::now() >= checkpoint_due) {
            checkpoint_due = tokio::time::Instant::now() + CHECKPOINT_EVERY;
            let c = Checkpoint {
                run: info.run,
                seq,
                stream_seq: last_stream_seq,
                done: false,
                state: st.checkpoint()?,
                parts: None,
            };
            writer.put(&fleet, &cell, c).await?;
        }
    }
    let state = match (&stages, done) {
        (Some(st), false) => st.checkpoint()?,
        _ => Vec::new(),
    };
    let c = Checkpoint {
        run: info.run,
        seq,
        stream_seq: last_stream_seq,
        done,
        state,
        parts: None,
    };
    writer.put(&fleet, &cell, c).await?;
    Ok(())
}

/// Tell, on `info`'s events subject (once per run: the message id) and on stderr, that the cell's
/// checkpoint cannot be taken up (`why`) and that the cell is processed from its run's first
/// frame.
async fn tell_unusable_checkpoint(fleet: &Fleet, info: &CellInfo, cfg: &WorkerConfig, why: &str) {
    let cell = &info.cell;
    let message = format!(
        "the checkpoint of {cell} in {CHECKPOINTS_BUCKET} cannot be taken up: {why}; the cell \
         is processed from its run's first frame the stream holds, as without a checkpoint"
    );
    eprintln!("physid worker {}: {message}", cfg.name);
    let e = Event::Error {
        t_s: f64::NAN,
        input: Input::Checkpoint,
        line: 0,
        message,
    };
    let json = serde_json::to_vec(&e).unwrap_or_default();
    let id = format!("{cell}/{}/checkpoint", info.run);
    if let Err(e) = send_until_acked(
        &fleet.js,
        subject(cell, "events"),
        json.into(),
        id,
        cfg.give_up,
    )
    .await
    {
        eprintln!("physid worker {}: cell {cell}: {e}", cfg.name);
    }
}

/// The run the registry has for `cell` now (`None`: no entry, or not one that reads).
async fn registered_run(fleet: &Fleet, cell: &str) -> Option<u64> {
    let v = fleet.cells.get(cell).await.ok()??;
    serde_json::from_slice::<CellInfo>(&v).ok().map(|i| i.run)
}

/// An ordered consumer of `cell`'s frames from stream sequence `start` on.
async fn open_frames(
    fleet: &Fleet,
    cell: &str,
    start: u64,
) -> Result<async_nats::jetstream::consumer::pull::Ordered, FleetError> {
    let what = || format!("reading the frames of {cell}");
    fleet
        .samples
        .create_consumer(OrderedConfig {
            filter_subject: subject(cell, "samples"),
            deliver_policy: DeliverPolicy::ByStartSequence {
                start_sequence: start,
            },
            ..Default::default()
        })
        .await
        .map_err(|e| nats(what())(e.into()))?
        .messages()
        .await
        .map_err(|e| nats(what())(e.into()))
}

/// What became of a frame.
enum Outcome {
    Taken,
    Refused,
    /// A frame of an earlier run of the cell (before its current run started): passed over.
    OldRun,
    /// A frame of a later run than the one being processed: the publisher started it (when
    /// the registry says so), else refused.
    NewerRun(u64),
    End,
}

/// One frame checked and through the stages (or refused, with an `error` event).
fn take_frame(
    stages: &mut Stages<Emit>,
    info: &CellInfo,
    seq: &mut u64,
    stream_seq: u64,
    payload: &[u8],
) -> Result<Outcome, FleetError> {
    let refuse = |stages: &mut Stages<Emit>, why: String| -> Result<Outcome, FleetError> {
        stages.refuse(
            Input::Frames,
            stream_seq as usize,
            format!("frame at stream sequence {stream_seq}: {why}"),
        )?;
        Ok(Outcome::Refused)
    };
    let frame = match wire::decode(payload) {
        Ok(f) => f,
        Err(e) => return refuse(stages, e.0),
    };
    if frame.cell != info.cell {
        return refuse(
            stages,
            format!(
                "a frame of cell '{}' on cell '{}''s subject",
                frame.cell, info.cell
            ),
        );
    }
    if frame.run < info.run {
        return Ok(Outcome::OldRun);
    }
    if frame.run > info.run {
        return Ok(Outcome::NewerRun(frame.run));
    }
    if frame.seq <= *seq {
        return refuse(
            stages,
            format!(
                "frame {} again or out of order (frames up to {} are processed): not counted",
                frame.seq, *seq
            ),
        );
    }
    if frame.rate_hz != info.rate_hz {
        return refuse(
            stages,
            format!(
                "a rate of {} Hz; the cell's is {} Hz",
                frame.rate_hz, info.rate_hz
            ),
        );
    }
    if frame.seq > *seq + 1 || frame.first_sample != stages.samples() as u64 {
        let t_s = f64::NAN;
        stages.send(&Event::finding(
            t_s,
            format!(
                "frames {}–{} are missing (samples {}–{}): the stream has a gap",
                *seq + 1,
                frame.seq - 1,
                stages.samples(),
                frame.first_sample.saturating_sub(1)
            ),
        ))?;
    }
    *seq = frame.seq;
    if !frame.chunk.is_empty() {
        // A frame the stages cannot take (e.g. an angle that is not finite for the cycle
        // statistics) is reported; the cell goes on with the next (run_live would stop: a
        // worker must not stop a cell, nor retake it to fail on the same frame for ever).
        if let Err(e) = stages.chunk(&frame.chunk) {
            return refuse(stages, format!("the stages could not take it: {e}"));
        }
    }
    if frame.end {
        return Ok(Outcome::End);
    }
    Ok(Outcome::Taken)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::fleet::local::{nats_server_bin, LocalServer};

    /// A worker frees its own lease, and not one it has lost to another worker: the other's
    /// stays. On a real nats-server started here.
    #[test]
    fn a_worker_frees_only_the_lease_it_holds() {
        if nats_server_bin().is_none() {
            eprintln!("skipped: nats-server is not installed (apt-get install nats-server)");
            return;
        }
        let server = LocalServer::start(&[]).unwrap();
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        rt.block_on(async {
            let client = async_nats::connect(server.url("")).await.unwrap();
            let fleet = Fleet::open(client).await.unwrap();
            let held = fleet.leases.create("c1", "a".into()).await.unwrap();
            // Lost: expired (here deleted) and taken by worker b.
            fleet.leases.delete("c1").await.unwrap();
            fleet.leases.create("c1", "b".into()).await.unwrap();
            free_lease(&fleet, "c1", held).await;
            let holder = fleet.leases.get("c1").await.unwrap();
            assert_eq!(
                holder.as_deref(),
                Some(&b"b"[..]),
                "b's lease was freed by a"
            );
            // Renewed and held: freed.
            let r = fleet.leases.create("c2", "a".into()).await.unwrap();
            let r = fleet.leases.update("c2", "a".into(), r).await.unwrap();
            free_lease(&fleet, "c2", r).await;
            assert!(fleet.leases.get("c2").await.unwrap().is_none());
        });
    }
}
