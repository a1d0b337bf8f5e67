//! Writing a recording file, whole ([`write`]) or a chunk at a time ([`ChunkWriter`]), in the
//! format its extension names.

use crate::format::Format;
use crate::{write_csv, write_mdf, write_parquet, IoError, MdfCompression};
use physid_core::Recording;
use std::path::Path;

/// How to write.
#[derive(Debug, Clone, Copy, Default)]
pub struct WriteOptions {
    /// MDF4 data-block compression.
    pub mdf_compression: MdfCompression,
}

/// Write a recording in the format its extension names — whole or not at all: into a staging
/// file beside `path` (`.NAME.physid-PID-N.partial`), renamed onto `path` once complete. A write
/// that fails (a full disk, an I/O error) leaves no torn file, and a file already at `path`
/// as it was.
pub fn write(path: impl AsRef<Path>, rec: &Recording, opts: &WriteOptions) -> Result<(), IoError> {
    let path = path.as_ref();
    let shown = path.display().to_string();
    let Some(format) = Format::from_extension(path) else {
        return Err(IoError::Malformed {
            path: shown,
            detail: "unknown extension: expected .csv, .parquet or .mf4".into(),
        });
    };
    // Refused before any work, and again at the rename (a writer may have started since).
    crate::lock::refuse_if_in_use(path)?;
    // The process and a count: two writes at once (threads) stage apart.
    static STAGED: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = STAGED.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    let staged = path.with_file_name(format!(".{name}.physid-{}-{n}.partial", std::process::id()));
    let written = match format {
        Format::Csv => write_csv(&staged, rec),
        Format::Parquet => write_parquet(&staged, rec),
        Format::Mdf4 => write_mdf(&staged, rec, opts.mdf_compression, None),
    }
    .and_then(|()| crate::lock::refuse_if_in_use(path))
    .and_then(|()| {
        std::fs::rename(&staged, path).map_err(|source| IoError::Os {
            path: shown.clone(),
            source,
        })
    });
    if let Err(e) = written {
        let _ = std::fs::remove_file(&staged);
        return Err(e.named(&staged.display().to_string(), &shown));
    }
    Ok(())
}

/// After a [`ChunkWriter`]'s write to `path` failed (a full disk, an I/O error) and its writer
/// was dropped: make the file readable with what is on the disk — Parquet: the torn end after
/// the last complete row group cut off and the footer written from its journal
/// ([`crate::recover_parquet`]; the cut frees the space the footer takes); uncompressed MDF4:
/// the record count set in place to the records wholly on the disk ([`crate::settle_mdf`]);
/// CSV: the torn last line cut ([`crate::recover_csv`]). The samples kept, where the format
/// says (not CSV; not a compressed MDF4 file, which is readable only once closed).
pub fn salvage(path: impl AsRef<Path>) -> Result<Option<u64>, IoError> {
    let path = path.as_ref();
    match Format::from_extension(path) {
        Some(Format::Parquet) => Ok(match crate::recover_parquet(path)? {
            crate::Recovered::Restored { rows, .. } => Some(rows),
            crate::Recovered::Closed => None,
        }),
        Some(Format::Mdf4) => crate::settle_mdf(path),
        Some(Format::Csv) => crate::recover_csv(path).map(|_| None),
        None => Ok(None),
    }
}

/// Rows per Parquet row group when a recording is written as it comes: the writer holds at
/// most this many rows (≈ 18 MB at 35 channels).
pub const STREAM_ROWS_PER_GROUP: usize = 65_536;

/// A recording written chunk by chunk in the format its extension names (`physid simulate`'s
/// output, `convert`'s, the live service's logs): CSV and MDF4 byte for byte what [`write`]
/// writes for the whole (MDF4 uncompressed; compressed, the same values in deflated blocks of
/// [`crate::MDF_BLOCK_BYTES`]), Parquet the same values in row groups of
/// [`STREAM_ROWS_PER_GROUP`]. Memory stays bounded however long it writes.
///
/// **A write that fails** (the operating system refuses: a full disk, an I/O error) leaves the
/// file readable with what reached the disk ([`salvage`]) and ends the writer: the error is
/// [`IoError::WriteFailed`], saying what the file keeps; every later call is refused.
pub struct ChunkWriter {
    path: std::path::PathBuf,
    /// `None` once a write failed.
    inner: Option<Inner>,
}

enum Inner {
    Csv(Box<crate::CsvWriter>),
    Parquet(Box<crate::ParquetWriter>),
    Mdf(Box<crate::MdfWriter>),
}

impl ChunkWriter {
    /// Create `path` for recordings with `like`'s channels, units, basis and metadata (the
    /// metadata where the format keeps it: Parquet).
    pub fn create(
        path: impl AsRef<Path>,
        like: &Recording,
        opts: &WriteOptions,
    ) -> Result<Self, IoError> {
        let path = path.as_ref();
        let inner = match Format::from_extension(path) {
            Some(Format::Csv) => Inner::Csv(Box::new(crate::CsvWriter::create(path, like)?)),
            Some(Format::Parquet) => Inner::Parquet(Box::new(crate::ParquetWriter::create(
                path,
                like,
                STREAM_ROWS_PER_GROUP,
            )?)),
            Some(Format::Mdf4) => Inner::Mdf(Box::new(crate::MdfWriter::create_compressed(
                path,
                like,
                None,
                opts.mdf_compression,
                crate::MDF_BLOCK_BYTES,
            )?)),
            None => {
                return Err(IoError::Malformed {
                    path: path.display().to_string(),
                    detail: "unknown extension: expected .csv, .parquet or .mf4".into(),
                })
            }
        };
        Ok(Self {
            path: path.to_path_buf(),
            inner: Some(inner),
        })
    }

