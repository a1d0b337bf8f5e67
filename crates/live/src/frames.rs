//! Frames from outside — a DAQ, another program — one JSON object per line, so a script in
//! any language can feed physid live (`physid live --headless --json --frames -` reads stdin).
//!
//! A frame is a chunk of samples, columnar:
//!
//! ```json
//! {"seq": 0, "t": [0.0, 0.0001], "theta_dy": [0.0, 0.0105], "theta_en": [0.0, 0.0104],
//!  "omega_dy": [104.7, 104.7], "omega_en": [104.7, 104.6], "torque_shaft": [1.2, 1.3]}
//! ```
//!
//! * `seq` (optional): the frame's number, counting from 0; a gap is reported, a repeat or a
//!   step back refuses the frame.
//! * `t` [s]: uniformly spaced at the stream's sample rate (`--sample-rate`), continuing from
//!   the previous frame; other keys are channels in SI units (DESIGN.md's names), each as long
//!   as `t`. Keys the stages do not use are ignored.
//!
//! A frame that is not valid — not JSON, a channel missing or of another length, a value that is
//! not a finite number, time not advancing by the sample step — is refused with a
//! [`LiveError::BadFrame`] naming its line and what was wrong; the stream goes on with the next
//! frame (the service counts it as dropped). A gap in time or `seq` is accepted and reported.

use crate::service::LiveError;
use crate::source::Source;
use physid_core::{Basis, Channel, Recording};
use serde_json::Value;
use std::io::BufRead;

/// The channels a frame must carry (the shaft monitor's).
pub const FRAME_CHANNELS: [&str; 6] = [
    "t",
    "theta_dy",
    "theta_en",
    "omega_dy",
    "omega_en",
    "torque_shaft",
];

/// Frames read line by line from `R`.
pub struct FrameSource<R: BufRead> {
    reader: R,
    rate_hz: f64,
    line: usize,
    buf: String,
    next_seq: Option<u64>,
    last_t: Option<f64>,
    /// A gap reported with the next chunk.
    notice: Option<String>,
}

impl<R: BufRead> FrameSource<R> {
    /// Frames at `rate_hz` [Hz] from `reader`.
    pub fn new(reader: R, rate_hz: f64) -> Result<Self, LiveError> {
        if !(rate_hz.is_finite() && rate_hz > 0.0) {
            return Err(LiveError::Invalid(format!(
                "sample rate {rate_hz} Hz: expected > 0"
            )));
        }
        Ok(Self {
            reader,
            rate_hz,
            line: 0,
            buf: String::new(),
            next_seq: None,
            last_t: None,
            notice: None,
        })
    }

    /// A gap found in the last frame taken (time or `seq`), once.
    pub fn take_notice(&mut self) -> Option<String> {
        self.notice.take()
    }

    fn bad(&self, what: String) -> LiveError {
        LiveError::BadFrame {
            line: self.line,
            what,
        }
    }

    fn parse(&mut self) -> Result<Recording, LiveError> {
        let v: Value = serde_json::from_str(self.buf.trim())
            .map_err(|e| self.bad(format!("not a JSON object: {e}")))?;
        let obj = v
            .as_object()
            .ok_or_else(|| self.bad("not a JSON object".into()))?;
        let seq = match obj.get("seq") {
            None => None,
            Some(s) => Some(
                s.as_u64()
                    .ok_or_else(|| self.bad(format!("seq {s}: expected a whole number ≥ 0")))?,
            ),
        };
        let mut rec = Recording::new(Basis::Time);
        let mut n = None;
        for name in FRAME_CHANNELS {
            let col = obj
                .get(name)
                .and_then(Value::as_array)
                .ok_or_else(|| self.bad(format!("channel '{name}' missing or not an array")))?;
            if *n.get_or_insert(col.len()) != col.len() {
                return Err(self.bad(format!(
                    "channel '{name}' has {} values, 't' has {}",
                    col.len(),
                    n.unwrap_or(0)
                )));
            }
            let mut values = Vec::with_capacity(col.len());
            for (i, x) in col.iter().enumerate() {
                match x.as_f64() {
                    Some(f) if f.is_finite() => values.push(f),
                    _ => {
                        return Err(self.bad(format!(
                            "'{name}' value {i} is {x}: expected a finite number"
                        )))
                    }
                }
            }
            rec.push(Channel {
                name: name.into(),
                unit: String::new(),
                values,
            })
            .map_err(|e| self.bad(e.to_string()))?;
        }
        let mut notice = None;
        if let (Some(s), Some(want)) = (seq, self.next_seq) {
            if s < want {
                return Err(self.bad(format!(
                    "seq {s} after {}: repeated or out of order",
                    want - 1
                )));
            }
            if s > want {
                notice = Some(format!(
                    "line {}: seq {s} after {}: {} frames missing",
                    self.line,
                    want - 1,
                    s - want
                ));
            }
        }
        let t = rec.values("t")?;
        let dt = 1.0 / self.rate_hz;
        let tol = 1e-3 * dt;
        if let Some(i) = t.windows(2).position(|w| (w[1] - w[0] - dt).abs() > tol) {
            return Err(self.bad(format!(
                "t[{}] − t[{i}] = {} s: expected the sample step {dt} s",
                i + 1,
                t[i + 1] - t[i]
            )));
        }
        if let (Some(last), Some(&first)) = (self.last_t, t.first()) {
            let step = first - last;
            if step < dt - tol {
                return Err(self.bad(format!(
                    "t starts at {first} s, not after the previous frame's {last} s"
                )));
            }
            if step > dt + tol {
                notice = Some(format!(
                    "line {}: a gap of {:.0} samples in time before t = {first} s",
                    self.line,
                    step / dt - 1.0
                ));
            }
        }
        // Taken: the stream's state moves on.
        if let Some(s) = seq {
            self.next_seq = Some(s + 1);
        }
        if let Some(&l) = t.last() {
            self.last_t = Some(l);
        }
        self.notice = notice;
        Ok(rec)
    }
}

impl<R: BufRead> Source for FrameSource<R> {
    fn rate_hz(&self) -> f64 {
        self.rate_hz
    }

    fn next_chunk(&mut self) -> Result<Option<Recording>, LiveError> {
        loop {
            self.buf.clear();
            let read = self
                .reader
                .read_line(&mut self.buf)
                .map_err(|e| LiveError::Invalid(format!("reading frames: {e}")))?;
            if read == 0 {
                return Ok(None);
            }
            self.line += 1;
            if self.buf.trim().is_empty() {
                continue;
            }
            return self.parse().map(Some);
        }
    }

    fn notice(&mut self) -> Option<String> {
        self.take_notice()
    }
}
