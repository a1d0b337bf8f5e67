//! The analyses over rows given in chunks, as a file read again on every pass gives them: the
//! same ranking, fits, Wu criterion and identification as over the columns held whole (bit
//! for bit — every analysis folds its rows in order), and an error's row counted from the first
//! row of the recording, not of its chunk.
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_core::Reopen;
use physid_expr::ExprModel;
use physid_ident::*;
use std::cell::Cell;

/// Columns handed over in chunks of the given sizes (cycled), counting the passes.
struct Chunked<'a> {
    x: &'a [f64],
    y: Option<&'a [f64]>,
    sizes: &'a [usize],
    passes: Cell<usize>,
}

impl Rows for Chunked<'_> {
    fn has_y(&self) -> bool {
        self.y.is_some()
    }
}

impl Reopen<DataRows, IdentError> for Chunked<'_> {
    fn pass(
        &self,
        visit: &mut dyn for<'c> FnMut(&'c Data<'c>) -> Result<(), IdentError>,
    ) -> Result<(), IdentError> {
        self.passes.set(self.passes.get() + 1);
        let mut at = 0;
        for &size in self.sizes.iter().cycle() {
            if at >= self.x.len() {
                break;
            }
            let end = (at + size).min(self.x.len());
            visit(&Data {
                inputs: vec![&self.x[at..end]],
                y: self.y.map(|y| &y[at..end]),
            })?;
            at = end;
        }
        Ok(())
    }
}

fn signal() -> (Vec<f64>, Vec<f64>) {
    let t: Vec<f64> = (0..300).map(|i| i as f64 * 0.02).collect();
    let y = t
        .iter()
        .enumerate()
        .map(|(i, t)| {
            2.0 * (-0.8 * t).exp()
                + 0.3 * t
                + 0.01 * ((i * 7919 % 1000) as f64 / 1000.0 - 0.5) * 3.46
        })
        .collect();
    (t, y)
}

#[test]
fn chunked_rows_give_what_the_whole_columns_give() {
    let m = ExprModel::parse("A*exp(-B*t) + C*t + D*t^2", &["A", "B", "C", "D"]).unwrap();
    let (t, y) = signal();
    let whole = Data {
        inputs: vec![&t],
        y: Some(&y),
    };
    let nominal = [2.0, 0.8, 0.3, 0.01];
    let want = identify(
        &m,
        &whole,
        &nominal,
        &[],
        IdentConfig {
            centre: true,
            ..IdentConfig::default()
        },
        Selection::Wu { sigma2: None },
        None,
    )
    .unwrap();
    let want_json = serde_json::to_value(want.report()).unwrap();
    for sizes in [&[1][..], &[0, 7, 1, 0, 13], &[299], &[300], &[1000]] {
        let chunked = Chunked {
            x: &t,
            y: Some(&y),
            sizes,
            passes: Cell::new(0),
        };
        let got = identify(
            &m,
            &chunked,
            &nominal,
            &[],
            IdentConfig {
                centre: true,
                ..IdentConfig::default()
            },
            Selection::Wu { sigma2: None },
            None,
        )
        .unwrap();
        assert_eq!(
            serde_json::to_value(got.report()).unwrap(),
            want_json,
            "chunks {sizes:?}"
        );
        // The output's level, the factors, then Gauss–Newton passes for each K of Wu's
        // criterion and for the final fit: the rows were gone over many times, none held.
        assert!(chunked.passes.get() > 10, "{}", chunked.passes.get());
        let fit = fit_subset(&m, &chunked, &[1.5, 1.0, 0.2, 0.0], &[0, 1, 2], 50).unwrap();
        let fit_whole = fit_subset(&m, &whole, &[1.5, 1.0, 0.2, 0.0], &[0, 1, 2], 50).unwrap();
        assert_eq!(fit.theta, fit_whole.theta);
        assert_eq!(fit.rss, fit_whole.rss);
        assert_eq!(fit.iterations, fit_whole.iterations);
    }
}

#[test]
fn an_error_in_a_chunk_names_the_recordings_row() {
    let m = ExprModel::parse("A*exp(-B*t) + C*t", &["A", "B", "C"]).unwrap();
    let (mut t, mut y) = signal();
    t[123] = f64::NAN;
    let chunked = Chunked {
        x: &t,
        y: Some(&y),
        sizes: &[50],
        passes: Cell::new(0),
    };
    let e = analyse(&m, &chunked, &[2.0, 0.8, 0.3], &[], IdentConfig::default()).unwrap_err();
    assert!(
        matches!(&e, IdentError::BadValue { row: 123, column, .. } if column == "t"),
        "{e:?}"
    );
    t[123] = 1.0;
    y[251] = f64::INFINITY;
    let chunked = Chunked {
        x: &t,
        y: Some(&y),
        sizes: &[50],
        passes: Cell::new(0),
    };
    let e = fit_subset(&m, &chunked, &[2.0, 0.8, 0.3], &[0, 1], 5).unwrap_err();
    assert!(
        matches!(&e, IdentError::BadValue { row: 251, column, .. } if column == "output"),
        "{e:?}"
    );
    // No rows at all: said.
    let empty = Chunked {
        x: &[],
        y: Some(&[]),
        sizes: &[10],
        passes: Cell::new(0),
    };
    let e = analyse(&m, &empty, &[2.0, 0.8, 0.3], &[], IdentConfig::default()).unwrap_err();
    assert_eq!(e.to_string(), "no data rows");
}
