//! `physid.twin_calibrate` and `physid.twin_check`: the self-calibrated test cell (docs/twin.md).

use crate::err;
use crate::recording::Recording;
use physid_apps::twin::calibrate::DEFAULT_PARAMS;
use physid_apps::twin::{calibrate, check, CalibrateConfig, Demand, Replay, Uncertainty};
use pyo3::prelude::*;
use std::collections::BTreeMap;

/// The cell with `set` over the defaults.
fn cell_of(set: &BTreeMap<String, f64>) -> PyResult<physid_sim::params::CellParams> {
    let mut cell = physid_sim::params::CellParams::default();
    for (k, v) in set {
        cell.set(k, *v).map_err(err)?;
    }
    Ok(cell)
}

/// What the recording's `speed_demand` holds, by name (`"speed"`, `"torque"`; `None`: its
/// metadata's).
fn demand_of(demand: Option<String>) -> PyResult<Option<Demand>> {
    demand.map(|d| d.parse::<Demand>().map_err(err)).transpose()
}

/// Calibrate the cell (`set` over the defaults) on `rec`: the calibration as JSON, each
/// parameter under its path, and the calibrated cell's scenario file (TOML).
#[pyfunction]
#[pyo3(signature = (rec, params, channels, set, max_rel_se, threads, demand))]
#[allow(clippy::too_many_arguments)]
pub fn twin_calibrate(
    py: Python<'_>,
    rec: &Recording,
    params: Option<Vec<String>>,
    channels: Option<Vec<String>>,
    set: BTreeMap<String, f64>,
    max_rel_se: f64,
    threads: usize,
    demand: Option<String>,
) -> PyResult<(String, String)> {
    let cell = cell_of(&set)?;
    let replay =
        Replay::new(&rec.inner, channels.as_deref(), demand_of(demand)?, &cell).map_err(err)?;
    let cfg = CalibrateConfig {
        cell: cell.clone(),
        params: params.unwrap_or_else(|| DEFAULT_PARAMS.iter().map(|s| s.to_string()).collect()),
        max_rel_se,
        threads,
        ..CalibrateConfig::default()
    };
    let cal = py.detach(|| calibrate(&replay, &cfg)).map_err(err)?;
    let mut scenario = replay.scenario.clone();
    scenario.name = "twin".into();
    scenario.set.extend(set);
    for p in cal.params.iter().filter(|p| p.estimable) {
        scenario.set.insert(p.path.clone(), p.value);
    }
    let params: serde_json::Map<String, serde_json::Value> = cal
        .params
        .iter()
        .map(|p| Ok((p.path.clone(), serde_json::to_value(p).map_err(err)?)))
        .collect::<PyResult<_>>()?;
    let json = serde_json::json!({
        "params": params,
        "covariance": cal.covariance,
        "channels": cal.channels,
        "collinear": cal.collinear,
        "iterations": cal.iterations,
        "samples": cal.samples,
        "replays": cal.replays,
    });
    Ok((json.to_string(), scenario.to_toml().map_err(err)?))
}

/// Each channel's NRMSE on `rec` with the cell (`set` over the defaults) and with it
/// calibrated (`calibrated` over that), and with `calibration` (a calibration's JSON: its
/// covariance and channel noise) the residual's band, as JSON.
#[pyfunction]
#[pyo3(signature = (rec, calibrated, channels, set, calibration, demand))]
pub fn twin_check(
    py: Python<'_>,
    rec: &Recording,
    calibrated: BTreeMap<String, f64>,
    channels: Option<Vec<String>>,
    set: BTreeMap<String, f64>,
    calibration: Option<String>,
    demand: Option<String>,
) -> PyResult<String> {
    let uncertainty = match calibration {
        Some(s) => {
            let v: serde_json::Value = serde_json::from_str(&s).map_err(err)?;
            Some(Uncertainty::from_json(&v).map_err(err)?)
        }
        None => None,
    };
    let nominal = cell_of(&set)?;
    let mut cal = nominal.clone();
    for (k, v) in &calibrated {
        cal.set(k, *v).map_err(err)?;
    }
    let replay = Replay::new(
        &rec.inner,
        channels.as_deref(),
        demand_of(demand)?,
        &nominal,
    )
    .map_err(err)?;
    let checks = py
        .detach(|| check(&replay, &nominal, &cal, uncertainty.as_ref()))
        .map_err(err)?;
    let map: serde_json::Map<String, serde_json::Value> = checks
        .iter()
        .map(|c| Ok((c.name.clone(), serde_json::to_value(c).map_err(err)?)))
        .collect::<PyResult<_>>()?;
    Ok(serde_json::json!({"channels": map, "samples": replay.n}).to_string())
}
