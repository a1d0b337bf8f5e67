//! Reading a chunk at a time ([`ChunkReader`]) gives what the whole-file readers give, bit for
//! bit, in every format: the files other tools wrote (pandas, pyarrow, asammdf — plain,
//! compressed, angle master), and files physid wrote that span many chunks, with a selection,
//! a channel map and unit conversion. Chunks never exceed [`CHUNK_ROWS`].
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_core::{Basis, Channel, Recording};
use physid_io::{
    read, read_csv, read_mdf, read_parquet, write, ChunkReader, CsvOptions, ReadOptions,
    WriteOptions, CHUNK_ROWS,
};
use physid_testkit::Scratch;
use std::path::{Path, PathBuf};

fn golden(sub: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/golden")
        .join(sub)
}

fn same_values(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len()
        && a.iter()
            .zip(b)
            .all(|(x, y)| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()))
}

fn assert_same(got: &Recording, want: &Recording, what: &str) {
    assert_eq!(got.names(), want.names(), "{what}");
    assert_eq!(got.basis, want.basis, "{what}");
    for (g, w) in got.channels().iter().zip(want.channels()) {
        assert_eq!(g.unit, w.unit, "{what} {}", g.name);
        assert!(same_values(&g.values, &w.values), "{what} {}", g.name);
    }
}

/// Drain a reader chunk by chunk, checking each chunk's size and channels.
fn drained(path: &Path, opts: &ReadOptions) -> (Recording, usize) {
    let mut r = ChunkReader::open(path, opts).unwrap();
    let mut rec = r.header().clone();
    let mut cols: Vec<Vec<f64>> = vec![Vec::new(); rec.channels().len()];
    let mut chunks = 0;
    while let Some(chunk) = r.next_chunk().unwrap() {
        assert!(chunk.len() <= CHUNK_ROWS && !chunk.is_empty());
        assert_eq!(chunk.names(), rec.names());
        assert_eq!(chunk.basis, rec.basis);
        for (c, ch) in cols.iter_mut().zip(chunk.channels()) {
            c.extend_from_slice(&ch.values);
        }
        chunks += 1;
    }
    assert_eq!(r.rows_read(), cols.first().map_or(0, Vec::len));
    let header = std::mem::replace(&mut rec, Recording::new(Basis::Time));
    rec.basis = header.basis;
    rec.meta = r.header().meta.clone();
    for (c, values) in header.channels().iter().zip(cols) {
        rec.push(Channel {
            name: c.name.clone(),
            unit: c.unit.clone(),
            values,
        })
        .unwrap();
    }
    (rec, chunks)
}

#[test]
fn other_tools_files_read_in_chunks_as_whole() {
    let raw = ReadOptions {
        keep_units: true,
        ..Default::default()
    };
    for name in [
        "time_plain",
        "time_deflate",
        "time_transposed",
        "angle",
        "physid_written",
        "physid_written_deflate",
        "physid_written_transposed",
    ] {
        let f = golden("mdf").join(format!("{name}.mf4"));
        let (rec, _) = drained(&f, &raw);
        let mut want = read_mdf(&f, None).unwrap();
        want.basis = physid_io::basis_by_channels(&want);
        assert_same(&rec, &want, name);
        assert_eq!(rec.meta.get("master"), want.meta.get("master"), "{name}");
        // A selection: the master first, then the channels asked for, in that order.
        let names: Vec<String> = want.names()[1..]
            .iter()
            .rev()
            .map(|s| s.to_string())
            .collect();
        let (sub, _) = drained(
            &f,
            &ReadOptions {
                channels: Some(names.clone()),
                keep_units: true,
                ..Default::default()
            },
        );
        let want = read_mdf(&f, Some(&names)).unwrap();
        assert_same(&sub, &want, name);
    }
    for name in ["pyarrow_written", "physid_written", "tiny"] {
        let f = golden("parquet").join(format!("{name}.parquet"));
        let (rec, _) = drained(&f, &raw);
        let mut want = read_parquet(&f, None).unwrap();
        want.basis = physid_io::basis_by_channels(&want);
        assert_same(&rec, &want, name);
    }
    let f = golden("csv").join("physid_written.csv");
    let (rec, _) = drained(&f, &raw);
    let mut want = read_csv(&f, &CsvOptions::default()).unwrap();
    want.basis = physid_io::basis_by_channels(&want);
    assert_same(&rec, &want, "csv");
    assert_eq!(rec.meta["first_data_line"], want.meta["first_data_line"]);
}

