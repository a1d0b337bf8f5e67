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
//!   step back refuses the frame — except back to 0: the sender started again.
//! * `t` [s]: uniformly spaced at the stream's sample rate (`--sample-rate`), continuing from
//!   the previous frame; other keys are channels in SI units (DESIGN.md's names), each as long
//!   as `t`. Keys the stages do not use are ignored.
//!
//! A frame that is not valid — not JSON, a channel missing or of another length, a value that is
//! not a finite number, time not advancing by the sample step — is refused with a
//! [`LiveError::BadFrame`] naming its line and what was wrong; the stream goes on with the next
//! frame (the service counts it as dropped). A gap in time or `seq` is accepted and reported.
//!
//! A sender that starts again — `seq` back at 0, or, without `seq`, `t` back at or before the
//! time its frames started at — is told with the next chunk and its frames go on after a gap
//! in the data, their time and crank angles shifted to continue the stream ([`seam`]).

mod columns;
mod piped;
mod seam;
#[cfg(unix)]
mod socket;
pub use piped::PipedFrames;
pub use seam::{Sample, Shift};
#[cfg(unix)]
pub use socket::SocketFrames;

use crate::service::LiveError;
use crate::source::Source;
use physid_core::{Basis, Channel, Recording};
use std::io::BufRead;
use std::time::Instant;

/// The channels a frame must carry (the shaft monitor's).
pub const FRAME_CHANNELS: [&str; 6] = physid_apps::shaft_monitor::SHAFT_CHANNELS;

/// How often a frame reader with a stop flag ([`PipedFrames::until`]) looks at it while it
/// waits for its sender, and hands its caller an empty chunk: the run applies its controls.
pub const POLL: std::time::Duration = std::time::Duration::from_millis(100);

/// Where the channels the seam shifts stand in [`FRAME_CHANNELS`].
const T: usize = 0;
const THETA_DY: usize = 1;
const THETA_EN: usize = 2;
const OMEGA_EN: usize = 4;

/// Where frame lines come from: a reader of lines that may have something to tell of its
/// connection (a client that connected again, [`SocketFrames`]).
pub trait FrameLines: BufRead {
    /// What happened to the connection since last asked, once.
    fn notice(&mut self) -> Option<String> {
        None
    }
}

impl FrameLines for Box<dyn BufRead + Send> {}

/// `Read::read` of a frame reader that is a `BufRead` at heart: what its buffer holds, copied
/// and consumed.
fn read_buffered<R: BufRead + ?Sized>(r: &mut R, buf: &mut [u8]) -> std::io::Result<usize> {
    let avail = r.fill_buf()?;
    let n = avail.len().min(buf.len());
    buf[..n].copy_from_slice(&avail[..n]);
    r.consume(n);
    Ok(n)
}
impl<T: AsRef<[u8]>> FrameLines for std::io::Cursor<T> {}

/// Frames read line by line from `R`.
pub struct FrameSource<R: FrameLines> {
    reader: R,
    rate_hz: f64,
    line: usize,
    /// The line being read, as it comes (a wait for the sender may fall in the middle of it).
    pending: Vec<u8>,
    /// The bytes of a line past [`MAX_FRAME_BYTES`] so far, skipped to its end.
    skipped: Option<usize>,
    /// The line being parsed.
    buf: String,
    next_seq: Option<u64>,
    /// The last sample taken (shifted, as the stages took it), and when its frame was taken.
    last: Option<(Sample, Instant)>,
    /// The time the sender's frames started at, as sent (since it last started again).
    started_t: f64,
    /// What is added to the sender's time and angles since it last started again.
    shift: Shift,
    /// A gap or a restart reported with the next chunk.
    notice: Option<String>,
}

