//! Frames over a local socket: `physid live --frames-socket PATH`.
//!
//! The service listens on a Unix socket at `PATH`, created with mode 0600 (only its owner can
//! connect) and removed when dropped; a socket left by a killed run, on which nobody answers,
//! is replaced; any other file is not. The first client that sends something is the DAQ, its
//! frames read as lines, like stdin. When it closes its connection the frames end — or, with
//! [`SocketFrames::reconnecting`], the next client that sends something goes on (a DAQ whose
//! software started again: its frames are placed by [`super::seam`]); a line the closed client
//! left unfinished is ended there, so that it is refused alone and the next client's first
//! line is its own.
//!
//! With a stop flag ([`SocketFrames::until`]) nothing waits past it: waiting for a client, or
//! for a silent client's next bytes, ends the frames within [`POLL`] of the flag being set, so
//! that SIGINT or SIGTERM ends the run as its end does; until then such a wait hands its
//! caller a `WouldBlock` every [`POLL`], so that the run applies its controls meanwhile.

use super::{FrameLines, POLL};
use crate::service::LiveError;
use std::io::{BufRead, BufReader, ErrorKind, Read};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

/// What a client's closing is told to (a line for the operator's terminal).
type Tell = Box<dyn FnMut(&str) + Send>;

/// Frames over a local socket (module docs).
pub struct SocketFrames {
    path: PathBuf,
    listener: UnixListener,
    stream: Option<BufReader<UnixStream>>,
    /// Whether the client has sent anything (one that closes without a byte — a probe — is
    /// not the client: the next one is accepted).
    heard: bool,
    /// Whether a client that closes is followed by the next one.
    reconnect: bool,
    /// Set when the run is to end.
    stop: Option<Arc<AtomicBool>>,
    /// Whether the bytes consumed so far end inside a line.
    mid_line: bool,
    /// A line end handed out for a line the closed client left unfinished (not yet consumed).
    ending_line: bool,
    /// Clients heard from, and when the last one closed.
    clients: usize,
    closed: Option<Instant>,
    /// Told by [`FrameLines::notice`] once.
    notice: Option<String>,
    /// Told as it happens (a client closed: waiting for the next), for the operator's terminal.
    on_wait: Option<Tell>,
}

/// A Unix socket listening at `path` that is never open to others, not even for an instant:
/// bound in a directory of its own (mode 0700) beside `path`, given mode 0600 there, then
/// linked to `path` (which fails if `path` has come meanwhile) — binding at `path` and then
/// changing its mode left it, between the two, as the umask made it (a group-writable socket
/// under umask 002).
fn bind_private(path: &Path) -> std::io::Result<UnixListener> {
    use std::os::unix::fs::{DirBuilderExt, PermissionsExt};
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let dir = parent.join(format!(".physid-{}", std::process::id()));
    std::fs::DirBuilder::new().mode(0o700).create(&dir)?;
    let tmp = dir.join("s");
    let bound = UnixListener::bind(&tmp).and_then(|l| {
        std::fs::set_permissions(&tmp, std::fs::Permissions::from_mode(0o600))?;
        std::fs::hard_link(&tmp, path)?;
        Ok(l)
    });
    let _ = std::fs::remove_file(&tmp);
    let _ = std::fs::remove_dir(&dir);
    bound
}

