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
    let s = physid_testkit::Scratch::new("physid-io");
    let rec = sample(Basis::CrankAngle);
    let out = s.file("w.parquet");
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

/// A crank-angle recording as the acquisition chain writes it: `t`, `theta`, `cycle`,
/// `crank_deg`, then channels.
fn crank_sample() -> Recording {
    let mut r = Recording::new(Basis::CrankAngle);
    let n = 1440;
    let deg: Vec<f64> = (0..n).map(|i| (i % 720) as f64).collect();
    let cols = [
        (
            "t",
            "s",
            (0..n).map(|i| i as f64 * 1.7e-4).collect::<Vec<_>>(),
        ),
        (
            "theta",
            "rad",
            (0..n).map(|i| (i as f64).to_radians()).collect(),
        ),
        ("cycle", "-", (0..n).map(|i| (i / 720) as f64).collect()),
        ("crank_deg", "deg", deg),
        (
            "p_cyl",
            "Pa",
            (0..n).map(|i| 1e5 + (i as f64 / 7.0).sin() * 3e5).collect(),
        ),
    ];
    for (name, unit, v) in cols {
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
fn every_format_round_trips_through_every_other_with_units_and_basis() {
    let s = physid_testkit::Scratch::new("physid-io");
    // Written by physid in one format, read back with no option, written in the next, …:
    // every value, unit and the basis survive every pair of formats.
    for original in [sample(Basis::Time), crank_sample()] {
        for a in ["csv", "parquet", "mf4"] {
            for b in ["csv", "parquet", "mf4"] {
                let pa = s.file(&format!("pair-{:?}-a.{a}", original.basis));
                write(&pa, &original, &WriteOptions::default()).unwrap();
                let mid = read(&pa, &ReadOptions::default()).unwrap();
                let pb = s.file(&format!("pair-{:?}-b.{b}", original.basis));
                write(&pb, &mid, &WriteOptions::default()).unwrap();
                let back = read(&pb, &ReadOptions::default()).unwrap();
                assert_eq!(back.basis, original.basis, "{a} → {b}");
                assert_eq!(back.names(), original.names(), "{a} → {b}");
                for ch in original.channels() {
                    let got = back.channel(&ch.name).unwrap();
                    assert!(got.values == ch.values, "{a} → {b}: {}", ch.name);
                    assert_eq!(got.unit, ch.unit, "{a} → {b}: {}", ch.name);
                }
                // A selection without the basis channels keeps the basis.
                let some = read(
                    &pb,
                    &ReadOptions {
                        channels: Some(vec!["t".into(), "p_cyl".into()]),
                        ..Default::default()
                    },
                )
                .unwrap();
                assert_eq!(some.basis, original.basis, "{a} → {b}, selected");
            }
        }
    }
}

#[test]
fn selection_and_a_channel_map_in_every_format() {
    let s = physid_testkit::Scratch::new("physid-io");
    for ext in ["csv", "parquet", "mf4"] {
        let rec = sample(Basis::Time);
        let path = s.file(&format!("round.{ext}"));
        write(&path, &rec, &WriteOptions::default()).unwrap();
        // The file's 'p_cyl' read as 'pressure'.
        let opts = ReadOptions {
            channels: Some(vec!["t".into(), "pressure".into()]),
            map: ReadOptions::parse_map(&["pressure=p_cyl".into()]).unwrap(),
            ..Default::default()
        };
        let m = read(&path, &opts).unwrap();
        assert_eq!(m.names(), ["t", "pressure"], "{ext}");
        assert!(m.values("pressure").unwrap() == rec.values("p_cyl").unwrap());
    }
}

#[test]
fn units_are_brought_to_si_on_reading_and_a_map_can_state_them() {
    let s = physid_testkit::Scratch::new("physid-io");
    let d = s.file("units.csv");
    // A test-cell log: angles in degrees, speed in rpm, oil in °C, pressure in bar, torque in
    // kNm; one column without a unit that the map labels.
    std::fs::write(
        &d,
        "t,theta_en,omega_en,T_oil,p_int,torque_shaft,EngSpeed\n\
         s,deg,rpm,°C,bar,kNm,\n\
         0,180,1500,90,0.7,0.25,1500\n\
         0.001,360,3000,100,1.0,-0.5,3000\n",
    )
    .unwrap();
    let r = read(
        &d,
        &ReadOptions {
            map: ReadOptions::parse_map(&["omega_dy=EngSpeed:rpm".into()]).unwrap(),
            ..Default::default()
        },
    )
    .unwrap();
    let pi = std::f64::consts::PI;
    let close = |a: &[f64], b: &[f64]| {
        a.iter()
            .zip(b)
            .all(|(x, y)| (x - y).abs() <= 1e-12 * y.abs().max(1.0))
    };
    assert!(close(r.values("theta_en").unwrap(), &[pi, 2.0 * pi]));
    assert!(close(
        r.values("omega_en").unwrap(),
        &[50.0 * pi, 100.0 * pi]
    ));
    assert!(close(
        r.values("omega_dy").unwrap(),
        &[50.0 * pi, 100.0 * pi]
    ));
    assert!(close(r.values("T_oil").unwrap(), &[363.15, 373.15]));
    assert!(close(r.values("p_int").unwrap(), &[70_000.0, 100_000.0]));
    assert!(close(r.values("torque_shaft").unwrap(), &[250.0, -500.0]));
    assert_eq!(r.channel("omega_dy").unwrap().unit, "rad/s");
    assert!(r.meta["units_converted"].contains("omega_en: rpm → rad/s"));
    // keep_units reads the file as it is.
    let raw = read(
        &d,
        &ReadOptions {
            keep_units: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(raw.values("omega_en").unwrap(), [1500.0, 3000.0]);
    // A unit that does not convert is refused naming the channel; so is a map unit that
    // contradicts the file.
    let bad = s.file("badunit.csv");
    std::fs::write(&bad, "t,torque_shaft\ns,lbf*ft\n0,1\n").unwrap();
    let e = read(&bad, &ReadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("'torque_shaft' is in 'lbf*ft'"), "{e}");
    let e = read(
        &d,
        &ReadOptions {
            map: ReadOptions::parse_map(&["omega_dy=omega_en:rad/s".into()]).unwrap(),
            ..Default::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("the unit 'rad/s', but the file says 'rpm'"),
        "{e}"
    );
    let m = ReadOptions::parse_map(&["x=Col:With:Colons".into(), "y=A:rpm".into()]).unwrap();
    assert_eq!(
        (m[0].column.as_str(), m[0].unit.as_deref()),
        ("Col:With:Colons", None)
    );
    assert_eq!(
        (m[1].column.as_str(), m[1].unit.as_deref()),
        ("A", Some("rpm"))
    );
}

#[test]
fn detection_and_errors() {
    let s = physid_testkit::Scratch::new("physid-io");
    let rec = sample(Basis::Time);
    let pq = s.file("a.parquet");
    write_parquet(&pq, &rec).unwrap();
    assert_eq!(detect(&pq).unwrap(), Format::Parquet);
    // A Parquet file named .csv, an MDF file named .parquet, text named .mf4.
    let lie = s.file("a.csv");
    std::fs::copy(&pq, &lie).unwrap();
    let e = read(&lie, &ReadOptions::default()).unwrap_err().to_string();
    assert!(
        e.contains("the extension says CSV but the file is Parquet"),
        "{e}"
    );
    let mdf = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden/mdf/time_plain.mf4");
    let lie2 = s.file("b.parquet");
    std::fs::copy(&mdf, &lie2).unwrap();
    let e = read(&lie2, &ReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("the extension says Parquet but the file is MDF4"),
        "{e}"
    );
    let lie3 = s.file("c.mf4");
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
    let cut = s.file("cut.parquet");
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
            map: ReadOptions::parse_map(&["omega_en=EngSpeed".into()]).unwrap(),
            ..Default::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("EngSpeed (mapped to omega_en)"), "{e}");
    assert!(ReadOptions::parse_map(&["a=b".into(), "bad".into()])
        .unwrap_err()
        .contains("--map 'bad'"));
    // Another extension is read by content: text as CSV, binary refused, MDF 3 named.
    let txt = s.file("x.dat");
    std::fs::write(&txt, "t;p_cyl\n0;1,5\n0,001;2,5\n").unwrap();
    let r = read(&txt, &ReadOptions::default()).unwrap();
    assert_eq!(r.values("p_cyl").unwrap(), [1.5, 2.5]);
    assert_eq!(r.values("t").unwrap(), [0.0, 0.001]);
    let bin = s.file("x.bin");
    std::fs::write(&bin, [0u8, 1, 2, 3, 0, 0]).unwrap();
    let e = read(&bin, &ReadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("neither CSV text, Parquet nor MDF4"), "{e}");
    let mdf3 = s.file("x.mdf");
    std::fs::write(&mdf3, b"MDF     3.30    TGT 15.0\0\0").unwrap();
    let e = read(&mdf3, &ReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("MDF version 3"), "{e}");
}

#[test]
fn parquet_keeps_the_recordings_metadata() {
    let s = physid_testkit::Scratch::new("physid-io");
    let mut r = sample(Basis::CrankAngle);
    r.meta.insert("scenario".into(), "torque-ramp".into());
    r.meta.insert("param.engine.m_rec".into(), "0.84".into());
    let f = s.file("meta.parquet");
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
