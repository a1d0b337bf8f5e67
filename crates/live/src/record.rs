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

    /// Finish the log, if one is open: its last `log` event.
    pub fn stop(&mut self, t_s: f64) -> Result<Option<Event>, LiveError> {
        let Some((path, writer)) = self.file.take() else {
            return Ok(None);
        };
        let samples = writer.as_ref().map_or(0, ChunkWriter::rows);
        if let Some(w) = writer {
            w.close()?;
        }
        let bytes = std::fs::metadata(&path).map_or(0, |m| m.len() as usize);
        Ok(Some(Event::Log {
            t_s,
            file: path.display().to_string(),
            samples,
            bytes,
            state: LogState::Closed,
        }))
    }
}

impl Drop for Recorder {
    /// A run that ends on an error (or a panic) still closes its log.
    fn drop(&mut self) {
        if let Some((_, Some(w))) = self.file.take() {
            let _ = w.close();
        }
    }
}
