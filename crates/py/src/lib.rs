//! # physid-py — physid from Python
//!
//! The extension module `physid._physid` under the Python package `physid`
//! (`crates/py/python/physid`), which gives it its Python face (keyword arguments, checks of
//! numpy arrays, result objects, docstrings). Everything computed here is physid's own library:
//!
//! * [`Recording`] — a recording (`physid_core::Recording`): read and written by `physid-io`
//!   (CSV, Parquet, MDF4), channels out as float64 arrays.
//! * [`Estimator`] — the recursive estimators of `physid-estim`: the linear ones (RLS, RLSF,
//!   DSFC, Kalman, thesis Alg. 5.2–5.5, Eq. 5.19) and the filters over a formula model (EKF,
//!   UKF, SR-UKF, Alg. 5.6–5.7); `run` over whole arrays without the GIL.
//! * [`identify`] — the identifiability analysis of `physid-ident` (Alg. 5.1, Eq. 5.11–5.13).
//! * [`simulate`] — the virtual test cell of `physid-sim`.
//! * [`monitor_shaft`], [`friction_fit`], [`torque_fit`] — the three applications of
//!   `physid-apps` (thesis ch. 6–8): their summaries and tracks.
//! * [`live`] — the live service of `physid-live`: its events as an iterator ([`LiveStream`]).
//!
//! Errors are `physid.Error` (a `ValueError`) with physid's message: the file, the channel,
//! the sample.