/// 200 003 samples (four chunks and a bit) of a time recording with a unit to convert.
fn long_recording() -> Recording {
    let n = 3 * CHUNK_ROWS + 3 * 1000 + 3;
    let mut r = Recording::new(Basis::Time);
    let t: Vec<f64> = (0..n).map(|i| i as f64 * 1e-4).collect();
    let rpm: Vec<f64> = t.iter().map(|x| 1500.0 + 30.0 * (7.0 * x).sin()).collect();
    let tq: Vec<f64> = t
        .iter()
        .map(|x| 40.0 * (55.0 * x).cos() + 1.0 / 3.0)
        .collect();
    let count: Vec<f64> = (0..n).map(|i| (i / 7) as f64).collect();
    for (name, unit, values) in [
        ("t", "s", t),
        ("omega_en", "rpm", rpm),
        ("Torque", "N*m", tq),
        ("count_en", "-", count),
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
fn long_files_stream_in_bounded_chunks_with_selection_map_and_units() {
    let s = Scratch::new("physid-io-chunks");
    let rec = long_recording();
    for ext in ["csv", "parquet", "mf4"] {
        let f = s.file(&format!("long.{ext}"));
        write(&f, &rec, &WriteOptions::default()).unwrap();
        // Everything, brought to SI: rpm → rad/s on every chunk.
        let all = ReadOptions::default();
        let (got, chunks) = drained(&f, &all);
        assert!(chunks >= 4, "{ext}: {chunks} chunks");
        assert_same(&got, &read(&f, &all).unwrap(), ext);
        let w = got.values("omega_en").unwrap();
        let rpm = rec.values("omega_en").unwrap();
        assert_eq!(got.channel("omega_en").unwrap().unit, "rad/s");
        assert!(w
            .iter()
            .zip(rpm)
            .all(|(a, b)| (a - b * std::f64::consts::PI / 30.0).abs() < 1e-12 * a.abs()));
        assert!(got.meta["units_converted"].contains("omega_en: rpm → rad/s"));
        // Two channels, in the order asked, one of them mapped from the file's name.
        let opts = ReadOptions {
            channels: Some(vec!["torque_shaft".into(), "t".into()]),
            map: ReadOptions::parse_map(&["torque_shaft=Torque".into()]).unwrap(),
            ..Default::default()
        };
        let (sub, _) = drained(&f, &opts);
        let whole = read(&f, &opts).unwrap();
        assert_same(&sub, &whole, ext);
        let mut names = sub.names();
        names.sort_unstable();
        assert_eq!(names, ["t", "torque_shaft"], "{ext}");
        assert!(same_values(
            sub.values("torque_shaft").unwrap(),
            rec.values("Torque").unwrap()
        ));
        assert!(same_values(
            sub.values("t").unwrap(),
            rec.values("t").unwrap()
        ));
    }
}

#[test]
fn errors_in_a_later_chunk_name_the_line_and_stop_the_stream() {
    let s = Scratch::new("physid-io-chunks");
    let f = s.file("bad.csv");
    let mut text = String::from("t,x\n");
    for i in 0..(CHUNK_ROWS + 10) {
        text.push_str(&format!("{i},1.5\n"));
    }
    text.push_str("99,abc\n");
    std::fs::write(&f, text).unwrap();
    let mut r = ChunkReader::open(&f, &ReadOptions::default()).unwrap();
    assert_eq!(r.next_chunk().unwrap().unwrap().len(), CHUNK_ROWS);
    let e = r.next_chunk().unwrap_err().to_string();
    assert!(
        e.contains(&format!("line {}", CHUNK_ROWS + 12)) && e.contains("'abc'"),
        "{e}"
    );
    // A column not asked for is not parsed: the rest of the file reads.
    let (only_t, _) = drained(
        &f,
        &ReadOptions {
            channels: Some(vec!["t".into()]),
            ..Default::default()
        },
    );
    assert_eq!(only_t.len(), CHUNK_ROWS + 11);
    // A missing channel is refused on opening, naming what there is.
    let e = ChunkReader::open(
        &f,
        &ReadOptions {
            channels: Some(vec!["omega_en".into()]),
            ..Default::default()
        },
    )
    .err()
    .unwrap()
    .to_string();
    assert!(e.contains("omega_en") && e.contains("t, x"), "{e}");
}

/// Threads of this process named like the MDF reader's (Linux: `/proc/self/task/*/comm`).
fn mdf_reader_threads() -> usize {
    std::fs::read_dir("/proc/self/task")
        .map(|d| {
            d.filter_map(Result::ok)
                .filter(|e| {
                    std::fs::read_to_string(e.path().join("comm"))
                        .is_ok_and(|c| c.starts_with("physid-mdf-rea"))
                })
                .count()
        })
        .unwrap_or(0)
}

#[test]
fn a_reader_dropped_midway_stops_its_mdf_thread() {
    let s = Scratch::new("physid-io-chunks");
    let f = s.file("long.mf4");
    write(&f, &long_recording(), &WriteOptions::default()).unwrap();
    for _ in 0..20 {
        let mut r = ChunkReader::open(&f, &ReadOptions::default()).unwrap();
        assert!(r.next_chunk().unwrap().is_some());
        drop(r);
    }
    // Every reading thread ends once its reader is gone (other tests' readers, drained, end
    // too): none is left waiting to hand over a chunk nobody takes.
    let start = std::time::Instant::now();
    while mdf_reader_threads() > 0 && start.elapsed().as_secs() < 20 {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    assert_eq!(mdf_reader_threads(), 0);
    assert_eq!(
        read(&f, &ReadOptions::default()).unwrap().len(),
        long_recording().len()
    );
}

#[test]
fn an_mdf_file_of_several_channel_groups_reads_by_its_first_groups_master() {
    // asammdf wrote three groups: omega_en and torque_shaft on one 1 kHz time base (in two
    // groups), T_oil at 10 Hz (`gen_asammdf.py --groups`).
    let f = golden("mdf").join("groups.mf4");
    let e: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(golden("mdf").join("expected_groups.json")).unwrap(),
    )
    .unwrap();
    let floats = |k: &str| -> Vec<f64> {
        e[k].as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let all = ReadOptions::default();
    let (rec, _) = drained(&f, &all);
    assert_eq!(rec.names(), ["t", "omega_en", "torque_shaft"]);
    assert_eq!(rec.meta["skipped"], "T_oil");
    for k in ["t", "omega_en", "torque_shaft"] {
        assert!(same_values(rec.values(k).unwrap(), &floats(k)), "{k}");
    }
    assert_same(&read(&f, &all).unwrap(), &rec, "groups");
    // One channel of the slow group: on its own master.
    let (slow, _) = drained(
        &f,
        &ReadOptions {
            channels: Some(vec!["T_oil".into()]),
            ..Default::default()
        },
    );
    assert_eq!(slow.names(), ["t", "T_oil"]);
    assert!(same_values(slow.values("t").unwrap(), &floats("slow_t")));
    assert!(same_values(slow.values("T_oil").unwrap(), &floats("T_oil")));
    // Channels of two time bases asked for together: refused, saying why.
    let e = ChunkReader::open(
        &f,
        &ReadOptions {
            channels: Some(vec!["omega_en".into(), "T_oil".into()]),
            ..Default::default()
        },
    )
    .err()
    .unwrap()
    .to_string();
    assert!(e.contains("different time bases"), "{e}");
}

/// Channel groups on one time base are read side by side, a window of each at a time, not
/// whole: a file of five groups longer than two reader chunks (written here with
/// `falcon_mdf`'s writer). The second group's times are the first's: its channel is read,
/// its `a` skipped as a duplicate; the third's are shifted by a microsecond, the fourth's
/// differ only after the first window, the fifth is slow: skipped, named. The values are
/// those written, bit for bit, in chunks as whole; asked for by name, a channel of the
/// second group comes with the first's, one of the fourth is refused.
#[test]
fn channel_groups_on_one_time_base_are_read_side_by_side_in_windows() {
    let s = Scratch::new("physid-mdf-groups");
    let n = 2 * CHUNK_ROWS + 123;
    let t: Vec<f64> = (0..n).map(|i| i as f64 * 1e-4).collect();
    let wave = |k: f64| -> Vec<f64> { (0..n).map(|i| (i as f64 * k).sin() * 10.0).collect() };
    let (a, b, c, d, x) = (wave(1e-3), wave(2e-3), wave(3e-3), wave(4e-3), wave(5e-3));
    let shifted: Vec<f64> = t.iter().map(|v| v + 1e-6).collect();
    let mut late = t.clone();
    for v in &mut late[CHUNK_ROWS + 7..] {
        *v += 1e-6;
    }
    let slow_t: Vec<f64> = (0..10).map(|i| i as f64 * 0.1).collect();
    let slow: Vec<f64> = (0..10).map(|i| 350.0 + i as f64).collect();
    let mut w = falcon_mdf::Mf4Writer::with_start_time_ns(1_700_000_000_000_000_000);
    let g = w.add_group(&t).unwrap();
    g.add_channel("a", "V", &a).unwrap();
    g.add_channel("b", "N*m", &b).unwrap();
    let g = w.add_group(&t).unwrap();
    g.add_channel("c", "rad/s", &c).unwrap();
    g.add_channel("a", "V", &x).unwrap();
    let g = w.add_group(&shifted).unwrap();
    g.add_channel("d", "K", &d).unwrap();
    let g = w.add_group(&late).unwrap();
    g.add_channel("late", "K", &d).unwrap();
    let g = w.add_group(&slow_t).unwrap();
    g.add_channel("T_oil", "K", &slow).unwrap();
    let f = s.file("groups.mf4");
    w.write_to_file(&f).unwrap();

    let all = ReadOptions::default();
    let (rec, chunks) = drained(&f, &all);
    assert!(chunks >= 3, "{chunks}");
    assert_eq!(rec.names(), ["t", "a", "b", "c"]);
    assert_eq!(rec.meta["skipped"], "a (duplicate name), d, late, T_oil");
    for (name, unit, want) in [
        ("t", "s", &t),
        ("a", "V", &a),
        ("b", "N*m", &b),
        ("c", "rad/s", &c),
    ] {
        assert_eq!(rec.channel(name).unwrap().unit, unit, "{name}");
        assert!(same_values(rec.values(name).unwrap(), want), "{name}");
    }
    assert_same(&read(&f, &all).unwrap(), &rec, "whole");
    assert_same(&read_mdf(&f, None).unwrap(), &rec, "read_mdf");
    // By name: across the two groups of one time base, in the order asked.
    let asked = ReadOptions {
        channels: Some(vec!["c".into(), "b".into()]),
        ..Default::default()
    };
    let (got, _) = drained(&f, &asked);
    assert_eq!(got.names(), ["t", "c", "b"]);
    assert!(same_values(got.values("c").unwrap(), &c));
    assert!(same_values(got.values("b").unwrap(), &b));
    for other in ["late", "d"] {
        let e = ChunkReader::open(
            &f,
            &ReadOptions {
                channels: Some(vec!["a".into(), other.into()]),
                ..Default::default()
            },
        )
        .err()
        .unwrap()
        .to_string();
        assert!(
            e.contains("different time bases") && e.contains("samples each, at different times"),
            "{other}: {e}"
        );
    }
}
