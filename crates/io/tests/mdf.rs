//! MDF4 interoperability with asammdf (`golden/mdf/gen_asammdf.py`): files asammdf wrote —
//! uncompressed, deflate, transposed deflate, an angle master — read with the same values,
//! names, units and master; a file we write is the committed one that asammdf reads back
//! (`gen_asammdf.py --check`).
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_core::{Basis, Channel, Recording};
use physid_io::{read_mdf, write_mdf, MdfCompression};
use serde_json::Value;
use std::path::PathBuf;

fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden/mdf")
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

fn expected() -> Value {
    serde_json::from_str(&std::fs::read_to_string(dir().join("expected.json")).unwrap()).unwrap()
}

#[test]
fn reads_asammdf_time_files_plain_and_compressed() {
    let e = &expected()["time"];
    for name in ["time_plain", "time_deflate", "time_transposed"] {
        let rec = read_mdf(dir().join(format!("{name}.mf4")), None).unwrap();
        assert_eq!(rec.basis, Basis::Time, "{name}");
        assert_eq!(
            rec.values("t").unwrap(),
            floats(&e["t"]).as_slice(),
            "{name}"
        );
        for ch in ["omega_en", "torque_shaft", "count_en", "T_oil"] {
            let got = rec.values(ch).unwrap();
            let want = floats(&e[ch]);
            assert_eq!(got.len(), want.len(), "{name} {ch}");
            for (a, b) in got.iter().zip(&want) {
                // The linear conversion of T_oil is applied in f64 both sides.
                assert!(
                    (a - b).abs() <= 1e-12 * b.abs().max(1.0),
                    "{name} {ch}: {a} vs {b}"
                );
            }
            assert_eq!(rec.channel(ch).unwrap().unit, e["units"][ch], "{name} {ch}");
        }
        // A channel list reads only those channels.
        let sub = read_mdf(
            dir().join(format!("{name}.mf4")),
            Some(&["T_oil".to_string()]),
        )
        .unwrap();
        assert_eq!(sub.names(), ["t", "T_oil"]);
    }
}

#[test]
fn reads_an_angle_master_as_crank_angle_data() {
    let e = &expected()["angle"];
    let rec = read_mdf(dir().join("angle.mf4"), None).unwrap();
    assert_eq!(rec.basis, Basis::CrankAngle);
    for ch in ["theta", "p_cyl", "cycle"] {
        let (got, want) = (rec.values(ch).unwrap(), floats(&e[ch]));
        assert_eq!(got.len(), want.len(), "{ch}");
        let bad = got.iter().zip(&want).position(|(a, b)| a != b);
        assert!(
            bad.is_none(),
            "{ch}: first difference at {bad:?}: {:?} vs {:?}",
            bad.map(|i| got[i]),
            bad.map(|i| want[i])
        );
    }
    assert_eq!(rec.channel("theta").unwrap().unit, "rad");
}

/// The recording the writer test writes (deterministic).
fn written() -> Recording {
    let mut r = Recording::new(Basis::Time);
    let t: Vec<f64> = (0..500).map(|i| i as f64 * 2e-3).collect();
    let w: Vec<f64> = t.iter().map(|t| 100.0 + 5.0 * (7.0 * t).sin()).collect();
    let tau: Vec<f64> = t.iter().map(|t| 3.0 * (40.0 * t).cos() - 0.25).collect();
    for (name, unit, values) in [
        ("t", "s", t),
        ("omega_en", "rad/s", w),
        ("torque_shaft", "N*m", tau),
    ] {
        r.push(Channel {
            name: name.into(),
            unit: unit.into(),
            values,
        })
        .unwrap();
    }
    r
}

