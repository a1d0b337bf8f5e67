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

mod angle;
mod design;
mod estimator;
mod live;
mod recording;
mod twin;

pub use estimator::Estimator;
pub use live::LiveStream;
pub use recording::Recording;

use numpy::{IntoPyArray, PyReadonlyArray1};
use physid_core::ParamModel;
use physid_estim::MethodName;
use physid_expr::ExprModel;
use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
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
/// (engine, shaft), the coefficients' ranking with `cutoff` (or those in `estimate`), DSFC
/// (`lam`, `s0`). Returns the summary (JSON text) and the per-cycle tracks.
#[pyfunction]
#[pyo3(signature = (rec, preset, set, source, cutoff, s0, lam, transient_s, p_atm_kpa, estimate))]
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
    estimate: Option<Vec<String>>,
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
    cfg.estimate = estimate;
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

/// Cylinder-pressure analysis per cycle (`physid cycles`) of `channel` in a crank-angle
/// recording: with `geometry` (bore, stroke, rod, compression ratio) IMEP, the polytropic
/// exponents and the combustion (heat release with `gamma`, MFB10/50/90, fired or motored);
/// `peg` as `--peg` takes it. Returns the summary (JSON text: channel, unit, cov_imep, lnv_imep,
/// notes, dropouts) and the per-cycle columns.
#[pyfunction]
#[pyo3(signature = (rec, channel, geometry, peg, gamma, mfb, knock, gas_temperature, wall_heat, mfb_method, rw_exponent, torque, cylinders, pressure_lowpass, friction))]
#[allow(clippy::too_many_arguments)]
fn cycles<'py>(
    py: Python<'py>,
    rec: &Recording,
    channel: &str,
    geometry: Option<(f64, f64, f64, f64)>,
    peg: Option<&str>,
    gamma: f64,
    mfb: Vec<f64>,
    knock: Option<(f64, f64, f64, f64, f64)>,
    gas_temperature: Option<(f64, f64)>,
    wall_heat: Option<(f64, f64)>,
    mfb_method: &str,
    rw_exponent: Option<f64>,
    torque: Option<String>,
    cylinders: u32,
    pressure_lowpass: Option<f64>,
    friction: Option<(String, Vec<String>, f64, f64, f64)>,
) -> PyResult<(String, Bound<'py, PyDict>)> {
    use physid_apps::combustion::HeatRelease;
    use physid_apps::pressure::{CycleAnalyser, Geometry, Pegging};
    let peg = Pegging::parse(peg).map_err(err)?;
    let method =
        physid_apps::combustion::BurnMethod::parse(mfb_method, rw_exponent).map_err(err)?;
    let geometry = geometry.map(|(bore, stroke, rod, compression_ratio)| Geometry {
        bore,
        stroke,
        rod,
        compression_ratio,
    });
    let friction = friction
        .map(|(preset, set, p_int_kpa, p_atm_kpa, t_oil_c)| {
            physid_apps::fmep_model::FrictionModel::new(
                &preset, &set, p_int_kpa, p_atm_kpa, t_oil_c,
            )
        })
        .transpose()
        .map_err(err)?;
    let inner = &rec.inner;
    let a = py
        .detach(|| {
            let a = CycleAnalyser::new(inner, channel, geometry.as_ref(), peg)?.with_heat_release(
                HeatRelease {
                    gamma,
                    mfb,
                    temperature: gas_temperature.map(|(ivc_deg, t_ivc_k)| {
                        physid_apps::combustion::GasTemperature { ivc_deg, t_ivc_k }
                    }),
                    wall: wall_heat.map(|(t_wall_k, c2)| physid_apps::combustion::WallHeat {
                        t_wall_k,
                        c1: physid_apps::combustion::WOSCHNI_C1,
                        c2,
                    }),
                    method,
                    ..HeatRelease::default()
                },
            )?;
            let a = match torque {
                Some(channel) => {
                    a.with_brake(inner, physid_apps::per_cycle::Brake { channel, cylinders })?
                }
                None => a,
            };
            let a = match friction {
                Some(model) => a.with_friction_model(model)?,
                None => a,
            };
            let a = match pressure_lowpass {
                Some(cutoff_hz) => a.with_lowpass(physid_apps::per_cycle::PressureLowpass {
                    cutoff_hz,
                    order: physid_apps::per_cycle::LOWPASS_ORDER,
                })?,
                None => a,
            };
            let mut a = match knock {
                Some((lo, hi, from, to, threshold_pa)) => {
                    a.with_knock(physid_apps::knock::Knock {
                        band_hz: (lo, hi),
                        window: (from, to),
                        threshold_pa,
                    })?
                }
                None => a,
            };
            a.push(inner)?;
            a.finish()
        })
        .map_err(err)?;
    let summary = serde_json::json!({
        "channel": a.channel,
        "unit": a.unit,
        "cov_imep": a.cov_imep,
        "lnv_imep": a.lnv_imep,
        "notes": a.notes,
        "dropouts": a.dropouts,
    });
    let columns = a.columns().into_iter().map(|(n, _, v)| (n, v)).collect();
    Ok((summary.to_string(), arrays(py, columns)?))
}

