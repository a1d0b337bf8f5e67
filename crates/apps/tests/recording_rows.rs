//! A file's columns gone over in passes ([`RecordingRows`]): held after the first pass within the
//! limit, read again on every pass beyond it; the same chunks' values either way, equal to the
//! file read whole; a file that changes under a pass read again is caught, not absorbed.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_apps::recording_rows::{Column, RecordingRows};
use physid_core::Reopen;
use physid_core::{Basis, Channel, Recording};
use physid_ident::{for_each_row, Data, DataRows, IdentError, Rows};
use physid_testkit::Scratch;

fn recording(n: usize) -> Recording {
    let mut rec = Recording::new(Basis::Time);
    for (name, unit, k) in [
        ("t", "s", 1e-4),
        ("omega_en", "rad/s", 0.5),
        ("torque_shaft", "N m", 3.0),
    ] {
        rec.push(Channel {
            name: name.into(),
            unit: unit.into(),
            values: (0..n).map(|i| k * i as f64).collect(),
        })
        .unwrap();
    }
    rec
}

/// A one-input model over `omega_en`, only to walk the rows.
fn walk() -> physid_expr::ExprModel {
    physid_expr::ExprModel::parse("A*omega_en", &["A"]).unwrap()
}

fn rows_of(rows: &RecordingRows) -> (Vec<f64>, Vec<f64>) {
    let (mut u, mut y) = (Vec::new(), Vec::new());
    for_each_row(&walk(), rows, |_, row, out| {
        u.push(row[0]);
        y.push(out.unwrap());
        Ok(())
    })
    .unwrap();
    (u, y)
}

#[test]
fn held_within_the_limit_read_again_beyond_it_the_same_rows() {
    let s = Scratch::new("physid-file-rows");
    let n = physid_io::CHUNK_ROWS * 2 + 11;
    let rec = recording(n);
    let want_u: Vec<f64> = rec.values("omega_en").unwrap().to_vec();
    // Converted on reading (`CHANNEL:UNIT`).
    let want_rpm: Vec<f64> = rec.values_in("omega_en", "rpm").unwrap();
    let want_y = rec.values("torque_shaft").unwrap().to_vec();
    for ext in ["csv", "parquet", "mf4"] {
        let path = s.file(&format!("r.{ext}"));
        physid_io::write(&path, &rec, &Default::default()).unwrap();
        // What is held is the channels read: the two columns, and an MDF4 file's time master.
        let open = |hold| {
            RecordingRows::file(
                &path,
                &Default::default(),
                vec![Column::named("omega_en")],
                Some(Column::named("torque_shaft")),
                &[],
                hold,
            )
            .unwrap()
        };
        let bytes = n * 8 * open(0).header().channels().len();
        assert_eq!(bytes, n * 8 * if ext == "mf4" { 3 } else { 2 }, "{ext}");
        for (hold, held) in [
            (usize::MAX, true),
            (bytes, true),
            (bytes - 1, false),
            (0, false),
        ] {
            let rows = open(hold);
            assert!(rows.has_y());
            for pass in 0..3 {
                let (u, y) = rows_of(&rows);
                assert_eq!(rows.held(), held, "{ext}, hold {hold}, pass {pass}");
                assert_eq!(u, want_u, "{ext}, hold {hold}, pass {pass}");
                assert_eq!(y, want_y, "{ext}, hold {hold}, pass {pass}");
            }
        }
        let rows = RecordingRows::file(
            &path,
            &Default::default(),
            vec![Column::parse("omega_en:rpm")],
            Some(Column::named("torque_shaft")),
            &[],
            0,
        )
        .unwrap();
        let (u, _) = rows_of(&rows);
        for (a, b) in u.iter().zip(&want_rpm) {
            assert_eq!(a, b, "{ext}");
        }
    }
}

/// Rows whose file is rewritten, shorter, after their first pass.
struct Shortened<'a> {
    rows: &'a RecordingRows<'a>,
    path: &'a std::path::Path,
    passes: std::cell::Cell<usize>,
}

impl Rows for Shortened<'_> {
    fn has_y(&self) -> bool {
        self.rows.has_y()
    }
}

impl Reopen<DataRows, IdentError> for Shortened<'_> {
    fn pass(
        &self,
        visit: &mut dyn for<'c> FnMut(&'c Data<'c>) -> Result<(), IdentError>,
    ) -> Result<(), IdentError> {
        let r = self.rows.pass(visit);
        if self.passes.replace(self.passes.get() + 1) == 0 {
            physid_io::write(self.path, &recording(4000), &Default::default()).unwrap();
        }
        r
    }
}

#[test]
fn a_file_that_changes_between_passes_is_caught_and_a_missing_channel_named() {
    let s = Scratch::new("physid-file-rows-change");
    let path = s.file("r.parquet");
    physid_io::write(&path, &recording(5000), &Default::default()).unwrap();
    let rows = RecordingRows::file(
        &path,
        &Default::default(),
        vec![Column::named("omega_en")],
        Some(Column::named("torque_shaft")),
        &[],
        0,
    )
    .unwrap();
    let shortened = Shortened {
        rows: &rows,
        path: &path,
        passes: Default::default(),
    };
    let e =
        physid_ident::analyse(&walk(), &shortened, &[1.0], &[], Default::default()).unwrap_err();
    assert_eq!(
        e.to_string(),
        "the data gave 4000 rows on a second pass, 5000 on the first"
    );
    let e = RecordingRows::file(
        &path,
        &Default::default(),
        vec![Column::named("omega_dy")],
        None,
        &[],
        0,
    )
    .err()
    .unwrap()
    .to_string();
    assert!(e.contains("r.parquet") && e.contains("omega_dy"), "{e}");
}
