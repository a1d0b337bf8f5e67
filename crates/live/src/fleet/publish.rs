//! `physid live --nats URL --cell ID`: a cell's samples on the fleet. The source's chunks (the
//! virtual test cell, a replayed recording) are gathered into frames of
//! [`PublishConfig::frame_s`] (cut where the server's message size needs it), numbered, and
//! published to `physid.cell.<ID>.samples` with the message id `<ID>/<run>/<seq>` — a frame
//! sent again after a lost acknowledgement (a server restart) is stored once. Each frame is sent until the stream acknowledges it: none is lost while the
//! server is away; the source waits. Control messages (`physid.cell.<ID>.control`, request and
//! reply, the JSON of `physid live`'s controls) are applied between chunks; each is answered
//! and reported on the events subject as the local live service reports it.

use super::{nats, send_until_acked, subject, CellInfo, Fleet, FleetError, NatsTarget};
use crate::control::Control;
use crate::event::{Event, Input};
use crate::message::Reply;
use crate::source::{Pace, Pacer, Source};
use crate::wire::{self, Frame};
use futures_util::StreamExt;
use physid_core::{Basis, Recording};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};
use tokio::sync::mpsc::UnboundedReceiver;

/// How a cell publishes.
#[derive(Debug, Clone)]
pub struct PublishConfig {
    /// The cell id (see [`wire::valid_cell`]).
    pub cell: String,
    /// How fast against the wall clock.
    pub pace: Pace,
    /// What is published, for the registry (a scenario's name, a file).
    pub source_name: String,
    /// The angle of a firing TDC on `theta_en` [rad], for the workers' cycle statistics.
    pub theta_tdc: f64,
    /// Give up a frame the server has not acknowledged for this long (the server is gone).
    pub give_up: Duration,
    /// The recording time a frame carries [s]: the source's chunks are gathered into frames of
    /// this much, to the nearest chunk (0: a frame per chunk). The server's and the worker's
    /// cost is mostly per message, not per sample (BENCHMARKS.md, issue 47); the price is up
    /// to this much more latency.
    pub frame_s: f64,
}

/// The default of [`PublishConfig::frame_s`] [s]: 20 frames a second per cell, a latency the
/// shaft monitor's 34 ms look-ahead and its alarms' dwell already exceed.
pub const FRAME_S: f64 = 0.05;

/// What a publisher did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PublishSummary {
    /// Frames published (the end frame included).
    pub frames: u64,
    /// Samples published.
    pub samples: u64,
    /// Control messages taken.
    pub controls: u64,
    /// Frames sent more than once (an acknowledgement lost: stored once all the same).
    pub retries: u64,
    /// How far behind the wall clock a chunk got out at worst [s]: from its last sample being
    /// due (paced) to the stream having it all (`None` at `--pace max`).
    pub max_behind_s: Option<f64>,
}

/// A control message from NATS with where its answer goes.
struct Request {
    text: String,
    reply: tokio::sync::oneshot::Sender<String>,
}