/// Application 3, the cyclic engine torque (thesis ch. 8, Eq. 8.2): the ranking of its 15
/// parameters (nominal: the test cell's engine, overridden by `nominal`), the estimable ones
/// (`cutoff`, the application's default if `None`; `fixed` held) estimated by `method` (ekf, ukf, srukf) with `p0`, `r2` (the batch
/// fit's residual variance if `None`), random walks `track`. Returns the summary (JSON text)
/// and the tracks.
#[pyfunction]
#[pyo3(signature = (rec, method, nominal, fixed, cutoff, estimate, p0, r2, track))]
#[allow(clippy::too_many_arguments)]
fn torque_fit<'py>(
    py: Python<'py>,
    rec: &Recording,
    method: &str,
    nominal: BTreeMap<String, f64>,
    fixed: Vec<String>,
    cutoff: Option<&str>,
    estimate: Option<Vec<String>>,
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
    cfg.method = MethodName::parse_model_based(method).map_err(|e| err(format!("method {e}")))?;
    cfg.fixed = fixed;
    if let Some(c) = cutoff {
        cfg.selection = physid_ident::Selection::parse(c).map_err(err)?;
    }
    cfg.estimate = estimate;
    cfg.chosen().map_err(|e| err(format!("estimate: {e}")))?;
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

/// The inputs of the formula `expr` whose parameters are `names`: every other name in it, in
/// order of first appearance.
#[pyfunction]
fn formula_inputs(expr: &str, names: Vec<String>) -> PyResult<Vec<String>> {
    Ok(ExprModel::parse(expr, &names)
        .map_err(err)?
        .inputs()
        .to_vec())
}

/// The module.
#[pymodule]
fn _physid(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("Error", m.py().get_type::<Error>())?;
    m.add_class::<Recording>()?;
    m.add_class::<Estimator>()?;
    m.add_function(wrap_pyfunction!(estimator::_estimator, m)?)?;
    m.add_function(wrap_pyfunction!(formula_inputs, m)?)?;
    m.add_function(wrap_pyfunction!(recording::read, m)?)?;
    m.add_function(wrap_pyfunction!(identify, m)?)?;
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(monitor_shaft, m)?)?;
    m.add_function(wrap_pyfunction!(design::design, m)?)?;
    m.add_function(wrap_pyfunction!(friction_fit, m)?)?;
    m.add_function(wrap_pyfunction!(torque_fit, m)?)?;
    m.add_function(wrap_pyfunction!(twin::twin_calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(twin::twin_check, m)?)?;
    m.add_function(wrap_pyfunction!(cycles, m)?)?;
    m.add_function(wrap_pyfunction!(live::live, m)?)?;
    m.add_class::<LiveStream>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
