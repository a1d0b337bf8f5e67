//! Control messages for the virtual test cell while it runs — what the panel's controls send,
//! and what a script can send on stdin (`physid live --headless --json --controls -`): one JSON
//! object per line.
//!
//! | message | effect |
//! |---|---|
//! | `{"cmd": "speed", "rpm": 1200}` | the speed demand from now on [rpm] (a torque demand [N·m] in torque mode) |
//! | `{"cmd": "throttle", "deg": 30}` | the throttle opening from now on [deg] |
//! | `{"cmd": "fault", "spec": "shaft.k=1000@12"}` | a fault, as `--fault` (its time is the recording's) |
//! | `{"cmd": "scenario", "name": "shaft-ramp"}` | a built-in scenario's demand, throttle and demand mode from now on (its time 0 = now; the cell's parameters and faults stay) |
//! | `{"cmd": "mode", "demand": "torque"}` (or `"speed"`) | the dynamometer follows a torque (or speed) demand, held at its mean torque over the last whole engine cycle (or its present speed) |
//! | `{"cmd": "pause"}`, `{"cmd": "resume"}` | hold the run (the source and every stage) and go on |
//! | `{"cmd": "record", "file": "NAME.parquet"}` (or `NAME.mf4`), `{"cmd": "record", "stop": true}` | log every channel to a file in the log directory (Parquet or MDF4), and finish it |
//! | `{"cmd": "restart", "stage": "shaft"}` (or `cycles`, `friction`, `torque`, `combustion`) | start a stage afresh (one that stopped on an error comes back) |
//! | `{"cmd": "stop"}` | end the run after the current chunk |
//!
//! A malformed message is refused with an error naming the field; the run goes on. A message
//! that changes the cell is first tried on a copy of it for [`TRY_AHEAD_S`] (a fault at its
//! full value from now): one under which the cell's solution would diverge (a shaft too stiff
//! or too damped for the solver's step, a reciprocating mass of a tonne) is refused with the
//! reason, and the cell runs on as it was.

use physid_sim::run::Run;
use physid_sim::scenario::{named, Fault, Profile, Scenario, NAMED};
use serde_json::Value;
use std::sync::mpsc::SyncSender;

/// A control message (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub enum Control {
    /// Speed demand [rpm] from now on.
    Speed(f64),
    /// Throttle [deg] from now on.
    Throttle(f64),
    /// A fault.
    Fault(Fault),
    /// Hold the run.
    Pause,
    /// Go on after a pause.
    Resume,
    /// Start logging to this file name (`Some`) or finish the log (`None`).
    Record(Option<String>),
    /// Another built-in scenario's demand, throttle and demand mode from now on.
    Scenario(Box<Scenario>),
    /// The dynamometer's demand: torque (`true`) or speed, continuing from where it is.
    TorqueMode(bool),
    /// Start an application's stage afresh: `shaft`, `friction` or `torque`.
    Restart(&'static str),
    /// End the run.
    Stop,
}

/// The messages' `cmd`s.
const CMDS: &[&str] = &[
    "speed", "throttle", "fault", "scenario", "mode", "pause", "resume", "record", "restart",
    "stop",
];

/// How far ahead a message that changes the cell is tried on a copy of it [s of the
/// recording's time]: two engine cycles at 1000 rpm, about 1–3 ms of computing.
pub const TRY_AHEAD_S: f64 = 0.25;

/// The virtual cell's operating envelope for a speed demand [rpm]: below the minimum the
/// dynamometer would stall the engine (a stopped engine teaches the shaft monitor nothing and
/// its stages lose their excitation), above the maximum it overspeeds.
pub const SPEED_ENVELOPE_RPM: (f64, f64) = (500.0, 6000.0);

/// The stages a `restart` control can start afresh.
pub const STAGES: [&str; 6] = [
    "shaft",
    "cycles",
    "friction",
    "torque",
    "combustion",
    "twin",
];

