//! Between the live loop and the panel's clients: every event is numbered, kept for clients
//! that connect later (bounded, per kind) and broadcast to the connected ones through a
//! bounded channel. The loop never waits for a client: [`Hub::publish`] does not block, and a
//! client that falls more than [`BROADCAST_CAPACITY`] messages behind loses the oldest — it is
//! told how many (`{"type": "lagged", "dropped": n}`), and the total is counted and shown.
//!
//! A client that connects (or reconnects) first gets `hello`, then what the hub kept — the
//! latest estimates, every alarm and its acknowledgement, the last cycles, the last traces,
//! the other events — in their original order, then the live stream without a gap or a repeat.

use crate::event::Event;
use crate::message::{Hello, PanelMessage};
use std::collections::VecDeque;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use tokio::sync::broadcast;

/// Messages a client may fall behind before it loses the oldest.
pub const BROADCAST_CAPACITY: usize = 4096;

/// One numbered message: its number and its JSON text.
pub type Message = (u64, Arc<str>);

/// What the hub keeps of each kind for clients that connect later.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Estimate,
    Alarm,
    Cycle,
    Trace,
    Other,
}

impl Kind {
    const ALL: [Kind; 5] = [
        Kind::Estimate,
        Kind::Alarm,
        Kind::Cycle,
        Kind::Trace,
        Kind::Other,
    ];

    /// How many are kept: 3000 estimates, friction cycles and identifiability changes (5 min of
    /// the shaft's 10 estimates a second), 2000 alarms and
    /// acknowledgements, the last 20 cycles, 30 s of traces at 20 events a second, 500 others.
    fn keep(self) -> usize {
        match self {
            Kind::Estimate => 3000,
            Kind::Alarm => 2000,
            Kind::Cycle => 20,
            Kind::Trace => 600,
            Kind::Other => 500,
        }
    }

    fn of(e: &Event) -> Self {
        match e {
            Event::Estimate { .. }
            | Event::Friction { .. }
            | Event::Torque { .. }
            | Event::Twin { .. }
            | Event::Identifiability { .. } => Kind::Estimate,
            Event::Alarm { .. } => Kind::Alarm,
            Event::Cycle { .. } => Kind::Cycle,
            Event::Trace { .. } => Kind::Trace,
            _ => Kind::Other,
        }
    }
}

#[derive(Debug, Default)]
struct Kept {
    seq: u64,
    rings: [VecDeque<Message>; 5],
}

/// The hub (share it in an [`Arc`]).
#[derive(Debug)]
pub struct Hub {
    hello: Arc<str>,
    kept: Mutex<Kept>,
    tx: broadcast::Sender<Message>,
    clients: AtomicUsize,
    lagged: AtomicU64,
}

/// A connected client: what was kept, and the live stream after it.
pub struct Subscription {
    /// `hello`, then the kept messages in order.
    pub backlog: Vec<Message>,
    /// The live messages (skip those numbered at or below `after`).
    pub rx: broadcast::Receiver<Message>,
    /// The number of the last kept message.
    pub after: u64,
    /// Counts the client until dropped.
    pub guard: ClientGuard,
}

/// Counts a connected client while it lives.
pub struct ClientGuard(Arc<Hub>);

impl Drop for ClientGuard {
    fn drop(&mut self) {
        self.0.clients.fetch_sub(1, Ordering::Relaxed);
    }
}

impl Hub {
    /// A hub whose clients are greeted with `hello` (what runs, the healthy bounds, the
    /// units).
    pub fn new(hello: Hello) -> Arc<Self> {
        let (tx, _) = broadcast::channel(BROADCAST_CAPACITY);
        Arc::new(Self {
            hello: PanelMessage::Hello(Box::new(hello)).to_json().into(),
            kept: Mutex::new(Kept::default()),
            tx,
            clients: AtomicUsize::new(0),
            lagged: AtomicU64::new(0),
        })
    }

    fn kept(&self) -> MutexGuard<'_, Kept> {
        // A panic elsewhere while holding the lock leaves consistent rings: go on with them.
        self.kept.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Number, keep and broadcast an event (never waits for a client).
    pub fn publish(&self, e: &Event) -> Result<(), String> {
        let text = serde_json::to_string(e).map_err(|e| e.to_string())?;
        self.publish_text(Kind::of(e), text);
        Ok(())
    }

