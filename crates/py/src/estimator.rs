//! The recursive estimators in Python: [`Estimator`] over a model linear in its parameters
//! (RLS, RLSF, DSFC, Kalman, thesis Alg. 5.2–5.5, Eq. 5.19) or over a formula model (EKF, UKF,
//! SR-UKF, Alg. 5.6–5.7); one sample at a time or whole arrays without the GIL; copied,
//! reset and pickled whole (its state is serialised: a copy continues bit for bit).

use crate::err;
use numpy::ndarray::Array2;
use numpy::{
    IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods,
};
use physid_core::{FreeSet, ParamModel, ParamSet};
use physid_estim::tracks::{track, Track};
use physid_estim::{
    build_linear, CovSpec, EstimatorSpec, LinearEstimator, MethodName, NonlinearEstimator,
    Recursive, SigmaPoints,
};
use physid_expr::ExprModel;
use pyo3::prelude::*;

/// What an estimator is over.
#[derive(Clone, serde::Serialize, serde::Deserialize)]
enum Kind {
    /// A model linear in its parameters: `update(phi, y)` with the regressor φ (Eq. 5.14).
    Linear(Box<LinearEstimator>),
    /// A filter over a formula model: `update(u, y)` with the model's inputs.
    Model(Box<NonlinearEstimator<ExprModel>>),
}

/// A recursive estimator (thesis §5.3).
#[pyclass(module = "physid._physid")]
#[derive(Clone, serde::Serialize, serde::Deserialize)]
pub struct Estimator {
    kind: Kind,
    /// The estimator as built, before its first sample: what [`Estimator::reset`] returns to.
    initial: Kind,
    /// Inputs per sample: the parameters (linear) or the model's inputs.
    width: usize,
}

/// An estimator from the bytes its `__reduce__` gave (`pickle`): the whole state, MessagePack.
#[pyfunction]
pub(crate) fn _estimator(bytes: &[u8]) -> PyResult<Estimator> {
    rmp_serde::from_slice(bytes).map_err(|e| {
        err(format!(
            "not a pickled physid estimator of this version: {e}"
        ))
    })
}

impl Estimator {
    fn built(kind: Kind, width: usize) -> Self {
        Self {
            initial: kind.clone(),
            kind,
            width,
        }
    }

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
    /// A linear estimator (`method`: rls, rlsf, dsfc, kf) of the parameters `names`
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
        let mut spec = match method.parse::<MethodName>() {
            Ok(m @ (MethodName::Rls | MethodName::Rlsf | MethodName::Dsfc | MethodName::Kf)) => {
                EstimatorSpec::new(m)
            }
            _ => {
                return Err(err(format!(
                    "method '{method}': expected rls, rlsf, dsfc or kf"
                )))
            }
        };
        spec.lambda = lam;
        spec.p0 = cov(p0, n, "p0")?;
        if let Some(r) = r1 {
            spec.r1 = cov(r, n, "r1")?;
        }
        spec.r2 = r2.unwrap_or(1.0);
        let (params, free) = param_set(names, theta0)?;
        let e = build_linear(&spec, &params, &free).map_err(err)?;
        Ok(Self::built(Kind::Linear(Box::new(e)), n))
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
        let method =
            MethodName::parse_model_based(method).map_err(|e| err(format!("method {e}")))?;
        let k = free.free().len();
        let spec = EstimatorSpec {
            p0: cov(p0, k, "p0")?,
            r1: cov(r1, k, "r1")?,
            r2,
            scaled,
            sigma_points: SigmaPoints { alpha, beta, kappa },
            ..EstimatorSpec::new(method)
        };
        let width = model.input_names().len();
        let e = spec
            .nl_config()
            .and_then(|nl| NonlinearEstimator::new(model, &params, &free, &nl))
            .map_err(err)?;
        Ok(Self::built(Kind::Model(Box::new(e)), width))
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
    /// returns the prediction error `e` and the innovation variance `Var(e)` (the RLS family
    /// and DSFC: in units of the noise variance σ²; the filters: absolute). A refused sample
    /// (NaN, a bad number) raises and leaves the estimator as it was.
    fn update(&mut self, x: PyReadonlyArray1<'_, f64>, y: f64) -> PyResult<(f64, f64)> {
        let x = x.as_slice().map_err(err)?;
        if x.len() != self.width {
            return Err(err(format!("{} values for {} inputs", x.len(), self.width)));
        }
        let step = match &mut self.kind {
            Kind::Linear(e) => e.update(x, y),
            Kind::Model(e) => e.update(x, y),
        }
        .map_err(err)?;
        Ok((step.prediction_error, step.innovation_variance))
    }

    /// Back to the estimator as it was built: its starting estimate and covariance, no sample.
    fn reset(&mut self) {
        self.kind = self.initial.clone();
    }

    /// An independent copy (`copy.copy`): it continues bit for bit as this one would.
    fn __copy__(&self) -> Self {
        self.clone()
    }

    /// As `__copy__` (the estimator holds no Python objects).
    fn __deepcopy__(&self, _memo: &Bound<'_, PyAny>) -> Self {
        self.clone()
    }

    /// `pickle`: the whole state as bytes ([`_estimator`] rebuilds it).
    fn __reduce__<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyAny>, (Bound<'py, pyo3::types::PyBytes>,))> {
        let bytes = rmp_serde::to_vec_named(self).map_err(err)?;
        Ok((
            py.import("physid._physid")?.getattr("_estimator")?,
            (pyo3::types::PyBytes::new(py, &bytes),),
        ))
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
