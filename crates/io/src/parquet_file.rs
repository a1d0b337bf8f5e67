//! Parquet recordings (Arrow): one column per channel, the unit in each field's metadata under
//! `"unit"` (pyarrow: `pa.field(name, pa.float64(), metadata={"unit": "rad/s"})`), the basis in
//! the schema metadata under `"physid.basis"` (`time` or `crank_angle`), and the recording's
//! metadata (scenario, parameters and faults of a simulated run, …) under `"physid.meta.KEY"`.
//!
//! Reading projects the columns asked for (memory proportional to them) and converts every
//! numeric type to f64; nulls are refused with their row. Writing uses float64 columns,
//! Snappy compression.

use crate::parquet_crc::{self, Checks, ChunkCrcs};
use crate::IoError;
use arrow_array::cast::AsArray;
use arrow_array::types::{
    Float32Type, Float64Type, Int16Type, Int32Type, Int64Type, Int8Type, UInt16Type, UInt32Type,
    UInt64Type, UInt8Type,
};
use arrow_array::{Array, ArrayRef, Float64Array, RecordBatch};
use arrow_schema::{DataType, Field, Schema};
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use parquet::arrow::arrow_writer::ArrowWriterOptions;
use parquet::arrow::{ArrowWriter, ProjectionMask};
use parquet::basic::Compression;
use parquet::file::metadata::{
    FileMetaData, ParquetMetaData, ParquetMetaDataReader, ParquetMetaDataWriter, RowGroupMetaData,
};
use parquet::file::properties::WriterProperties;
use physid_core::{Basis, Recording};
use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

const BASIS_KEY: &str = "physid.basis";
/// Schema-metadata prefix of the recording's own metadata entries.
const META_PREFIX: &str = "physid.meta.";

fn pq_err(path: &str, e: impl std::fmt::Display) -> IoError {
    IoError::Malformed {
        path: path.into(),
        detail: format!("Parquet: {e}"),
    }
}

/// A writer's error: the operating system's own where it is one (a full disk, an I/O error —
/// what [`crate::ChunkWriter`] makes the file readable after), else [`pq_err`].
fn write_err(path: &str, e: parquet::errors::ParquetError) -> IoError {
    match e {
        parquet::errors::ParquetError::External(b) if b.is::<std::io::Error>() => {
            match b.downcast::<std::io::Error>() {
                Ok(source) => IoError::Os {
                    path: path.into(),
                    source: *source,
                },
                Err(b) => pq_err(path, b),
            }
        }
        e => pq_err(path, e),
    }
}

/// The Arrow fields of `rec`'s channels as physid writes them (Parquet files, the fleet's
/// frames): non-null float64, the unit in the field's metadata under `unit`.
pub fn arrow_fields(rec: &Recording) -> Vec<Field> {
    rec.channels()
        .iter()
        .map(|c| {
            Field::new(&c.name, DataType::Float64, false)
                .with_metadata(HashMap::from([("unit".to_string(), c.unit.clone())]))
        })
        .collect()
}

/// Append an Arrow column to `out` as f64; an error names the first null.
fn extend_f64(col: &ArrayRef, out: &mut Vec<f64>, name: &str, row0: usize) -> Result<(), String> {
    if col.null_count() > 0 {
        let i = (0..col.len()).find(|&i| col.is_null(i)).unwrap_or(0);
        return Err(format!(
            "column '{name}' has a null at row {} (expected a number in every row)",
            row0 + i
        ));
    }
    macro_rules! num {
        ($t:ty) => {
            out.extend(col.as_primitive::<$t>().values().iter().map(|&v| v as f64))
        };
    }
    match col.data_type() {
        DataType::Float64 => out.extend_from_slice(col.as_primitive::<Float64Type>().values()),
        DataType::Float32 => num!(Float32Type),
        DataType::Int8 => num!(Int8Type),
        DataType::Int16 => num!(Int16Type),
        DataType::Int32 => num!(Int32Type),
        DataType::Int64 => num!(Int64Type),
        DataType::UInt8 => num!(UInt8Type),
        DataType::UInt16 => num!(UInt16Type),
        DataType::UInt32 => num!(UInt32Type),
        DataType::UInt64 => num!(UInt64Type),
        DataType::Boolean => out.extend(
            col.as_boolean()
                .iter()
                .map(|b| f64::from(u8::from(b.unwrap_or(false)))),
        ),
        other => return Err(format!("column '{name}' is {other}, not a number")),
    }
    Ok(())
}