use numpy::ndarray::Array2;
use numpy::{
    IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods,
};
use physid_core::{Basis, Channel, FreeSet, ParamModel, ParamSet};
use physid_estim::tracks::{track, Track};
use physid_estim::{
    CovSpec, EstimatorConfig, LinearEstimator, Method, NlConfig, NlMethod, NonlinearEstimator,
    Recursive, SigmaPoints,
};
use physid_expr::ExprModel;
use pyo3::create_exception;
use pyo3::exceptions::{PyKeyError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::collections::BTreeMap;

create_exception!(
    physid,
    Error,
    PyValueError,
    "An error of physid: what went wrong, with the file, the channel or the sample."
);

fn err(e: impl std::fmt::Display) -> PyErr {
    Error::new_err(e.to_string())
}

/// A recording: channels of float64 samples with units, on a time or crank-angle basis.
#[pyclass(module = "physid._physid")]
#[derive(Clone)]
pub struct Recording {
    inner: physid_core::Recording,
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
fn read(
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

/// What an estimator is over.
enum Kind {
    /// A model linear in its parameters: `update(phi, y)` with the regressor φ (Eq. 5.14).
    Linear(Box<LinearEstimator>),
    /// A filter over a formula model: `update(u, y)` with the model's inputs.
    Model(Box<NonlinearEstimator<ExprModel>>),
}

/// A recursive estimator (thesis §5.3).
#[pyclass(module = "physid._physid")]
pub struct Estimator {
    kind: Kind,
    /// Inputs per sample: the parameters (linear) or the model's inputs.
    width: usize,
}

impl Estimator {
    fn rec(&self) -> &dyn Recursive {
        match &self.kind {
            Kind::Linear(e) => e.as_ref(),
            Kind::Model(e) => e.as_ref(),
        }
    }

    fn std_errors_into(&self, out: &mut [f64]) {
        match &self.kind {
            Kind::Linear(e) => Track::std_err_into(e.as_ref(), out),
            Kind::Model(e) => Track::std_err_into(e.as_ref(), out),
        }
    }
}

fn cov(p0: &Bound<'_, PyAny>, n: usize, what: &str) -> PyResult<CovSpec> {
    if let Ok(c) = p0.extract::<f64>() {
        return Ok(CovSpec::Scaled(c));
    }
    if let Ok(v) = p0.extract::<Vec<f64>>() {
        if v.len() != n {
            return Err(err(format!(
                "{what}: {} values for {n} parameters",
                v.len()
            )));
        }
        return Ok(CovSpec::Diagonal(v));
    }
    if let Ok(m) = p0.extract::<Vec<Vec<f64>>>() {
        return Ok(CovSpec::Full(m));
    }
    Err(err(format!(
        "{what}: expected a number (c·I), a diagonal or a square matrix"
    )))
}

fn param_set(names: Vec<String>, theta0: Vec<f64>) -> PyResult<(ParamSet, FreeSet)> {
    let params = ParamSet::new(names, theta0).map_err(err)?;
    let free = params.all_free();
    Ok((params, free))
}

#[pymethods]
impl Estimator {
    /// A linear estimator (`method`: rls, rlsf, dsfc, kalman) of the parameters `names`
    /// starting at `theta0`, with forgetting `lam`, initial covariance `p0` (number, diagonal
    /// or matrix; DSFC: of its square root's square), and for the Kalman filter `r1`, `r2`.
    #[staticmethod]
    #[pyo3(signature = (method, names, theta0, lam, p0, r1=None, r2=None))]
    fn linear(
        method: &str,
        names: Vec<String>,
        theta0: Vec<f64>,
        lam: f64,
        p0: &Bound<'_, PyAny>,
        r1: Option<&Bound<'_, PyAny>>,
        r2: Option<f64>,
    ) -> PyResult<Self> {
        let n = names.len();
        let method = match method {
            "rls" => Method::Rls,
            "rlsf" => Method::Rlsf { lambda: lam },
            "dsfc" => Method::Dsfc { lambda: lam },
            "kalman" => Method::Kalman {
                r1: match r1 {
                    Some(r) => cov(r, n, "r1")?,
                    None => CovSpec::Scaled(0.0),
                },
                r2: r2.unwrap_or(1.0),
            },
            m => {
                return Err(err(format!(
                    "method '{m}': expected rls, rlsf, dsfc or kalman"
                )))
            }
        };
        let mut config = EstimatorConfig::new(method);
        config.p0 = cov(p0, n, "p0")?;
        let (params, free) = param_set(names, theta0)?;
        let e = LinearEstimator::new(&config, &params, &free).map_err(err)?;
        Ok(Self {
            kind: Kind::Linear(Box::new(e)),
            width: n,
        })
    }

    /// A filter (`method`: ekf, ukf, srukf) over the formula `expr` whose parameters are
    /// `names` (starting at `theta0`; `free`: those estimated, all if `None`), with initial
    /// covariance `p0`, random walk `r1`, measurement variance `r2`, scaled coordinates,
    /// sigma-point spread `alpha`, `beta`, `kappa`.
    #[staticmethod]
    #[pyo3(signature = (method, expr, names, theta0, free, p0, r1, r2, scaled, alpha, beta, kappa))]
    #[allow(clippy::too_many_arguments)]
    fn model(
        method: &str,
        expr: &str,
        names: Vec<String>,
        theta0: Vec<f64>,
        free: Option<Vec<String>>,
        p0: &Bound<'_, PyAny>,
        r1: &Bound<'_, PyAny>,
        r2: f64,
        scaled: bool,
        alpha: f64,
        beta: f64,
        kappa: Option<f64>,
    ) -> PyResult<Self> {
        let model = ExprModel::parse(expr, &names).map_err(err)?;
        let params = ParamSet::new(names, theta0).map_err(err)?;
        let free = match free {
            Some(f) => params.free(&f).map_err(err)?,
            None => params.all_free(),
        };
        let points = SigmaPoints { alpha, beta, kappa };
        let nl = match method {
            "ekf" => NlMethod::Ekf,
            "ukf" => NlMethod::Ukf(points),
            "srukf" => NlMethod::Srukf(points),
            m => return Err(err(format!("method '{m}': expected ekf, ukf or srukf"))),
        };
        let k = free.free().len();
        let mut config = NlConfig::new(nl);
        config.p0 = cov(p0, k, "p0")?;
        config.r1 = cov(r1, k, "r1")?;
        config.r2 = r2;
        config.scaled = scaled;
        let width = model.input_names().len();
        let e = NonlinearEstimator::new(model, &params, &free, &config).map_err(err)?;
        Ok(Self {
            kind: Kind::Model(Box::new(e)),
            width,
        })
    }

    /// The model's input names (a filter over a formula), in the order `update` takes them.
    #[getter]
    fn inputs(&self) -> Vec<String> {
        match &self.kind {
            Kind::Linear(_) => Vec::new(),
            Kind::Model(e) => e.model().input_names().to_vec(),
        }
    }

    /// The method's name.
    #[getter]
    fn method(&self) -> &'static str {
        self.rec().method_name()
    }

    /// The names of the estimated parameters.
    #[getter]
    fn names(&self) -> Vec<String> {
        self.rec()
            .free_names()
            .iter()
            .map(|s| s.to_string())
            .collect()
    }

    /// The current estimate ϑ of the estimated parameters.
    #[getter]
    fn estimate<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.rec().estimate().into_pyarray(py)
    }

    /// Their standard errors (NaN while they cannot be estimated yet).
    #[getter]
    fn std_err<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let mut out = vec![0.0; self.rec().free_names().len()];
        self.std_errors_into(&mut out);
        out.into_pyarray(py)
    }

    /// The covariance over the estimated parameters (the estimator's coordinates).
    #[getter]
    fn covariance<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let c = self.rec().covariance();
        Array2::from_shape_fn((c.nrows(), c.ncols()), |(i, j)| c[(i, j)]).into_pyarray(py)
    }

    /// Samples taken.
    #[getter]
    fn samples(&self) -> u64 {
        self.rec().samples()
    }

    /// One sample: the regressor φ (linear) or the model's inputs, and the output `y`;
    /// returns the prediction error. A refused sample (NaN, a bad number) raises and leaves
    /// the estimator as it was.
    fn update(&mut self, x: PyReadonlyArray1<'_, f64>, y: f64) -> PyResult<f64> {
        let x = x.as_slice().map_err(err)?;
        if x.len() != self.width {
            return Err(err(format!("{} values for {} inputs", x.len(), self.width)));
        }
        match &mut self.kind {
            Kind::Linear(e) => e.step(x, y),
            Kind::Model(e) => e.step(x, y),
        }
        .map_err(err)
    }

    /// The whole arrays, without the GIL: `x` (n × inputs, C order), `y` (n). Returns the
    /// estimate and standard-error tracks (n × estimated), the prediction errors (n) and the
    /// rows skipped (`skip_bad`: a refused row is skipped, its track row the previous one;
    /// otherwise the first raises, naming its row). Without `std_err` the standard-error
    /// track is left NaN (and not computed).
    #[pyo3(signature = (x, y, skip_bad=false, std_err=true))]
    #[allow(clippy::type_complexity)]
    fn run<'py>(
        &mut self,
        py: Python<'py>,
        x: PyReadonlyArray2<'py, f64>,
        y: PyReadonlyArray1<'py, f64>,
        skip_bad: bool,
        std_err: bool,
    ) -> PyResult<(
        Bound<'py, PyArray2<f64>>,
        Bound<'py, PyArray2<f64>>,
        Bound<'py, PyArray1<f64>>,
        Vec<usize>,
    )> {
        let shape = x.shape();
        let (n, w) = (shape[0], shape[1]);
        if w != self.width {
            return Err(err(format!("{w} columns for {} inputs", self.width)));
        }
        if w == 0 {
            return Err(err("the model has no inputs: nothing to take row by row"));
        }
        let y = y.as_slice().map_err(err)?;
        if y.len() != n {
            return Err(err(format!("{n} rows of inputs, {} outputs", y.len())));
        }
        let xs = x.as_slice().map_err(err)?;
        let k = match &self.kind {
            Kind::Linear(e) => e.estimate().len(),
            Kind::Model(e) => e.free_names().len(),
        };
        let kind = &mut self.kind;
        let t = py
            .detach(|| match kind {
                Kind::Linear(e) => track(e.as_mut(), xs, y, w, k, skip_bad, std_err),
                Kind::Model(e) => track(e.as_mut(), xs, y, w, k, skip_bad, std_err),
            })
            .map_err(err)?;
        let (theta, se, errors, skipped) = (t.theta, t.se, t.errors, t.skipped);
        let shape2 = |v: Vec<f64>| Array2::from_shape_vec((n, k), v).map_err(err);
        Ok((
            shape2(theta)?.into_pyarray(py),
            shape2(se)?.into_pyarray(py),
            errors.into_pyarray(py),
            skipped,
        ))
    }
}

