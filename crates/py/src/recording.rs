//! A recording in Python: [`Recording`] (channels as float64 arrays, units, basis, metadata),
//! built from arrays or pandas columns, read and written by `physid-io`, copied and pickled.

use crate::err;
use numpy::{PyArray1, PyReadonlyArray1};
use physid_core::{Basis, Channel};
use pyo3::exceptions::PyKeyError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::collections::BTreeMap;

/// A recording: channels of float64 samples with units, on a time or crank-angle basis.
#[pyclass(module = "physid._physid")]
#[derive(Clone)]
pub struct Recording {
    pub(crate) inner: physid_core::Recording,
}

fn basis_name(b: Basis) -> &'static str {
    match b {
        Basis::Time => "time",
        Basis::CrankAngle => "crank_angle",
    }
}

#[pymethods]
impl Recording {
    /// A recording from channels — `{name: values}` or `[(name, values), …]`, the values a
    /// 1-D array or sequence of numbers, all the same length — their `units` (`{name: unit}`,
    /// none if absent), the `basis` (`time` or `crank_angle`) and `meta` (`{key: text}`).
    #[new]
    #[pyo3(signature = (channels, units=None, basis="time", meta=None))]
    fn new(
        channels: &Bound<'_, PyAny>,
        units: Option<BTreeMap<String, String>>,
        basis: &str,
        meta: Option<BTreeMap<String, String>>,
    ) -> PyResult<Self> {
        let basis = match basis {
            "time" => Basis::Time,
            "crank_angle" | "crank" => Basis::CrankAngle,
            b => return Err(err(format!("basis '{b}': expected time or crank_angle"))),
        };
        let pairs: Vec<(String, Bound<'_, PyAny>)> = match channels.cast::<PyDict>() {
            Ok(d) => d.extract()?,
            Err(_) => channels.extract()?,
        };
        let units = units.unwrap_or_default();
        let mut inner = physid_core::Recording::new(basis);
        for (name, values) in pairs {
            let values = match values.extract::<PyReadonlyArray1<'_, f64>>() {
                Ok(a) => a.as_slice().map_err(err)?.to_vec(),
                Err(_) => values.extract::<Vec<f64>>().map_err(|_| {
                    err(format!(
                        "channel '{name}': expected a 1-D array or sequence of numbers"
                    ))
                })?,
            };
            let unit = units.get(&name).cloned().unwrap_or_default();
            inner.push(Channel { values, name, unit }).map_err(err)?;
        }
        inner.meta.extend(meta.unwrap_or_default());
        Ok(Self { inner })
    }

    /// The channel names, in order.
    #[getter]
    fn channels(&self) -> Vec<String> {
        self.inner.names().iter().map(|s| s.to_string()).collect()
    }

    /// `{name: unit}` (`""` where none is known).
    #[getter]
    fn units(&self) -> BTreeMap<String, String> {
        self.inner
            .channels()
            .iter()
            .map(|c| (c.name.clone(), c.unit.clone()))
            .collect()
    }

    /// `time` or `crank_angle`.
    #[getter]
    fn basis(&self) -> &'static str {
        basis_name(self.inner.basis)
    }

    /// The recording's metadata (a simulated run's scenario, parameters, faults …).
    #[getter]
    fn meta(&self) -> BTreeMap<String, String> {
        self.inner.meta.clone().into_iter().collect()
    }

    /// Number of samples.
    fn __len__(&self) -> usize {
        self.inner.len()
    }

    fn __contains__(&self, name: &str) -> bool {
        self.inner.channel(name).is_ok()
    }

    /// A channel's samples as a new float64 array; `KeyError` naming the channels there are.
    fn __getitem__<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyArray1<f64>>> {
        match self.inner.values(name) {
            Ok(v) => Ok(PyArray1::from_slice(py, v)),
            Err(e) => Err(PyKeyError::new_err(e.to_string())),
        }
    }

    fn __repr__(&self) -> String {
        format!(
            "<physid.Recording: {} basis, {} channels × {} samples: {}>",
            basis_name(self.inner.basis),
            self.inner.channels().len(),
            self.inner.len(),
            self.inner.names().join(", ")
        )
    }

    /// Write to `path`; the extension picks the format (`.csv`, `.parquet`, `.mf4`).
    fn write(&self, py: Python<'_>, path: std::path::PathBuf) -> PyResult<()> {
        let rec = &self.inner;
        py.detach(|| physid_io::write(&path, rec, &Default::default()))
            .map_err(err)
    }
}

/// Read a recording (CSV, text, Parquet, MDF4 by extension): `channels` (physid names after
/// `map`; all if `None`), `map` (`{name: "COLUMN[:UNIT]"}`), `columns` (a header-less text
/// file's column names), `scale` (`{name: (gain, offset)}`). Standard channels are converted
/// to SI on reading, as in every verb.
#[pyfunction]
#[pyo3(signature = (path, channels=None, map=None, columns=None, scale=None))]
pub(crate) fn read(
    py: Python<'_>,
    path: std::path::PathBuf,
    channels: Option<Vec<String>>,
    map: Option<BTreeMap<String, String>>,
    columns: Option<Vec<String>>,
    scale: Option<BTreeMap<String, (f64, f64)>>,
) -> PyResult<Recording> {
    let map_items: Vec<String> = map
        .unwrap_or_default()
        .into_iter()
        .map(|(k, v)| format!("{k}={v}"))
        .collect();
    let scale_items: Vec<String> = scale
        .unwrap_or_default()
        .into_iter()
        .map(|(k, (g, o))| format!("{k}={g},{o}"))
        .collect();
    let opts = physid_io::ReadOptions {
        channels,
        map: physid_io::ReadOptions::parse_map(&map_items).map_err(err)?,
        columns,
        scale: physid_io::ReadOptions::parse_scale(&scale_items).map_err(err)?,
        ..Default::default()
    };
    let inner = py.detach(|| physid_io::read(&path, &opts)).map_err(err)?;
    Ok(Recording { inner })
}