/// A control message on its way to the running loop, with where to send the answer (the
/// command's name, or what was wrong) when someone waits for it.
#[derive(Debug)]
pub struct ControlRequest {
    /// The message's text (one JSON object), or why a line could not be taken as one (it is
    /// refused with an `error` event, and the run goes on).
    pub text: Result<String, String>,
    /// Where the answer goes.
    pub reply: Option<tokio::sync::oneshot::Sender<Result<&'static str, String>>>,
}

impl ControlRequest {
    /// A message nobody waits an answer for (the answer is the event).
    pub fn fire(text: String) -> Self {
        Self {
            text: Ok(text),
            reply: None,
        }
    }

    /// A line that is not a message (not UTF-8, too long): refused by the loop as it comes.
    pub fn unreadable(why: String) -> Self {
        Self {
            text: Err(why),
            reply: None,
        }
    }
}

/// The longest control line or body taken [bytes] (a message is a few dozen bytes).
pub const MAX_CONTROL_BYTES: usize = 64 * 1024;

/// Send each non-empty line of `reader` to `tx` as a control message until the end of the
/// input or until nobody receives (blocking: run it on a thread of its own). A line that is
/// not UTF-8, or longer than [`MAX_CONTROL_BYTES`] (never held whole), is sent as
/// [`ControlRequest::unreadable`]: refused with an `error` event, and the lines after it go on.
pub fn forward_control_lines(mut reader: impl std::io::BufRead, tx: SyncSender<ControlRequest>) {
    use std::io::{BufRead, Read};
    let mut line = Vec::with_capacity(256);
    let mut number = 0usize;
    loop {
        line.clear();
        match (&mut reader)
            .take(MAX_CONTROL_BYTES as u64 + 1)
            .read_until(b'\n', &mut line)
        {
            Ok(0) => return,
            Ok(_) => {}
            Err(e) => {
                let _ = tx.send(ControlRequest::unreadable(format!(
                    "reading the controls after line {number}: {e}"
                )));
                return;
            }
        }
        number += 1;
        let req = if line.len() > MAX_CONTROL_BYTES && !line.ends_with(b"\n") {
            // The rest of the line, read and dropped.
            let mut rest = line.len();
            loop {
                line.clear();
                match (&mut reader)
                    .take(MAX_CONTROL_BYTES as u64)
                    .read_until(b'\n', &mut line)
                {
                    Ok(0) | Err(_) => break,
                    Ok(n) => rest += n,
                }
                if line.ends_with(b"\n") {
                    rest -= 1;
                    break;
                }
            }
            ControlRequest::unreadable(format!(
                "line {number} of the controls is {rest} bytes long: expected at most \
                 {MAX_CONTROL_BYTES} (one JSON object)"
            ))
        } else {
            match std::str::from_utf8(&line) {
                Ok(text) if text.trim().is_empty() => continue,
                Ok(text) => ControlRequest::fire(text.trim_end().to_string()),
                Err(e) => ControlRequest::unreadable(format!(
                    "line {number} of the controls is not UTF-8 (byte {} of the line): expected \
                     one JSON object",
                    e.valid_up_to() + 1
                )),
            }
        };
        if tx.send(req).is_err() {
            return;
        }
    }
}