/// Publish `source` as cell `cfg.cell` until its end or `stop` (SIGTERM): the run is
/// registered in [`super::CELLS_BUCKET`], its frames published in order, an end frame last.
pub fn publish(
    source: &mut dyn Source,
    target: &NatsTarget,
    cfg: &PublishConfig,
    stop: Arc<AtomicBool>,
) -> Result<PublishSummary, FleetError> {
    if !wire::valid_cell(&cfg.cell) {
        return Err(FleetError::Invalid(format!(
            "--cell '{}': expected 1–64 of A–Z a–z 0–9 - _",
            cfg.cell
        )));
    }
    // The client runs on this thread: every wait (the pace, an acknowledgement, a control while
    // paused) is inside `block_on`, which drives the connection and answers the controls; no
    // second thread to wake per frame.
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .map_err(|e| FleetError::Invalid(format!("starting the NATS client: {e}")))?;
    let client = rt.block_on(target.connect(
        &format!("physid live {}", cfg.cell),
        Duration::from_secs(10),
        Arc::default(),
    ))?;
    let fleet = rt.block_on(Fleet::open(client.clone()))?;
    let run = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as u64);
    let info = CellInfo {
        cell: cfg.cell.clone(),
        run,
        rate_hz: source.rate_hz(),
        source: cfg.source_name.clone(),
        theta_tdc: cfg.theta_tdc,
    };
    let json = serde_json::to_vec(&info).map_err(|e| FleetError::Invalid(e.to_string()))?;
    rt.block_on(fleet.cells.put(&cfg.cell, json.into()))
        .map_err(|e| nats(format!("registering cell {}", cfg.cell))(e.into()))?;
    // Controls: answered by the loop between chunks.
    let (tx, mut rx) = tokio::sync::mpsc::unbounded_channel::<Request>();
    let control_subject = subject(&cfg.cell, "control");
    let mut sub = rt
        .block_on(client.subscribe(control_subject.clone()))
        .map_err(|e| nats(format!("subscribing to {control_subject}"))(e.into()))?;
    let answer_client = client.clone();
    rt.spawn(async move {
        while let Some(msg) = sub.next().await {
            let Some(reply_to) = msg.reply.clone() else {
                continue;
            };
            let (reply, answer) = tokio::sync::oneshot::channel();
            let text = String::from_utf8_lossy(&msg.payload).into_owned();
            if tx.send(Request { text, reply }).is_err() {
                break;
            }
            let a = answer
                .await
                .unwrap_or_else(|_| r#"{"ok":false,"error":"the run has ended"}"#.into());
            let _ = answer_client.publish(reply_to, a.into()).await;
        }
    });
    let mut p = Publisher {
        rt: &rt,
        fleet: &fleet,
        cfg,
        run,
        rate_hz: source.rate_hz(),
        seq: 0,
        samples: 0,
        controls: 0,
        retries: 0,
        control_line: 0,
        events: 0,
        last_t: f64::NAN,
        max_payload: client.server_info().max_payload,
        pending: None,
        stop,
    };
    let mut pacer = Pacer::new(cfg.pace);
    let mut paused = false;
    let mut behind = None;
    loop {
        if p.stop.load(Ordering::Relaxed) {
            break;
        }
        if p.controls(&mut rx, source, &mut paused, &mut pacer)? {
            break;
        }
        if paused {
            continue;
        }
        let chunk = match source.next_chunk() {
            Ok(Some(c)) => c,
            Ok(None) => break,
            Err(crate::LiveError::BadFrame { line, what }) => {
                p.event(&Event::Error {
                    t_s: p.last_t,
                    input: Input::Frames,
                    line,
                    message: what,
                })?;
                continue;
            }
            Err(e) => {
                // The source failed (a damaged file): what was gathered published, the error
                // told on the cell's events and the end frame sent — the cell ends for its
                // worker and the fleet view, instead of going quiet for ever — then the error
                // returned.
                let _ = p
                    .flush()
                    .and_then(|()| {
                        p.event(&Event::Error {
                            t_s: p.last_t,
                            input: Input::Source,
                            line: usize::try_from(p.samples).unwrap_or(usize::MAX),
                            message: e.to_string(),
                        })
                    })
                    .and_then(|()| p.frame(Recording::new(Basis::Time), true));
                return Err(e.into());
            }
        };
        if chunk.is_empty() {
            continue;
        }
        let t = chunk.values("t").map_err(crate::LiveError::from)?;
        if let Some(left) = pacer.left_until(t[t.len() - 1]) {
            rt.block_on(async { tokio::time::sleep(left).await });
        }
        p.last_t = t[t.len() - 1];
        if p.hold(chunk)? {
            if let Some(late) = pacer.since_due(p.last_t) {
                behind = Some(behind.map_or(late, |b: f64| b.max(late)));
            }
        }
    }
    p.flush()?;
    p.frame(Recording::new(Basis::Time), true)?;
    Ok(PublishSummary {
        frames: p.seq,
        samples: p.samples,
        controls: p.controls,
        retries: p.retries,
        max_behind_s: behind,
    })
}

/// Rows per frame of `channels` columns: at most three quarters of the server's largest
/// message in samples (8 bytes each; the rest is room for the schema).
fn max_rows(max_payload: usize, channels: usize) -> usize {
    (max_payload * 3 / 4 / (8 * channels.max(1))).max(1)
}

struct Publisher<'a> {
    rt: &'a tokio::runtime::Runtime,
    fleet: &'a Fleet,
    cfg: &'a PublishConfig,
    run: u64,
    rate_hz: f64,
    seq: u64,
    samples: u64,
    controls: u64,
    retries: u64,
    control_line: usize,
    /// Events the publisher has sent (their message ids).
    events: u64,
    last_t: f64,
    max_payload: usize,
    /// Chunks gathered for the next frame (see [`PublishConfig::frame_s`]).
    pending: Option<Recording>,
    stop: Arc<AtomicBool>,
}