impl SocketFrames {
    /// Listen at `path` (which must not exist).
    pub fn bind(path: &Path) -> Result<Self, LiveError> {
        // A socket left by a run that was killed: nobody answers on it, so it is replaced.
        if UnixStream::connect(path).is_err_and(|e| e.kind() == ErrorKind::ConnectionRefused) {
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
        // Not blocking: a wait for a client looks at the stop flag every [`POLL`].
        let listener = bind_private(path)
            .and_then(|l| l.set_nonblocking(true).map(|()| l))
            .map_err(|e| LiveError::Invalid(format!("{}: {e}", path.display())))?;
        Ok(Self {
            path: path.to_path_buf(),
            listener,
            stream: None,
            heard: false,
            reconnect: false,
            stop: None,
            mid_line: false,
            ending_line: false,
            clients: 0,
            closed: None,
            notice: None,
            on_wait: None,
        })
    }

    /// When a client closes its connection, take the next client's frames instead of ending;
    /// `on_wait` is told each time a client closes (what for the operator's terminal).
    pub fn reconnecting(mut self, on_wait: impl FnMut(&str) + Send + 'static) -> Self {
        self.reconnect = true;
        self.on_wait = Some(Box::new(on_wait));
        self
    }

    /// End the frames within [`POLL`] of `stop` being set, rather than wait for a client or
    /// its bytes.
    pub fn until(mut self, stop: Arc<AtomicBool>) -> Self {
        self.stop = Some(stop);
        self
    }

    fn stopped(&self) -> bool {
        self.stop
            .as_ref()
            .is_some_and(|s| s.load(Ordering::Relaxed))
    }

    /// The next client, or `None` when the stop flag was set while waiting for it; with a stop
    /// flag, `WouldBlock` when none came within [`POLL`].
    fn accept(&mut self) -> std::io::Result<Option<UnixStream>> {
        loop {
            if self.stopped() {
                return Ok(None);
            }
            match self.listener.accept() {
                Ok((s, _)) => {
                    s.set_nonblocking(false)?;
                    if self.stop.is_some() {
                        s.set_read_timeout(Some(POLL))?;
                    }
                    return Ok(Some(s));
                }
                Err(e) if e.kind() == ErrorKind::WouldBlock => {
                    std::thread::sleep(POLL);
                    // Nothing yet: the caller applies its controls and asks again.
                    if self.stop.is_some() && !self.stopped() {
                        return Err(ErrorKind::WouldBlock.into());
                    }
                }
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
    }

    /// The client's buffered bytes: empty at the end of the frames (the client closed and no
    /// other follows, or the stop flag was set); a line end for a line a closed client left
    /// unfinished.
    fn fill(&mut self) -> std::io::Result<&[u8]> {
        loop {
            if self.ending_line {
                return Ok(b"\n");
            }
            if self.stream.is_none() {
                match self.accept()? {
                    Some(s) => self.stream = Some(BufReader::new(s)),
                    None => return Ok(&[]),
                }
            }
            let Some(s) = self.stream.as_mut() else {
                continue;
            };
            let empty = match s.fill_buf() {
                Ok(b) => b.is_empty(),
                Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {
                    if self.stopped() {
                        return Ok(&[]);
                    }
                    // Nothing yet (a read timeout is set only with a stop flag): the caller
                    // applies its controls and asks again.
                    return Err(ErrorKind::WouldBlock.into());
                }
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                Err(e) => return Err(e),
            };
            if empty {
                if !self.heard {
                    // A probe: not the client.
                    self.stream = None;
                    continue;
                }
                if !self.reconnect {
                    return Ok(&[]);
                }
                // The client closed: the next one goes on.
                self.stream = None;
                self.heard = false;
                self.closed = Some(Instant::now());
                let unfinished = if self.mid_line {
                    " in the middle of a line (refused)"
                } else {
                    ""
                };
                let what = format!(
                    "the client on {} (the {}) closed its connection{unfinished}: waiting for the next",
                    self.path.display(),
                    ordinal(self.clients)
                );
                if let Some(tell) = self.on_wait.as_mut() {
                    tell(&what);
                }
                if self.mid_line {
                    self.ending_line = true;
                }
                continue;
            }
            if !self.heard {
                self.heard = true;
                self.clients += 1;
                if let Some(at) = self.closed.take() {
                    self.notice = Some(format!(
                        "the {} client connected on {} {:.3} s after the {} closed its connection",
                        ordinal(self.clients),
                        self.path.display(),
                        at.elapsed().as_secs_f64(),
                        ordinal(self.clients - 1)
                    ));
                }
            }
            return match self.stream.as_mut() {
                Some(s) => Ok(s.buffer()),
                None => Ok(&[]),
            };
        }
    }
}

/// 1st, 2nd, 3rd, 4th, … 11th, 12th, 13th, 21st …
fn ordinal(n: usize) -> String {
    let suffix = match (n % 10, n % 100) {
        (_, 11..=13) => "th",
        (1, _) => "st",
        (2, _) => "nd",
        (3, _) => "rd",
        _ => "th",
    };
    format!("{n}{suffix}")
}

impl Read for SocketFrames {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        super::read_buffered(self, buf)
    }
}

impl BufRead for SocketFrames {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        self.fill()
    }

    fn consume(&mut self, amt: usize) {
        if amt == 0 {
            return;
        }
        if self.ending_line {
            self.ending_line = false;
            self.mid_line = false;
            return;
        }
        if let Some(s) = self.stream.as_mut() {
            let end = s.buffer().get(..amt).and_then(|b| b.last()).copied();
            self.mid_line = end != Some(b'\n');
            s.consume(amt);
        }
    }
}

impl FrameLines for SocketFrames {
    fn notice(&mut self) -> Option<String> {
        self.notice.take()
    }
}

impl Drop for SocketFrames {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use std::io::Write;
    use std::time::Duration;