/// The identifiability of the parameters of the formula `expr` (names `names`, nominal values
/// `nominal`, analysed: `free`, all if empty) over `inputs` (`{name: array}`) with the
/// measured output `y` if given: ranking (Alg. 5.1), the estimable set (`cutoff`), Fisher
/// information, intervals — physid's identify report, as JSON text.
#[pyfunction]
#[pyo3(signature = (expr, names, nominal, inputs, y, free, scaling, cutoff, sigma))]
#[allow(clippy::too_many_arguments)]
fn identify(
    py: Python<'_>,
    expr: &str,
    names: Vec<String>,
    nominal: Vec<f64>,
    inputs: BTreeMap<String, PyReadonlyArray1<'_, f64>>,
    y: Option<PyReadonlyArray1<'_, f64>>,
    free: Vec<String>,
    scaling: &str,
    cutoff: &str,
    sigma: Option<f64>,
) -> PyResult<String> {
    let model = ExprModel::parse(expr, &names).map_err(err)?;
    let columns: Vec<&[f64]> = model
        .input_names()
        .iter()
        .map(|c| {
            inputs
                .get(c)
                .ok_or_else(|| {
                    err(format!(
                        "the formula needs the input '{c}'; the data have {}",
                        inputs.keys().cloned().collect::<Vec<_>>().join(", ")
                    ))
                })
                .and_then(|a| a.as_slice().map_err(err))
        })
        .collect::<PyResult<_>>()?;
    let y = match &y {
        Some(a) => Some(a.as_slice().map_err(err)?),
        None => None,
    };
    let free: Vec<usize> = free
        .iter()
        .map(|f| {
            names.iter().position(|n| n == f).ok_or_else(|| {
                err(format!(
                    "free '{f}': the parameters are {}",
                    names.join(", ")
                ))
            })
        })
        .collect::<PyResult<_>>()?;
    let config = physid_ident::IdentConfig {
        scaling: physid_ident::Scaling::parse(scaling).ok_or_else(|| {
            err(format!(
                "scaling '{scaling}': expected thesis, sigma or none"
            ))
        })?,
        ..Default::default()
    };
    let selection = physid_ident::Selection::parse(cutoff).map_err(err)?;
    let data = physid_ident::Data { inputs: columns, y };
    let id = py
        .detach(|| physid_ident::identify(&model, &data, &nominal, &free, config, selection, sigma))
        .map_err(|e| match e {
            physid_ident::IdentError::BadValue { row, column, value } => err(format!(
                "row {row}: '{column}' is {value} (expected a finite number)"
            )),
            e => err(e),
        })?;
    serde_json::to_string(&id.report()).map_err(err)
}

