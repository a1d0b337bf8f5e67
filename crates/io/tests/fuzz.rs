//! Mutation fuzzing of every reader, on stable Rust: committed seed files (CSV with units and
//! with `;` decimal commas, Parquet from pyarrow and from physid, MDF4 plain, deflate and
//! transposed from asammdf, and an angle-master file) are mutated byte-wise
//! ([`physid_testkit::fuzz::mutate`]: bit flips, interesting integers written over lengths and
//! counts (0, −1, 2³¹, 2³³, 2⁶⁰ …), a Thrift list claiming 2³¹ − 1 elements, bytes inserted,
//! deleted and duplicated, the file cut) with extra weight on the metadata at the end of a
//! Parquet file and the block headers at the start of an MDF4 file. The verbs themselves, run
//! as the `physid` binary on mutated recordings, are fuzzed by `crates/cli/tests/fuzz_verbs.rs`. Every case must
//! come back as a recording or an error: no panic, no hang (a watchdog), no memory blow-up
//! (peak resident memory checked at the end).
//!
//! CI runs `PHYSID_FUZZ_CASES` (default 400) cases per seed. The long run (docs/data.md
//! records its count and time):
//!
//! ```text
//! PHYSID_FUZZ_CASES=20000 cargo test --release -p physid-io --test fuzz -- --nocapture
//! ```
//!
//! A failing case is reproduced by its seed file and case number (the mutations are drawn
//! from a fixed-seed generator): `PHYSID_FUZZ_ONLY=file:case` (or `=file` for every case of
//! one seed). `PHYSID_FUZZ_SHOW=1` prints
//! the third-party decoders' panics the readers contained (to report upstream).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_io::{read, ReadOptions};
use physid_testkit::fuzz::{mutate, THRIFT_CLAIM as BOOL_LIST};
use physid_testkit::Scratch;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

struct Seed {
    name: &'static str,
    bytes: Vec<u8>,
    ext: &'static str,
    hot: std::ops::Range<usize>,
}

fn golden(rel: &str) -> Vec<u8> {
    std::fs::read(
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("tests/golden")
            .join(rel),
    )
    .unwrap()
}

fn seeds() -> Vec<Seed> {
    let tail = |b: &[u8], n: usize| b.len().saturating_sub(n)..b.len();
    let mut v = Vec::new();
    let csv = golden("csv/physid_written.csv");
    v.push(Seed {
        name: "csv/physid_written.csv",
        hot: 0..64.min(csv.len()),
        bytes: csv,
        ext: "csv",
    });
    let eu =
        b"Zeit;omega_en;p_int\r\ns;rpm;bar\r\n0,000;1000;0,95\r\n0,001;1500,5;1,013\r\n".to_vec();
    v.push(Seed {
        name: "csv/semicolon-decimal-comma",
        hot: 0..32,
        bytes: eu,
        ext: "csv",
    });
    for (name, ext) in [
        ("parquet/pyarrow_written.parquet", "parquet"),
        ("parquet/physid_written.parquet", "parquet"),
        ("parquet/tiny.parquet", "parquet"),
    ] {
        let b = golden(name);
        v.push(Seed {
            name,
            hot: tail(&b, 2048),
            bytes: b,
            ext,
        });
    }
    for name in [
        "mdf/time_plain.mf4",
        "mdf/time_deflate.mf4",
        "mdf/time_transposed.mf4",
        "mdf/angle.mf4",
    ] {
        let b = golden(name);
        v.push(Seed {
            name,
            hot: 0..4096.min(b.len()),
            bytes: b,
            ext: "mf4",
        });
    }
    v
}

/// Peak resident memory of this process [bytes] (`VmHWM`).
fn peak_rss() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let l = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    Some(l.split_whitespace().nth(1)?.parse::<u64>().ok()? * 1024)
}

/// Read one mutated file: 0 read as a recording, 1 refused, 2 refused after the third-party
/// decoder panicked (contained at the reader's boundary: worth reporting upstream).
fn one(path: &Path) -> usize {
    match read(path, &ReadOptions::default()) {
        Ok(_) => 0,
        Err(e) if e.to_string().contains("the decoder failed") => {
            if std::env::var("PHYSID_FUZZ_SHOW").is_ok() {
                println!("contained: {e}");
            }
            if let Ok(dir) = std::env::var("PHYSID_FUZZ_SAVE") {
                let name = path
                    .file_name()
                    .unwrap_or_default()
                    .to_string_lossy()
                    .to_string();
                let n = std::fs::read_dir(&dir).map_or(0, |d| d.count());
                std::fs::copy(path, Path::new(&dir).join(format!("{n:03}-{name}"))).unwrap();
            }
            2
        }
        Err(_) => 1,
    }
}

/// The inputs that made a third-party decoder panic (saved by `PHYSID_FUZZ_SAVE=DIR` from the
/// small seed `golden/parquet/tiny.parquet`): each stays a clear error.
#[test]
fn the_crashing_inputs_found_are_clear_errors() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz/crashes");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let e = read(&path, &ReadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("corrupt Parquet") || e.contains("Parquet:"),
            "{}: {e}",
            path.display()
        );
        n += 1;
    }
    assert!(n > 0, "no crash seeds in {}", dir.display());
}

