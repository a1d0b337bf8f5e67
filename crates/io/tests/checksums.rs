//! A Parquet file physid wrote carries the CRC-32 of each column chunk, and a reader refuses a
//! chunk that does not match it, naming the column and the rows; a file pyarrow wrote with page
//! checksums (`golden/parquet/gen_pyarrow.py`) has its pages checked by the `parquet` crate.
//! The sums are checked against a CRC-32 written here bit by bit (the standard's check value
//! `CBF43926` for "123456789"), not against the crate physid hashes with.
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use arrow_array::{ArrayRef, Float64Array, RecordBatch};
use arrow_schema::{DataType, Field, Schema};
use parquet::arrow::ArrowWriter;
use parquet::file::metadata::{ParquetMetaData, ParquetMetaDataReader};
use physid_core::{Basis, Channel, Recording};
use physid_io::{read_parquet, recover_parquet, IoError, ParquetChunks, ParquetWriter, Recovered};
use physid_testkit::Scratch;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

const KEY: &str = "physid.chunk_crc32";

/// CRC-32 (IEEE 802.3, reflected, polynomial 0xEDB88320), one bit at a time.
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in bytes {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 == 1 {
                (c >> 1) ^ 0xEDB8_8320
            } else {
                c >> 1
            };
        }
    }
    !c
}

fn recording(n: usize) -> Recording {
    let mut r = Recording::new(Basis::Time);
    let t: Vec<f64> = (0..n).map(|i| i as f64 * 1e-4).collect();
    let p: Vec<f64> = t
        .iter()
        .map(|t| 1e5 + 4e6 * (50.0 * t).sin().powi(8))
        .collect();
    let w: Vec<f64> = t.iter().map(|t| 100.0 + (3.0 * t).cos()).collect();
    for (name, unit, v) in [("t", "s", t), ("p_cyl", "Pa", p), ("omega_en", "rad/s", w)] {
        r.push(Channel {
            name: name.into(),
            unit: unit.into(),
            values: v,
        })
        .unwrap();
    }
    r
}

fn metadata(path: &Path) -> ParquetMetaData {
    let f = std::fs::File::open(path).unwrap();
    ParquetMetaDataReader::new().parse_and_finish(&f).unwrap()
}

/// The sums under [`KEY`]: each row group's first byte and its chunks' CRCs.
fn sums(meta: &ParquetMetaData) -> Vec<(u64, Vec<u32>)> {
    let kv = meta.file_metadata().key_value_metadata().unwrap();
    let v = kv
        .iter()
        .find(|e| e.key == KEY)
        .unwrap()
        .value
        .clone()
        .unwrap();
    v.split(';')
        .map(|g| {
            let (start, crcs) = g.split_once(':').unwrap();
            let crcs = crcs.split(',').map(|c| u32::from_str_radix(c, 16).unwrap());
            (start.parse().unwrap(), crcs.collect())
        })
        .collect()
}

/// Where column `col` of row group `g` lies in the file.
fn chunk(meta: &ParquetMetaData, g: usize, col: usize) -> (usize, usize) {
    let c = meta.row_group(g).column(col);
    let start = c.dictionary_page_offset().unwrap_or(c.data_page_offset());
    (start as usize, c.compressed_size() as usize)
}

/// Each stored sum is the CRC-32 of its chunk's bytes, and each group's first byte is right.
fn assert_sums_hold(path: &Path, groups: usize) {
    let meta = metadata(path);
    let bytes = std::fs::read(path).unwrap();
    let s = sums(&meta);
    assert_eq!(s.len(), groups);
    assert_eq!(meta.num_row_groups(), groups);
    for (g, (start, crcs)) in s.iter().enumerate() {
        assert_eq!(crcs.len(), 3);
        assert_eq!(*start as usize, chunk(&meta, g, 0).0, "row group {g}");
        for (col, crc) in crcs.iter().enumerate() {
            let (at, len) = chunk(&meta, g, col);
            assert_eq!(
                crc32(&bytes[at..at + len]),
                *crc,
                "row group {g}, column {col}"
            );
        }
    }
}

fn flip(path: &Path, at: usize) {
    let mut bytes = std::fs::read(path).unwrap();
    bytes[at] ^= 0x5a;
    std::fs::write(path, bytes).unwrap();
}

/// One byte changed in the middle of column `col` of row group `g`.
fn damage(path: &Path, g: usize, col: usize) {
    let (at, len) = chunk(&metadata(path), g, col);
    flip(path, at + len / 2);
}

/// Reading all of `path` is refused with an error that says `want`.
fn assert_refused(path: &Path, want: &str) {
    let e = detail(read_parquet(path, None).unwrap_err());
    assert!(e.contains(want), "{e}");
}

fn detail(e: IoError) -> String {
    match e {
        IoError::Malformed { detail, .. } => detail,
        other => panic!("not a malformed-file error: {other}"),
    }
}

#[test]
fn the_crc_here_is_the_standard_one() {
    assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
}

fn written(s: &Scratch, name: &str) -> PathBuf {
    let rec = recording(5000);
    let path = s.file(name);
    let mut w = ParquetWriter::create(&path, &rec, 2000).unwrap();
    w.append(&rec).unwrap();
    w.close().unwrap();
    path
}

