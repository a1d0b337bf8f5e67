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
use physid_core::{Basis, Channel, Recording, RecordingError};
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
    let p = path.as_ref().display().to_string();
    crate::contained(&p, "Parquet", || {
        read_parquet_inner(path.as_ref(), &p, channels)
    })
}

fn read_parquet_inner(
    path: &Path,
    p: &str,
    channels: Option<&[String]>,
) -> Result<Recording, IoError> {
    let p = p.to_string();
    let file = std::fs::File::open(path).map_err(|source| IoError::Os {
        path: p.clone(),
        source,
    })?;
    let builder = ParquetRecordBatchReaderBuilder::try_new(file).map_err(|e| pq_err(&p, e))?;
    let schema = builder.schema().clone();
    let names: Vec<String> = schema.fields().iter().map(|f| f.name().clone()).collect();
    let wanted: Vec<usize> = match channels {
        Some(list) => list
            .iter()
            .map(|n| {
                names
                    .iter()
                    .position(|m| m == n)
                    .ok_or_else(|| IoError::Recording {
                        path: p.clone(),
                        source: RecordingError::MissingChannel {
                            name: n.clone(),
                            available: names.join(", "),
                        },
                    })
            })
            .collect::<Result<_, _>>()?,
        None => (0..names.len()).collect(),
    };
    let mask = ProjectionMask::roots(builder.parquet_schema(), wanted.iter().copied());
    // The row count is the file's claim: checked against what the columns asked for would
    // take in memory before anything is sized from it (a corrupt footer can claim 2⁶⁰ rows).
    let claimed = builder.metadata().file_metadata().num_rows();
    let rows = usize::try_from(claimed).map_err(|_| IoError::Malformed {
        path: p.clone(),
        detail: format!("corrupt Parquet: the footer claims {claimed} rows"),
    })?;
    let need = (rows as u128) * (wanted.len().max(1) as u128) * 8;
    if let Some(free) = physid_core::memory::available() {
        if need > u128::from(free) {
            return Err(IoError::Malformed {
                path: p.clone(),
                detail: format!(
                    "the file claims {rows} rows: {} channels of them would take {:.1} GB, and this machine has {:.1} GB free (read fewer channels, or the footer is corrupt)",
                    wanted.len(),
                    need as f64 / 1e9,
                    free as f64 / 1e9
                ),
            });
        }
    }
    // Capacity is only a hint: never more than the file's size could hold in plain values.
    let size = std::fs::metadata(path).map_or(0, |m| m.len()) as usize;
    let rows = rows.min(size / 8 + 1);
    let reader = builder
        .with_projection(mask)
        .with_batch_size(65_536)
        .build()
        .map_err(|e| pq_err(&p, e))?;
    // The projected batches keep the file's column order; map back to the order asked for.
    let mut sorted = wanted.clone();
    sorted.sort_unstable();
    let mut columns: Vec<Vec<f64>> = sorted.iter().map(|_| Vec::with_capacity(rows)).collect();
    let mut row0 = 0;
    for batch in reader {
        let batch = batch.map_err(|e| pq_err(&p, e))?;
        for (k, col) in batch.columns().iter().enumerate() {
            extend_f64(col, &mut columns[k], &names[sorted[k]], row0).map_err(|detail| {
                IoError::Malformed {
                    path: p.clone(),
                    detail,
                }
            })?;
        }
        row0 += batch.num_rows();
    }
    let basis = match schema.metadata().get(BASIS_KEY).map(String::as_str) {
        Some("crank_angle") => Basis::CrankAngle,
        _ => Basis::Time,
    };
    let mut rec = Recording::new(basis);
    for (k, v) in schema.metadata() {
        if let Some(key) = k.strip_prefix(META_PREFIX) {
            if !crate::FILE_META.contains(&key) {
                rec.meta.insert(key.to_string(), v.clone());
            }
        }
    }
    rec.meta.insert("source".into(), p.clone());
    let mut taken: Vec<Option<Vec<f64>>> = columns.into_iter().map(Some).collect();
    for &j in &wanted {
        let k = sorted.iter().position(|&s| s == j).unwrap_or(0);
        let values = taken[k].take().unwrap_or_default();
        let field = schema.field(j);
        rec.push(Channel {
            name: field.name().clone(),
            unit: field.metadata().get("unit").cloned().unwrap_or_default(),
            values,
        })
        .map_err(|source| IoError::Recording {
            path: p.clone(),
            source,
        })?;
    }
    Ok(rec)
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
        let fields: Vec<Field> = like
            .channels()
            .iter()
            .map(|c| {
                Field::new(&c.name, DataType::Float64, false)
                    .with_metadata(HashMap::from([("unit".to_string(), c.unit.clone())]))
            })
            .collect();
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
