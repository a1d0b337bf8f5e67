//! # physid-io — recording files
//!
//! File formats are adapters at the edge: each reads a file into a
//! [`Recording`](physid_core::Recording) or writes one out — CSV ([`csv_file`]), Parquet
//! ([`parquet_file`]) and ASAM MDF4 ([`mdf`]); [`format`] picks one by extension, checks the
//! file's first bytes agree, selects channels and applies a channel map. Every format is read
//! a chunk of rows at a time ([`ChunkReader`], what the file verbs stream through their
//! stages); reading a whole file ([`read`]) is that reader, drained.
//!
//! Errors name the file, the line and the column, and what was expected — never a panic.

pub mod csv_file;
pub mod format;
mod lock;
pub mod mdf;
mod parquet_check;
mod parquet_crc;
pub mod parquet_file;
mod reader;
mod reopen;
mod source;
mod thrift_walk;
mod writer;

pub use csv_file::{read_csv, recover_csv, write_csv, CsvChunks, CsvOptions, CsvWriter};
pub use format::{basis_by_channels, detect, Format, MapItem, ReadOptions, CHUNK_ROWS};
pub use lock::refuse_to_recover_while_written;
pub use mdf::{
    read_mdf, settle_mdf, write_mdf, MdfChunks, MdfCompression, MdfWriter, MDF_BLOCK_BYTES,
};
pub use parquet_file::{
    read_parquet, recover_parquet, write_parquet, ParquetChunks, ParquetWriter, Recovered,
};
pub use reader::{read, ChunkReader};
pub use reopen::FileChunks;
pub use source::ChunkSource;
pub use writer::{salvage, write, ChunkWriter, WriteOptions, STREAM_ROWS_PER_GROUP};

/// Errors reading or writing recording files.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// The operating system refused (missing file, permissions, …).
    #[error("{path}: {source}")]
    Os {
        /// The file.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// The file has no header or no data rows.
    #[error("{path}: {what}")]
    Empty {
        /// The file.
        path: String,
        /// What is missing.
        what: &'static str,
    },
    /// A cell that is not a number.
    #[error("{path}, line {line}, column '{column}': '{value}' is not a number")]
    NotNumeric {
        /// The file.
        path: String,
        /// 1-based line in the file.
        line: u64,
        /// Column name.
        column: String,
        /// The cell's text.
        value: String,
    },
    /// A row with the wrong number of cells (than the header row has, or `--columns` names).
    #[error("{path}, line {line}: {got} cells, but the header has {expected}{hint}")]
    Ragged {
        /// The file.
        path: String,
        /// 1-based line in the file.
        line: u64,
        /// Cells in the header.
        expected: usize,
        /// Cells in this row.
        got: usize,
        /// What may be the cause, when one is likely (empty otherwise).
        hint: &'static str,
    },
    /// Malformed CSV (quoting, encoding).
    #[error("{path}: {detail}")]
    Malformed {
        /// The file.
        path: String,
        /// The parser's message.
        detail: String,
    },
    /// A write the operating system refused (a full disk, an I/O error): the file was made
    /// readable with what reached the disk ([`salvage`]).
    #[error("{source}; {kept}")]
    WriteFailed {
        /// The refusal.
        source: Box<IoError>,
        /// What the file keeps, in words.
        kept: String,
        /// The samples it keeps, where the format says.
        rows: Option<u64>,
    },
    /// The file is in use: locked by a writer that has not closed it (a live log being
    /// recorded, a `simulate` or `convert` still running), or read by this process; what was
    /// asked of it would lose what it holds, or it cannot be read yet ([`lock`]).
    #[error("{path} {detail}")]
    InUse {
        /// The file.
        path: String,
        /// What was not done, and what to do.
        detail: String,
    },
    /// The columns do not make a valid recording (duplicate names …).
    #[error("{path}: {source}")]
    Recording {
        /// The file.
        path: String,
        /// What is wrong.
        source: physid_core::RecordingError,
    },
}

impl IoError {
    /// The same error, naming the file `path` where it named `staged` (a whole write's staging
    /// file, [`write`]).
    fn named(self, staged: &str, path: &str) -> Self {
        let mut e = self;
        let p = match &mut e {
            Self::Os { path, .. }
            | Self::Empty { path, .. }
            | Self::NotNumeric { path, .. }
            | Self::Ragged { path, .. }
            | Self::Malformed { path, .. }
            | Self::InUse { path, .. }
            | Self::Recording { path, .. } => path,
            Self::WriteFailed { .. } => return e,
        };
        if p == staged {
            *p = path.to_string();
        }
        e
    }

    /// The samples a file keeps after a write that failed ([`IoError::WriteFailed`]), where
    /// its format says.
    pub fn kept(&self) -> Option<u64> {
        match self {
            Self::WriteFailed { rows, .. } => *rows,
            _ => None,
        }
    }
}

/// The most channels a file may give at once (all its columns, or those selected): a reader
/// and every verb work in time linear in the channels up to it (100 000 columns of a CSV
/// header are read in ≈ 1.5 s by a debug build). docs/data.md.
pub const MAX_CHANNELS: usize = 100_000;

/// Metadata keys that describe the file a recording was read from (its path, the CSV line of
/// sample 0, its separator, a warning about it, the units converted, the MDF master): they
/// belong to that file, so they are neither written into another one nor taken from one.
pub const FILE_META: [&str; 8] = [
    "source",
    "first_data_line",
    "csv_separator",
    "warning",
    "units_converted",
    "master",
    "master_unit_label",
    "skipped",
];