#[test]
fn writes_the_file_asammdf_reads_back() {
    let rec = written();
    let scratch = physid_testkit::Scratch::new("physid-mdf");
    let out = scratch.file("w.mf4");
    write_mdf(
        &out,
        &rec,
        MdfCompression::None,
        Some(1_700_000_000_000_000_000),
    )
    .unwrap();
    // Our own reader agrees exactly.
    let back = read_mdf(&out, None).unwrap();
    for ch in ["t", "omega_en", "torque_shaft"] {
        assert_eq!(back.values(ch).unwrap(), rec.values(ch).unwrap(), "{ch}");
        assert_eq!(
            back.channel(ch).unwrap().unit,
            rec.channel(ch).unwrap().unit
        );
    }
    // Byte for byte the committed file that `gen_asammdf.py --check` opened in asammdf.
    let bytes = std::fs::read(&out).unwrap();
    if std::env::var("PHYSID_BLESS").is_ok() {
        std::fs::write(dir().join("physid_written.mf4"), &bytes).unwrap();
        let exp = serde_json::json!({
            "t": rec.values("t").unwrap(),
            "channels": {"omega_en": rec.values("omega_en").unwrap(),
                         "torque_shaft": rec.values("torque_shaft").unwrap()},
            "units": {"omega_en": "rad/s", "torque_shaft": "N*m"},
        });
        std::fs::write(dir().join("expected_physid.json"), exp.to_string()).unwrap();
    } else {
        let golden = std::fs::read(dir().join("physid_written.mf4")).unwrap();
        assert!(
            bytes == golden,
            "the writer's output changed: re-run with PHYSID_BLESS=1 and gen_asammdf.py --check"
        );
    }
    // Compressed files read back the same, and are the committed ones asammdf read.
    for (c, name) in [
        (MdfCompression::Deflate, "physid_written_deflate.mf4"),
        (
            MdfCompression::TransposedDeflate,
            "physid_written_transposed.mf4",
        ),
    ] {
        write_mdf(&out, &rec, c, Some(1_700_000_000_000_000_000)).unwrap();
        let back = read_mdf(&out, None).unwrap();
        assert_eq!(
            back.values("omega_en").unwrap(),
            rec.values("omega_en").unwrap()
        );
        let bytes = std::fs::read(&out).unwrap();
        if std::env::var("PHYSID_BLESS").is_ok() {
            std::fs::write(dir().join(name), &bytes).unwrap();
        } else {
            assert!(
                bytes == std::fs::read(dir().join(name)).unwrap(),
                "{name} changed"
            );
        }
    }
    let _ = std::fs::remove_file(&out);
}

#[test]
fn errors_name_the_file_and_the_problem() {
    let e = read_mdf(
        dir().join("time_plain.mf4"),
        Some(&["omega_dy".to_string()]),
    )
    .unwrap_err();
    let s = e.to_string();
    assert!(
        s.contains("no channel 'omega_dy'") && s.contains("omega_en, torque_shaft")
            || s.contains("T_oil"),
        "{s}"
    );
    // Truncated file.
    let bytes = std::fs::read(dir().join("time_plain.mf4")).unwrap();
    let scratch = physid_testkit::Scratch::new("physid-mdf");
    let cut = scratch.file("cut.mf4");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let e = read_mdf(&cut, None).unwrap_err().to_string();
    assert!(e.contains(cut.to_str().unwrap()), "{e}");
    // Not an MDF file at all.
    std::fs::write(&cut, b"t,x\n1,2\n").unwrap();
    let e = read_mdf(&cut, None).unwrap_err().to_string();
    assert!(e.contains("MDF4"), "{e}");
    let _ = std::fs::remove_file(&cut);
    let mut no_t = Recording::new(Basis::Time);
    no_t.push(Channel {
        name: "x".into(),
        unit: String::new(),
        values: vec![1.0],
    })
    .unwrap();
    let e = write_mdf(&cut, &no_t, MdfCompression::None, None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("needs a 't' channel"), "{e}");
}