/// Read a Parquet file; `channels` selects columns by name (all if `None`). A corrupt file is
/// an error, never a panic or an allocation the file's claims alone asked for.
pub fn read_parquet(
    path: impl AsRef<Path>,
    channels: Option<&[String]>,
) -> Result<Recording, IoError> {
    let mut chunks = ParquetChunks::open(path, channels)?;
    // The row count is the file's claim: checked against what the columns asked for would
    // take in memory before anything is sized from it (a corrupt footer can claim 2⁶⁰ rows).
    let rows = crate::format::claimed_fits(&chunks.p, chunks.claimed_rows(), chunks.names.len())?;
    let (names, units, p) = (chunks.names.clone(), chunks.units.clone(), chunks.p.clone());
    let header = chunks.header();
    crate::drain(header, &names, &units, rows, || chunks.next_columns(), &p)
}

/// A Parquet file read a batch of rows at a time ([`read_parquet`] is this, drained): only
/// the columns asked for are decoded, each batch converted to f64. Every call into the
/// decoder is [`crate::contained`].
pub struct ParquetChunks {
    pub(crate) p: String,
    reader: parquet::arrow::arrow_reader::ParquetRecordBatchReader,
    /// The columns read, in the order asked.
    pub(crate) names: Vec<String>,
    pub(crate) units: Vec<String>,
    /// For each column asked for, its place in a batch (batches keep the file's order).
    place: Vec<usize>,
    basis: Basis,
    meta: Vec<(String, String)>,
    claimed: i64,
    row0: usize,
    /// The column chunks' checksums, read before their rows.
    checks: Checks,
}

impl ParquetChunks {
    /// Open `path` and read its footer; `channels`: the columns to read, in that order (all if
    /// `None`).
    pub fn open(path: impl AsRef<Path>, channels: Option<&[String]>) -> Result<Self, IoError> {
        let path = path.as_ref();
        let p = path.display().to_string();
        crate::contained(&p, "Parquet", || Self::open_inner(path, &p, channels))
    }

