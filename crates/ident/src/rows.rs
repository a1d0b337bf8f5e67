//! The rows an analysis goes over: [`Data`], columns held in memory, or any [`Rows`] — rows
//! that can be gone over again, in order, a chunk at a time (a file read once per pass: a
//! [`Reopen`] of [`DataRows`]). The
//! batch analyses ([`analyse`](crate::analyse), [`fit_subset`](crate::fit_subset), the Wu
//! criterion) fold each row into O(p²) state, so over a source that reads its file again on
//! every pass they run in memory independent of the recording's length.

use crate::IdentError;
use physid_core::{ChunkKind, ParamModel, Reopen};

/// Columns of data: one slice per model input (in the model's input order), all the same
/// length, and optionally the measured output.
#[derive(Debug, Clone)]
pub struct Data<'a> {
    /// Input columns.
    pub inputs: Vec<&'a [f64]>,
    /// Measured output, if any.
    pub y: Option<&'a [f64]>,
}

impl<'a> Data<'a> {
    /// Number of rows; checks that every column has it and that there are as many input columns
    /// as the model has inputs.
    pub fn rows<M: ParamModel>(&self, model: &M) -> Result<usize, IdentError> {
        match self.len(model)? {
            0 => Err(IdentError::Invalid("no data rows".into())),
            n => Ok(n),
        }
    }

    /// Number of rows, which may be 0 (a chunk); the shape checked as by [`rows`](Self::rows).
    fn len<M: ParamModel>(&self, model: &M) -> Result<usize, IdentError> {
        let names = model.input_names();
        if self.inputs.len() != names.len() {
            return Err(IdentError::Invalid(format!(
                "the model has {} inputs ({}), the data {} columns",
                names.len(),
                names.join(", "),
                self.inputs.len()
            )));
        }
        let n = self
            .inputs
            .first()
            .map(|c| c.len())
            .or(self.y.map(|y| y.len()))
            .unwrap_or(0);
        for (c, name) in self.inputs.iter().zip(names) {
            if c.len() != n {
                return Err(IdentError::Invalid(format!(
                    "column '{name}' has {} rows, expected {n}",
                    c.len()
                )));
            }
        }
        if let Some(y) = self.y {
            if y.len() != n {
                return Err(IdentError::Invalid(format!(
                    "the output column has {} rows, expected {n}",
                    y.len()
                )));
            }
        }
        Ok(n)
    }

    /// Row `i`'s inputs into `u`; an error names a non-finite value's column and row.
    pub fn row<M: ParamModel>(&self, model: &M, i: usize, u: &mut [f64]) -> Result<(), IdentError> {
        for (k, (c, slot)) in self.inputs.iter().zip(u.iter_mut()).enumerate() {
            let v = c[i];
            if !v.is_finite() {
                return Err(IdentError::BadValue {
                    row: i,
                    column: model.input_names()[k].clone(),
                    value: v,
                });
            }
            *slot = v;
        }
        Ok(())
    }

    /// The measured output at row `i`, checked.
    pub fn y_at(&self, i: usize) -> Result<Option<f64>, IdentError> {
        match self.y {
            Some(y) if !y[i].is_finite() => Err(IdentError::BadValue {
                row: i,
                column: "output".into(),
                value: y[i],
            }),
            Some(y) => Ok(Some(y[i])),
            None => Ok(None),
        }
    }
}

/// The chunks of [`Rows`]: a [`Data`] borrowing the pass's buffers.
#[derive(Debug, Clone, Copy)]
pub struct DataRows;

impl ChunkKind for DataRows {
    type Chunk<'c> = &'c Data<'c>;
}

/// Rows that can be gone over more than once, in the same order each time, a chunk at a time
/// ([`Reopen`] of [`Data`] chunks; chunks may be empty).
pub trait Rows: Reopen<DataRows, IdentError> {
    /// Whether the rows carry the measured output (they do unless they say otherwise).
    fn has_y(&self) -> bool {
        true
    }
}

impl Rows for Data<'_> {
    fn has_y(&self) -> bool {
        self.y.is_some()
    }
}

impl Reopen<DataRows, IdentError> for Data<'_> {
    fn pass(
        &self,
        visit: &mut dyn for<'c> FnMut(&'c Data<'c>) -> Result<(), IdentError>,
    ) -> Result<(), IdentError> {
        visit(self)
    }
}

/// One pass over `rows`: `each(i, u, y)` for every row in order, `i` counted from the first row
/// of the pass, `u` the model's inputs and `y` the measured output (both checked finite; an
/// error names the row). Returns the number of rows; none is an error.
pub fn for_each_row<M: ParamModel, R: Rows + ?Sized>(
    model: &M,
    rows: &R,
    mut each: impl FnMut(usize, &[f64], Option<f64>) -> Result<(), IdentError>,
) -> Result<usize, IdentError> {
    let mut u = vec![0.0; model.input_names().len()];
    let mut n = 0;
    rows.pass(&mut |chunk| {
        let shift = |e: IdentError| match e {
            IdentError::BadValue { row, column, value } => IdentError::BadValue {
                row: row + n,
                column,
                value,
            },
            e => e,
        };
        for i in 0..chunk.len(model)? {
            chunk.row(model, i, &mut u).map_err(shift)?;
            let y = chunk.y_at(i).map_err(shift)?;
            each(n + i, &u, y)?;
        }
        n += chunk.len(model)?;
        Ok(())
    })?;
    if n == 0 {
        return Err(IdentError::Invalid("no data rows".into()));
    }
    Ok(n)
}