impl Publisher<'_> {
    /// Gather `chunk` for the next frame; publish when the frame holds
    /// [`PublishConfig::frame_s`] of recording, to the nearest chunk (a source's chunks may
    /// differ by a sample: 99 and 100 rows). `true`: published.
    fn hold(&mut self, chunk: Recording) -> Result<bool, FleetError> {
        let last = chunk.len();
        match self.pending.as_mut() {
            // A chunk of other channels (frames from outside may change them) starts a frame.
            Some(held) if held.names() == chunk.names() => {
                held.append(&chunk).map_err(crate::LiveError::from)?
            }
            _ => {
                self.flush()?;
                self.pending = Some(chunk);
            }
        }
        let rows = self.pending.as_ref().map_or(0, Recording::len);
        // Another chunk like the last would overshoot at least as much as this falls short
        // (the target in whole samples: a tie is a tie at any rate).
        let target = (self.cfg.frame_s * self.rate_hz).round();
        if rows as f64 + last as f64 / 2.0 >= target {
            self.flush()?;
            return Ok(true);
        }
        Ok(false)
    }

    /// Publish the chunks gathered, in frames no larger than the server takes.
    fn flush(&mut self) -> Result<(), FleetError> {
        let Some(chunk) = self.pending.take() else {
            return Ok(());
        };
        let rows = max_rows(self.max_payload, chunk.channels().len());
        if chunk.len() <= rows {
            return self.frame(chunk, false);
        }
        let mut at = 0;
        while at < chunk.len() {
            let n = (chunk.len() - at).min(rows);
            self.frame(chunk.slice(at..at + n), false)?;
            at += n;
        }
        Ok(())
    }

    /// Publish one frame, until the stream has it.
    fn frame(&mut self, chunk: Recording, end: bool) -> Result<(), FleetError> {
        self.seq += 1;
        let frame = Frame {
            cell: self.cfg.cell.clone(),
            run: self.run,
            seq: self.seq,
            first_sample: self.samples,
            rate_hz: self.rate_hz,
            end,
            chunk,
        };
        let bytes = wire::encode(&frame).map_err(|e| FleetError::Invalid(e.to_string()))?;
        let id = format!("{}/{}/{}", self.cfg.cell, self.run, self.seq);
        self.samples += frame.chunk.len() as u64;
        self.send(subject(&self.cfg.cell, "samples"), bytes, id)
    }

    /// One event of the publisher's (a control's answer, a refused frame) on the cell's events
    /// subject.
    fn event(&mut self, e: &Event) -> Result<(), FleetError> {
        let json = serde_json::to_vec(e).map_err(|e| FleetError::Invalid(e.to_string()))?;
        self.events += 1;
        let id = format!("{}/{}/p{}", self.cfg.cell, self.run, self.events);
        self.send(subject(&self.cfg.cell, "events"), json, id)
    }

    /// Publish to JetStream until acknowledged (see [`send_until_acked`]).
    fn send(&mut self, subject: String, bytes: Vec<u8>, id: String) -> Result<(), FleetError> {
        let retries = self.rt.block_on(send_until_acked(
            &self.fleet.js,
            subject,
            bytes.into(),
            id,
            self.cfg.give_up,
        ))?;
        self.retries += u64::from(retries > 0);
        Ok(())
    }

    /// Apply the control messages waiting; while paused, wait for them. `true`: stop.
    fn controls(
        &mut self,
        rx: &mut UnboundedReceiver<Request>,
        source: &mut dyn Source,
        paused: &mut bool,
        pacer: &mut Pacer,
    ) -> Result<bool, FleetError> {
        let mut paused_at: Option<Instant> = None;
        let mut stop = false;
        loop {
            let req = if *paused && !stop {
                if paused_at.is_none() {
                    // Nothing held back while the cell is paused.
                    self.flush()?;
                }
                paused_at.get_or_insert_with(Instant::now);
                let next = self.rt.block_on(async {
                    tokio::time::timeout(Duration::from_millis(50), rx.recv()).await
                });
                match next {
                    Ok(Some(r)) => r,
                    Err(_) if self.stop.load(Ordering::Relaxed) => return Ok(true),
                    Err(_) => continue,
                    Ok(None) => return Ok(true),
                }
            } else {
                match rx.try_recv() {
                    Ok(r) => r,
                    Err(_) => break,
                }
            };
            self.controls += 1;
            self.control_line += 1;
            let result = Control::parse(&req.text).and_then(|c| {
                match &c {
                    Control::Pause => *paused = true,
                    Control::Resume => *paused = false,
                    Control::Stop => {
                        *paused = false;
                        stop = true;
                    }
                    Control::Record(_) => {
                        return Err(
                            "'record': a fleet cell's data is in its samples stream already".into(),
                        )
                    }
                    _ => source.control(&c)?,
                }
                Ok(c.name())
            });
            let (t_s, line) = (self.last_t, self.control_line);
            let (event, answer) = match result {
                Ok(cmd) => (
                    Event::Control {
                        t_s,
                        cmd: cmd.into(),
                        line,
                    },
                    Reply::applied(cmd),
                ),
                Err(message) => (
                    Event::Error {
                        t_s,
                        input: Input::Controls,
                        line,
                        message: message.clone(),
                    },
                    Reply::refused(message),
                ),
            };
            let _ = req
                .reply
                .send(serde_json::to_string(&answer).unwrap_or_default());
            self.event(&event)?;
        }
        if let Some(at) = paused_at {
            pacer.shift(at.elapsed());
        }
        Ok(stop)
    }
}