    fn open_inner(path: &Path, p: &str, channels: Option<&[String]>) -> Result<Self, IoError> {
        let p = p.to_string();
        let mut file = std::fs::File::open(path).map_err(|source| IoError::Os {
            path: p.clone(),
            source,
        })?;
        // The footer's and the pages' claims checked against their bytes first: a corrupt
        // header must not cost more than its length in the crate's decoding.
        crate::parquet_check::footer(&mut file, &p)?;
        let builder =
            ParquetRecordBatchReaderBuilder::try_new(file.try_clone().map_err(|source| {
                IoError::Os {
                    path: p.clone(),
                    source,
                }
            })?)
            .map_err(|e| pq_err(&p, e))?;
        let schema = builder.schema().clone();
        let names: Vec<String> = schema.fields().iter().map(|f| f.name().clone()).collect();
        let wanted = crate::positions(&names, channels, &p)?;
        let mut read = vec![false; names.len()];
        for &j in &wanted {
            read[j] = true;
        }
        let leaves: Vec<usize> = (0..builder.parquet_schema().num_columns())
            .filter(|&leaf| {
                read.get(builder.parquet_schema().get_column_root_idx(leaf))
                    .is_some_and(|r| *r)
            })
            .collect();
        crate::parquet_check::pages(&mut file, &p, builder.metadata(), &leaves)?;
        let checks =
            Checks::new(builder.metadata(), &leaves, path).map_err(|source| IoError::Os {
                path: p.clone(),
                source,
            })?;
        let mask = ProjectionMask::roots(builder.parquet_schema(), wanted.iter().copied());
        let claimed = builder.metadata().file_metadata().num_rows();
        let reader = builder
            .with_projection(mask)
            .with_batch_size(crate::format::CHUNK_ROWS)
            .build()
            .map_err(|e| pq_err(&p, e))?;
        // The projected batches keep the file's column order; map back to the order asked for.
        let mut sorted = wanted.clone();
        sorted.sort_unstable();
        sorted.dedup();
        let place = wanted
            .iter()
            .map(|j| sorted.iter().position(|s| s == j).unwrap_or(0))
            .collect();
        let basis = match schema.metadata().get(BASIS_KEY).map(String::as_str) {
            Some("crank_angle") => Basis::CrankAngle,
            _ => Basis::Time,
        };
        let meta = schema
            .metadata()
            .iter()
            .filter_map(|(k, v)| {
                let key = k.strip_prefix(META_PREFIX)?;
                (!crate::FILE_META.contains(&key)).then(|| (key.to_string(), v.clone()))
            })
            .collect();
        Ok(Self {
            reader,
            names: wanted.iter().map(|&j| names[j].clone()).collect(),
            units: wanted
                .iter()
                .map(|&j| {
                    schema
                        .field(j)
                        .metadata()
                        .get("unit")
                        .cloned()
                        .unwrap_or_default()
                })
                .collect(),
            place,
            basis,
            meta,
            claimed,
            row0: 0,
            p,
            checks,
        })
    }

    /// The rows the footer claims (a claim: a corrupt footer can claim anything).
    pub fn claimed_rows(&self) -> i64 {
        self.claimed
    }

    /// The recording's basis and metadata, with no channels.
    pub fn header(&self) -> Recording {
        let mut rec = Recording::new(self.basis);
        for (k, v) in &self.meta {
            rec.meta.insert(k.clone(), v.clone());
        }
        rec.meta.insert("source".into(), self.p.clone());
        rec
    }

    /// The next batch of the columns read (`None` after the last).
    pub fn next_columns(&mut self) -> Result<Option<Vec<Vec<f64>>>, IoError> {
        let p = self.p.clone();
        crate::contained(&p, "Parquet", || {
            // The row groups the next batch can reach are checked against their sums first.
            let end = (self.row0 + crate::format::CHUNK_ROWS) as u64;
            self.checks.before(end, &self.p)?;
            let Some(batch) = self.reader.next() else {
                return Ok(None);
            };
            let batch = batch.map_err(|e| {
                let e = e.to_string();
                if e.contains("CRC checksum mismatch") {
                    // A page whose writer stored its CRC-32 (pyarrow's `write_page_checksum`).
                    IoError::Malformed {
                        path: self.p.clone(),
                        detail: format!(
                            "corrupt Parquet: a page of the rows from {} on does not match the \
                             CRC-32 its writer stored ({e}); the file was damaged or changed \
                             after it was written",
                            self.row0
                        ),
                    }
                } else {
                    pq_err(&self.p, e)
                }
            })?;
            let mut out = Vec::with_capacity(self.names.len());
            for (name, &k) in self.names.iter().zip(&self.place) {
                let mut v = Vec::with_capacity(batch.num_rows());
                let col = batch
                    .columns()
                    .get(k)
                    .ok_or_else(|| pq_err(&self.p, format!("a batch lacks column '{name}'")))?;
                extend_f64(col, &mut v, name, self.row0).map_err(|detail| IoError::Malformed {
                    path: self.p.clone(),
                    detail,
                })?;
                out.push(v);
            }
            self.row0 += batch.num_rows();
            Ok(Some(out))
        })
    }
}