/// Run the virtual test cell: a built-in scenario or a scenario file, for `duration` seconds
/// (the scenario's if `None`), with `faults` (`PATH=VALUE@T[+RAMP]`) and parameter settings
/// `set` (`{path: value}`), sampled on a time basis at `rate` Hz or one sample per `step_deg`
/// crank degrees (`basis="crank_angle"`).
#[pyfunction]
#[pyo3(signature = (scenario, duration=None, faults=None, set=None, basis="time", rate=None, step_deg=1.0))]
#[allow(clippy::too_many_arguments)]
fn simulate(
    py: Python<'_>,
    scenario: &str,
    duration: Option<f64>,
    faults: Option<Vec<String>>,
    set: Option<BTreeMap<String, f64>>,
    basis: &str,
    rate: Option<f64>,
    step_deg: f64,
) -> PyResult<Recording> {
    use physid_sim::run::{OutputBasis, RunOptions};
    use physid_sim::scenario::{Fault, Scenario};
    let mut sc = Scenario::load(scenario).map_err(err)?;
    sc.set.extend(set.unwrap_or_default());
    let faults = faults
        .unwrap_or_default()
        .iter()
        .map(|f| Fault::parse(f))
        .collect::<Result<Vec<_>, _>>()
        .map_err(err)?;
    let basis = match basis {
        "time" => rate.map_or(RunOptions::default().basis, OutputBasis::Time),
        "crank_angle" | "crank" => OutputBasis::Crank(step_deg),
        b => return Err(err(format!("basis '{b}': expected time or crank_angle"))),
    };
    let opts = RunOptions {
        duration,
        faults,
        basis,
        ..Default::default()
    };
    let inner = py
        .detach(|| physid_sim::run::simulate(&sc, &opts, |_| {}))
        .map_err(err)?;
    Ok(Recording { inner })
}

