//! The panel's own messages — beside the run's [`Event`](crate::Event)s on the same WebSocket
//! and SSE streams, tagged by `"type"` the same way — and the replies of its HTTP endpoints and
//! of a fleet cell's control subject. Typed both ways (`Serialize + Deserialize`): the service,
//! the fleet view and the tests read and write the one definition.

use physid_apps::shaft_monitor::{MonitorConfig, PerParam};
use serde::{Deserialize, Serialize};

/// A message of the panel's own.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum PanelMessage {
    /// The first message to every client: what runs and how to read it.
    Hello(Box<Hello>),
    /// The panel's clients now, and the messages dropped for clients that fell behind.
    Status {
        /// Clients connected.
        clients: usize,
        /// Messages dropped so far for lagging clients.
        lagged: u64,
    },
    /// An alarm (by its message number) acknowledged by an operator; kept with the alarms.
    Ack {
        /// The alarm's message number.
        seq: u64,
    },
    /// This client fell behind: `dropped` messages were skipped.
    Lagged {
        /// Messages skipped.
        dropped: u64,
    },
    /// The fleet view's table: every cell.
    Fleet {
        /// One row per cell.
        cells: Vec<CellRow>,
    },
}

/// What a client is greeted with. The fleet view's own page has only its `source`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Hello {
    /// physid's version.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub version: Option<String>,
    /// What runs (a scenario, a replayed file, frames, a fleet cell).
    pub source: String,
    /// How it is paced.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pace: Option<String>,
    /// The shaft's healthy K and B.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub healthy: Option<PerParam>,
    /// The alarm bound on the relative error (Eq. 6.3).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bound: Option<f64>,
    /// The units of the panel's quantities.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub units: Option<Units>,
}

/// The units the panel labels its axes with.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Units {
    /// Shaft stiffness.
    #[serde(rename = "K")]
    pub k: String,
    /// Shaft damping.
    #[serde(rename = "B")]
    pub b: String,
    /// Time.
    pub t_s: String,
    /// Speeds.
    pub omega: String,
    /// Torques.
    pub torque: String,
    /// Pressures.
    pub p: String,
    /// Throttle.
    pub throttle: String,
}

impl Default for Units {
    fn default() -> Self {
        let s = |v: &str| v.to_string();
        Self {
            k: s("N·m/rad"),
            b: s("N·m·s/rad"),
            t_s: s("s"),
            omega: s("rad/s"),
            torque: s("N·m"),
            p: s("Pa"),
            throttle: s("deg"),
        }
    }
}

impl Hello {
    /// The greeting of a run of `source` paced by `pace`, its shaft monitored by `monitor`.
    pub fn run(source: String, pace: String, monitor: &MonitorConfig) -> Self {
        Self {
            version: Some(env!("CARGO_PKG_VERSION").to_string()),
            source,
            pace: Some(pace),
            healthy: Some(monitor.healthy),
            bound: Some(monitor.bound),
            units: Some(Units::default()),
        }
    }

    /// The greeting of a page that only says what it is.
    pub fn only(source: String) -> Self {
        Self {
            version: None,
            source,
            pace: None,
            healthy: None,
            bound: None,
            units: None,
        }
    }
}

/// A row of the fleet view's table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CellRow {
    /// The cell's id.
    pub cell: String,
    /// What it runs.
    pub source: Option<String>,
    /// Its sample rate [Hz].
    pub rate_hz: Option<f64>,
    /// `running`, `quiet` (no event for a while) or `ended`.
    pub state: CellState,
    /// Its latest estimate event.
    pub estimate: Option<crate::Event>,
    /// Alarms so far.
    pub alarms: u64,
    /// Its latest alarm event.
    pub last_alarm: Option<crate::Event>,
    /// Refused inputs so far.
    pub errors: u64,
}

/// A fleet cell's state as the view sees it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CellState {
    /// Events came within the last seconds.
    Running,
    /// No event for a while.
    Quiet,
    /// Its `end` event came.
    Ended,
}

/// The answer to a control message or an acknowledgement: `{"ok": true, "cmd": …}`,
/// `{"ok": true, "seq": …}` or `{"ok": false, "error": …}`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Reply {
    /// Whether it was applied.
    pub ok: bool,
    /// The command applied.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cmd: Option<String>,
    /// The alarm acknowledged.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seq: Option<u64>,
    /// Why it was refused.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

impl Reply {
    /// `cmd` applied.
    pub fn applied(cmd: &str) -> Self {
        Self {
            ok: true,
            cmd: Some(cmd.to_string()),
            seq: None,
            error: None,
        }
    }

    /// Alarm `seq` acknowledged.
    pub fn acknowledged(seq: u64) -> Self {
        Self {
            ok: true,
            cmd: None,
            seq: Some(seq),
            error: None,
        }
    }

    /// Refused, with the reason.
    pub fn refused(error: impl Into<String>) -> Self {
        Self {
            ok: false,
            cmd: None,
            seq: None,
            error: Some(error.into()),
        }
    }
}

impl PanelMessage {
    /// The message as JSON text.
    pub fn to_json(&self) -> String {
        // Plain data of strings and numbers: serialising cannot fail.
        serde_json::to_string(self).unwrap_or_default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_message_reads_back_as_written() {
        let messages = [
            PanelMessage::Hello(Box::new(Hello::run(
                "scenario shaft-steady".into(),
                "1×".into(),
                &MonitorConfig::default(),
            ))),
            PanelMessage::Hello(Box::new(Hello::only("the fleet view: open a cell".into()))),
            PanelMessage::Status {
                clients: 2,
                lagged: 7,
            },
            PanelMessage::Ack { seq: 12 },
            PanelMessage::Lagged { dropped: 3 },
        ];
        for m in messages {
            let text = m.to_json();
            let back: PanelMessage = serde_json::from_str(&text).unwrap();
            assert_eq!(back, m, "{text}");
        }
        let v: serde_json::Value = serde_json::from_str(
            &PanelMessage::Status {
                clients: 1,
                lagged: 0,
            }
            .to_json(),
        )
        .unwrap();
        assert_eq!(v["type"], "status");
        for r in [
            Reply::applied("fault"),
            Reply::acknowledged(4),
            Reply::refused("no"),
        ] {
            let text = serde_json::to_string(&r).unwrap();
            assert_eq!(serde_json::from_str::<Reply>(&text).unwrap(), r);
        }
    }
}