#[test]
fn a_record_count_corrupted_smaller_than_the_data_is_refused() {
    // The channel group's cycle count (after the CG block's 24-byte header, its links and the
    // 8-byte record id) patched to 1, in asammdf's files and physid's.
    let scratch = physid_testkit::Scratch::new("physid-mdf");
    for name in [
        "time_plain.mf4",
        "time_deflate.mf4",
        "time_transposed.mf4",
        "physid_written.mf4",
    ] {
        let mut b = std::fs::read(dir().join(name)).unwrap();
        let i = b.windows(4).position(|w| w == b"##CG").unwrap();
        let links = u64::from_le_bytes(b[i + 16..i + 24].try_into().unwrap()) as usize;
        let at = i + 24 + 8 * links + 8;
        let count = u64::from_le_bytes(b[at..at + 8].try_into().unwrap());
        assert!(count > 1, "{name}: {count}");
        b[at..at + 8].copy_from_slice(&1u64.to_le_bytes());
        let f = scratch.file(name);
        std::fs::write(&f, &b).unwrap();
        let e = read_mdf(&f, None).unwrap_err().to_string();
        assert!(
            e.contains(&format!(
                "claims 1 records, but its data blocks hold {count}"
            )),
            "{name}: {e}"
        );
    }
}

/// The log written as the samples arrive ([`MdfWriter`]): for chunks of 1, 17 and 64 samples
/// and whole it is byte for byte the committed file that asammdf opened (`gen_asammdf.py
/// --check`), i.e. what `write_mdf` writes uncompressed; time that goes back is refused
/// naming it.
#[test]
fn the_streaming_writer_writes_the_file_asammdf_read() {
    use physid_io::MdfWriter;
    let rec = written();
    let golden = std::fs::read(dir().join("physid_written.mf4")).unwrap();
    let scratch = physid_testkit::Scratch::new("physid-mdf-stream");
    for chunk in [1, 17, 64, rec.len()] {
        let out = scratch.file(&format!("s{chunk}.mf4"));
        let mut w = MdfWriter::create(&out, &rec, Some(1_700_000_000_000_000_000)).unwrap();
        for start in (0..rec.len()).step_by(chunk) {
            w.append(&rec.slice(start..(start + chunk).min(rec.len())))
                .unwrap();
        }
        assert_eq!(w.rows(), rec.len());
        let reported = w.bytes();
        w.close().unwrap();
        let bytes = std::fs::read(&out).unwrap();
        assert_eq!(reported, bytes.len());
        assert!(
            bytes == golden,
            "chunk {chunk}: not the asammdf-checked file"
        );
    }
    // Time going back: refused, naming it; the samples before it are kept.
    let out = scratch.file("back.mf4");
    let mut w = MdfWriter::create(&out, &rec, None).unwrap();
    w.append(&rec.slice(100..200)).unwrap();
    let e = w.append(&rec.slice(0..10)).unwrap_err().to_string();
    assert!(e.contains("time master") && e.contains("back.mf4"), "{e}");
    w.close().unwrap();
    let back = read_mdf(&out, None).unwrap();
    assert_eq!(
        back.values("t").unwrap(),
        &rec.values("t").unwrap()[100..200]
    );
}