    /// The writer, unless a write has failed.
    fn inner(&mut self) -> Result<&mut Inner, IoError> {
        self.inner.as_mut().ok_or_else(|| IoError::Malformed {
            path: self.path.display().to_string(),
            detail: "not written to after a write failed".into(),
        })
    }

    /// `result` of a call on the writer: an error of the operating system's ends the writer,
    /// the file made readable with what is on the disk ([`salvage`]).
    fn checked<T>(&mut self, result: Result<T, IoError>) -> Result<T, IoError> {
        match result {
            Err(e @ IoError::Os { .. }) => {
                let empty = self.holds_nothing();
                // The writer goes first (a buffer's last write with it).
                self.inner = None;
                Err(failed(&self.path, e, empty))
            }
            r => r,
        }
    }

    /// Append `rec`'s samples (the file's channels, in its order).
    pub fn append(&mut self, rec: &Recording) -> Result<(), IoError> {
        let r = match self.inner()? {
            Inner::Csv(w) => w.append(rec),
            Inner::Parquet(w) => w.append(rec),
            Inner::Mdf(w) => w.append(rec),
        };
        self.checked(r)
    }

    /// Make every sample appended so far survive a crash or a power loss: a writer killed
    /// from now on leaves a file readable up to here (CSV and uncompressed MDF4 as they are,
    /// Parquet through [`crate::recover_parquet`]); a compressed MDF4 file is only flushed.
    pub fn commit(&mut self) -> Result<(), IoError> {
        let r = match self.inner()? {
            Inner::Csv(w) => w.commit(),
            Inner::Parquet(w) => w.commit(),
            Inner::Mdf(w) => w.commit(),
        };
        self.checked(r)
    }

    /// Samples written so far (0 after a failed write).
    pub fn rows(&self) -> usize {
        match &self.inner {
            Some(Inner::Csv(w)) => w.rows(),
            Some(Inner::Parquet(w)) => w.rows(),
            Some(Inner::Mdf(w)) => w.rows(),
            None => 0,
        }
    }

    /// Bytes so far (written, and for Parquet buffered for the next row group).
    pub fn bytes(&self) -> usize {
        match &self.inner {
            Some(Inner::Csv(w)) => w.bytes(),
            Some(Inner::Parquet(w)) => w.bytes(),
            Some(Inner::Mdf(w)) => w.bytes(),
            None => 0,
        }
    }

    /// Whether the file can keep nothing after a failed write: a Parquet file before its first
    /// row group (the footer needs one).
    fn holds_nothing(&self) -> bool {
        matches!(&self.inner, Some(Inner::Parquet(w)) if w.groups() == 0)
    }

    /// Give the file up: the file this writer created is removed (while its lock is still
    /// held), not a file of the same name that another writer holds or that it never created
    /// — a command that fails removes its own partial output and nothing else.
    pub fn discard(mut self) {
        let _ = std::fs::remove_file(&self.path);
        self.inner = None;
    }

    /// Finish the file.
    pub fn close(mut self) -> Result<(), IoError> {
        let empty = self.holds_nothing();
        let r = match self.inner.take() {
            Some(Inner::Csv(w)) => w.close(),
            Some(Inner::Parquet(w)) => w.close(),
            Some(Inner::Mdf(w)) => (*w).close(),
            None => return self.inner().map(|_| ()),
        };
        match r {
            Err(e @ IoError::Os { .. }) => Err(failed(&self.path, e, empty)),
            r => r,
        }
    }
}

/// The error of a write to `path` that failed with `e`, its writer dropped: the file made
/// readable with what is on the disk, and what it keeps said; one that can keep nothing
/// (`empty`) removed — it would be readable by no reader.
fn failed(path: &Path, e: IoError, empty: bool) -> IoError {
    let p = path.display().to_string();
    if empty {
        let _ = std::fs::remove_file(path);
        return IoError::WriteFailed {
            source: Box::new(e),
            kept: format!(
                "{p} had no complete row group yet (a Parquet file is readable by its row groups): removed, nothing of it could be kept"
            ),
            rows: Some(0),
        };
    }
    let (kept, rows) = match salvage(path) {
        Ok(Some(rows)) => (
            format!("{p} keeps its first {rows} samples, readable"),
            Some(rows),
        ),
        Ok(None) => (format!("{p} keeps what reached the disk, readable"), None),
        Err(s) => (
            format!(
                "{p} could not be made readable ({s}): free space and run `physid recover {p}`"
            ),
            None,
        ),
    };
    IoError::WriteFailed {
        source: Box::new(e),
        kept,
        rows,
    }
}
