//! What each format implements to be read a chunk at a time ([`ChunkSource`]): its header —
//! the channels as the file names them, their units, the basis and the metadata — and its
//! columns, chunk after chunk, in the file's own units. [`ChunkReader`](crate::ChunkReader)
//! puts the channel map, the calibrations and the SI units over any of them.

use crate::csv_file::CsvChunks;
use crate::format::CHUNK_ROWS;
use crate::mdf::MdfChunks;
use crate::parquet_file::ParquetChunks;
use crate::IoError;
use physid_core::{Basis, Channel, Recording};

/// One format's reader of a recording's columns, a chunk at a time (`Send`: a reader may be
/// handed to another thread, as the live replay does).
pub trait ChunkSource: Send {
    /// The channels read (no samples), as the file names them and with its units, the basis
    /// and the metadata.
    fn header(&self) -> Result<Recording, IoError>;
    /// The next chunk's columns, in the header's order and the file's units (`None` after the
    /// last).
    fn next_columns(&mut self) -> Result<Option<Vec<Vec<f64>>>, IoError>;
    /// The rows the file claims to hold (Parquet's footer, MDF4's channel group; none for
    /// CSV). A claim: a corrupt file can claim anything.
    fn claimed_rows(&self) -> Option<i64> {
        None
    }
    /// What the reader noticed but read all the same (a cut-short last line), once known.
    fn warning(&self) -> Option<String> {
        None
    }
}

/// `header` with channels `names` in `units` and no samples.
fn with_channels(
    mut header: Recording,
    names: &[String],
    units: &[String],
) -> Result<Recording, IoError> {
    let path = header.meta.get("source").cloned().unwrap_or_default();
    for (n, u) in names.iter().zip(units) {
        header
            .push(Channel {
                name: n.clone(),
                unit: u.clone(),
                values: Vec::new(),
            })
            .map_err(|source| IoError::Recording {
                path: path.clone(),
                source,
            })?;
    }
    Ok(header)
}

/// A CSV file's rows, [`CHUNK_ROWS`] at a time. Its basis is decided by the whole file's
/// columns, before a selection ([`crate::basis_by_channels`]).
impl ChunkSource for CsvChunks {
    fn header(&self) -> Result<Recording, IoError> {
        let mut h = CsvChunks::header(self);
        let all = self.file_columns();
        if all.iter().any(|n| n == "cycle") && all.iter().any(|n| n == "crank_deg") {
            h.basis = Basis::CrankAngle;
        }
        with_channels(h, &self.names, &self.units)
    }
    fn next_columns(&mut self) -> Result<Option<Vec<Vec<f64>>>, IoError> {
        CsvChunks::next_columns(self, CHUNK_ROWS)
    }
    fn warning(&self) -> Option<String> {
        CsvChunks::header(self).meta.get("warning").cloned()
    }
}

/// A Parquet file's record batches.
impl ChunkSource for ParquetChunks {
    fn header(&self) -> Result<Recording, IoError> {
        with_channels(ParquetChunks::header(self), &self.names, &self.units)
    }
    fn next_columns(&mut self) -> Result<Option<Vec<Vec<f64>>>, IoError> {
        ParquetChunks::next_columns(self)
    }
    fn claimed_rows(&self) -> Option<i64> {
        Some(ParquetChunks::claimed_rows(self))
    }
}

/// An MDF4 file's data blocks.
impl ChunkSource for MdfChunks {
    fn header(&self) -> Result<Recording, IoError> {
        Ok(MdfChunks::header(self).clone())
    }
    fn next_columns(&mut self) -> Result<Option<Vec<Vec<f64>>>, IoError> {
        MdfChunks::next_columns(self)
    }
    fn claimed_rows(&self) -> Option<i64> {
        Some(i64::try_from(MdfChunks::claimed_rows(self)).unwrap_or(i64::MAX))
    }
}