/// Write a recording as Parquet (float64 columns, units in field metadata, Snappy).
pub fn write_parquet(path: impl AsRef<Path>, rec: &Recording) -> Result<(), IoError> {
    let chunk = 1 << 20;
    let mut w = ParquetWriter::create(path, rec, chunk)?;
    let n = rec.len();
    let mut start = 0;
    while start < n {
        let end = (start + chunk).min(n);
        w.append_range(rec, start..end)?;
        start = end;
    }
    if n == 0 {
        w.append_range(rec, 0..0)?;
    }
    w.close()
}

/// The four bytes that end a journal entry (a footer naming one row group, which a Parquet
/// reader must not take for the file's own footer: that ends in `PAR1`).
const JOURNAL_MAGIC: &[u8; 4] = b"PHJ1";

/// A Parquet file written chunk by chunk (`simulate`, `convert`, the live service's logs):
/// float64 columns, units in field metadata, Snappy; a row group every `rows_per_group` rows,
/// so memory stays bounded however long it writes. The file is valid once closed.
///
/// **Crash safety.** After each row group ([`commit`](Self::commit), or every
/// `rows_per_group` rows) a *journal entry* follows it in the file: a Parquet footer naming
/// that row group alone, ending in `PHJ1` instead of `PAR1`. Readers skip the entries (they read
/// row groups where the final footer says they are); a file whose writer was killed before
/// closing it ends without a footer, and [`recover_parquet`] chains the entries back from the
/// last complete one and writes the footer of every row group committed — nothing after the
/// last commit is lost beyond it.
pub struct ParquetWriter {
    path: String,
    schema: Arc<Schema>,
    names: Vec<String>,
    w: ArrowWriter<std::fs::File>,
    rows: usize,
    rows_per_group: usize,
    /// The file's metadata as its footer will carry it (schema, key-value metadata): what
    /// each journal entry names beside its row group.
    template: FileMetaData,
    /// The column chunks' CRC-32 as the writer splices them into the file.
    crcs: ChunkCrcs,
    /// Each row group's entry of the sums ([`parquet_crc::KEY`]), in order.
    sums: Vec<String>,
}

impl ParquetWriter {
    /// Create `path` for recordings with `like`'s channels, units, basis and metadata.
    pub fn create(
        path: impl AsRef<Path>,
        like: &Recording,
        rows_per_group: usize,
    ) -> Result<Self, IoError> {
        let p = path.as_ref().display().to_string();
        let fields = arrow_fields(like);
        let basis = match like.basis {
            Basis::Time => "time",
            Basis::CrankAngle => "crank_angle",
        };
        let mut meta = HashMap::from([(BASIS_KEY.to_string(), basis.to_string())]);
        for (k, v) in like
            .meta
            .iter()
            .filter(|(k, _)| !crate::FILE_META.contains(&k.as_str()))
        {
            meta.insert(format!("{META_PREFIX}{k}"), v.clone());
        }
        let schema = Arc::new(Schema::new_with_metadata(fields, meta));
        // Row groups are cut here, not by the writer: each is followed by its journal entry.
        let props = WriterProperties::builder()
            .set_compression(Compression::SNAPPY)
            .set_dictionary_enabled(false)
            .set_max_row_group_row_count(None)
            .set_max_row_group_bytes(None)
            .build();
        // The footer's metadata, from an empty file written the same way.
        let template = ArrowWriter::try_new(Vec::new(), schema.clone(), Some(props.clone()))
            .and_then(ArrowWriter::close)
            .map_err(|e| pq_err(&p, e))?
            .file_metadata()
            .clone();
        let file = crate::lock::create(path.as_ref())?;
        let crcs = ChunkCrcs::default();
        let options = ArrowWriterOptions::new()
            .with_properties(props)
            .with_page_store_factory(Arc::new(crcs.clone()));
        let w = ArrowWriter::try_new_with_options(file, schema.clone(), options)
            .map_err(|e| pq_err(&p, e))?;
        Ok(Self {
            names: like.channels().iter().map(|c| c.name.clone()).collect(),
            path: p,
            schema,
            w,
            rows: 0,
            rows_per_group: rows_per_group.max(1),
            template,
            crcs,
            sums: Vec::new(),
        })
    }

