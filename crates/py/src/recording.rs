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

/// A channel's values as float64: a numpy array of any number type and any strides, a pandas
/// column (the nullable `Float64`/`Int64` too, a missing value read as NaN) or a sequence of
/// numbers; anything else is an error naming the channel.
fn values_of(name: &str, values: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
    let py = values.py();
    let bad = |why: String| {
        err(format!(
            "channel '{name}': expected a 1-D array or sequence of numbers ({why})"
        ))
    };
    let values = if values.hasattr("to_numpy")? {
        let kwargs = PyDict::new(py);
        kwargs.set_item("dtype", "float64")?;
        kwargs.set_item("na_value", f64::NAN)?;
        values
            .call_method("to_numpy", (), Some(&kwargs))
            .or_else(|_| values.call_method0("to_numpy"))
            .map_err(|e| bad(e.to_string()))?
    } else {
        values.clone()
    };
    let numpy = py.import("numpy")?;
    // Complex numbers would lose their imaginary parts to the cast, with a warning only.
    let raw = numpy
        .call_method1("asarray", (values,))
        .map_err(|e| bad(e.to_string()))?;
    if raw.getattr("dtype")?.getattr("kind")?.extract::<String>()? == "c" {
        return Err(bad(
            "complex numbers: their imaginary parts would be dropped".into(),
        ));
    }
    let a = numpy
        .call_method1("asarray", (raw, "float64"))
        .map_err(|e| bad(e.to_string()))?;
    let a: PyReadonlyArray1<'_, f64> = a.extract().map_err(|_| {
        bad(format!(
            "an array of shape {}",
            a.getattr("shape")
                .map(|s| s.to_string())
                .unwrap_or_default()
        ))
    })?;
    Ok(a.as_array().to_vec())
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
            Ok(d) => d
                .items()
                .iter()
                .map(|kv| kv.extract())
                .collect::<PyResult<_>>()?,
            Err(_) => channels
                .extract()
                .map_err(|_| err("channels: expected {name: values} or [(name, values), …]"))?,
        };
        let units = units.unwrap_or_default();
        let mut inner = physid_core::Recording::new(basis);
        for (name, values) in pairs {
            let values = values_of(&name, &values)?;
            let unit = units.get(&name).cloned().unwrap_or_default();
            inner.push(Channel { values, name, unit }).map_err(err)?;
        }
        inner.meta.extend(meta.unwrap_or_default());
        Ok(Self { inner })
    }

    /// `copy`, `deepcopy` and `pickle`: the recording rebuilt from its channels, units, basis
    /// and metadata.
    #[allow(clippy::type_complexity)]
    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(
        Bound<'py, PyAny>,
        (
            Vec<(String, Bound<'py, PyArray1<f64>>)>,
            BTreeMap<String, String>,
            &'static str,
            BTreeMap<String, String>,
        ),
    )> {
        let py = slf.py();
        let me = slf.borrow();
        let channels = me
            .inner
            .channels()
            .iter()
            .map(|c| (c.name.clone(), PyArray1::from_slice(py, &c.values)))
            .collect();
        Ok((
            slf.get_type().into_any(),
            (channels, me.units(), me.basis(), me.meta()),
        ))
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

    /// Write to `path`; the extension picks the format (`.csv`, `.parquet`, `.mf4`). Whole or
    /// not at all: a write the disk refuses leaves a file already at `path` as it was.
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
///
/// With `crank_angle` (implied by `wheel`, `quadrature`, `encoders` or `tdc_from`): on a
/// crank-angle basis, one sample every `step_deg` degrees, the engine angle from `theta_en`, an
/// encoder's counts (`encoders`: `["CHANNEL=PPR", …]`, `marker`), a trigger wheel's raw signal
/// (`wheel`: `"CHANNEL=N-M"`, `edge`, `threshold`: `"LEVEL,HYSTERESIS"`) or a quadrature
/// encoder's (`quadrature`: `"A,B,Z=LINES"`) or a pulse encoder's with its index
/// (`encoder_raw`: `"CHANNEL=PULSES"`, `index_raw`), the TDC `tdc_offset` degrees after the sensor's
/// reference or placed from the motored pressure `tdc_from` (with `stroke`, `rod` [m]), the
/// firing revolution from `phase_from` — as `physid convert --crank-angle`.
#[pyfunction]
#[pyo3(signature = (path, channels=None, map=None, columns=None, scale=None, crank_angle=false,
    step_deg=1.0, wheel=None, quadrature=None, encoders=None, marker=None, tdc_offset=0.0,
    phase_from=None, tdc_from=None, stroke=None, rod=None, edge="rising", threshold=None,
    encoder_raw=None, index_raw=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn read(
    py: Python<'_>,
    path: std::path::PathBuf,
    channels: Option<Vec<String>>,
    map: Option<BTreeMap<String, String>>,
    columns: Option<Vec<String>>,
    scale: Option<BTreeMap<String, (f64, f64)>>,
    crank_angle: bool,
    step_deg: f64,
    wheel: Option<String>,
    quadrature: Option<String>,
    encoders: Option<Vec<String>>,
    marker: Option<String>,
    tdc_offset: f64,
    phase_from: Option<String>,
    tdc_from: Option<String>,
    stroke: Option<f64>,
    rod: Option<f64>,
    edge: &str,
    threshold: Option<String>,
    encoder_raw: Option<String>,
    index_raw: Option<String>,
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
    let angle = crate::angle::AngleArgs {
        wheel,
        quadrature,
        encoder_raw,
        index_raw,
        encoders,
        marker,
        tdc_offset,
        phase_from,
        tdc_from,
        stroke,
        rod,
        edge: edge.to_string(),
        threshold,
        step_deg,
    };
    let inner = if crank_angle || angle.any() {
        py.detach(|| crate::angle::read_crank_angle(&path, opts, &angle))?
    } else {
        py.detach(|| physid_io::read(&path, &opts)).map_err(err)?
    };
    Ok(Recording { inner })
}
