//! The panel's fleet view (`physid live --fleet URL`): every cell of the fleet, its state, its
//! latest estimates and alarms; a cell's own live view is the operator's panel fed by that
//! cell's events from NATS, its controls sent to the cell's control subject.
//!
//! The view reads the events stream [`EVENTS_STREAM`] from its start (an ordered consumer) and
//! the registry [`super::CELLS_BUCKET`] every two seconds; each cell's events go to a [`Hub`] of its
//! own, which keeps what a late page needs (as the single-cell panel does).

use super::{nats, subject, CellInfo, Fleet, FleetError, NatsTarget, EVENTS_STREAM};
use crate::event::Event;
use crate::hub::Hub;
use crate::message::{CellRow, CellState, Hello, PanelMessage, Reply};
use async_nats::jetstream::consumer::{pull::OrderedConfig, DeliverPolicy};
use futures_util::StreamExt;
use std::collections::BTreeMap;
use std::sync::atomic::AtomicU64;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// How long a cell without events is still called `running`.
const QUIET: Duration = Duration::from_secs(5);

/// One cell as the view sees it.
struct CellView {
    hub: Arc<Hub>,
    info: Option<CellInfo>,
    last_event: Option<Instant>,
    /// The latest estimate event.
    estimate: Option<Event>,
    alarms: u64,
    last_alarm: Option<Event>,
    errors: u64,
    ended: bool,
}

/// The fleet as the panel shows it.
pub struct FleetView {
    cells: Mutex<BTreeMap<String, CellView>>,
    client: async_nats::Client,
}

fn hello(cell: &str, source: &str) -> Hello {
    Hello::run(
        format!("fleet cell {cell}: {source}"),
        "the cell's".into(),
        &physid_apps::shaft_monitor::MonitorConfig::default(),
    )
}

impl CellView {
    fn new(cell: &str, info: Option<CellInfo>) -> Self {
        let source = info.as_ref().map_or("", |i| i.source.as_str()).to_string();
        Self {
            hub: Hub::new(hello(cell, &source)),
            info,
            last_event: None,
            estimate: None,
            alarms: 0,
            last_alarm: None,
            errors: 0,
            ended: false,
        }
    }
}

impl FleetView {
    /// Connect to the fleet at `target` and follow it (tasks on the current runtime).
    pub async fn start(target: &NatsTarget) -> Result<Arc<Self>, FleetError> {
        let connections = Arc::new(AtomicU64::new(0));
        let client = target
            .connect(
                "physid panel (fleet view)",
                Duration::from_secs(10),
                connections,
            )
            .await?;
        let fleet = Fleet::open(client.clone()).await?;
        let view = Arc::new(Self {
            cells: Mutex::new(BTreeMap::new()),
            client,
        });
        let events = fleet
            .js
            .get_stream(EVENTS_STREAM)
            .await
            .map_err(|e| nats(format!("opening {EVENTS_STREAM}"))(e.into()))?;
        let consumer = events
            .create_consumer(OrderedConfig {
                filter_subject: "physid.cell.*.events".into(),
                deliver_policy: DeliverPolicy::All,
                ..Default::default()
            })
            .await
            .map_err(|e| nats("reading the fleet's events")(e.into()))?;
        let mut messages = consumer
            .messages()
            .await
            .map_err(|e| nats("reading the fleet's events")(e.into()))?;
        let v = view.clone();
        tokio::spawn(async move {
            while let Some(m) = messages.next().await {
                let Ok(m) = m else { continue };
                let Some(cell) = m
                    .subject
                    .as_str()
                    .strip_prefix("physid.cell.")
                    .and_then(|s| s.strip_suffix(".events"))
                else {
                    continue;
                };
                // Passed on as it came; what does not read as an event (another version's) is
                // left out.
                let Ok(text) = std::str::from_utf8(&m.payload) else {
                    continue;
                };
                if let Ok(e) = serde_json::from_str::<Event>(text) {
                    v.event(cell, e, text.to_string());
                }
            }
        });
        let v = view.clone();
        tokio::spawn(async move {
            let mut tick = tokio::time::interval(Duration::from_secs(2));
            loop {
                tick.tick().await;
                let Ok(mut keys) = fleet.cells.keys().await else {
                    continue;
                };
                while let Some(Ok(key)) = keys.next().await {
                    if let Ok(Some(bytes)) = fleet.cells.get(&key).await {
                        if let Ok(info) = serde_json::from_slice::<CellInfo>(&bytes) {
                            v.registered(info);
                        }
                    }
                }
            }
        });
        Ok(view)
    }

    fn cells(&self) -> std::sync::MutexGuard<'_, BTreeMap<String, CellView>> {
        self.cells.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn registered(&self, info: CellInfo) {
        let mut cells = self.cells();
        let cell = info.cell.clone();
        let view = cells
            .entry(cell.clone())
            .or_insert_with(|| CellView::new(&cell, None));
        // A new run starts the cell's page afresh.
        if view.info.as_ref().is_some_and(|i| i.run != info.run) {
            *view = CellView::new(&cell, Some(info));
        } else {
            view.info = Some(info);
        }
    }

    fn event(&self, cell: &str, e: Event, text: String) {
        let mut cells = self.cells();
        let view = cells
            .entry(cell.to_string())
            .or_insert_with(|| CellView::new(cell, None));
        view.last_event = Some(Instant::now());
        view.hub.publish_received(&e, text);
        match e {
            Event::Estimate { .. } => view.estimate = Some(e),
            Event::Alarm { .. } => {
                view.alarms += 1;
                view.last_alarm = Some(e);
            }
            Event::Error { .. } => view.errors += 1,
            Event::End { .. } => view.ended = true,
            _ => {}
        }
    }

    /// The hub of `cell`'s events, if the fleet has the cell.
    pub fn hub(&self, cell: &str) -> Option<Arc<Hub>> {
        self.cells().get(cell).map(|c| c.hub.clone())
    }

    /// Every cell: its id, source, rate, state (`running`, `quiet`, `ended`), latest K, B and
    /// their standard errors, alarms and errors so far, the latest alarm.
    pub fn summary(&self) -> PanelMessage {
        let cells = self.cells();
        let cells = cells
            .iter()
            .map(|(id, c)| CellRow {
                cell: id.clone(),
                source: c.info.as_ref().map(|i| i.source.clone()),
                rate_hz: c.info.as_ref().map(|i| i.rate_hz),
                state: if c.ended {
                    CellState::Ended
                } else if c.last_event.is_some_and(|t| t.elapsed() < QUIET) {
                    CellState::Running
                } else {
                    CellState::Quiet
                },
                estimate: c.estimate.clone(),
                alarms: c.alarms,
                last_alarm: c.last_alarm.clone(),
                errors: c.errors,
            })
            .collect();
        PanelMessage::Fleet { cells }
    }

    /// Send a control message to `cell` and wait for its answer (`{"ok": …}`).
    pub async fn control(&self, cell: &str, body: String) -> Result<Reply, String> {
        if !crate::wire::valid_cell(cell) {
            return Err(format!("cell '{cell}': not a cell id"));
        }
        let reply = tokio::time::timeout(
            Duration::from_secs(5),
            self.client.request(subject(cell, "control"), body.into()),
        )
        .await
        .map_err(|_| format!("no answer from cell {cell} within 5 s"))?
        .map_err(|e| format!("cell {cell} does not answer ({e}): is its publisher running?"))?;
        serde_json::from_slice(&reply.payload).map_err(|e| format!("cell {cell}'s answer: {e}"))
    }
}
