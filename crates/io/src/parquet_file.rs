//! Parquet recordings (Arrow): one column per channel, the unit in each field's metadata under
//! `"unit"` (pyarrow: `pa.field(name, pa.float64(), metadata={"unit": "rad/s"})`), the basis in
//! the schema metadata under `"physid.basis"` (`time` or `crank_angle`), and the recording's
//! metadata (scenario, parameters and faults of a simulated run, …) under `"physid.meta.KEY"`.
//!
//! Reading projects the columns asked for (memory proportional to them) and converts every
//! numeric type to f64; nulls are refused with their row. Writing uses float64 columns,
//! Snappy compression.

use crate::IoError;
use arrow_array::cast::AsArray;
use arrow_array::types::{
    Float32Type, Float64Type, Int16Type, Int32Type, Int64Type, Int8Type, UInt16Type, UInt32Type,
    UInt64Type, UInt8Type,
};
use arrow_array::{Array, ArrayRef, Float64Array, RecordBatch};
use arrow_schema::{DataType, Field, Schema};
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use parquet::arrow::{ArrowWriter, ProjectionMask};
use parquet::basic::Compression;
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
        let file = std::fs::File::open(path).map_err(|source| IoError::Os {
            path: p.clone(),
            source,
        })?;
        let builder = ParquetRecordBatchReaderBuilder::try_new(file).map_err(|e| pq_err(&p, e))?;
        let schema = builder.schema().clone();
        let names: Vec<String> = schema.fields().iter().map(|f| f.name().clone()).collect();
        let wanted = crate::positions(&names, channels, &p)?;
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
            let Some(batch) = self.reader.next() else {
                return Ok(None);
            };
            let batch = batch.map_err(|e| pq_err(&self.p, e))?;
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

/// A Parquet file written chunk by chunk (the live service's logging): float64 columns, units
/// in field metadata, Snappy; a row group every `rows_per_group` rows, so memory stays bounded
/// however long it writes. The file is valid once closed.
pub struct ParquetWriter {
    path: String,
    schema: Arc<Schema>,
    names: Vec<String>,
    w: ArrowWriter<std::fs::File>,
    rows: usize,
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
        let file = std::fs::File::create(path.as_ref()).map_err(|source| IoError::Os {
            path: p.clone(),
            source,
        })?;
        let props = WriterProperties::builder()
            .set_compression(Compression::SNAPPY)
            .set_dictionary_enabled(false)
            .set_max_row_group_row_count(Some(rows_per_group.max(1)))
            .build();
        let w =
            ArrowWriter::try_new(file, schema.clone(), Some(props)).map_err(|e| pq_err(&p, e))?;
        Ok(Self {
            names: like.channels().iter().map(|c| c.name.clone()).collect(),
            path: p,
            schema,
            w,
            rows: 0,
        })
    }

    /// Append `rec`'s rows (the same channels, in the same order, as the file's).
    pub fn append(&mut self, rec: &Recording) -> Result<(), IoError> {
        self.append_range(rec, 0..rec.len())
    }

    /// Append rows `range` of `rec`.
    fn append_range(
        &mut self,
        rec: &Recording,
        range: std::ops::Range<usize>,
    ) -> Result<(), IoError> {
        crate::check_appended(&self.path, &self.names, rec)?;
        let cols: Vec<ArrayRef> = rec
            .channels()
            .iter()
            .map(|c| Arc::new(Float64Array::from(c.values[range.clone()].to_vec())) as ArrayRef)
            .collect();
        let batch =
            RecordBatch::try_new(self.schema.clone(), cols).map_err(|e| pq_err(&self.path, e))?;
        self.w.write(&batch).map_err(|e| pq_err(&self.path, e))?;
        self.rows += range.len();
        Ok(())
    }

    /// Rows written so far.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Bytes in the file so far, and buffered for the next row group.
    pub fn bytes(&self) -> usize {
        self.w.bytes_written() + self.w.in_progress_size()
    }

    /// Finish the file (its footer).
    pub fn close(self) -> Result<(), IoError> {
        self.w.close().map_err(|e| pq_err(&self.path, e))?;
        Ok(())
    }
}
