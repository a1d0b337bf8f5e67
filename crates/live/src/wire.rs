//! The fleet's wire format, version [`WIRE_VERSION`]: one chunk of one cell's samples is one
//! **Arrow IPC stream** (a schema message, record batches, the end-of-stream marker) — the
//! standard columnar interchange format that pyarrow, arrow-rs, Arrow's C++/Java/Go libraries
//! and DuckDB read and write without physid's code. Its schema is the schema of physid's
//! Parquet files (`docs/data.md`), with the frame's identity in the schema's metadata:
//!
//! | metadata key          | value                                                          |
//! |-----------------------|----------------------------------------------------------------|
//! | `physid.wire`         | `"1"` (this format's version; another is refused)               |
//! | `physid.cell`         | the cell id: 1–64 of `A–Z a–z 0–9 - _`                          |
//! | `physid.run`          | the run: its publisher's start, ms since the Unix epoch         |
//! | `physid.seq`          | the frame's sequence number in its cell's stream: 1, 2, 3, …    |
//! | `physid.first_sample` | the index of the frame's first sample in the cell's stream (0 …)|
//! | `physid.rate_hz`      | the nominal sample rate [Hz]                                    |
//! | `physid.basis`        | `"time"` (the live stages run on a time basis)                  |
//! | `physid.end`          | `"true"` on the cell's last frame (it may have no rows)         |
//!
//! Every column is a non-null `float64` named as in DESIGN.md's channel table with its unit in
//! the field's metadata (`unit`, an SI string); `t` [s] is required. A frame that breaks any of
//! this is refused with the reason ([`WireError`]) — never absorbed.

use arrow_array::{Array, ArrayRef, Float64Array, RecordBatch};
use arrow_buffer::Buffer;
use arrow_ipc::reader::StreamDecoder;
use arrow_ipc::writer::StreamWriter;
use arrow_schema::{DataType, Schema};
use physid_core::{Basis, Channel, Recording};
use std::collections::HashMap;
use std::sync::Arc;

/// The version of the wire format this physid writes and reads.
pub const WIRE_VERSION: &str = "1";

/// Metadata keys of a frame's schema.
pub mod key {
    /// The format's version.
    pub const WIRE: &str = "physid.wire";
    /// The cell id.
    pub const CELL: &str = "physid.cell";
    /// The run.
    pub const RUN: &str = "physid.run";
    /// The frame's sequence number.
    pub const SEQ: &str = "physid.seq";
    /// The index of the frame's first sample.
    pub const FIRST_SAMPLE: &str = "physid.first_sample";
    /// The nominal sample rate [Hz].
    pub const RATE_HZ: &str = "physid.rate_hz";
    /// The basis.
    pub const BASIS: &str = "physid.basis";
    /// The cell's last frame.
    pub const END: &str = "physid.end";
}

/// One frame: a chunk of one cell's samples and where it belongs.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// The cell.
    pub cell: String,
    /// The run (its publisher's start, ms since the Unix epoch).
    pub run: u64,
    /// Its sequence number in the cell's stream (from 1, consecutive).
    pub seq: u64,
    /// The index of its first sample in the cell's stream.
    pub first_sample: u64,
    /// The nominal sample rate [Hz].
    pub rate_hz: f64,
    /// The cell's last frame.
    pub end: bool,
    /// The samples (time basis, `t` among them unless it has no rows).
    pub chunk: Recording,
}

/// Why a frame was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct WireError(pub String);

fn bad(what: impl Into<String>) -> WireError {
    WireError(what.into())
}

/// Whether `id` is a valid cell id (1–64 of `A–Z a–z 0–9 - _`: it is a NATS subject token).
pub fn valid_cell(id: &str) -> bool {
    (1..=64).contains(&id.len())
        && id
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_')
}

