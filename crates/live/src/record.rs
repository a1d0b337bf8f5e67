//! Logging the live data: `{"cmd": "record", "file": "NAME.parquet"}` (or `NAME.mf4`) starts
//! writing every channel of every chunk to that file in the log directory (`--log-dir`,
//! default `physid-logs`), `{"cmd": "record", "stop": true}` finishes the file. The file is
//! written as the chunks arrive ([`ChunkWriter`]: Parquet a row group every 65 536 rows, MDF4
//! record by record into one growing data block) — so memory stays bounded however long it
//! records; its size is reported in `log` events (each second of recording and at the end).
//!
//! **No data lost.** Each [`COMMIT_EVERY`] of wall-clock time the log is committed
//! ([`ChunkWriter::commit`]): on the disk, and readable as it is (MDF4: the record count and
//! the data block's length written after the records) or after `physid recover FILE` (Parquet:
//! the footer written from the journal entry after each row group). A run killed (`kill -9`,
//! a power loss) loses at most the samples since the last commit; a run stopped by SIGINT or
//! SIGTERM closes the log.
//!
//! **A full disk.** The log knows how much it may still add to its file: the file system's free
//! space less what its writer holds (a Parquet row group in progress), asked for each
//! [`LOOK_EVERY`] and again before the log would outgrow it, less the samples appended since.
//! When the next chunk and the closing footer ([`closing_room`]) would not fit, the log is
//! closed there — every sample so far kept, the file readable — and the run goes on
//! ([`LogStopped`]). A write that fails anyway (another writer filled the disk, an I/O error)
//! leaves the file readable with what reached the disk ([`physid_io::salvage`]).
//!
//! Only a plain file name is taken (no directory part, no overwriting): a panel that may be
//! reached by others must not write where it likes.

use crate::event::{Event, LogState};
use crate::service::LiveError;
use physid_core::memory::disk_available;
use physid_core::Recording;
use physid_io::{ChunkWriter, WriteOptions};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// How often a log being written is committed (wall-clock time): the most a crash loses.
pub const COMMIT_EVERY: Duration = Duration::from_secs(1);

/// How often the log asks its file system for the free space (wall-clock time; other
/// programs write there too), besides before it would outgrow what it last heard.
pub const LOOK_EVERY: Duration = Duration::from_millis(250);

/// The log being written, if any.
pub struct Recorder {
    dir: PathBuf,
    /// The file asked for, and its writer once the first chunk has come.
    file: Option<(PathBuf, Option<ChunkWriter>)>,
    last_report: f64,
    /// When the log was last committed (`None`: not yet).
    last_commit: Option<Instant>,
    /// The samples at the last commit: what a failed write keeps at least.
    committed: usize,
    /// Commits so far (each a Parquet row group, whose footer entry closing the file needs).
    commits: usize,
    /// Bytes of samples appended (8 a value).
    appended: u64,
    /// At the last look at the disk: the bytes the log may add (the free space less what its
    /// writer held), [`Self::appended`] then, and when.
    room: Option<(u64, u64, Instant)>,
}

/// A log that stopped by itself (its disk nearly full, a write that failed): what to tell the
/// operator, and its last `log` event (closed, with the samples kept; or empty).
#[derive(Debug)]
pub struct LogStopped {
    /// Why, and what was kept.
    pub message: String,
    /// The log's last `log` event.
    pub last: Box<Event>,
}

/// The room [bytes] a log must keep to take a chunk of `rows` × `channels` samples and still
/// close, at most: the chunk twice over as float64 (Parquet and MDF4 store float64; Snappy
/// does not grow them beyond a few bytes a page), and for the closing footer 1 MiB plus 256
/// bytes a channel for each row group (measured: 100–150).
pub fn closing_room(rows: usize, channels: usize, groups: usize) -> u64 {
    2 * 8 * (rows * channels) as u64 + (1 << 20) + 256 * (channels * groups) as u64
}

