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

/// Write a recording in the format its extension names.
pub fn write(path: impl AsRef<Path>, rec: &Recording, opts: &WriteOptions) -> Result<(), IoError> {
    let path = path.as_ref();
    match Format::from_extension(path) {
        Some(Format::Csv) => write_csv(path, rec),
        Some(Format::Parquet) => write_parquet(path, rec),
        Some(Format::Mdf4) => write_mdf(path, rec, opts.mdf_compression, None),
        None => Err(IoError::Malformed {
            path: path.display().to_string(),
            detail: "unknown extension: expected .csv, .parquet or .mf4".into(),
        }),
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
pub enum ChunkWriter {
    /// CSV.
    Csv(Box<crate::CsvWriter>),
    /// Parquet.
    Parquet(Box<crate::ParquetWriter>),
    /// MDF4.
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
        match Format::from_extension(path) {
            Some(Format::Csv) => Ok(Self::Csv(Box::new(crate::CsvWriter::create(path, like)?))),
            Some(Format::Parquet) => Ok(Self::Parquet(Box::new(crate::ParquetWriter::create(
                path,
                like,
                STREAM_ROWS_PER_GROUP,
            )?))),
            Some(Format::Mdf4) => Ok(Self::Mdf(Box::new(crate::MdfWriter::create_compressed(
                path,
                like,
                None,
                opts.mdf_compression,
                crate::MDF_BLOCK_BYTES,
            )?))),
            None => Err(IoError::Malformed {
                path: path.display().to_string(),
                detail: "unknown extension: expected .csv, .parquet or .mf4".into(),
            }),
        }
    }

    /// Append `rec`'s samples (the file's channels, in its order).
    pub fn append(&mut self, rec: &Recording) -> Result<(), IoError> {
        match self {
            Self::Csv(w) => w.append(rec),
            Self::Parquet(w) => w.append(rec),
            Self::Mdf(w) => w.append(rec),
        }
    }

    /// Make every sample appended so far survive a crash or a power loss: a writer killed
    /// from now on leaves a file readable up to here (CSV and uncompressed MDF4 as they are,
    /// Parquet through [`crate::recover_parquet`]); a compressed MDF4 file is only flushed.
    pub fn commit(&mut self) -> Result<(), IoError> {
        match self {
            Self::Csv(w) => w.commit(),
            Self::Parquet(w) => w.commit(),
            Self::Mdf(w) => w.commit(),
        }
    }

    /// Samples written so far.
    pub fn rows(&self) -> usize {
        match self {
            Self::Csv(w) => w.rows(),
            Self::Parquet(w) => w.rows(),
            Self::Mdf(w) => w.rows(),
        }
    }

    /// Bytes so far (written, and for Parquet buffered for the next row group).
    pub fn bytes(&self) -> usize {
        match self {
            Self::Csv(w) => w.bytes(),
            Self::Parquet(w) => w.bytes(),
            Self::Mdf(w) => w.bytes(),
        }
    }

    /// Finish the file.
    pub fn close(self) -> Result<(), IoError> {
        match self {
            Self::Csv(w) => w.close(),
            Self::Parquet(w) => w.close(),
            Self::Mdf(w) => (*w).close(),
        }
    }
}