/// A frame as an Arrow IPC stream.
pub fn encode(frame: &Frame) -> Result<Vec<u8>, WireError> {
    if !valid_cell(&frame.cell) {
        return Err(bad(format!(
            "cell id '{}': expected 1–64 of A–Z a–z 0–9 - _",
            frame.cell
        )));
    }
    if frame.chunk.basis != Basis::Time {
        return Err(bad("a frame's samples are on a time basis"));
    }
    let fields = physid_io::parquet_file::arrow_fields(&frame.chunk);
    let meta = HashMap::from([
        (key::WIRE.to_string(), WIRE_VERSION.to_string()),
        (key::CELL.to_string(), frame.cell.clone()),
        (key::RUN.to_string(), frame.run.to_string()),
        (key::SEQ.to_string(), frame.seq.to_string()),
        (
            key::FIRST_SAMPLE.to_string(),
            frame.first_sample.to_string(),
        ),
        (key::RATE_HZ.to_string(), format!("{:?}", frame.rate_hz)),
        (key::BASIS.to_string(), "time".to_string()),
        (key::END.to_string(), frame.end.to_string()),
    ]);
    let schema = Arc::new(Schema::new_with_metadata(fields, meta));
    let cols: Vec<ArrayRef> = frame
        .chunk
        .channels()
        .iter()
        .map(|c| Arc::new(Float64Array::from(c.values.clone())) as ArrayRef)
        .collect();
    let err = |e: arrow_schema::ArrowError| bad(format!("encoding a frame: {e}"));
    let opts = arrow_array::RecordBatchOptions::new().with_row_count(Some(frame.chunk.len()));
    let batch = RecordBatch::try_new_with_options(schema.clone(), cols, &opts).map_err(err)?;
    let mut w = StreamWriter::try_new(Vec::new(), &schema).map_err(err)?;
    w.write(&batch).map_err(err)?;
    w.finish().map_err(err)?;
    w.into_inner().map_err(err)
}

/// A frame from its bytes, checked against the format; the error says what is wrong (a
/// malformed stream is contained here: whatever the bytes, an error, never a panic).
pub fn decode(bytes: &[u8]) -> Result<Frame, WireError> {
    std::panic::catch_unwind(|| decode_inner(bytes))
        .unwrap_or_else(|_| Err(bad("not a readable Arrow IPC stream (its decoder failed)")))
}

