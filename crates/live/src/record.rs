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
//! Only a plain file name is taken (no directory part, no overwriting): a panel that may be
//! reached by others must not write where it likes.

use crate::event::{Event, LogState};
use crate::service::LiveError;
use physid_core::Recording;
use physid_io::{ChunkWriter, WriteOptions};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// How often a log being written is committed (wall-clock time): the most a crash loses.
pub const COMMIT_EVERY: Duration = Duration::from_secs(1);

/// The log being written, if any.
pub struct Recorder {
    dir: PathBuf,
    /// The file asked for, and its writer once the first chunk has come.
    file: Option<(PathBuf, Option<ChunkWriter>)>,
    last_report: f64,
    /// When the log was last committed (`None`: not yet).
    last_commit: Option<Instant>,
}

impl Recorder {
    /// Logs go to `dir` (created when the first log starts).
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        Self {
            dir: dir.into(),
            file: None,
            last_report: f64::NEG_INFINITY,
            last_commit: None,
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
        Ok(path)
    }

    /// Write a chunk when a log is open; a `log` event each second of recording.
    pub fn push(&mut self, chunk: &Recording, t_s: f64) -> Result<Option<Event>, LiveError> {
        let Some((path, writer)) = self.file.as_mut() else {
            return Ok(None);
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
        if self
            .last_commit
            .is_none_or(|at| at.elapsed() >= COMMIT_EVERY)
        {
            w.commit()?;
            self.last_commit = Some(Instant::now());
        }
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