thread_local! {
    /// Set while a decoder runs under [`contained`]: its panics are reported as errors, so the
    /// panic hook stays quiet for them.
    static CONTAINED: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Where each of `wanted` is among a file's columns `names` (all of them, in order, if `None`);
/// a missing one is an error naming the columns there are.
pub(crate) fn positions(
    names: &[String],
    wanted: Option<&[String]>,
    path: &str,
) -> Result<Vec<usize>, IoError> {
    let Some(wanted) = wanted else {
        return Ok((0..names.len()).collect());
    };
    wanted
        .iter()
        .map(|n| {
            names
                .iter()
                .position(|m| m == n)
                .ok_or_else(|| IoError::Recording {
                    path: path.into(),
                    source: physid_core::RecordingError::MissingChannel {
                        name: n.clone(),
                        available: names.join(", "),
                    },
                })
        })
        .collect()
}

/// A recording from a source read a chunk at a time, drained: `rec` (basis and metadata) with
/// channels `names` in `units`, their values the chunks' columns one after another (`capacity`:
/// the rows expected, a hint).
pub(crate) fn drain(
    mut rec: physid_core::Recording,
    names: &[String],
    units: &[String],
    capacity: usize,
    mut next: impl FnMut() -> Result<Option<Vec<Vec<f64>>>, IoError>,
    path: &str,
) -> Result<physid_core::Recording, IoError> {
    let mut columns: Vec<Vec<f64>> = names.iter().map(|_| Vec::with_capacity(capacity)).collect();
    while let Some(chunk) = next()? {
        for (c, v) in columns.iter_mut().zip(chunk) {
            c.extend(v);
        }
    }
    for ((name, unit), values) in names.iter().zip(units).zip(columns) {
        rec.push(physid_core::Channel {
            name: name.clone(),
            unit: unit.clone(),
            values,
        })
        .map_err(|source| IoError::Recording {
            path: path.into(),
            source,
        })?;
    }
    Ok(rec)
}

/// A file a writer was killed while writing, opened to be mended in place: the file, its size,
/// and the error for an operating-system failure on it.
pub(crate) fn open_torn(
    path: &std::path::Path,
) -> Result<(std::fs::File, u64, impl Fn(std::io::Error) -> IoError), IoError> {
    let p = path.display().to_string();
    let os = move |source| IoError::Os {
        path: p.clone(),
        source,
    };
    let f = crate::lock::open_to_mend(path)?;
    let size = f.metadata().map_err(&os)?.len();
    Ok((f, size, os))
}

/// A chunk appended to a file written as it comes must have the file's channels, in its order.
pub(crate) fn check_appended(
    path: &str,
    names: &[String],
    rec: &physid_core::Recording,
) -> Result<(), IoError> {
    let same = rec.channels().len() == names.len()
        && rec.channels().iter().zip(names).all(|(c, n)| &c.name == n);
    if same {
        return Ok(());
    }
    Err(IoError::Malformed {
        path: path.into(),
        detail: format!(
            "appending channels {:?} to a file of {:?}",
            rec.names(),
            names
        ),
    })
}

/// Keep the panic hook quiet for the decoder panics [`contained`] turns into errors (a corrupt
/// file is reported once, as an error, not also as a panic message): for a program, called
/// once at its start. A library host (the Python package) does not call it, so its process's
/// panic hook stays its own; there a contained panic prints the hook's message and is still
/// an error.
pub fn quiet_contained_panics() {
    static HOOK: std::sync::Once = std::sync::Once::new();
    HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !CONTAINED.with(std::cell::Cell::get) {
                previous(info);
            }
        }));
    });
}

/// Run a third-party decoder (the parquet and MDF crates) so that a panic on a corrupt file
/// becomes `FILE: corrupt FORMAT (…)` instead of ending the program: the boundary the readers
/// keep, since those crates assert on some malformed inputs (see `tests/fuzz.rs`). Allocation
/// failure aborts and cannot be contained: the readers check claimed sizes before allocating.
/// No process-wide state is changed here ([`quiet_contained_panics`] is the program's choice).
pub(crate) fn contained<T>(
    path: &str,
    format: &str,
    f: impl FnOnce() -> Result<T, IoError>,
) -> Result<T, IoError> {
    let was = CONTAINED.with(|c| c.replace(true));
    let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
    CONTAINED.with(|c| c.set(was));
    r.unwrap_or_else(|payload| {
        let why = payload
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "the decoder stopped".into());
        Err(IoError::Malformed {
            path: path.into(),
            detail: format!("corrupt {format} (the decoder failed: {why})"),
        })
    })
}

#[cfg(test)]
mod tests {
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::Arc;

    /// A host's panic hook (Python's, an application's) still sees a decoder's panic that
    /// [`super::contained`] turns into an error: the library installs no hook of its own.
    #[test]
    fn a_contained_panic_is_an_error_and_leaves_the_hosts_panic_hook_alone() {
        let seen = Arc::new(AtomicUsize::new(0));
        let s = seen.clone();
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if info.to_string().contains("physid-test-decoder-panic") {
                s.fetch_add(1, Ordering::SeqCst);
            }
        }));
        let r: Result<(), _> = super::contained("x.parquet", "Parquet", || {
            panic!("physid-test-decoder-panic")
        });
        let _ = std::panic::take_hook();
        std::panic::set_hook(previous);
        let e = r.err().map(|e| e.to_string()).unwrap_or_default();
        assert!(e.contains("x.parquet: corrupt Parquet"), "{e}");
        assert_eq!(
            seen.load(Ordering::SeqCst),
            1,
            "the host's hook was bypassed"
        );
    }
}