impl<R: FrameLines> FrameSource<R> {
    /// Frames at `rate_hz` [Hz] from `reader`.
    pub fn new(reader: R, rate_hz: f64) -> Result<Self, LiveError> {
        if !(rate_hz.is_finite() && rate_hz > 0.0) {
            return Err(LiveError::Invalid(format!(
                "sample rate {rate_hz} Hz: expected > 0",
                rate_hz = physid_core::Num(rate_hz)
            )));
        }
        Ok(Self {
            reader,
            rate_hz,
            line: 0,
            pending: Vec::new(),
            skipped: None,
            buf: String::new(),
            next_seq: None,
            last: None,
            started_t: 0.0,
            shift: Shift::default(),
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
        let (seq, mut cols) = columns::columns(self.buf.trim()).map_err(|e| self.bad(e))?;
        let dt = 1.0 / self.rate_hz;
        let tol = 1e-3 * dt;
        let t = &cols[T];
        if let Some(i) = t.windows(2).position(|w| (w[1] - w[0] - dt).abs() > tol) {
            return Err(self.bad(format!(
                "t[{}] − t[{i}] = {} s: expected the sample step {dt} s",
                i + 1,
                t[i + 1] - t[i]
            )));
        }
        // The sender started again: `seq` back at 0, or, without `seq`, its time back at or
        // before where its frames started.
        let sent_t0 = t.first().copied();
        let restart = match (&self.last, sent_t0, seq, self.next_seq) {
            (Some(_), Some(_), Some(0), Some(want)) => Some(format!("seq 0 after {}", want - 1)),
            (Some(_), Some(t0), None, _) if t0 <= self.started_t => Some(format!(
                "t back at {t0} s, where its frames started at {} s",
                self.started_t
            )),
            _ => None,
        };
        let mut notice = None;
        if let (None, Some(s), Some(want)) = (&restart, seq, self.next_seq) {
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
        let shift = match (&restart, &self.last) {
            (Some(_), Some((last, at))) => {
                let first = Sample {
                    t: cols[T][0],
                    theta_en: cols[THETA_EN][0],
                    theta_dy: cols[THETA_DY][0],
                    omega_en: cols[OMEGA_EN][0],
                };
                self.shift
                    .join(last, &first, at.elapsed().as_secs_f64(), dt)
            }
            _ => self.shift,
        };
        if !shift.is_none() {
            for (k, by) in [
                (T, shift.t),
                (THETA_EN, shift.theta_en),
                (THETA_DY, shift.theta_dy),
            ] {
                for v in &mut cols[k] {
                    *v += by;
                }
            }
        }
        if let (Some((last, _)), Some(&first)) = (&self.last, cols[T].first()) {
            let step = first - last.t;
            if step < dt - tol {
                let sent = if shift.t == 0.0 {
                    String::new()
                } else {
                    format!(" ({} s as sent)", first - shift.t)
                };
                return Err(self.bad(format!(
                    "t starts at {first} s{sent}, not after the previous frame's {} s",
                    last.t
                )));
            }
            if let Some(why) = &restart {
                notice = Some(format!(
                    "line {}: the sender started again ({why}): its frames go on {:.4} s \
                     after its last sample — from here on the stream's t is the sender's {:+.6} s, \
                     'theta_en' the sender's shifted by {} cycles (4π rad) and 'theta_dy' by \
                     {} turns (2π rad); the cycle the gap cuts is left out",
                    self.line,
                    step,
                    shift.t,
                    (shift.theta_en / (4.0 * std::f64::consts::PI)).round(),
                    (shift.theta_dy / std::f64::consts::TAU).round(),
                ));
            } else if step > dt + tol {
                notice = Some(format!(
                    "line {}: a gap of {:.0} samples in time before t = {first} s",
                    self.line,
                    step / dt - 1.0
                ));
            }
        }
        let mut rec = Recording::new(Basis::Time);
        for (name, values) in FRAME_CHANNELS.into_iter().zip(cols) {
            rec.push(Channel {
                name: name.into(),
                unit: String::new(),
                values,
            })
            .map_err(|e| self.bad(e.to_string()))?;
        }
        // Taken: the stream's state moves on.
        if let Some(s) = seq {
            self.next_seq = Some(s + 1);
        }
        if let Some(t0) = sent_t0.filter(|_| self.last.is_none() || restart.is_some()) {
            self.started_t = t0;
        }
        self.shift = shift;
        let col = |name| rec.values(name).ok().and_then(|v| v.last().copied());
        if let (Some(t), Some(theta_en), Some(theta_dy), Some(omega_en)) =
            (col("t"), col("theta_en"), col("theta_dy"), col("omega_en"))
        {
            let last = Sample {
                t,
                theta_en,
                theta_dy,
                omega_en,
            };
            self.last = Some((last, Instant::now()));
        }
        self.notice = notice;
        Ok(rec)
    }
}

impl<R: FrameLines> Source for FrameSource<R> {
    fn rate_hz(&self) -> f64 {
        self.rate_hz
    }

    /// The next frame; an empty chunk when the reader has nothing yet and says so
    /// ([`std::io::ErrorKind::WouldBlock`]: a reader with a stop flag, every [`POLL`]) — the
    /// run applies its controls and asks again, the line in
    /// progress kept.
    fn next_chunk(&mut self) -> Result<Option<Recording>, LiveError> {
        loop {
            let avail = match self.reader.fill_buf() {
                Ok(b) => b,
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                    return Ok(Some(Recording::new(Basis::Time)))
                }
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(LiveError::Invalid(format!("reading frames: {e}"))),
            };
            if avail.is_empty() {
                // The end; a last line without its line end is still a line.
                if self.pending.is_empty() && self.skipped.is_none() {
                    return Ok(None);
                }
            } else {
                let (n, end) = match memchr::memchr(b'\n', avail) {
                    Some(i) => (i + 1, true),
                    None => (avail.len(), false),
                };
                match self.skipped.as_mut() {
                    Some(k) => *k += n,
                    // Past the longest frame: the rest of the line is skipped, holding
                    // nothing of it.
                    None if self.pending.len() + n > MAX_FRAME_BYTES => {
                        self.skipped = Some(self.pending.len() + n);
                        self.pending.clear();
                    }
                    None => self.pending.extend_from_slice(&avail[..n]),
                }
                self.reader.consume(n);
                if !end {
                    continue;
                }
            }
            self.line += 1;
            if let Some(k) = self.skipped.take() {
                return Err(self.bad(format!(
                    "longer than {MAX_FRAME_BYTES} bytes ({k} read): refused"
                )));
            }
            // The line as text, its buffer kept for the next (no allocation per line).
            let bytes = std::mem::take(&mut self.pending);
            let parsed = match String::from_utf8(bytes) {
                Ok(text) => {
                    self.buf = text;
                    let parsed = if self.buf.trim().is_empty() {
                        None
                    } else {
                        Some(self.parse())
                    };
                    self.pending = std::mem::take(&mut self.buf).into_bytes();
                    parsed
                }
                Err(e) => {
                    self.pending = e.into_bytes();
                    Some(Err(self.bad("not UTF-8 text".into())))
                }
            };
            self.pending.clear();
            match parsed {
                Some(r) => return r.map(Some),
                None => continue,
            }
        }
    }

    fn notice(&mut self) -> Option<String> {
        match (self.reader.notice(), self.take_notice()) {
            (Some(a), Some(b)) => Some(format!("{a}; {b}")),
            (a, b) => a.or(b),
        }
    }
}

/// The longest frame line taken [bytes]: a longer one is refused (and skipped to its end), so
/// that a client cannot make the service hold an endless line.
pub const MAX_FRAME_BYTES: usize = 64 << 20;

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use serde_json::Value;

    fn frame(t0: usize) -> String {
        let t: Vec<f64> = (t0..t0 + 3).map(|k| k as f64 * 1e-4).collect();
        let mut obj = serde_json::Map::new();
        for name in FRAME_CHANNELS {
            obj.insert(name.into(), t.clone().into());
        }
        Value::Object(obj).to_string()
    }

    /// The channels the seam shifts are where [`T`], [`THETA_EN`], … say.
    #[test]
    fn the_shifted_channels_are_named() {
        assert_eq!(
            [T, THETA_DY, THETA_EN, OMEGA_EN].map(|k| FRAME_CHANNELS[k]),
            ["t", "theta_dy", "theta_en", "omega_en"]
        );
    }

    /// A crank at 1000 rpm, 10 kHz, frames of 100 samples; the shaft twisted by 0.02 rad.
    fn crank_frame(k: usize, seq: Option<usize>, restarted_at: Option<usize>) -> String {
        use std::f64::consts::{PI, TAU};
        let w = 1000.0 * TAU / 60.0;
        let mut obj = serde_json::Map::new();
        if let Some(s) = seq {
            obj.insert("seq".into(), s.into());
        }
        let n = k * 100..(k + 1) * 100;
        // A DAQ started again at frame `r` counts its time from 0 and its absolute encoders'
        // angles from where they stood: the engine's within the cycle, the dynamometer's within
        // its turn.
        let t0 = restarted_at.map_or(0.0, |r| r as f64 * 100.0 * 1e-4);
        let from = |x0: f64, unit: f64| x0 - x0.rem_euclid(unit);
        let (en0, dy0) = (w * t0 + 0.3, w * t0 + 0.28);
        let (en0, dy0) = match restarted_at {
            Some(_) => (from(en0, 4.0 * PI), from(dy0, TAU)),
            None => (0.0, 0.0),
        };
        let t: Vec<f64> = n.clone().map(|i| i as f64 * 1e-4 - t0).collect();
        let en: Vec<f64> = n.clone().map(|i| w * i as f64 * 1e-4 + 0.3 - en0).collect();
        let dy: Vec<f64> = n
            .clone()
            .map(|i| w * i as f64 * 1e-4 + 0.28 - dy0)
            .collect();
        for (name, v) in [("t", t), ("theta_en", en), ("theta_dy", dy)] {
            obj.insert(name.into(), v.into());
        }
        for name in ["omega_en", "omega_dy"] {
            obj.insert(name.into(), vec![w; 100].into());
        }
        obj.insert("torque_shaft".into(), vec![25.0; 100].into());
        Value::Object(obj).to_string()
    }

    /// A DAQ that starts again (its `seq` back at 0, its clock at 0, its angles within their
    /// cycle and turn) goes on after a gap: its frames are taken, the restart told once, the
    /// time goes on after the last sample, the crank angle keeps its place in the cycle and
    /// advances at the crank's speed, the twist is the same; a frame repeated after the restart
    /// is still refused. Without `seq`, its time back at its start is a restart, and a time
    /// back within what was taken is refused.
    #[test]
    fn a_sender_that_starts_again_goes_on_after_a_gap() {
        use std::f64::consts::PI;
        for with_seq in [true, false] {
            let mut lines = Vec::new();
            for k in 0..10 {
                lines.push(crank_frame(k, with_seq.then_some(k), None));
            }
            for k in 10..20 {
                lines.push(crank_frame(k, with_seq.then_some(k - 10), Some(10)));
            }
            lines.push(crank_frame(13, with_seq.then_some(3), Some(10)));
            let input = lines.join("\n") + "\n";
            let mut src = FrameSource::new(std::io::Cursor::new(input), 10_000.0).unwrap();
            let mut taken: Vec<Recording> = Vec::new();
            let mut notices = Vec::new();
            for k in 0..20 {
                taken.push(src.next_chunk().unwrap().unwrap());
                notices.extend(src.take_notice().map(|n| (k, n)));
            }
            assert_eq!(notices.len(), 1, "{notices:?}");
            assert_eq!(notices[0].0, 10);
            let why = if with_seq {
                "seq 0 after 9"
            } else {
                "t back at 0 s"
            };
            assert!(
                notices[0]
                    .1
                    .contains(&format!("the sender started again ({why}")),
                "{}",
                notices[0].1
            );
            match src.next_chunk() {
                Err(LiveError::BadFrame { line: 21, what }) => assert!(
                    what.contains(if with_seq {
                        "repeated or out of order"
                    } else {
                        "not after the previous"
                    }),
                    "{what}"
                ),
                other => panic!("{:?}", other.map(|r| r.map(|r| r.len()))),
            }
            let col = |name| {
                taken
                    .iter()
                    .flat_map(|r| r.values(name).unwrap().to_vec())
                    .collect::<Vec<f64>>()
            };
            let (t, en, dy) = (col("t"), col("theta_en"), col("theta_dy"));
            let seam = 1000;
            for i in 1..t.len() {
                let step = t[i] - t[i - 1];
                if i == seam {
                    let speed = (en[i] - en[i - 1]) / step;
                    assert!(
                        (speed / (1000.0 * std::f64::consts::TAU / 60.0) - 1.0).abs() < 0.5,
                        "{speed}"
                    );
                    assert!(en[i] - en[i - 1] > 4.0 * PI);
                } else {
                    assert!((step - 1e-4).abs() < 1e-9, "{i}: {step}");
                    assert!(
                        (en[i] - en[i - 1] - 1000.0 * std::f64::consts::TAU / 60.0 * 1e-4).abs()
                            < 1e-9,
                        "{i}"
                    );
                }
                // The crank angle's place in the cycle and the twist are the sender's.
                let place = |x: f64| (x - 0.3).rem_euclid(4.0 * PI);
                let want = place(1000.0 * std::f64::consts::TAU / 60.0 * i as f64 * 1e-4 + 0.3);
                let d = (place(en[i]) - want).abs();
                assert!(d.min(4.0 * PI - d) < 1e-9, "{i}: {} {}", en[i], want);
                assert!(
                    (dy[i] - en[i] + 0.02).abs() < 1e-9,
                    "{i}: twist {}",
                    dy[i] - en[i]
                );
            }
        }
    }

    /// A line that is not UTF-8, and one longer than [`MAX_FRAME_BYTES`], are refused by line;
    /// the frames after them are taken.
    #[test]
    fn undecodable_and_endless_lines_are_refused_and_the_stream_goes_on() {
        let mut input = Vec::new();
        input.extend_from_slice(frame(0).as_bytes());
        input.extend_from_slice(b"\n{\"t\": [\xff\xfe]}\n");
        input.extend_from_slice(&vec![b' '; MAX_FRAME_BYTES + 10]);
        input.push(b'\n');
        input.extend_from_slice(frame(3).as_bytes());
        input.push(b'\n');
        let mut src = FrameSource::new(std::io::Cursor::new(input), 10_000.0).unwrap();
        assert_eq!(src.next_chunk().unwrap().unwrap().len(), 3);
        match src.next_chunk() {
            Err(LiveError::BadFrame { line: 2, what }) => assert!(what.contains("UTF-8"), "{what}"),
            other => panic!("{:?}", other.map(|r| r.map(|r| r.len()))),
        }
        match src.next_chunk() {
            Err(LiveError::BadFrame { line: 3, what }) => {
                assert!(what.contains("longer than"), "{what}")
            }
            other => panic!("{:?}", other.map(|r| r.map(|r| r.len()))),
        }
        let last = src.next_chunk().unwrap().unwrap();
        assert!((last.values("t").unwrap()[0] - 3e-4).abs() < 1e-12);
        assert!(src.next_chunk().unwrap().is_none());
    }

    /// A reader that gives its pieces one read at a time, `None` as a wait (`WouldBlock`).
    struct Pieces(std::collections::VecDeque<Option<Vec<u8>>>, Vec<u8>);

    impl std::io::Read for Pieces {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            read_buffered(self, buf)
        }
    }