/// A dict of arrays (the tracks of an application), built from named columns.
fn arrays<'py>(py: Python<'py>, columns: Vec<(String, Vec<f64>)>) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (name, v) in columns {
        d.set_item(name, v.into_pyarray(py))?;
    }
    Ok(d)
}

/// Application 1, the coupling-shaft monitor (thesis ch. 6): K and B of Eq. 6.1 tracked by
/// `method` (rls, rlsvf, dsfc) with forgetting `lam` from a time-basis recording low-passed at
/// `cutoff_hz` and taken at `rate_hz`; the relative-error detector (Eq. 6.3) with `bound` and
/// `dwell` against the `healthy` (K, B). Returns the summary (JSON text) and the tracks.
#[pyfunction]
#[pyo3(signature = (rec, method, lam, p0, healthy, theta0, bound, dwell, cutoff_hz, rate_hz, settle_s, supervise))]
#[allow(clippy::too_many_arguments)]
fn monitor_shaft<'py>(
    py: Python<'py>,
    rec: &Recording,
    method: &str,
    lam: f64,
    p0: f64,
    healthy: (f64, f64),
    theta0: (f64, f64, f64),
    bound: f64,
    dwell: u64,
    cutoff_hz: f64,
    rate_hz: f64,
    settle_s: f64,
    supervise: bool,
) -> PyResult<(String, Bound<'py, PyDict>)> {
    use physid_apps::shaft_monitor::{
        monitor_shaft, MonitorConfig, MonitorMethod, PerParam, ShaftParams,
    };
    let cfg = MonitorConfig {
        method: method
            .parse::<MonitorMethod>()
            .map_err(|e| err(format!("method {e}")))?,
        lambda: lam,
        p0,
        healthy: PerParam {
            k: healthy.0,
            b: healthy.1,
        },
        theta0: ShaftParams {
            k: theta0.0,
            b: theta0.1,
            tau0: theta0.2,
        },
        bound,
        dwell,
        cutoff_hz,
        rate_hz,
        settle_s,
        supervise,
    };
    let inner = &rec.inner;
    let r = py.detach(|| monitor_shaft(inner, &cfg)).map_err(err)?;
    let summary = serde_json::to_string(&r.summary()).map_err(err)?;
    let mut cols = vec![
        ("t".to_string(), r.t),
        ("K".to_string(), r.k),
        ("B".to_string(), r.b),
        ("tau0".to_string(), r.tau0),
        (
            "K_std_err".to_string(),
            r.std_err.iter().map(|s| s[0]).collect(),
        ),
        (
            "B_std_err".to_string(),
            r.std_err.iter().map(|s| s[1]).collect(),
        ),
    ];
    if let Some((k, b)) = r.truth {
        cols.push(("K_true".into(), k));
        cols.push(("B_true".into(), b));
    }
    Ok((summary, arrays(py, cols)?))
}