    /// Append `rec`'s rows (the same channels, in the same order, as the file's).
    pub fn append(&mut self, rec: &Recording) -> Result<(), IoError> {
        self.append_range(rec, 0..rec.len())
    }

    /// Append rows `range` of `rec`, a row group committed each `rows_per_group` rows.
    fn append_range(
        &mut self,
        rec: &Recording,
        range: std::ops::Range<usize>,
    ) -> Result<(), IoError> {
        crate::check_appended(&self.path, &self.names, rec)?;
        let mut start = range.start;
        loop {
            let room = self.rows_per_group - self.w.in_progress_rows();
            let end = range.end.min(start + room);
            let cols: Vec<ArrayRef> = rec
                .channels()
                .iter()
                .map(|c| Arc::new(Float64Array::from(c.values[start..end].to_vec())) as ArrayRef)
                .collect();
            let batch = RecordBatch::try_new(self.schema.clone(), cols)
                .map_err(|e| pq_err(&self.path, e))?;
            self.w.write(&batch).map_err(|e| write_err(&self.path, e))?;
            self.rows += end - start;
            if self.w.in_progress_rows() >= self.rows_per_group {
                self.group()?;
            }
            start = end;
            if start >= range.end {
                return Ok(());
            }
        }
    }

    /// Make every row appended so far survive a crash: the rows buffered become a row group,
    /// its journal entry follows it, and both are on the disk (a writer killed, or a machine
    /// that loses power, from now on leaves a file [`recover_parquet`] restores up to here).
    pub fn commit(&mut self) -> Result<(), IoError> {
        self.group()?;
        self.w.inner().sync_data().map_err(|source| IoError::Os {
            path: self.path.clone(),
            source,
        })
    }

    /// The rows buffered as a row group with its journal entry, handed to the operating system
    /// (a writer killed from now on leaves a file [`recover_parquet`] restores up to here).
    fn group(&mut self) -> Result<(), IoError> {
        if self.w.in_progress_rows() == 0 {
            return Ok(());
        }
        self.w.flush().map_err(|e| write_err(&self.path, e))?;
        let group = self
            .w
            .flushed_row_groups()
            .last()
            .cloned()
            .ok_or_else(|| pq_err(&self.path, "no row group after a flush"))?;
        let sums = parquet_crc::entry(
            group_span(&group).map_or(0, |s| s.0),
            &self.crcs.take(group.num_columns()),
        );
        let entry = footer(
            &self.template,
            vec![group],
            JOURNAL_MAGIC,
            Some(sums.clone()),
        )
        .map_err(|e| pq_err(&self.path, e))?;
        self.sums.push(sums);
        self.w
            .write_all(&entry)
            .and_then(|()| self.w.sync())
            .map_err(|source| IoError::Os {
                path: self.path.clone(),
                source,
            })
    }

    /// Rows written so far.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Row groups handed to the file so far, each with its journal entry.
    pub(crate) fn groups(&self) -> usize {
        self.w.flushed_row_groups().len()
    }

    /// Bytes in the file so far, and buffered for the next row group.
    pub fn bytes(&self) -> usize {
        self.w.bytes_written() + self.w.in_progress_size()
    }

    /// Finish the file (the last row group, and the footer naming every row group).
    pub fn close(mut self) -> Result<(), IoError> {
        self.group()?;
        if !self.sums.is_empty() {
            self.w
                .append_key_value_metadata(parquet::file::metadata::KeyValue::new(
                    parquet_crc::KEY.to_string(),
                    self.sums.join(";"),
                ));
        }
        self.w.close().map_err(|e| write_err(&self.path, e))?;
        Ok(())
    }
}