impl Recorder {
    /// Logs go to `dir` (created when the first log starts).
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        Self {
            dir: dir.into(),
            file: None,
            last_report: f64::NEG_INFINITY,
            last_commit: None,
            committed: 0,
            commits: 0,
            appended: 0,
            room: None,
        }
    }

    /// Whether a log is being written.
    pub fn is_recording(&self) -> bool {
        self.file.is_some()
    }

    /// Start a log named `name`; the error names the field that is wrong.
    pub fn start(&mut self, name: &str) -> Result<PathBuf, String> {
        if self.file.is_some() {
            return Err("field 'file': a log is being written; stop it first".into());
        }
        let plain = Path::new(name).file_name().is_some_and(|f| f == name);
        if !plain || name.starts_with('.') {
            return Err(format!(
                "field 'file' is '{name}': expected a plain file name (the log directory is {})",
                self.dir.display()
            ));
        }
        if !(name.ends_with(".parquet") || name.ends_with(".mf4")) {
            return Err(format!(
                "field 'file' is '{name}': expected a name ending in .parquet or .mf4"
            ));
        }
        std::fs::create_dir_all(&self.dir)
            .map_err(|e| format!("the log directory {}: {e}", self.dir.display()))?;
        let path = self.dir.join(name);
        // Claim the name now, so that an existing file is refused at once.
        std::fs::File::create_new(&path)
            .map_err(|e| format!("field 'file': {}: {e}", path.display()))?;
        self.file = Some((path.clone(), None));
        self.last_report = f64::NEG_INFINITY;
        // The first chunk is committed at once: the file is a readable log from its start.
        self.last_commit = None;
        self.committed = 0;
        self.commits = 0;
        self.appended = 0;
        self.room = None;
        Ok(path)
    }

    /// Write a chunk when a log is open; a `log` event each second of recording. A log whose
    /// disk is too full to take the chunk and close is closed first; one whose write fails is
    /// left readable with what reached the disk: either stops it ([`LogStopped`]).
    pub fn push(&mut self, chunk: &Recording, t_s: f64) -> Result<Option<Event>, LogStopped> {
        let Some((path, writer)) = &self.file else {
            return Ok(None);
        };
        let need = closing_room(chunk.len(), chunk.channels().len(), self.commits + 1);
        let look = self.room.is_none_or(|(room, then, at)| {
            self.appended - then + need > room || at.elapsed() >= LOOK_EVERY
        });
        if let (true, Some(free)) = (look, disk_available(&self.dir)) {
            // What the writer holds is asked here only (a Parquet writer sums its buffers).
            let on_disk = std::fs::metadata(path).map_or(0, |m| m.len());
            let held = writer
                .as_ref()
                .map_or(0, |w| (w.bytes() as u64).saturating_sub(on_disk));
            let room = free.saturating_sub(held);
            self.room = Some((room, self.appended, Instant::now()));
            if need > room {
                return Err(self.closed_for_room(free, need + held, t_s));
            }
        }
        if let Err(e) = self.write(chunk) {
            return Err(self.ended(&format!("the log stopped: {e}"), Some(&e), t_s));
        }
        let Some((path, Some(w))) = &self.file else {
            return Ok(None);
        };
        if t_s - self.last_report < 1.0 {
            return Ok(None);
        }
        self.last_report = t_s;
        Ok(Some(Event::Log {
            t_s,
            file: path.display().to_string(),
            samples: w.rows(),
            bytes: w.bytes(),
            state: LogState::Recording,
        }))
    }

    /// Finish the log, if one is open: its last `log` event. A log that no chunk reached is
    /// not kept: its claimed, empty file is removed ([`LogState::Empty`]).
    pub fn stop(&mut self, t_s: f64) -> Result<Option<Event>, LiveError> {
        let Some((path, writer)) = self.file.take() else {
            return Ok(None);
        };
        let (samples, state) = match writer {
            Some(w) => {
                let rows = w.rows();
                w.close()?;
                (rows, LogState::Closed)
            }
            None => {
                free_claim(&path);
                (0, LogState::Empty)
            }
        };
        let bytes = std::fs::metadata(&path).map_or(0, |m| m.len() as usize);
        Ok(Some(Event::Log {
            t_s,
            file: path.display().to_string(),
            samples,
            bytes,
            state,
        }))
    }

    /// Append `chunk` to the open log (its writer made at the first), committed each
    /// [`COMMIT_EVERY`].
    fn write(&mut self, chunk: &Recording) -> Result<(), physid_io::IoError> {
        let Some((path, writer)) = self.file.as_mut() else {
            return Ok(());
        };
        let w = match writer {
            Some(w) => w,
            None => writer.insert(ChunkWriter::create(
                &*path,
                chunk,
                &WriteOptions::default(),
            )?),
        };
        w.append(chunk)?;
        self.appended += 8 * (chunk.len() * chunk.channels().len()) as u64;
        if self
            .last_commit
            .is_none_or(|at| at.elapsed() >= COMMIT_EVERY)
        {
            w.commit()?;
            self.last_commit = Some(Instant::now());
            self.commits += 1;
            self.committed = w.rows();
        }
        Ok(())
    }

    /// The log closed before its disk fills: `free` bytes left where it needs `need`.
    fn closed_for_room(&mut self, free: u64, need: u64, t_s: f64) -> LogStopped {
        let mb = |b: u64| b as f64 / 1e6;
        let why = format!(
            "the log was closed: {} has {:.2} MB free, less than the log needs to go on and close ({:.2} MB)",
            self.dir.display(),
            mb(free),
            mb(need)
        );
        self.ended(&why, None, t_s)
    }

    /// The log ended by itself, `why`: closed (every sample kept) unless the write `failed`
    /// with the disk's refusal — then its writer has made the file readable with what reached
    /// the disk, the samples it says (else the last commit's, at least those). A log no sample
    /// reached leaves no file.
    fn ended(&mut self, why: &str, failed: Option<&physid_io::IoError>, t_s: f64) -> LogStopped {
        let Some((path, writer)) = self.file.take() else {
            return LogStopped {
                message: why.to_string(),
                last: Box::new(empty_log(t_s, Path::new(""))),
            };
        };
        let Some(w) = writer else {
            free_claim(&path);
            return LogStopped {
                message: format!("{why}; the log had no sample yet: no file is kept"),
                last: Box::new(empty_log(t_s, &path)),
            };
        };
        let rows = w.rows();
        let (samples, message) = match failed {
            Some(e @ physid_io::IoError::WriteFailed { .. }) => (
                e.kept().map_or(self.committed, |k| k as usize),
                why.to_string(),
            ),
            // Closed here: a full disk ahead, or a write refused before the file was touched.
            _ => match w.close() {
                Ok(()) => (
                    rows,
                    format!("{why}; {} keeps all its {rows} samples, readable. Free space and start a new log", path.display()),
                ),
                Err(e) => (
                    e.kept().map_or(self.committed, |k| k as usize),
                    format!("{why}; closing it: {e}"),
                ),
            },
        };
        LogStopped {
            message,
            last: Box::new(Event::Log {
                t_s,
                file: path.display().to_string(),
                samples,
                bytes: std::fs::metadata(&path).map_or(0, |m| m.len() as usize),
                state: LogState::Closed,
            }),
        }
    }
}