impl Control {
    /// Parse one message; the error names the field that is wrong.
    pub fn parse(text: &str) -> Result<Self, String> {
        let v: Value =
            serde_json::from_str(text.trim()).map_err(|e| format!("not a JSON object: {e}"))?;
        let obj = v.as_object().ok_or("not a JSON object")?;
        let number = |field: &str, lo: f64, hi: f64| -> Result<f64, String> {
            let x = obj
                .get(field)
                .ok_or_else(|| format!("field '{field}' is missing"))?;
            match x.as_f64() {
                Some(f) if (lo..=hi).contains(&f) => Ok(f),
                _ => Err(format!(
                    "field '{field}' is {x}: expected a number in [{lo}, {hi}]"
                )),
            }
        };
        // A field the message does not take is refused, not ignored (a misspelt one would
        // otherwise do nothing, unseen).
        let cmd = obj.get("cmd").and_then(Value::as_str);
        let takes: &[&str] = match cmd {
            Some("speed") => &["rpm"],
            Some("throttle") => &["deg"],
            Some("fault") => &["spec"],
            Some("record") => &["file", "stop"],
            Some("scenario") => &["name"],
            Some("mode") => &["demand"],
            Some("restart") => &["stage"],
            _ => &[],
        };
        if let Some(extra) = obj
            .keys()
            .find(|k| k.as_str() != "cmd" && !takes.contains(&k.as_str()))
        {
            if cmd.is_some_and(|c| CMDS.contains(&c)) {
                return Err(format!(
                    "field '{}': '{}' takes {}",
                    crate::event::quote(extra, 40),
                    cmd.unwrap_or(""),
                    if takes.is_empty() {
                        "no other field".to_string()
                    } else {
                        takes
                            .iter()
                            .map(|t| format!("'{t}'"))
                            .collect::<Vec<_>>()
                            .join(" or ")
                    }
                ));
            }
        }
        match cmd {
            Some("speed") => Ok(Control::Speed(number("rpm", 0.0, 10_000.0)?)),
            Some("throttle") => Ok(Control::Throttle(number("deg", 0.0, 90.0)?)),
            Some("fault") => {
                let spec = obj
                    .get("spec")
                    .and_then(Value::as_str)
                    .ok_or("field 'spec' is missing or not a string (PATH=VALUE@T[+RAMP])")?;
                Ok(Control::Fault(
                    Fault::parse(spec).map_err(|e| format!("field 'spec': {e}"))?,
                ))
            }
            Some("pause") => Ok(Control::Pause),
            Some("resume") => Ok(Control::Resume),
            Some("record") => match (obj.get("file"), obj.get("stop")) {
                (None, Some(Value::Bool(true))) => Ok(Control::Record(None)),
                (Some(Value::String(f)), None) => Ok(Control::Record(Some(f.clone()))),
                _ => Err(
                    "field 'file' (a file name ending in .parquet or .mf4) or 'stop' (true): expected one of them"
                        .into(),
                ),
            },
            Some("scenario") => {
                let name = obj
                    .get("name")
                    .and_then(Value::as_str)
                    .ok_or("field 'name' is missing or not a string (a built-in scenario)")?;
                // Built-in names only: a panel must not make the service read files.
                let s = named(name).ok_or_else(|| {
                    format!(
                        "field 'name' is '{name}': the built-in scenarios are {}",
                        NAMED.iter().map(|n| n.0).collect::<Vec<_>>().join(", ")
                    )
                })?;
                Ok(Control::Scenario(Box::new(s)))
            }
            Some("mode") => match obj.get("demand").and_then(Value::as_str) {
                Some("torque") => Ok(Control::TorqueMode(true)),
                Some("speed") => Ok(Control::TorqueMode(false)),
                _ => Err("field 'demand': expected \"speed\" or \"torque\"".into()),
            },
            Some("restart") => {
                let stage = obj.get("stage").and_then(Value::as_str).unwrap_or("");
                STAGES
                    .iter()
                    .find(|s| **s == stage)
                    .map(|s| Control::Restart(s))
                    .ok_or_else(|| {
                        format!(
                            "field 'stage' is '{}': expected {}",
                            crate::event::quote(stage, 40),
                            STAGES.join(", ")
                        )
                    })
            }
            Some("stop") => Ok(Control::Stop),
            other => Err(format!(
                "field 'cmd' is {}: expected {}",
                match (other, obj.get("cmd")) {
                    (Some(c), _) => format!("'{c}'"),
                    // Present, but not a text.
                    (None, Some(v)) => crate::event::quote(&v.to_string(), 40).into_owned(),
                    (None, None) => "missing".to_string(),
                },
                CMDS.join(", ")
            )),
        }
    }