/// A Parquet footer for `groups` with `template`'s schema and key-value metadata, ending in
/// `magic` (`PAR1` for a file's footer, [`JOURNAL_MAGIC`] for a journal entry); `sums`: the
/// groups' column chunk checksums ([`parquet_crc`]), in place of any the template has.
fn footer(
    template: &FileMetaData,
    groups: Vec<RowGroupMetaData>,
    magic: &[u8; 4],
    sums: Option<String>,
) -> Result<Vec<u8>, parquet::errors::ParquetError> {
    let rows = groups.iter().map(RowGroupMetaData::num_rows).sum();
    let meta = ParquetMetaData::new(
        FileMetaData::new(
            template.version(),
            rows,
            template.created_by().map(str::to_string),
            parquet_crc::with_entry(template.key_value_metadata(), sums),
            template.schema_descr_ptr(),
            template.column_orders().cloned(),
        ),
        groups,
    );
    let mut out = Vec::new();
    ParquetMetaDataWriter::new(&mut out, &meta).finish()?;
    let n = out.len();
    out[n - 4..].copy_from_slice(magic);
    Ok(out)
}

/// What [`recover_parquet`] did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Recovered {
    /// The file was closed properly: nothing to do.
    Closed,
    /// The footer was written: `rows` rows in `groups` row groups kept, `dropped` bytes after
    /// the last committed row group cut off.
    Restored {
        /// Rows kept.
        rows: u64,
        /// Row groups kept.
        groups: usize,
        /// Bytes of the torn end cut off.
        dropped: u64,
    },
}

/// `len` bytes of `f` at `at` (`None` past its end).
fn bytes_at(mut f: &std::fs::File, at: u64, len: usize) -> Option<Vec<u8>> {
    use std::io::{Read, Seek};
    let mut buf = vec![0; len];
    f.seek(std::io::SeekFrom::Start(at)).ok()?;
    f.read_exact(&mut buf).ok()?;
    Some(buf)
}

/// Where a journal entry ending at byte `end` of `f` starts, its row group and the file's
/// metadata, if a complete entry ends there.
fn journal_entry(f: &std::fs::File, end: u64) -> Option<(u64, RowGroupMetaData, FileMetaData)> {
    let tail = bytes_at(f, end.checked_sub(8)?, 8)?;
    if tail[4..] != *JOURNAL_MAGIC {
        return None;
    }
    let len = u32::from_le_bytes(tail[..4].try_into().ok()?) as u64;
    let start = end.checked_sub(8 + len)?;
    let meta = ParquetMetaDataReader::decode_metadata(&bytes_at(f, start, len as usize)?).ok()?;
    let group = match meta.row_groups() {
        [g] => g.clone(),
        _ => return None,
    };
    Some((start, group, meta.file_metadata().clone()))
}

/// The end of the last complete journal entry in `f` (of `size` bytes), searched back from
/// its end a window at a time (a torn row group may follow it).
fn last_entry(
    f: &std::fs::File,
    size: u64,
) -> Option<(u64, (u64, RowGroupMetaData, FileMetaData))> {
    const WINDOW: u64 = 16 << 20;
    let mut hi = size;
    while hi >= 12 {
        let lo = hi.saturating_sub(WINDOW);
        let buf = bytes_at(f, lo, (hi - lo) as usize)?;
        for k in (4..=buf.len()).rev() {
            if buf[k - 4..k] == *JOURNAL_MAGIC {
                let end = lo + k as u64;
                if let Some(e) = journal_entry(f, end) {
                    return Some((end, e));
                }
            }
        }
        if lo == 0 {
            break;
        }
        // Overlap by three bytes: a magic across the windows' border is found.
        hi = lo + 3;
    }
    None
}