fn decode_inner(bytes: &[u8]) -> Result<Frame, WireError> {
    let ipc = |e: arrow_schema::ArrowError| bad(format!("not a readable Arrow IPC stream: {e}"));
    let mut decoder = StreamDecoder::new();
    let mut buf = Buffer::from(bytes.to_vec());
    let mut batches = Vec::new();
    while !buf.is_empty() {
        match decoder.decode(&mut buf).map_err(ipc)? {
            Some(b) => batches.push(b),
            None if buf.is_empty() => break,
            None => {}
        }
    }
    decoder.finish().map_err(ipc)?;
    let schema = decoder
        .schema()
        .ok_or_else(|| bad("not an Arrow IPC stream: no schema"))?;
    let meta = schema.metadata();
    let get = |k: &str| {
        meta.get(k).map(String::as_str).ok_or_else(|| {
            bad(format!(
                "no '{k}' in the schema's metadata: not a physid frame"
            ))
        })
    };
    let version = get(key::WIRE)?;
    if version != WIRE_VERSION {
        return Err(bad(format!(
            "wire format version '{version}': this physid reads version {WIRE_VERSION}"
        )));
    }
    let cell = get(key::CELL)?.to_string();
    if !valid_cell(&cell) {
        return Err(bad(format!(
            "'{}' is '{cell}': expected 1–64 of A–Z a–z 0–9 - _",
            key::CELL
        )));
    }
    let int = |k: &str| -> Result<u64, WireError> {
        let v = get(k)?;
        v.parse()
            .map_err(|_| bad(format!("'{k}' is '{v}': expected a whole number ≥ 0")))
    };
    let run = int(key::RUN)?;
    let seq = int(key::SEQ)?;
    if seq == 0 {
        return Err(bad(format!(
            "'{}' is 0: sequence numbers start at 1",
            key::SEQ
        )));
    }
    let first_sample = int(key::FIRST_SAMPLE)?;
    let rate = get(key::RATE_HZ)?;
    let rate_hz: f64 = rate
        .parse()
        .ok()
        .filter(|r: &f64| r.is_finite() && *r > 0.0)
        .ok_or_else(|| {
            bad(format!(
                "'{}' is '{rate}': expected a rate > 0 [Hz]",
                key::RATE_HZ
            ))
        })?;
    let basis = get(key::BASIS)?;
    if basis != "time" {
        return Err(bad(format!(
            "'{}' is '{basis}': the live stages take frames on a time basis",
            key::BASIS
        )));
    }
    let end = match meta.get(key::END).map(String::as_str) {
        None | Some("false") => false,
        Some("true") => true,
        Some(v) => {
            return Err(bad(format!(
                "'{}' is '{v}': expected true or false",
                key::END
            )))
        }
    };
    let mut chunk = Recording::new(Basis::Time);
    for (j, field) in schema.fields().iter().enumerate() {
        if field.data_type() != &DataType::Float64 {
            return Err(bad(format!(
                "column '{}' is {}: expected float64",
                field.name(),
                field.data_type()
            )));
        }
        let mut values = Vec::with_capacity(batches.iter().map(RecordBatch::num_rows).sum());
        for b in &batches {
            let col = b.column(j);
            if col.null_count() > 0 {
                return Err(bad(format!(
                    "column '{}' has a null: expected a number in every row",
                    field.name()
                )));
            }
            let col = col
                .as_any()
                .downcast_ref::<Float64Array>()
                .ok_or_else(|| bad(format!("column '{}': expected float64", field.name())))?;
            values.extend_from_slice(col.values());
        }
        chunk
            .push(Channel {
                name: field.name().clone(),
                unit: field.metadata().get("unit").cloned().unwrap_or_default(),
                values,
            })
            .map_err(|e| bad(e.to_string()))?;
    }
    if !chunk.is_empty() && chunk.channel("t").is_err() {
        return Err(bad(format!(
            "no column 't' [s]; the columns are: {}",
            chunk.names().join(", ")
        )));
    }
    Ok(Frame {
        cell,
        run,
        seq,
        first_sample,
        rate_hz,
        end,
        chunk,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame() -> Frame {
        let mut chunk = Recording::new(Basis::Time);
        for (name, unit, f) in [("t", "s", 1e-3), ("omega_en", "rad/s", 2.5)] {
            chunk
                .push(Channel {
                    name: name.into(),
                    unit: unit.into(),
                    values: (0..5).map(|k| f * k as f64 + 0.1).collect(),
                })
                .unwrap();
        }
        Frame {
            cell: "cell-7".into(),
            run: 1_764_000_000_000,
            seq: 3,
            first_sample: 10,
            rate_hz: 1000.0,
            end: false,
            chunk,
        }
    }

    /// Written and read back: the same frame, bit for bit.
    #[test]
    fn round_trip() {
        let f = frame();
        assert_eq!(decode(&encode(&f).unwrap()).unwrap(), f);
        let mut end = f.clone();
        end.end = true;
        end.chunk = Recording::new(Basis::Time);
        assert_eq!(decode(&encode(&end).unwrap()).unwrap(), end);
    }

    /// Every truncation and every single-byte change of a frame is refused or read as a frame —
    /// never a panic.
    #[test]
    fn corrupt_bytes_are_errors() {
        let bytes = encode(&frame()).unwrap();
        for n in 0..bytes.len() {
            let _ = decode(&bytes[..n]);
        }
        for k in 0..bytes.len() {
            let mut b = bytes.clone();
            b[k] ^= 0x5a;
            let _ = decode(&b);
        }
        assert!(decode(b"hello").unwrap_err().0.contains("Arrow IPC"));
    }
}