    impl BufRead for Pieces {
        fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
            if self.1.is_empty() {
                match self.0.pop_front() {
                    Some(Some(b)) => self.1 = b,
                    Some(None) => return Err(std::io::ErrorKind::WouldBlock.into()),
                    None => {}
                }
            }
            Ok(&self.1)
        }

        fn consume(&mut self, amt: usize) {
            self.1.drain(..amt);
        }
    }

    impl FrameLines for Pieces {}

    /// A wait for the sender (`WouldBlock`) — before a frame, in the middle of one, in the
    /// middle of a line too long — is an empty chunk (the run applies its controls), and the
    /// line in progress is kept: the frame is taken whole, the long line refused whole.
    #[test]
    fn a_wait_for_the_sender_is_an_empty_chunk_and_keeps_the_line() {
        let f = frame(0);
        let (a, b) = f.as_bytes().split_at(f.len() / 2);
        let long = vec![b' '; MAX_FRAME_BYTES];
        let pieces = [
            None,
            Some(a.to_vec()),
            None,
            None,
            Some([b, b"\n"].concat()),
            Some(long.clone()),
            None,
            Some([&long[..], b"\n"].concat()),
            Some(format!("{}\n", frame(3)).into_bytes()),
        ];
        let mut src =
            FrameSource::new(Pieces(pieces.into_iter().collect(), Vec::new()), 10_000.0).unwrap();
        let mut got = Vec::new();
        for _ in 0..20 {
            match src.next_chunk() {
                Ok(Some(c)) => got.push(Ok(c.len())),
                Ok(None) => break,
                Err(LiveError::BadFrame { line, what }) => got.push(Err((line, what))),
                Err(e) => panic!("{e}"),
            }
        }
        let long_read = format!(
            "longer than {MAX_FRAME_BYTES} bytes ({} read): refused",
            2 * MAX_FRAME_BYTES + 1
        );
        assert_eq!(
            got,
            [
                Ok(0),
                Ok(0),
                Ok(0),
                Ok(3),
                Ok(0),
                Err((2, long_read)),
                Ok(3)
            ]
        );
    }
}