/// The `log` event of a log at `path` that keeps no sample (no file).
fn empty_log(t_s: f64, path: &Path) -> Event {
    Event::Log {
        t_s,
        file: path.display().to_string(),
        samples: 0,
        bytes: 0,
        state: LogState::Empty,
    }
}

/// Remove the empty file [`Recorder::start`] created to claim a log's name — only while it is
/// still empty (nothing else's file is removed).
fn free_claim(path: &Path) {
    if std::fs::metadata(path).is_ok_and(|m| m.is_file() && m.len() == 0) {
        let _ = std::fs::remove_file(path);
    }
}

impl Drop for Recorder {
    /// A run that ends on an error (or a panic) still closes its log (and frees a name no chunk
    /// reached).
    fn drop(&mut self) {
        match self.file.take() {
            Some((_, Some(w))) => {
                let _ = w.close();
            }
            Some((path, None)) => free_claim(&path),
            None => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use physid_core::{Basis, Channel};

    fn chunk() -> Recording {
        let mut r = Recording::new(Basis::Time);
        for (name, unit, v) in [("t", "s", [0.0, 0.1]), ("throttle", "deg", [10.0, 11.0])] {
            r.push(Channel {
                name: name.into(),
                unit: unit.into(),
                values: v.to_vec(),
            })
            .unwrap();
        }
        r
    }

    /// A log stopped before any chunk came (a record and a stop in the same breath, or a
    /// paused run) leaves no file: it used to leave an empty one that no reader could open
    /// ("the extension says Parquet but the file is text"); the name is free again. A log
    /// that got a chunk is closed and readable; an existing file is never touched.
    #[test]
    fn a_log_no_sample_reached_leaves_no_file() {
        let dir = tempfile::tempdir().unwrap();
        for name in ["a.parquet", "b.mf4"] {
            let mut r = Recorder::new(dir.path());
            let path = r.start(name).unwrap();
            assert!(path.exists(), "the name is claimed at the start");
            match r.stop(1.0).unwrap() {
                Some(Event::Log { samples, state, .. }) => {
                    assert_eq!((samples, state), (0, LogState::Empty));
                }
                e => panic!("{e:?}"),
            }
            assert!(!path.exists(), "{name}: no empty file left");
            // Dropped (a run ending on an error) before any chunk: the same.
            let mut r = Recorder::new(dir.path());
            r.start(name).unwrap();
            drop(r);
            assert!(!path.exists(), "{name}: no empty file left on drop");
            // With a chunk: closed and readable.
            let mut r = Recorder::new(dir.path());
            r.start(name).unwrap();
            r.push(&chunk(), 0.1).unwrap();
            match r.stop(0.1).unwrap() {
                Some(Event::Log { samples, state, .. }) => {
                    assert_eq!((samples, state), (2, LogState::Closed));
                }
                e => panic!("{e:?}"),
            }
            let back = physid_io::read(&path, &Default::default()).unwrap();
            assert_eq!(back.values("throttle").unwrap(), &[10.0, 11.0]);
            // Its name is taken now: refused, the file untouched.
            let mut r = Recorder::new(dir.path());
            assert!(r.start(name).unwrap_err().contains("File exists"));
            drop(r);
            assert!(physid_io::read(&path, &Default::default()).is_ok());
        }
    }
}