/// The streaming writer compressed: records deflated (or transposed and deflated) into a
/// `##DZ` per block as they come, listed by a `##HL`/`##DL` at the close. With blocks of 1000
/// bytes (41 records; 13 blocks, the last shorter) and chunks of 1, 17 and 64 samples or
/// whole, the file is byte for byte the committed one that asammdf read (`gen_asammdf.py
/// --check`), and reads back bit for bit — whole and a chunk at a time; with the default block
/// size (one block here), too. No sample: an empty group that reads back empty.
#[test]
fn the_streaming_writer_compresses_block_by_block_into_files_asammdf_reads() {
    use physid_io::{ChunkReader, MdfWriter, ReadOptions, MDF_BLOCK_BYTES};
    let rec = written();
    let scratch = physid_testkit::Scratch::new("physid-mdf-stream-zip");
    let same = |back: &Recording, what: &str| {
        for name in ["t", "omega_en", "torque_shaft"] {
            assert_eq!(
                back.values(name).unwrap(),
                rec.values(name).unwrap(),
                "{what}: {name}"
            );
        }
        assert_eq!(back.channel("torque_shaft").unwrap().unit, "N*m", "{what}");
    };
    for (c, name) in [
        (MdfCompression::Deflate, "physid_streamed_deflate.mf4"),
        (
            MdfCompression::TransposedDeflate,
            "physid_streamed_transposed.mf4",
        ),
    ] {
        for chunk in [1, 17, 64, rec.len()] {
            let out = scratch.file(&format!("z{chunk}.mf4"));
            let mut w =
                MdfWriter::create_compressed(&out, &rec, Some(1_700_000_000_000_000_000), c, 1000)
                    .unwrap();
            for start in (0..rec.len()).step_by(chunk) {
                w.append(&rec.slice(start..(start + chunk).min(rec.len())))
                    .unwrap();
            }
            w.close().unwrap();
            let bytes = std::fs::read(&out).unwrap();
            assert_eq!(
                bytes.windows(4).filter(|w| w == b"##DZ").count(),
                13,
                "{name} {chunk}"
            );
            if std::env::var("PHYSID_BLESS").is_ok() {
                std::fs::write(dir().join(name), &bytes).unwrap();
            } else {
                assert!(
                    bytes == std::fs::read(dir().join(name)).unwrap(),
                    "{name}, chunk {chunk}: not the asammdf-checked file"
                );
            }
            same(&read_mdf(&out, None).unwrap(), name);
            // A chunk at a time across the blocks.
            let mut r = ChunkReader::open(&out, &ReadOptions::default()).unwrap();
            let mut whole = r.header().clone();
            while let Some(c) = r.next_chunk().unwrap() {
                whole.append(&c).unwrap();
            }
            same(&whole, &format!("{name} in chunks"));
        }
        let out = scratch.file("one.mf4");
        let mut w = MdfWriter::create_compressed(&out, &rec, None, c, MDF_BLOCK_BYTES).unwrap();
        w.append(&rec).unwrap();
        w.close().unwrap();
        same(&read_mdf(&out, None).unwrap(), "one block");
        let empty = scratch.file("empty.mf4");
        MdfWriter::create_compressed(&empty, &rec, None, c, MDF_BLOCK_BYTES)
            .unwrap()
            .close()
            .unwrap();
        let back = read_mdf(&empty, None).unwrap();
        assert_eq!(back.len(), 0);
        assert_eq!(back.names(), rec.names());
    }
}

/// A crank-angle recording as physid writes it (a time master, `theta` a data channel): a
/// selection that names `theta` reads it; on an angle master `theta` is the master.
#[test]
fn theta_is_read_by_name_on_a_time_master_and_is_the_master_on_an_angle_master() {
    let scratch = physid_testkit::Scratch::new("physid-mdf-theta");
    let mut r = Recording::new(Basis::CrankAngle);
    let theta: Vec<f64> = (0..1440).map(|k| (k as f64).to_radians()).collect();
    for (name, unit, values) in [
        (
            "t",
            "s",
            theta.iter().map(|th| th / 150.0).collect::<Vec<_>>(),
        ),
        ("theta", "rad", theta.clone()),
        ("cycle", "-", (0..1440).map(|k| (k / 720) as f64).collect()),
        (
            "crank_deg",
            "deg",
            (0..1440).map(|k| (k % 720) as f64).collect(),
        ),
        ("p_cyl", "Pa", theta.iter().map(|th| 1e5 + th).collect()),
    ] {
        r.push(Channel {
            name: name.into(),
            unit: unit.into(),
            values,
        })
        .unwrap();
    }
    let f = scratch.file("deg.mf4");
    write_mdf(&f, &r, MdfCompression::None, None).unwrap();
    let names: Vec<String> = ["t", "theta", "p_cyl"].map(String::from).to_vec();
    let got = read_mdf(&f, Some(&names)).unwrap();
    assert_eq!(got.basis, Basis::CrankAngle);
    assert_eq!(got.names(), ["t", "theta", "p_cyl"]);
    assert_eq!(got.values("theta").unwrap(), &theta[..]);
    let missing: Vec<String> = ["t", "theta"].map(String::from).to_vec();
    let e = read_mdf(dir().join("time_plain.mf4"), Some(&missing))
        .unwrap_err()
        .to_string();
    assert!(e.contains("no channel 'theta'"), "{e}");
    let angle: Vec<String> = ["theta", "p_cyl"].map(String::from).to_vec();
    let a = read_mdf(dir().join("angle.mf4"), Some(&angle)).unwrap();
    assert_eq!(a.names(), ["theta", "p_cyl"]);
}
