//! Frames from a pipe: `physid live --frames -` (stdin) or `--frames PATH` (a file, a FIFO).
//!
//! A read from a pipe blocks until the sender writes: a silent DAQ would hold the run there,
//! past SIGINT and SIGTERM, until the signal's grace ran out and the run exited without its
//! `end`. Here the pipe is read on a thread of its own, which hands blocks on through a bounded
//! channel ([`DEPTH`] blocks of [`BLOCK`] bytes: the memory stays bounded whatever the sender
//! does), and a wait for the next block looks at the stop flag every [`POLL`]: once it is set,
//! the frames end — the run finishes as at the end of its input; until then the wait hands
//! its caller a `WouldBlock` every [`POLL`], so that the run applies its controls (a `stop`
//! from the panel ends a run whose sender is silent). The blocks' buffers go back to
//! the thread to be filled again (no allocation per block once running).
//!
//! The thread stays in its read until the sender writes or closes; it holds nothing the run
//! needs, and the process ends without waiting for it.

use super::{FrameLines, POLL};
use std::io::{BufRead, Read};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, RecvTimeoutError, SyncSender};
use std::sync::Arc;

/// The bytes one read hands on at most.
pub const BLOCK: usize = 64 * 1024;

/// The blocks read ahead at most.
pub const DEPTH: usize = 4;

/// Frames from a pipe, read on a thread of its own (module docs).
pub struct PipedFrames {
    /// Blocks as read: an empty one at the end of the input.
    blocks: Receiver<std::io::Result<Vec<u8>>>,
    /// Emptied buffers, back to the reading thread.
    spare: SyncSender<Vec<u8>>,
    /// The block being consumed, and how far.
    block: Vec<u8>,
    at: usize,
    /// The frames have ended (the input's end, its error told, or the stop flag).
    ended: bool,
    stop: Option<Arc<AtomicBool>>,
}

impl PipedFrames {
    /// `input` read on a thread of its own (`what` names the thread).
    pub fn new<R: Read + Send + 'static>(mut input: R, what: &str) -> std::io::Result<Self> {
        let (tx, blocks) = sync_channel(DEPTH);
        let (spare, spares) = sync_channel::<Vec<u8>>(DEPTH + 2);
        std::thread::Builder::new()
            .name(format!("physid frames from {what}"))
            .spawn(move || loop {
                let mut b = spares.try_recv().unwrap_or_default();
                b.resize(BLOCK, 0);
                let read = loop {
                    match input.read(&mut b) {
                        Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                        r => break r,
                    }
                };
                let end = !matches!(read, Ok(n) if n > 0);
                let sent = tx.send(read.map(|n| {
                    b.truncate(n);
                    b
                }));
                if end || sent.is_err() {
                    return;
                }
            })?;
        Ok(Self {
            blocks,
            spare,
            block: Vec::new(),
            at: 0,
            ended: false,
            stop: None,
        })
    }

    /// End the frames within [`POLL`] of `stop` being set, rather than wait for the sender.
    pub fn until(mut self, stop: Arc<AtomicBool>) -> Self {
        self.stop = Some(stop);
        self
    }

    fn stopped(&self) -> bool {
        self.stop
            .as_ref()
            .is_some_and(|s| s.load(Ordering::Relaxed))
    }
}

impl Read for PipedFrames {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        super::read_buffered(self, buf)
    }
}

impl BufRead for PipedFrames {
    /// The block's bytes not yet consumed; the next block when there are none; empty at the end
    /// of the frames. With a stop flag, a wait ends every [`POLL`]: at the end of the frames
    /// once the flag is set, else with [`WouldBlock`](std::io::ErrorKind::WouldBlock) (nothing
    /// yet: ask again) — the run applies its controls meanwhile.
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        while self.at == self.block.len() && !self.ended {
            let wait = if self.stop.is_some() {
                POLL
            } else {
                std::time::Duration::from_secs(3600)
            };
            match self.blocks.recv_timeout(wait) {
                Ok(Ok(b)) => {
                    self.ended = b.is_empty();
                    let used = std::mem::replace(&mut self.block, b);
                    self.at = 0;
                    // A full channel only drops a buffer: the thread makes another.
                    let _ = self.spare.try_send(used);
                }
                Ok(Err(e)) => {
                    self.ended = true;
                    return Err(e);
                }
                Err(RecvTimeoutError::Timeout) => {
                    self.ended = self.stopped();
                    if !self.ended {
                        // Nothing yet: the caller applies its controls and asks again.
                        return Err(std::io::ErrorKind::WouldBlock.into());
                    }
                }
                Err(RecvTimeoutError::Disconnected) => self.ended = true,
            }
        }
        Ok(&self.block[self.at..])
    }

    fn consume(&mut self, amt: usize) {
        self.at = (self.at + amt).min(self.block.len());
    }
}

impl FrameLines for PipedFrames {}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use std::io::Write;
    use std::time::{Duration, Instant};

    /// Every byte of the input, in order and whatever its size (blocks of 64 KiB and a last
    /// short one), and the end.
    #[test]
    fn every_byte_is_read_in_order() {
        let input: Vec<u8> = (0..3 * BLOCK + 1234).map(|i| (i % 251) as u8).collect();
        let mut p = PipedFrames::new(std::io::Cursor::new(input.clone()), "a test").unwrap();
        let mut got = Vec::new();
        p.read_to_end(&mut got).unwrap();
        assert_eq!(got, input);
        assert!(p.fill_buf().unwrap().is_empty());
    }

    /// A silent sender: the lines written are read, then a wait for more says so (`WouldBlock`)
    /// every poll and ends at the stop flag (the pipe still open).
    #[test]
    fn a_wait_for_a_silent_sender_ends_at_the_stop_flag() {
        let (reader, mut writer) = std::io::pipe().unwrap();
        let stop = Arc::new(AtomicBool::new(false));
        let mut p = PipedFrames::new(reader, "a test")
            .unwrap()
            .until(stop.clone());
        writeln!(writer, "{{\"t\":0}}").unwrap();
        let mut line = String::new();
        p.read_line(&mut line).unwrap();
        assert_eq!(line, "{\"t\":0}\n");
        let stopper = stop.clone();
        let set_at = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(300));
            stopper.store(true, Ordering::Relaxed);
            Instant::now()
        });
        line.clear();
        // Nothing yet, every poll, until the flag: then the end.
        let mut waits = 0;
        let read = loop {
            match p.read_line(&mut line) {
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => waits += 1,
                r => break r.unwrap(),
            }
        };
        assert_eq!(read, 0, "{line:?}");
        assert!(waits >= 1, "the wait told its caller nothing");
        let ended = Instant::now();
        let set_at = set_at.join().unwrap();
        assert!(ended >= set_at, "ended before the flag was set");
        drop(writer);
    }
}
