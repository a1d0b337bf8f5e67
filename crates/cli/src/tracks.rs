//! `--tracks FILE`: what a verb tracks — time, each estimate, its standard error, alarms —
//! written as it comes into the file the user names, in the format its extension names (CSV,
//! Parquet or MDF4, so spreadsheet, pandas/pyarrow, asammdf and MATLAB users open it), with
//! units. The first column is the time `t` [s] (MDF4 keeps it as the master).

use miette::{IntoDiagnostic, Result, WrapErr};
use physid_core::{Basis, Channel, Recording};
use std::path::{Path, PathBuf};

/// Rows held before they are written.
const FLUSH_ROWS: usize = 65_536;

/// A tracks file written row by row (see the module docs).
pub struct TrackFile {
    path: PathBuf,
    writer: physid_io::ChunkWriter,
    columns: Vec<(String, String)>,
    buffers: Vec<Vec<f64>>,
}

impl TrackFile {
    /// Create `path` for `columns` (name, unit); the first should be `t` [s].
    pub fn create(path: &Path, columns: Vec<(String, String)>) -> Result<Self> {
        let writer = physid_io::ChunkWriter::create(
            path,
            &Self::chunk(&columns, None)?,
            &Default::default(),
        )
        .into_diagnostic()
        .wrap_err_with(|| format!("--tracks {}", path.display()))?;
        Ok(Self {
            path: path.to_path_buf(),
            writer,
            buffers: vec![Vec::with_capacity(FLUSH_ROWS); columns.len()],
            columns,
        })
    }

    fn chunk(columns: &[(String, String)], values: Option<&mut [Vec<f64>]>) -> Result<Recording> {
        let mut r = Recording::new(Basis::Time);
        let mut values = values.map(|v| v.iter_mut());
        for (name, unit) in columns {
            let v = values
                .as_mut()
                .and_then(|v| v.next())
                .map(std::mem::take)
                .unwrap_or_default();
            r.push(Channel {
                name: name.clone(),
                unit: unit.clone(),
                values: v,
            })
            .into_diagnostic()?;
        }
        Ok(r)
    }

    /// One row, a value per column in order.
    pub fn row(&mut self, values: impl IntoIterator<Item = f64>) -> Result<()> {
        for (b, v) in self.buffers.iter_mut().zip(values) {
            b.push(v);
        }
        if self.buffers[0].len() >= FLUSH_ROWS {
            self.flush()?;
        }
        Ok(())
    }

    fn flush(&mut self) -> Result<()> {
        if self.buffers.first().is_none_or(Vec::is_empty) {
            return Ok(());
        }
        let chunk = Self::chunk(&self.columns, Some(&mut self.buffers))?;
        self.writer
            .append(&chunk)
            .into_diagnostic()
            .wrap_err_with(|| format!("--tracks {}", self.path.display()))
    }

    /// Write what is held and finish the file.
    pub fn close(mut self) -> Result<()> {
        self.flush()?;
        self.writer
            .close()
            .into_diagnostic()
            .wrap_err_with(|| format!("--tracks {}", self.path.display()))
    }
}