#[test]
fn a_byte_changed_in_a_column_is_refused_naming_the_column_and_its_rows() {
    let s = Scratch::new("physid-io-crc");
    let path = written(&s, "run.parquet");
    assert_sums_hold(&path, 3);
    let rec = recording(5000);
    let back = read_parquet(&path, None).unwrap();
    assert!(back.values("p_cyl").unwrap() == rec.values("p_cyl").unwrap());

    // One byte in the middle of p_cyl's chunk of the second row group (rows 2000 to 3999).
    damage(&path, 1, 1);
    assert_refused(&path, "column 'p_cyl' of row group 1 (rows 2000 to 3999");
    assert_refused(&path, "damaged or changed after it was written");
    // The columns untouched still read, whole and right.
    let other = read_parquet(&path, Some(&["t".into(), "omega_en".into()])).unwrap();
    assert!(other.values("omega_en").unwrap() == rec.values("omega_en").unwrap());
}

#[test]
fn a_stream_hands_out_the_rows_before_a_damaged_row_group_then_stops() {
    let s = Scratch::new("physid-io-crc");
    let rec = recording(200_000);
    let path = s.file("long.parquet");
    let group = physid_io::CHUNK_ROWS;
    let mut w = ParquetWriter::create(&path, &rec, group).unwrap();
    w.append(&rec).unwrap();
    w.close().unwrap();
    damage(&path, 2, 0);
    let mut chunks = ParquetChunks::open(&path, None).unwrap();
    let mut t = Vec::new();
    let e = loop {
        match chunks.next_columns() {
            Ok(Some(c)) => t.extend_from_slice(&c[0]),
            Ok(None) => panic!("a damaged row group read to the end ({} rows)", t.len()),
            Err(e) => break e,
        }
    };
    // The two row groups before the damaged one, whole and right; nothing of it.
    assert_eq!(t.len(), 2 * group);
    assert!(t == rec.values("t").unwrap()[..2 * group]);
    let e = detail(e);
    assert!(
        e.contains("column 't' of row group 2 (rows 131072 to 196607"),
        "{e}"
    );
}

#[test]
fn a_recovered_file_keeps_its_sums() {
    let s = Scratch::new("physid-io-crc");
    let rec = recording(5000);
    let writing = s.file("writing.parquet");
    let mut w = ParquetWriter::create(&writing, &rec, 1000).unwrap();
    w.append(&rec).unwrap();
    w.commit().unwrap();
    // Killed: never closed, what it buffered after the commit lost — the file as the disk
    // has it, its writer gone (the writer here still holds its own, locked).
    w.append(&recording(300)).unwrap();
    let path = s.file("killed.parquet");
    std::fs::copy(&writing, &path).unwrap();
    drop(w);
    assert_eq!(
        recover_parquet(&path).unwrap(),
        Recovered::Restored {
            rows: 5000,
            groups: 5,
            dropped: 0
        }
    );
    assert_sums_hold(&path, 5);
    assert!(read_parquet(&path, None).unwrap().values("t").unwrap() == rec.values("t").unwrap());
    damage(&path, 4, 2);
    assert_refused(&path, "column 'omega_en' of row group 4 (rows 4000 to 4999");
}

#[test]
fn sums_carried_into_a_file_of_another_layout_are_passed_over() {
    // A tool that rewrites a physid file keeps its metadata (pyarrow does): the sums then
    // describe the old file's chunks, not this one's, and must not be taken for damage.
    let s = Scratch::new("physid-io-crc");
    let old = written(&s, "old.parquet");
    let meta = metadata(&old);
    let kv = meta.file_metadata().key_value_metadata().unwrap();
    let value = kv
        .iter()
        .find(|e| e.key == KEY)
        .unwrap()
        .value
        .clone()
        .unwrap();
    let rec = recording(5000);
    let fields: Vec<Field> = rec
        .channels()
        .iter()
        .map(|c| Field::new(&c.name, DataType::Float64, false))
        .collect();
    let schema = Arc::new(Schema::new_with_metadata(
        fields,
        HashMap::from([(KEY.to_string(), value)]),
    ));
    let cols: Vec<ArrayRef> = rec
        .channels()
        .iter()
        .map(|c| Arc::new(Float64Array::from(c.values.clone())) as ArrayRef)
        .collect();
    let new = s.file("rewritten.parquet");
    let mut w =
        ArrowWriter::try_new(std::fs::File::create(&new).unwrap(), schema.clone(), None).unwrap();
    w.write(&RecordBatch::try_new(schema, cols).unwrap())
        .unwrap();
    w.close().unwrap();
    let back = read_parquet(&new, None).unwrap();
    assert!(back.values("p_cyl").unwrap() == rec.values("p_cyl").unwrap());
}

fn golden() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden/parquet")
}

#[test]
fn pyarrows_page_checksums_are_checked() {
    let file = golden().join("pyarrow_checksummed.parquet");
    let e: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(golden().join("expected.json")).unwrap())
            .unwrap();
    let rec = read_parquet(&file, None).unwrap();
    let want: Vec<f64> = e["omega_en"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    assert!(rec.values("omega_en").unwrap() == want.as_slice());
    // Every page header carries its CRC: the file is pyarrow's with `write_page_checksum`.
    let s = Scratch::new("physid-io-crc");
    let copy = s.file("damaged.parquet");
    std::fs::copy(&file, &copy).unwrap();
    // The last page's data: past its header.
    let (at, len) = chunk(&metadata(&copy), 1, 1);
    flip(&copy, at + len - 8);
    assert_refused(
        &copy,
        "a page of the rows from 0 on does not match the CRC-32 its writer stored",
    );
}