    /// Apply it to a running cell (stop, pause, resume, record and restart are the caller's
    /// to act on); a speed demand outside [`SPEED_ENVELOPE_RPM`] is refused, naming the
    /// envelope (in torque mode the number is a torque, taken as it is). A message that
    /// changes the cell is tried first ([`try_ahead`](Self::try_ahead)).
    pub fn apply(&self, run: &mut Run) -> Result<(), String> {
        self.check(run)?;
        if !matches!(
            self,
            Control::Stop
                | Control::Pause
                | Control::Resume
                | Control::Record(_)
                | Control::Restart(_)
        ) {
            self.try_ahead(run)?;
        }
        self.act(run);
        Ok(())
    }

    /// Try it on a copy of `run` for [`TRY_AHEAD_S`] of the recording's time — a fault at its
    /// full value from now, wherever it is scheduled or however it is ramped — and refuse it,
    /// with the reason, where the copy's solution diverges.
    fn try_ahead(&self, run: &Run) -> Result<(), String> {
        let mut copy = run.clone();
        let now = copy.time();
        let tried = match self {
            Control::Fault(f) => Control::Fault(Fault {
                at: now.max(0.0),
                ramp: 0.0,
                ..f.clone()
            }),
            c => c.clone(),
        };
        tried.act(&mut copy);
        copy.step_until(now.max(0.0) + TRY_AHEAD_S)
            .map_err(|e| format!("refused: tried on a copy of the cell, {e}"))
    }

    /// What makes a message invalid for the run as it is: a speed demand outside the envelope.
    fn check(&self, run: &Run) -> Result<(), String> {
        if let Control::Speed(rpm) = self {
            let (lo, hi) = SPEED_ENVELOPE_RPM;
            if !run.torque_mode() && !(lo..=hi).contains(rpm) {
                return Err(format!(
                    "field 'rpm' is {}: outside the cell's operating envelope, {lo}–{hi} rpm \
                     (below it the dynamometer stalls the engine)",
                    physid_core::Num(*rpm)
                ));
            }
        }
        Ok(())
    }

    /// Make the change to `run`.
    fn act(&self, run: &mut Run) {
        // A constant from now on: the run only evaluates its inputs ahead.
        let forever = |v: f64| Profile::constant(v, f64::MAX);
        match self {
            Control::Speed(rpm) => run.set_speed(forever(*rpm)),
            Control::Throttle(deg) => run.set_throttle(forever(*deg)),
            Control::Fault(f) => run.add_fault(f.clone()),
            Control::Scenario(s) => run.set_scenario(s),
            Control::TorqueMode(on) => run.set_torque_mode(*on),
            Control::Stop
            | Control::Pause
            | Control::Resume
            | Control::Record(_)
            | Control::Restart(_) => {}
        }
    }