/// Application 2, the engine's friction from motored cycles (thesis §7.3): the preset model
/// (`thesis`, `sandoval2002`, `cell`) with `set` overrides, the motoring torque from `source`
/// (engine, shaft), the coefficients' ranking with `cutoff`, DSFC (`lam`, `s0`). Returns the
/// summary (JSON text) and the per-cycle tracks.
#[pyfunction]
#[pyo3(signature = (rec, preset, set, source, cutoff, s0, lam, transient_s, p_atm_kpa))]
#[allow(clippy::too_many_arguments)]
fn friction_fit<'py>(
    py: Python<'py>,
    rec: &Recording,
    preset: &str,
    set: BTreeMap<String, String>,
    source: &str,
    cutoff: &str,
    s0: f64,
    lam: f64,
    transient_s: f64,
    p_atm_kpa: Option<f64>,
) -> PyResult<(String, Bound<'py, PyDict>)> {
    use physid_apps::friction_fit::{
        friction_fit, friction_preset, FrictionFitConfig, TorqueSource, FRICTION_PRESETS,
    };
    let (mut d, mut st) = friction_preset(preset).ok_or_else(|| {
        err(format!(
            "no friction preset '{preset}'; the presets are {}",
            FRICTION_PRESETS.join(", ")
        ))
    })?;
    for (name, value) in &set {
        physid_models::friction::set_by_name(&mut d, &mut st, name, value).map_err(err)?;
    }
    let mut cfg = FrictionFitConfig::new(d, st);
    cfg.source = TorqueSource::parse(source)
        .ok_or_else(|| err(format!("source '{source}': expected engine or shaft")))?;
    cfg.selection = physid_ident::Selection::parse(cutoff).map_err(err)?;
    cfg.s0 = s0;
    cfg.lambda = lam;
    cfg.transient_s = transient_s;
    cfg.p_atm_kpa = p_atm_kpa;
    let inner = &rec.inner;
    let r = py.detach(|| friction_fit(inner, &cfg)).map_err(err)?;
    let summary = serde_json::to_string(&r.summary()).map_err(err)?;
    let d = &r.data;
    let mut cols = vec![
        ("t".to_string(), d.t_s.clone()),
        (
            "cycle".to_string(),
            d.cycle.iter().map(|&c| c as f64).collect(),
        ),
        ("n_rpm".to_string(), d.n_rpm.clone()),
        ("p_int_kpa".to_string(), d.p_int_kpa.clone()),
        ("t_oil_c".to_string(), d.t_oil_c.clone()),
        ("measured".to_string(), d.tau_nm.clone()),
        ("predicted".to_string(), r.predicted.clone()),
        ("nominal".to_string(), r.predicted_nominal.clone()),
        ("error_pct".to_string(), r.error_pct.clone()),
    ];
    if let Some(t) = &d.truth_nm {
        cols.push(("truth".into(), t.clone()));
    }
    Ok((summary, arrays(py, cols)?))
}

