//! Parquet interoperability with pyarrow (`golden/parquet/gen_pyarrow.py`) both ways, format
//! detection by extension and content, channel selection and mapping, and round trips through
//! every format.
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_core::{Basis, Channel, Recording};
use physid_io::{
    detect, read, read_parquet, write, write_parquet, Format, ReadOptions, WriteOptions,
};
use serde_json::Value;
use std::path::PathBuf;

fn gdir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden/parquet")
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("physid-io-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

#[test]
fn reads_pyarrow_files_with_units_and_types() {
    let e: Value =
        serde_json::from_str(&std::fs::read_to_string(gdir().join("expected.json")).unwrap())
            .unwrap();
    let rec = read_parquet(gdir().join("pyarrow_written.parquet"), None).unwrap();
    assert_eq!(rec.names(), ["t", "omega_en", "count_en", "torque_shaft"]);
    for ch in ["t", "omega_en", "count_en", "torque_shaft"] {
        assert!(rec.values(ch).unwrap() == floats(&e[ch]).as_slice(), "{ch}");
        assert_eq!(rec.channel(ch).unwrap().unit, e["units"][ch], "{ch}");
    }
    // Projection, in the order asked for.
    let sub = read_parquet(
        gdir().join("pyarrow_written.parquet"),
        Some(&["torque_shaft".into(), "t".into()]),
    )
    .unwrap();
    assert_eq!(sub.names(), ["torque_shaft", "t"]);
    assert!(sub.values("t").unwrap() == floats(&e["t"]).as_slice());
}

fn sample(basis: Basis) -> Recording {
    let mut r = Recording::new(basis);
    let n = 3000;
    let t: Vec<f64> = (0..n).map(|i| i as f64 * 1e-3).collect();
    let x: Vec<f64> = t
        .iter()
        .map(|t| (9.0 * t).sin() * 1e3 + 1.0 / 3.0)
        .collect();
    let y: Vec<f64> = t.iter().map(|t| (t * 1e4).floor()).collect();
    for (name, unit, v) in [("t", "s", t), ("p_cyl", "Pa", x), ("count_en", "-", y)] {
        r.push(Channel {
            name: name.into(),
            unit: unit.into(),
            values: v,
        })
        .unwrap();
    }
    r
}

#[test]
fn writes_the_parquet_file_pyarrow_reads_back() {
    let rec = sample(Basis::CrankAngle);
    let out = tmp("w.parquet");
    write_parquet(&out, &rec).unwrap();
    let back = read_parquet(&out, None).unwrap();
    assert_eq!(back.basis, Basis::CrankAngle);
    for ch in rec.channels() {
        assert!(
            back.values(&ch.name).unwrap() == ch.values.as_slice(),
            "{}",
            ch.name
        );
        assert_eq!(back.channel(&ch.name).unwrap().unit, ch.unit);
    }
    if std::env::var("PHYSID_BLESS").is_ok() {
        std::fs::copy(&out, gdir().join("physid_written.parquet")).unwrap();
        let exp = serde_json::json!({
            "basis": "crank_angle",
            "channels": rec.channels().iter().map(|c| (c.name.clone(), serde_json::json!(c.values))).collect::<serde_json::Map<_, _>>(),
            "units": rec.channels().iter().map(|c| (c.name.clone(), serde_json::json!(c.unit))).collect::<serde_json::Map<_, _>>(),
        });
        std::fs::write(gdir().join("expected_physid.json"), exp.to_string()).unwrap();
    }
    // The committed file pyarrow checked is still what the writer writes, value for value.
    let committed = read_parquet(gdir().join("physid_written.parquet"), None).unwrap();
    assert_eq!(committed.basis, back.basis);
    assert!(committed.channels() == back.channels());
}

#[test]
fn every_format_round_trips_through_read_and_write() {
    for ext in ["csv", "parquet", "mf4"] {
        let rec = sample(Basis::Time);
        let path = tmp(&format!("round.{ext}"));
        write(&path, &rec, &WriteOptions::default()).unwrap();
        let opts = ReadOptions {
            units_row: true,
            ..Default::default()
        };
        let back = read(&path, &opts).unwrap();
        for ch in rec.channels() {
            assert!(
                back.values(&ch.name).unwrap() == ch.values.as_slice(),
                "{ext} {}",
                ch.name
            );
            assert_eq!(back.channel(&ch.name).unwrap().unit, ch.unit, "{ext}");
        }
        // Selection and a channel map: the file's 'p_cyl' read as 'pressure'.
        let opts = ReadOptions {
            channels: Some(vec!["t".into(), "pressure".into()]),
            map: vec![("pressure".into(), "p_cyl".into())],
            units_row: true,
            ..Default::default()
        };
        let m = read(&path, &opts).unwrap();
        assert_eq!(m.names(), ["t", "pressure"], "{ext}");
        assert!(m.values("pressure").unwrap() == rec.values("p_cyl").unwrap());
    }
}

#[test]
fn detection_and_errors() {
    let rec = sample(Basis::Time);
    let pq = tmp("a.parquet");
    write_parquet(&pq, &rec).unwrap();
    assert_eq!(detect(&pq).unwrap(), Format::Parquet);
    // A Parquet file named .csv, an MDF file named .parquet, text named .mf4.
    let lie = tmp("a.csv");
    std::fs::copy(&pq, &lie).unwrap();
    let e = read(&lie, &ReadOptions::default()).unwrap_err().to_string();
    assert!(
        e.contains("the extension says CSV but the file is Parquet"),
        "{e}"
    );
    let mdf = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden/mdf/time_plain.mf4");
    let lie2 = tmp("b.parquet");
    std::fs::copy(&mdf, &lie2).unwrap();
    let e = read(&lie2, &ReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("the extension says Parquet but the file is MDF4"),
        "{e}"
    );
    let lie3 = tmp("c.mf4");
    std::fs::write(&lie3, "t,x\n0,1\n").unwrap();
    let e = read(&lie3, &ReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("the extension says MDF4 but the file is text"),
        "{e}"
    );
    // A truncated Parquet file.
    let bytes = std::fs::read(&pq).unwrap();
    let cut = tmp("cut.parquet");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let e = read(&cut, &ReadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("cut.parquet") && e.contains("Parquet"), "{e}");
    assert!(
        e.contains(&format!("the file ends at byte {}", bytes.len() / 2)),
        "{e}"
    );
    // A missing channel lists what is there; a map to a missing column says so.
    let e = read(
        &pq,
        &ReadOptions {
            channels: Some(vec!["omega_dy".into()]),
            ..Default::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("no channel 'omega_dy'; the channels are: t, p_cyl, count_en"),
        "{e}"
    );
    let e = read(
        &pq,
        &ReadOptions {
            map: vec![("omega_en".into(), "EngSpeed".into())],
            ..Default::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("EngSpeed (mapped to omega_en)"), "{e}");
    assert!(ReadOptions::parse_map(&["a=b".into(), "bad".into()])
        .unwrap_err()
        .contains("--map 'bad'"));
    let e = read(tmp("x.txt"), &ReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("unknown extension"), "{e}");
}

#[test]
fn parquet_keeps_the_recordings_metadata() {
    let mut r = sample(Basis::CrankAngle);
    r.meta.insert("scenario".into(), "torque-ramp".into());
    r.meta.insert("param.engine.m_rec".into(), "0.84".into());
    let f = tmp("meta.parquet");
    write_parquet(&f, &r).unwrap();
    let back = read_parquet(&f, None).unwrap();
    assert_eq!(back.meta["scenario"], "torque-ramp");
    assert_eq!(back.meta["param.engine.m_rec"], "0.84");
    assert_eq!(back.basis, Basis::CrankAngle);
    // pyarrow sees the entries as schema metadata, under a prefix.
    let file = std::fs::File::open(&f).unwrap();
    let b = parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder::try_new(file).unwrap();
    assert_eq!(
        b.schema()
            .metadata()
            .get("physid.meta.scenario")
            .map(String::as_str),
        Some("torque-ramp")
    );
}