    #[test]
    fn ordinals() {
        let got: Vec<String> = [1, 2, 3, 4, 11, 12, 13, 21, 22, 102, 111]
            .map(ordinal)
            .into();
        assert_eq!(
            got,
            [
                "1st", "2nd", "3rd", "4th", "11th", "12th", "13th", "21st", "22nd", "102nd",
                "111th"
            ]
        );
    }

    /// Reconnecting: a probe is skipped, a line the first client leaves unfinished is ended
    /// there (so the second client's first line is whole and its own), the second client's
    /// connection is told once; with the stop flag set, a wait for a client ends the lines.
    #[test]
    fn the_next_client_goes_on_after_a_closed_one() {
        let dir = std::env::temp_dir().join(format!("physid-sock-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("s");
        let stop = Arc::new(AtomicBool::new(false));
        let waits = Arc::new(std::sync::Mutex::new(Vec::new()));
        let told = waits.clone();
        let mut src = SocketFrames::bind(&path)
            .unwrap()
            .reconnecting(move |w| told.lock().unwrap().push(w.to_string()))
            .until(stop.clone());
        let p = path.clone();
        let stopper = stop.clone();
        let clients = std::thread::spawn(move || {
            drop(UnixStream::connect(&p).unwrap()); // a probe
            let mut a = UnixStream::connect(&p).unwrap();
            a.write_all(b"one\ntw").unwrap();
            drop(a);
            let mut b = UnixStream::connect(&p).unwrap();
            b.write_all(b"three\nfour\n").unwrap();
            drop(b);
            std::thread::sleep(Duration::from_millis(300));
            stopper.store(true, Ordering::Relaxed);
        });
        let mut lines = Vec::new();
        let mut notices = Vec::new();
        let deadline = Instant::now() + Duration::from_secs(20);
        loop {
            assert!(Instant::now() < deadline);
            let mut line = String::new();
            let read = loop {
                match src.read_line(&mut line) {
                    Err(e) if e.kind() == ErrorKind::WouldBlock => {
                        assert!(Instant::now() < deadline)
                    }
                    r => break r.unwrap(),
                }
            };
            if read == 0 {
                break;
            }
            notices.extend(src.notice());
            lines.push(line);
        }
        clients.join().unwrap();
        assert_eq!(lines, ["one\n", "tw\n", "three\n", "four\n"]);
        assert_eq!(notices.len(), 1, "{notices:?}");
        assert!(
            notices[0].starts_with("the 2nd client connected on"),
            "{notices:?}"
        );
        let waits = waits.lock().unwrap();
        assert_eq!(waits.len(), 2, "{waits:?}");
        assert!(waits[0].contains("(the 1st) closed its connection in the middle of a line"));
        assert!(waits[1].contains("(the 2nd) closed its connection: waiting"));
        drop(src);
        assert!(!path.exists());
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// Without reconnecting, the frames end when the client closes; with the stop flag set
    /// before any client, they end at once.
    #[test]
    fn the_frames_end_with_the_client_or_the_stop_flag() {
        let dir = std::env::temp_dir().join(format!("physid-sock1-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("s");
        let mut src = SocketFrames::bind(&path).unwrap();
        let mut a = UnixStream::connect(&path).unwrap();
        a.write_all(b"one\n").unwrap();
        drop(a);
        let mut all = String::new();
        src.read_to_string(&mut all).unwrap();
        assert_eq!(all, "one\n");
        drop(src);
        let stop = Arc::new(AtomicBool::new(true));
        let mut src = SocketFrames::bind(&path).unwrap().until(stop);
        let mut line = String::new();
        assert_eq!(src.read_line(&mut line).unwrap(), 0);
        drop(src);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