/// Application 3, the cyclic engine torque (thesis ch. 8, Eq. 8.2): the ranking of its 15
/// parameters (nominal: the test cell's engine, overridden by `nominal`), the estimable ones
/// (`cutoff`, the application's default if `None`; `fixed` held) estimated by `method` (ekf, ukf, srukf) with `p0`, `r2` (the batch
/// fit's residual variance if `None`), random walks `track`. Returns the summary (JSON text)
/// and the tracks.
#[pyfunction]
#[pyo3(signature = (rec, method, nominal, fixed, cutoff, p0, r2, track))]
#[allow(clippy::too_many_arguments)]
fn torque_fit<'py>(
    py: Python<'py>,
    rec: &Recording,
    method: &str,
    nominal: BTreeMap<String, f64>,
    fixed: Vec<String>,
    cutoff: Option<&str>,
    p0: f64,
    r2: Option<f64>,
    track: BTreeMap<String, f64>,
) -> PyResult<(String, Bound<'py, PyDict>)> {
    use physid_apps::torque_fit::{cyclic_torque_nominal, torque_fit, TorqueFitConfig};
    use physid_models::cyclic_torque::PARAMS;
    let mut nom = cyclic_torque_nominal(&physid_sim::params::CellParams::default()).map_err(err)?;
    for (name, v) in &nominal {
        let j = PARAMS.iter().position(|p| p == name).ok_or_else(|| {
            err(format!(
                "nominal '{name}': the parameters are {}",
                PARAMS.join(", ")
            ))
        })?;
        nom[j] = *v;
    }
    let mut cfg = TorqueFitConfig::new(nom);
    cfg.method = method
        .parse::<NlMethod>()
        .map_err(|e| err(format!("method {e}")))?;
    cfg.fixed = fixed;
    if let Some(c) = cutoff {
        cfg.selection = physid_ident::Selection::parse(c).map_err(err)?;
    }
    cfg.p0 = p0;
    cfg.r2 = r2;
    cfg.track = track.into_iter().collect();
    let inner = &rec.inner;
    let r = py.detach(|| torque_fit(inner, &cfg)).map_err(err)?;
    let summary = serde_json::to_string(&r.summary()).map_err(err)?;
    let mut cols = vec![
        ("t".to_string(), r.t.clone()),
        ("measured".to_string(), r.measured.clone()),
        ("predicted".to_string(), r.predicted.clone()),
    ];
    for tr in &r.tracks {
        cols.push((tr.param.clone(), tr.value.clone()));
        cols.push((format!("{}_std_err", tr.param), tr.std_err.clone()));
    }
    Ok((summary, arrays(py, cols)?))
}

/// The live service's events (`physid live --headless --json`), one JSON object each, as a
/// run goes: the run on a thread of its own, its events handed over a bounded channel that
/// `__next__` waits on without the GIL. Dropping the stream (or `close`) stops the run.
#[pyclass(module = "physid._physid")]
pub struct LiveStream {
    events: Option<std::sync::Mutex<std::sync::mpsc::Receiver<String>>>,
    controls: Option<std::sync::mpsc::SyncSender<physid_live::ControlRequest>>,
    worker: Option<std::thread::JoinHandle<Result<(), String>>>,
}

#[pymethods]
impl LiveStream {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    /// The next event as JSON text; at the end, the run's error if it failed.
    fn __next__(&mut self, py: Python<'_>) -> PyResult<Option<String>> {
        let Some(rx) = &self.events else {
            return Ok(None);
        };
        let next = py.detach(|| match rx.lock() {
            Ok(r) => r.recv().ok(),
            Err(_) => None,
        });
        match next {
            Some(line) => Ok(Some(line)),
            None => {
                self.events = None;
                self.controls = None;
                match self.worker.take().map(|w| w.join()) {
                    Some(Ok(Err(e))) => Err(err(e)),
                    Some(Err(_)) => Err(err("the live run stopped unexpectedly")),
                    _ => Ok(None),
                }
            }
        }
    }

    /// Send a control message (one JSON object, as the panel's: `{"cmd": "speed", "rpm":
    /// 1200}`); its answer comes as an event.
    fn control(&self, text: String) -> PyResult<()> {
        match &self.controls {
            Some(tx) => tx
                .send(physid_live::ControlRequest::fire(text))
                .map_err(|_| err("the live run has ended")),
            None => Err(err("the live run has ended")),
        }
    }

    /// Stop the run (the events not yet taken are dropped).
    fn close(&mut self, py: Python<'_>) {
        self.events = None;
        self.controls = None;
        if let Some(w) = self.worker.take() {
            let _ = py.detach(|| w.join());
        }
    }
}