#[test]
fn no_reader_panics_hangs_or_blows_up_on_mutated_files() {
    let cases: u64 = std::env::var("PHYSID_FUZZ_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(400);
    let only = std::env::var("PHYSID_FUZZ_ONLY").ok();
    let scratch = Scratch::new("physid-fuzz");
    for seed in seeds() {
        // PHYSID_FUZZ_ONLY=SEED:CASE runs one case, =SEED every case of one seed.
        let (from, to) = match only.as_deref().filter(|o| !o.is_empty()) {
            None => (0, cases),
            Some(o) => match o.rsplit_once(':') {
                Some((name, case)) if name == seed.name => {
                    let c: u64 = case.parse().unwrap();
                    (c, c + 1)
                }
                None if o == seed.name => (0, cases),
                _ => continue,
            },
        };
        let done = Arc::new(AtomicUsize::new(0));
        let ok = Arc::new(AtomicUsize::new(0));
        let caught = Arc::new(AtomicUsize::new(0));
        let path = scratch.file(&format!("case.{}", seed.ext));
        let worker = {
            let (done, ok, caught, path) = (done.clone(), ok.clone(), caught.clone(), path.clone());
            let (bytes, hot) = (seed.bytes.clone(), seed.hot.clone());
            std::thread::spawn(move || {
                for case in from..to {
                    std::fs::write(&path, mutate(&bytes, case, hot.clone())).unwrap();
                    match one(&path) {
                        0 => ok.fetch_add(1, Ordering::Relaxed),
                        2 => caught.fetch_add(1, Ordering::Relaxed),
                        _ => 0,
                    };
                    done.fetch_add(1, Ordering::Relaxed);
                }
            })
        };
        let t0 = Instant::now();
        let (mut last, mut since) = (usize::MAX, Instant::now());
        while !worker.is_finished() {
            std::thread::sleep(Duration::from_millis(20));
            let d = done.load(Ordering::Relaxed);
            if d != last {
                (last, since) = (d, Instant::now());
            }
            assert!(
                since.elapsed() < Duration::from_secs(20),
                "{}: case {} has run for 20 s (a hang): PHYSID_FUZZ_ONLY={}:{}",
                seed.name,
                from + d as u64,
                seed.name,
                from + d as u64
            );
        }
        if worker.join().is_err() {
            panic!(
                "{}: a reader panicked at case {} (PHYSID_FUZZ_ONLY={}:{})",
                seed.name,
                from + done.load(Ordering::Relaxed) as u64,
                seed.name,
                from + done.load(Ordering::Relaxed) as u64
            );
        }
        println!(
            "{:<34} {:>7} cases in {:>7.2} s: {:>6} read, the rest refused ({} after a decoder panic, contained)",
            seed.name,
            to - from,
            t0.elapsed().as_secs_f64(),
            ok.load(Ordering::Relaxed),
            caught.load(Ordering::Relaxed)
        );
    }
    if let Some(peak) = peak_rss() {
        println!("peak resident memory {:.0} MB", peak as f64 / 1e6);
        assert!(peak < 2_000_000_000, "peak resident memory {peak} bytes");
    }
}

#[test]
fn a_footer_claiming_a_trillion_rows_is_refused_before_allocating() {
    // physid's own Parquet file with the footer's row count patched to 10¹² (the count is an
    // i64 in the Thrift footer: found by its value, the file's real row count).
    let s = Scratch::new("physid-fuzz");
    let mut r = physid_core::Recording::new(physid_core::Basis::Time);
    r.push(physid_core::Channel {
        name: "x".into(),
        unit: String::new(),
        values: (0..777).map(f64::from).collect(),
    })
    .unwrap();
    let f = s.file("rows.parquet");
    physid_io::write_parquet(&f, &r).unwrap();
    let mut b = std::fs::read(&f).unwrap();
    // Thrift compact encoding of i64 777 as a zigzag varint: 1554 = 0x92 0x0C.
    let needle = [0x92u8, 0x0C];
    let footer_start =
        b.len() - 8 - u32::from_le_bytes(b[b.len() - 8..b.len() - 4].try_into().unwrap()) as usize;
    let at = (footer_start..b.len() - 1)
        .find(|&i| b[i..i + 2] == needle)
        .expect("the row count in the footer");
    // 10¹² zigzag = 2·10¹² as a varint (6 bytes): the footer grows by 4, so its length too.
    let mut v = 2_000_000_000_000u64;
    let mut varint = Vec::new();
    while v >= 0x80 {
        varint.push((v as u8) | 0x80);
        v >>= 7;
    }
    varint.push(v as u8);
    let grow = varint.len() - 2;
    b.splice(at..at + 2, varint);
    let n = b.len();
    let len = u32::from_le_bytes(b[n - 8..n - 4].try_into().unwrap()) + grow as u32;
    b[n - 8..n - 4].copy_from_slice(&len.to_le_bytes());
    std::fs::write(&f, &b).unwrap();
    let e = read(&f, &ReadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("the file claims 1000000000000 rows"), "{e}");
}

/// An MDF4 channel group claiming 10¹² cycles over 3 001 records (issue 41, item 3): read as it
/// comes, the 3 001 records are read and the mismatch is said, not passed over in silence.
#[test]
fn an_mdf4_cycle_count_the_records_do_not_bear_out_is_said() {
    let s = Scratch::new("physid-fuzz");
    let mut r = physid_core::Recording::new(physid_core::Basis::Time);
    for (name, unit) in [("t", "s"), ("x", "")] {
        r.push(physid_core::Channel {
            name: name.into(),
            unit: unit.into(),
            values: (0..3001).map(|k| f64::from(k) * 1e-3).collect(),
        })
        .unwrap();
    }
    let f = s.file("cycles.mf4");
    physid_io::write_mdf(&f, &r, physid_io::MdfCompression::None, None).unwrap();
    let mut b = std::fs::read(&f).unwrap();
    // The channel group block: "##CG", its link count at +16, then the links, the record id
    // (8 bytes) and the cycle count (u64).
    let cg = b.windows(4).position(|w| w == b"##CG").expect("a CG block");
    let links = u64::from_le_bytes(b[cg + 16..cg + 24].try_into().unwrap()) as usize;
    let at = cg + 24 + 8 * links + 8;
    assert_eq!(u64::from_le_bytes(b[at..at + 8].try_into().unwrap()), 3001);
    b[at..at + 8].copy_from_slice(&1_000_000_000_000u64.to_le_bytes());
    std::fs::write(&f, &b).unwrap();
    let mut reader = physid_io::ChunkReader::open(&f, &ReadOptions::default()).unwrap();
    let mut rows = 0;
    while let Some(c) = reader.next_chunk().unwrap() {
        rows += c.len();
    }
    assert_eq!(rows, 3001);
    let warning = reader
        .header()
        .meta
        .get("warning")
        .cloned()
        .unwrap_or_default();
    assert!(
        warning.contains("the file claims 1000000000000 rows but holds 3001"),
        "{warning}"
    );
}

fn small_parquet(s: &Scratch, name: &str) -> PathBuf {
    let mut r = physid_core::Recording::new(physid_core::Basis::Time);
    for name in ["t", "x", "y"] {
        r.push(physid_core::Channel {
            name: name.into(),
            unit: String::new(),
            values: (0..3001).map(|k| f64::from(k) * 1e-3).collect(),
        })
        .unwrap();
    }
    let f = s.file(name);
    physid_io::write_parquet(&f, &r).unwrap();
    f
}

/// Issue 41, item 1: page headers holding such lists (the fuzzed file that made `inspect` run
/// past a minute at 10 MB) are refused from their bytes, before the crate decodes them.
#[test]
fn a_page_header_claiming_more_than_its_bytes_is_refused_at_once() {
    let s = Scratch::new("physid-fuzz");
    let f = small_parquet(&s, "pages.parquet");
    let meta = parquet::file::serialized_reader::SerializedFileReader::new(
        std::fs::File::open(&f).unwrap(),
    )
    .unwrap();
    let at = parquet::file::reader::FileReader::metadata(&meta)
        .row_group(0)
        .column(1)
        .data_page_offset() as usize;
    let mut b = std::fs::read(&f).unwrap();
    for k in 0..4 {
        b[at + 9 * k..at + 9 * (k + 1)].copy_from_slice(&BOOL_LIST);
    }
    std::fs::write(&f, &b).unwrap();
    let e = read(&f, &ReadOptions::default()).unwrap_err().to_string();
    assert!(
        e.contains(&format!("the page header at byte {at} of column 'x'"))
            && e.contains("claims 2147483647 elements"),
        "{e}"
    );
    // The column not read is not looked at.
    let only_t = ReadOptions {
        channels: Some(vec!["t".into()]),
        ..ReadOptions::default()
    };
    assert_eq!(read(&f, &only_t).unwrap().len(), 3001);
}

/// The same claim in the footer (an unknown field of `FileMetaData`): refused, where the
/// crate would decode it for ≈ 8 s and accept it.
#[test]
fn a_footer_claiming_more_than_its_bytes_is_refused_at_once() {
    let s = Scratch::new("physid-fuzz");
    let f = small_parquet(&s, "footer.parquet");
    let mut b = std::fs::read(&f).unwrap();
    let n = b.len();
    // The footer's struct ends in its stop byte, just before the length and "PAR1".
    assert_eq!(b[n - 9], 0);
    b.splice(n - 9..n - 9, BOOL_LIST);
    let n = b.len();
    let len = u32::from_le_bytes(b[n - 8..n - 4].try_into().unwrap()) + BOOL_LIST.len() as u32;
    b[n - 8..n - 4].copy_from_slice(&len.to_le_bytes());
    std::fs::write(&f, &b).unwrap();
    let e = read(&f, &ReadOptions::default()).unwrap_err().to_string();
    assert!(
        e.contains("the footer") && e.contains("claims 2147483647 elements"),
        "{e}"
    );
}
