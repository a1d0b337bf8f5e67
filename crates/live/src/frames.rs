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
use std::io::{BufRead, Read};

/// The channels a frame must carry (the shaft monitor's).
pub const FRAME_CHANNELS: [&str; 6] = physid_apps::shaft_monitor::SHAFT_CHANNELS;

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
                "sample rate {rate_hz} Hz: expected > 0",
                rate_hz = physid_core::Num(rate_hz)
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
            let read = match (&mut self.reader)
                .take(MAX_FRAME_BYTES as u64)
                .read_line(&mut self.buf)
            {
                Ok(n) => n,
                // The line was read (and is dropped): refused, the stream goes on.
                Err(e) if e.kind() == std::io::ErrorKind::InvalidData => {
                    self.line += 1;
                    return Err(self.bad("not UTF-8 text".into()));
                }
                Err(e) => return Err(LiveError::Invalid(format!("reading frames: {e}"))),
            };
            if read == 0 {
                return Ok(None);
            }
            self.line += 1;
            if read == MAX_FRAME_BYTES && !self.buf.ends_with('\n') {
                // Skip the rest of the line, holding nothing of it.
                self.buf.clear();
                let mut skipped = 0usize;
                loop {
                    let chunk = self
                        .reader
                        .fill_buf()
                        .map_err(|e| LiveError::Invalid(format!("reading frames: {e}")))?;
                    if chunk.is_empty() {
                        break;
                    }
                    let (n, end) = match chunk.iter().position(|&b| b == b'\n') {
                        Some(i) => (i + 1, true),
                        None => (chunk.len(), false),
                    };
                    self.reader.consume(n);
                    skipped += n;
                    if end {
                        break;
                    }
                }
                return Err(self.bad(format!(
                    "longer than {MAX_FRAME_BYTES} bytes ({} read): refused",
                    read + skipped
                )));
            }
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

/// The longest frame line taken [bytes]: a longer one is refused (and skipped to its end), so
/// that a client cannot make the service hold an endless line.
pub const MAX_FRAME_BYTES: usize = 64 << 20;

/// Frames over a local socket: `physid live --frames-socket PATH` listens on a Unix socket at
/// `PATH` (created with mode 0600 — only its owner can connect — and removed when dropped; a
/// socket left by a killed run, on which nobody answers, is replaced; any other file is not),
/// takes the first client that sends something and reads its frames as lines, like stdin: the
/// run ends when that client closes its connection.
#[cfg(unix)]
pub struct SocketFrames {
    path: std::path::PathBuf,
    listener: std::os::unix::net::UnixListener,
    stream: Option<std::io::BufReader<std::os::unix::net::UnixStream>>,
    /// Whether the client has sent anything (one that closes without a byte — a probe — is
    /// not the client: the next one is accepted).
    heard: bool,
}

/// A Unix socket listening at `path` that is never open to others, not even for an instant:
/// bound in a directory of its own (mode 0700) beside `path`, given mode 0600 there, then
/// linked to `path` (which fails if `path` has come meanwhile) — binding at `path` and then
/// changing its mode left it, between the two, as the umask made it (a group-writable socket
/// under umask 002).
#[cfg(unix)]
fn bind_private(path: &std::path::Path) -> std::io::Result<std::os::unix::net::UnixListener> {
    use std::os::unix::fs::{DirBuilderExt, PermissionsExt};
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => std::path::Path::new("."),
    };
    let dir = parent.join(format!(".physid-{}", std::process::id()));
    std::fs::DirBuilder::new().mode(0o700).create(&dir)?;
    let tmp = dir.join("s");
    let bound = std::os::unix::net::UnixListener::bind(&tmp).and_then(|l| {
        std::fs::set_permissions(&tmp, std::fs::Permissions::from_mode(0o600))?;
        std::fs::hard_link(&tmp, path)?;
        Ok(l)
    });
    let _ = std::fs::remove_file(&tmp);
    let _ = std::fs::remove_dir(&dir);
    bound
}

#[cfg(unix)]
impl SocketFrames {
    /// Listen at `path` (which must not exist).
    pub fn bind(path: &std::path::Path) -> Result<Self, LiveError> {
        // A socket left by a run that was killed: nobody answers on it, so it is replaced.
        if std::os::unix::net::UnixStream::connect(path)
            .is_err_and(|e| e.kind() == std::io::ErrorKind::ConnectionRefused)
        {
            use std::os::unix::fs::FileTypeExt;
            if std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_socket()) {
                let _ = std::fs::remove_file(path);
            }
        }
        if path.exists() {
            return Err(LiveError::Invalid(format!(
                "{}: already exists; remove it or choose another path for the socket",
                path.display()
            )));
        }
        let listener = bind_private(path)
            .map_err(|e| LiveError::Invalid(format!("{}: {e}", path.display())))?;
        Ok(Self {
            path: path.to_path_buf(),
            listener,
            stream: None,
            heard: false,
        })
    }

    /// The client's stream with data buffered (or at its end), accepted on first use.
    fn stream(
        &mut self,
    ) -> std::io::Result<&mut std::io::BufReader<std::os::unix::net::UnixStream>> {
        loop {
            if self.stream.is_none() {
                let (s, _) = self.listener.accept()?;
                self.stream = Some(std::io::BufReader::new(s));
            }
            let Some(s) = self.stream.as_mut() else {
                continue;
            };
            let empty = s.fill_buf()?.is_empty();
            if empty && !self.heard {
                self.stream = None;
                continue;
            }
            self.heard = true;
            return self
                .stream
                .as_mut()
                .ok_or_else(|| std::io::Error::other("no client"));
        }
    }
}

#[cfg(unix)]
impl std::io::Read for SocketFrames {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.stream()?.read(buf)
    }
}

#[cfg(unix)]
impl BufRead for SocketFrames {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        self.stream()?.fill_buf()
    }

    fn consume(&mut self, amt: usize) {
        if let Some(s) = self.stream.as_mut() {
            s.consume(amt);
        }
    }
}

#[cfg(unix)]
impl Drop for SocketFrames {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn frame(t0: usize) -> String {
        let t: Vec<f64> = (t0..t0 + 3).map(|k| k as f64 * 1e-4).collect();
        let mut obj = serde_json::Map::new();
        for name in FRAME_CHANNELS {
            obj.insert(name.into(), t.clone().into());
        }
        Value::Object(obj).to_string()
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
}