    /// Its name (`speed`, `throttle`, `fault`, `stop`).
    pub fn name(&self) -> &'static str {
        match self {
            Control::Speed(_) => "speed",
            Control::Throttle(_) => "throttle",
            Control::Fault(_) => "fault",
            Control::Scenario(_) => "scenario",
            Control::TorqueMode(_) => "mode",
            Control::Pause => "pause",
            Control::Resume => "resume",
            Control::Record(_) => "record",
            Control::Restart(_) => "restart",
            Control::Stop => "stop",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_parse_and_mistakes_name_the_field() {
        assert_eq!(
            Control::parse(r#"{"cmd":"speed","rpm":1200}"#),
            Ok(Control::Speed(1200.0))
        );
        assert_eq!(Control::parse(r#"{"cmd":"stop"}"#), Ok(Control::Stop));
        assert!(matches!(
            Control::parse(r#"{"cmd":"fault","spec":"shaft.k=1000@2"}"#),
            Ok(Control::Fault(f)) if f.path == "shaft.k" && f.value == 1000.0
        ));
        for (msg, want) in [
            (r#"{"cmd":"speed","rpm":"fast"}"#, "field 'rpm'"),
            (r#"{"cmd":"speed"}"#, "field 'rpm' is missing"),
            (r#"{"cmd":"throttle","deg":120}"#, "field 'deg'"),
            (r#"{"cmd":"fault","spec":"shaft.x=1@1"}"#, "field 'spec'"),
            (r#"{"cmd":"warp"}"#, "field 'cmd' is 'warp'"),
            (r#"{"rpm":1}"#, "field 'cmd' is missing"),
            (r#"{"cmd":5}"#, "field 'cmd' is 5: expected speed"),
            ("speed 1200", "not a JSON object"),
            // A field the message does not take (a misspelling would do nothing, unseen).
            (
                r#"{"cmd":"speed","rmp":1200,"rpm":1200}"#,
                "field 'rmp': 'speed' takes 'rpm'",
            ),
            (
                r#"{"cmd":"record","file":"a.parquet","channels":["p_cyl"]}"#,
                "field 'channels': 'record' takes 'file' or 'stop'",
            ),
            (
                r#"{"cmd":"pause","for":5}"#,
                "field 'for': 'pause' takes no other field",
            ),
        ] {
            let e = Control::parse(msg).unwrap_err();
            assert!(e.contains(want), "{msg}: {e}");
        }
    }

    /// A message under which the cell would diverge is refused, naming the divergence, and
    /// leaves the cell untouched: the run goes on to the very recording of one never sent. A
    /// fault that would diverge only later (scheduled, or ramped) is tried at its full value
    /// now; a sound fault is taken.
    #[test]
    fn a_message_that_would_diverge_the_cell_is_refused_and_changes_nothing() {
        use physid_sim::run::{OutputBasis, RunOptions};
        let opts = RunOptions {
            duration: Some(0.6),
            basis: OutputBasis::Time(2000.0),
            stream: true,
            ..Default::default()
        };
        let scenario = named("shaft-steady").unwrap();
        let sound = Control::parse(r#"{"cmd":"fault","spec":"shaft.k=1100@0.2"}"#).unwrap();
        let drive = |messages: &[&str]| {
            let mut run = Run::new(&scenario, &opts).unwrap();
            let mut chunks = Vec::new();
            run.step_until(0.15).unwrap();
            chunks.push(run.drain().unwrap());
            let refusals: Vec<String> = messages
                .iter()
                .map(|m| Control::parse(m).unwrap().apply(&mut run).unwrap_err())
                .collect();
            sound.apply(&mut run).unwrap();
            while !run.is_done() {
                run.step_until(run.time() + 0.1).unwrap();
                chunks.push(run.drain().unwrap());
            }
            (chunks, refusals)
        };
        let (quiet, refused) = drive(&[r#"{"cmd":"speed","rpm":1e-300}"#]);
        // Outside the envelope, said as given (it printed 300 digits).
        assert!(
            refused[0].starts_with("field 'rpm' is 1e-300: outside the cell's operating envelope"),
            "{}",
            refused[0]
        );
        let (tried, refusals) = drive(&[
            r#"{"cmd":"fault","spec":"shaft.b=1e6@0.15"}"#,
            r#"{"cmd":"fault","spec":"shaft.k=1e7@0.3"}"#,
            r#"{"cmd":"fault","spec":"engine.m_rec=1e6@0.15+5"}"#,
        ]);
        for e in &refusals {
            assert!(
                e.contains("refused: tried on a copy of the cell, the simulation diverged"),
                "{e}"
            );
        }
        assert_eq!(quiet.len(), tried.len());
        for (a, b) in quiet.iter().zip(&tried) {
            for name in a.names() {
                assert_eq!(a.values(name).unwrap(), b.values(name).unwrap(), "{name}");
            }
        }
        // The sound fault acted: the truth's K moved to 1100 N·m/rad.
        let k = quiet.last().unwrap().values("true_shaft_k").unwrap();
        assert_eq!(k.last(), Some(&1100.0));
    }
}