    /// Number, keep and broadcast an event received as JSON `text` (a fleet cell's, from
    /// NATS; `e` is what it reads as), passed on as it came.
    pub fn publish_received(&self, e: &Event, text: String) {
        self.publish_text(Kind::of(e), text);
    }

    /// An alarm (by its number) acknowledged by an operator: `{"type": "ack", "seq": n}`,
    /// kept with the alarms.
    pub fn acknowledge(&self, seq: u64) {
        self.publish_text(Kind::Alarm, PanelMessage::Ack { seq }.to_json());
    }

    /// A passing message of the hub's own (`status`): broadcast, not kept (a client that
    /// connects changes the count and so gets a fresh one).
    pub fn publish_message(&self, m: &PanelMessage) {
        self.publish_text(None, m.to_json());
    }

    fn publish_text(&self, kind: impl Into<Option<Kind>>, text: String) {
        let mut kept = self.kept();
        kept.seq += 1;
        let msg: Message = (kept.seq, text.into());
        if let Some(kind) = kind.into() {
            let ring = &mut kept.rings[kind as usize];
            if ring.len() == kind.keep() {
                ring.pop_front();
            }
            ring.push_back(msg.clone());
        }
        // Sent under the lock, so that a subscriber sees each message once: in its backlog
        // or on its receiver. No receiver is not an error.
        let _ = self.tx.send(msg);
    }

    /// Connect a client.
    pub fn subscribe(self: &Arc<Self>) -> Subscription {
        let kept = self.kept();
        let rx = self.tx.subscribe();
        let mut backlog: Vec<Message> = Kind::ALL
            .iter()
            .flat_map(|k| kept.rings[*k as usize].iter().cloned())
            .collect();
        backlog.sort_unstable_by_key(|m| m.0);
        backlog.insert(0, (0, self.hello.clone()));
        let after = kept.seq;
        drop(kept);
        self.clients.fetch_add(1, Ordering::Relaxed);
        Subscription {
            backlog,
            rx,
            after,
            guard: ClientGuard(self.clone()),
        }
    }

    /// Count `n` messages a slow client lost.
    pub fn count_lagged(&self, n: u64) {
        self.lagged.fetch_add(n, Ordering::Relaxed);
    }

    /// Clients connected now.
    pub fn clients(&self) -> usize {
        self.clients.load(Ordering::Relaxed)
    }

    /// Messages slow clients have lost, in all.
    pub fn lagged(&self) -> u64 {
        self.lagged.load(Ordering::Relaxed)
    }

    /// Whether message `seq` is an alarm the hub still keeps (what can be acknowledged).
    pub fn is_alarm(&self, seq: u64) -> bool {
        let kept = self.kept();
        kept.rings[Kind::Alarm as usize]
            .iter()
            .any(|(s, m)| *s == seq && m.starts_with(r#"{"type":"alarm""#))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn finding(k: usize) -> Event {
        Event::finding(k as f64, format!("m{k}"))
    }

    /// A late subscriber gets hello, the kept messages in order, then the live ones, none twice;
    /// each kind keeps its last `keep()`.
    #[test]
    fn backlog_then_live_without_gap_or_repeat() {
        let hub = Hub::new(Hello::only(String::new()));
        for k in 0..600 {
            hub.publish(&finding(k)).unwrap();
        }
        let mut sub = hub.subscribe();
        assert_eq!(hub.clients(), 1);
        assert_eq!(&*sub.backlog[0].1, r#"{"type":"hello","source":""}"#);
        assert_eq!(sub.backlog.len(), 1 + 500);
        assert_eq!(sub.backlog[1].0, 101);
        assert_eq!(sub.after, 600);
        hub.publish(&finding(600)).unwrap();
        let (seq, m) = sub.rx.try_recv().unwrap();
        assert_eq!(seq, 601);
        assert!(m.contains("m600"));
        drop(sub);
        assert_eq!(hub.clients(), 0);
    }

    /// A client that does not read loses the oldest beyond the capacity, and is told so.
    #[test]
    fn a_slow_client_lags_and_the_publisher_never_waits() {
        let hub = Hub::new(Hello::only(String::new()));
        let mut sub = hub.subscribe();
        for k in 0..BROADCAST_CAPACITY + 10 {
            hub.publish(&finding(k)).unwrap();
        }
        match sub.rx.try_recv() {
            Err(broadcast::error::TryRecvError::Lagged(n)) => assert_eq!(n, 10),
            other => panic!("{other:?}"),
        }
    }
}
