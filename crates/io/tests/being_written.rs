//! A file being written is its writer's alone (`physid_io`'s `lock` module): while a
//! [`ChunkWriter`] holds it, another writer does not empty it, a whole write does not replace
//! it, `recover` and `settle` do not cut it, and a reader that cannot read it yet says that it
//! is being written — and once its writer closes it, every sample it was given is there, in
//! all three formats.
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_core::{Basis, Channel, Recording};
use physid_io::{
    read, recover_csv, recover_parquet, settle_mdf, write, ChunkWriter, IoError, WriteOptions,
};
use physid_testkit::Scratch;
use std::path::Path;

/// `n` samples from sample `from` on: `t` and one channel.
fn chunk(from: usize, n: usize) -> Recording {
    let mut r = Recording::new(Basis::Time);
    let t: Vec<f64> = (from..from + n).map(|i| i as f64 * 1e-4).collect();
    let x: Vec<f64> = t.iter().map(|t| (t * 50.0).sin()).collect();
    for (name, unit, values) in [("t", "s", t), ("x", "V", x)] {
        r.push(Channel {
            name: name.into(),
            unit: unit.into(),
            values,
        })
        .unwrap();
    }
    r
}

/// `r` is the refusal of a file being written, saying `says`.
fn being_written<T>(r: Result<T, IoError>, says: &str, what: &str) {
    match r {
        Err(e @ IoError::InUse { .. }) => {
            let m = e.to_string();
            assert!(m.contains("is being written"), "{what}: {m}");
            assert!(m.contains(says), "{what}: {m}");
        }
        Err(e) => panic!("{what}: expected the file being written refused, got {e}"),
        Ok(_) => panic!("{what}: the file being written was not refused"),
    }
}

/// `physid recover`'s mending of `path`, by its format.
fn mend(path: &Path) -> Result<(), IoError> {
    match path.extension().and_then(|e| e.to_str()) {
        Some("parquet") => recover_parquet(path).map(drop),
        Some("mf4") => settle_mdf(path).map(drop),
        _ => recover_csv(path).map(drop),
    }
}

#[test]
fn a_file_being_written_is_left_to_its_writer() {
    let s = Scratch::new("physid-being-written");
    for ext in ["parquet", "mf4", "csv"] {
        let path = s.file(&format!("log.{ext}"));
        let mut w = ChunkWriter::create(&path, &chunk(0, 0), &WriteOptions::default()).unwrap();
        w.append(&chunk(0, 70_000)).unwrap();
        w.commit().unwrap();
        let committed = std::fs::read(&path).unwrap();

        // Another writer, a whole write, a mend: refused, the file as it was.
        being_written(
            ChunkWriter::create(&path, &chunk(0, 0), &WriteOptions::default()),
            "not written over",
            ext,
        );
        being_written(
            write(&path, &chunk(0, 10), &WriteOptions::default()),
            "not replaced",
            ext,
        );
        being_written(mend(&path), "nothing to recover", ext);
        assert!(std::fs::read(&path).unwrap() == committed, "{ext}: changed");
        // A whole write refused leaves no staging file behind.
        let left: Vec<_> = std::fs::read_dir(s.file(""))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".partial"))
            .collect();
        assert!(left.is_empty(), "{ext}: {left:?}");

        // A reader: Parquet has no footer until the close, and says why; MDF4 and CSV read
        // what is committed.
        let r = read(&path, &Default::default());
        if ext == "parquet" {
            being_written(r, "not damaged", ext);
        } else {
            assert_eq!(r.unwrap().len(), 70_000, "{ext}");
        }

        // The writer goes on and closes: everything it was given.
        w.append(&chunk(70_000, 5_000)).unwrap();
        w.close().unwrap();
        let got = read(&path, &Default::default()).unwrap();
        assert_eq!(got.len(), 75_000, "{ext}");
        assert!(
            got.values("x").unwrap() == chunk(0, 75_000).values("x").unwrap(),
            "{ext}"
        );

        // Closed, it is anyone's: written over and mended as before.
        mend(&path).unwrap();
        write(&path, &chunk(0, 10), &WriteOptions::default()).unwrap();
        assert_eq!(read(&path, &Default::default()).unwrap().len(), 10, "{ext}");
        let mut again = ChunkWriter::create(&path, &chunk(0, 0), &WriteOptions::default()).unwrap();
        again.append(&chunk(0, 3)).unwrap();
        again.close().unwrap();
        assert_eq!(read(&path, &Default::default()).unwrap().len(), 3, "{ext}");
    }
}

/// A file nobody writes is not taken for one being written: a damaged Parquet file is said to
/// be damaged, a missing one missing.
#[test]
fn a_file_nobody_writes_is_not_said_to_be_written() {
    let s = Scratch::new("physid-not-written");
    let path = s.file("torn.parquet");
    write(&path, &chunk(0, 100_000), &WriteOptions::default()).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
    let e = read(&path, &Default::default()).unwrap_err();
    assert!(!matches!(e, IoError::InUse { .. }), "{e}");
    let e = read(Path::new(&s.file("none.parquet")), &Default::default()).unwrap_err();
    assert!(matches!(e, IoError::Os { .. }), "{e}");
}

/// A file being read is not written over by the same process — by its name or another (a
/// link, `./`): `convert run.parquet run.parquet` would have emptied the recording it reads.
/// Once its readers are gone it is written as any file.
#[test]
fn a_file_being_read_is_not_written_over() {
    let s = Scratch::new("physid-being-read");
    for ext in ["parquet", "mf4", "csv"] {
        let path = s.file(&format!("in.{ext}"));
        write(&path, &chunk(0, 1000), &WriteOptions::default()).unwrap();
        let link = s.file(&format!("link.{ext}"));
        std::os::unix::fs::symlink(&path, &link).unwrap();
        let before = std::fs::read(&path).unwrap();
        let reader = physid_io::ChunkReader::open(&path, &Default::default()).unwrap();
        let passes = physid_io::FileChunks::new(&path, Default::default());
        for out in [&path, &link, &s.file(&format!("./in.{ext}"))] {
            for r in [
                ChunkWriter::create(out, &chunk(0, 0), &WriteOptions::default()).map(drop),
                write(out, &chunk(0, 10), &WriteOptions::default()),
            ] {
                let e = r.expect_err(ext).to_string();
                assert!(e.contains("is also what this command reads"), "{ext}: {e}");
            }
        }
        assert!(std::fs::read(&path).unwrap() == before, "{ext}: changed");
        drop(reader);
        // The passes' reader still holds it.
        assert!(
            write(&path, &chunk(0, 10), &WriteOptions::default()).is_err(),
            "{ext}"
        );
        drop(passes);
        write(&path, &chunk(0, 10), &WriteOptions::default()).unwrap();
        assert_eq!(read(&path, &Default::default()).unwrap().len(), 10, "{ext}");
        // Read whole, then written: the reading is over.
        let whole = read(&path, &Default::default()).unwrap();
        write(&path, &whole, &WriteOptions::default()).unwrap();
    }
}