/// Start a live run: the virtual cell (`scenario`, `duration`, `faults`, `set`, sampled at
/// `rate` Hz) or a recording replayed (`replay`), at `pace` (`max` or a factor of real time),
/// in chunks of `chunk_s` seconds, an estimate event at most every `estimate_every_s`.
#[pyfunction]
#[pyo3(signature = (scenario, replay, duration, faults, set, pace, rate, chunk_s, estimate_every_s))]
#[allow(clippy::too_many_arguments)]
fn live(
    scenario: Option<String>,
    replay: Option<std::path::PathBuf>,
    duration: Option<f64>,
    faults: Vec<String>,
    set: BTreeMap<String, f64>,
    pace: &str,
    rate: f64,
    chunk_s: f64,
    estimate_every_s: f64,
) -> PyResult<LiveStream> {
    use physid_live::{run_live, LiveConfig, Pace, ReplaySource, ScenarioSource, Source};
    use physid_sim::run::{OutputBasis, RunOptions};
    use physid_sim::scenario::{Fault, Scenario};
    let pace: Pace = pace.parse().map_err(|e| err(format!("pace {e}")))?;
    if !(chunk_s.is_finite()
        && chunk_s > 0.0
        && estimate_every_s.is_finite()
        && estimate_every_s > 0.0)
    {
        return Err(err("chunk_s and estimate_every_s: expected times > 0 [s]"));
    }
    // The source is built here, so that a bad scenario or file is an error now.
    let (source, theta_tdc): (Box<dyn Source + Send>, f64) = match replay {
        Some(path) => {
            let r = ReplaySource::open(&path, &Default::default(), chunk_s).map_err(err)?;
            let tdc = r.theta_tdc();
            (Box::new(r), tdc)
        }
        None => {
            let mut sc =
                Scenario::load(scenario.as_deref().unwrap_or("shaft-steady")).map_err(err)?;
            sc.set.extend(set);
            let faults = faults
                .iter()
                .map(|f| Fault::parse(f))
                .collect::<Result<Vec<_>, _>>()
                .map_err(err)?;
            let opts = RunOptions {
                duration,
                faults,
                basis: OutputBasis::Time(rate),
                ..Default::default()
            };
            (
                Box::new(ScenarioSource::new(&sc, &opts, chunk_s).map_err(err)?),
                0.0,
            )
        }
    };
    let cfg = LiveConfig {
        pace,
        theta_tdc,
        estimate_every_s,
        ..Default::default()
    };
    let (tx, rx) = std::sync::mpsc::sync_channel::<String>(1024);
    let (ctx, crx) = std::sync::mpsc::sync_channel(256);
    let worker = std::thread::spawn(move || {
        let mut source = source;
        run_live(source.as_mut(), &cfg, Some(&crx), |e| {
            let line = serde_json::to_string(e).map_err(|e| e.to_string())?;
            tx.send(line)
                .map_err(|_| "the stream was closed".to_string())
        })
        .map(|_| ())
        .or_else(|e| {
            let text = e.to_string();
            // Closed from Python: not an error.
            if text.contains("the stream was closed") {
                Ok(())
            } else {
                Err(text)
            }
        })
    });
    Ok(LiveStream {
        events: Some(std::sync::Mutex::new(rx)),
        controls: Some(ctx),
        worker: Some(worker),
    })
}

/// The module.
#[pymodule]
fn _physid(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("Error", m.py().get_type::<Error>())?;
    m.add_class::<Recording>()?;
    m.add_class::<Estimator>()?;
    m.add_function(wrap_pyfunction!(read, m)?)?;
    m.add_function(wrap_pyfunction!(identify, m)?)?;
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(monitor_shaft, m)?)?;
    m.add_function(wrap_pyfunction!(friction_fit, m)?)?;
    m.add_function(wrap_pyfunction!(torque_fit, m)?)?;
    m.add_function(wrap_pyfunction!(live, m)?)?;
    m.add_class::<LiveStream>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