/// Where a row group's bytes start and end in the file (`None` when its metadata says
/// nothing sensible).
pub(crate) fn group_span(g: &RowGroupMetaData) -> Option<(u64, u64)> {
    let mut span: Option<(u64, u64)> = None;
    for c in g.columns() {
        let start = c.dictionary_page_offset().unwrap_or(c.data_page_offset());
        let (start, len) = (
            u64::try_from(start).ok()?,
            u64::try_from(c.compressed_size()).ok()?,
        );
        let (lo, hi) = span.unwrap_or((start, start + len));
        span = Some((lo.min(start), hi.max(start + len)));
    }
    span
}

/// Make a Parquet file physid was writing when it was killed (or the machine lost power)
/// readable again: the row groups up to the last journal entry complete on disk (see
/// [`ParquetWriter`]) are kept, the torn end after it is cut off, and the footer naming them
/// is written. A file closed properly is left as it is; a file without a complete entry is
/// refused, naming what is missing.
pub fn recover_parquet(path: impl AsRef<Path>) -> Result<Recovered, IoError> {
    let p = path.as_ref().display().to_string();
    let (mut f, size, os) = crate::open_torn(path.as_ref())?;
    if bytes_at(&f, 0, 4).as_deref() != Some(b"PAR1") {
        return Err(pq_err(
            &p,
            "not a Parquet file (it does not start with PAR1)",
        ));
    }
    if size >= 12 {
        let tail = bytes_at(&f, size - 8, 8).unwrap_or_default();
        let len = u32::from_le_bytes(tail[..4].try_into().unwrap_or([0; 4])) as u64;
        if tail[4..] == *b"PAR1"
            && len + 12 <= size
            && bytes_at(&f, size - 8 - len, len as usize)
                .is_some_and(|m| ParquetMetaDataReader::decode_metadata(&m).is_ok())
        {
            return Ok(Recovered::Closed);
        }
    }
    let Some((keep, (mut start, group, template))) = last_entry(&f, size) else {
        return Err(pq_err(
            &p,
            "no committed row group: the writer was stopped before its first commit (physid \
             commits a row group each second of a live log, and every 65 536 rows)",
        ));
    };
    // Back along the chain: each entry ends where the next row group starts, the first row
    // group starts after the leading PAR1.
    let mut groups = vec![group];
    // Each entry's checksums of its row group; all of them, or none (an older physid's file).
    let mut sums = vec![parquet_crc::find(template.key_value_metadata()).map(str::to_string)];
    loop {
        let Some((lo, hi)) = group_span(&groups[groups.len() - 1]) else {
            return Err(pq_err(
                &p,
                "a journal entry names a row group with no columns",
            ));
        };
        if hi != start {
            return Err(pq_err(
                &p,
                format!(
                    "a journal entry at byte {start} does not follow its row group (which ends at \
                     byte {hi})"
                ),
            ));
        }
        if lo == 4 {
            break;
        }
        let Some((s, g, meta)) = journal_entry(&f, lo) else {
            return Err(pq_err(
                &p,
                format!("no journal entry ends at byte {lo}, where a row group starts"),
            ));
        };
        start = s;
        groups.push(g);
        sums.push(parquet_crc::find(meta.key_value_metadata()).map(str::to_string));
    }
    groups.reverse();
    sums.reverse();
    let sums: Option<Vec<String>> = sums.into_iter().collect();
    let rows = groups.iter().map(|g| g.num_rows() as u64).sum();
    let n = groups.len();
    let foot =
        footer(&template, groups, b"PAR1", sums.map(|s| s.join(";"))).map_err(|e| pq_err(&p, e))?;
    use std::io::{Seek, Write};
    f.set_len(keep).map_err(&os)?;
    f.seek(std::io::SeekFrom::Start(keep)).map_err(&os)?;
    f.write_all(&foot).map_err(&os)?;
    f.sync_all().map_err(&os)?;
    Ok(Recovered::Restored {
        rows,
        groups: n,
        dropped: size - keep,
    })
}
