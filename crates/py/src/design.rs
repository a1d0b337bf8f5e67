//! `physid.design`: experiment design (issue 45, docs/design.md) for the shaft monitor and the
//! friction characterisation and the cyclic-torque fit.

use crate::{arrays, err};
use physid_apps::design::friction::{design_friction, select as friction_select, FrictionDesign};
use physid_apps::design::information::Criterion;
use physid_apps::design::profile::{Limits, ThrottleDraw};
use physid_apps::design::shaft::{design_shaft, select, ShaftDesign, PARAMS};
use physid_apps::design::torque::{design_torque, select as torque_select, TorqueDesign};
use physid_apps::design::{Design, Designed};
use physid_apps::friction_fit::TorqueSource;
use physid_apps::shaft_monitor::{MonitorConfig, MonitorMethod};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::collections::BTreeMap;

/// Experiment design for `app` (`shaft`: the shaft monitor with `method`, `lam` (0.98),
/// `cutoff_hz`, `rate_hz`; `friction`: the friction fit with `lam` (1), `s0`, `source`;
/// `torque`: the cyclic-torque fit's UKF, `alongside` estimated with `params`):
/// `candidates` profiles of `duration` s within `limits`
/// (`speed=LOW:HIGH,throttle=LOW:HIGH,dspeed=RATE`), judged for `params` by `criterion` on a
/// recording at `sample_rate`, the cell with `set`. Returns the result (JSON text) and arrays:
/// the chosen profile (`t`, `speed_demand_rpm` — `torque_demand_nm` in torque mode —
/// `throttle_deg`, every 50 ms; multisines drawn in `band` [Hz]) and its predicted
/// standard errors (`curve_t` and one per parameter).
#[pyfunction]
#[pyo3(signature = (app, params, criterion, target_rel_se, limits, duration, candidates, seed, threads, method, lam, cutoff_hz, rate_hz, s0, source, sample_rate, set, alongside, band))]
#[allow(clippy::too_many_arguments)]
pub fn design<'py>(
    py: Python<'py>,
    app: &str,
    params: Vec<String>,
    criterion: &str,
    target_rel_se: Option<f64>,
    limits: &str,
    duration: f64,
    candidates: usize,
    seed: u64,
    threads: usize,
    method: &str,
    lam: Option<f64>,
    cutoff_hz: f64,
    rate_hz: f64,
    s0: f64,
    source: &str,
    sample_rate: f64,
    set: BTreeMap<String, f64>,
    alongside: Vec<String>,
    band: (f64, f64),
) -> PyResult<(String, Bound<'py, PyDict>)> {
    let mut cell = physid_sim::params::CellParams::default();
    for (k, v) in &set {
        cell.set(k, *v).map_err(err)?;
    }
    let mut settings: Vec<(String, f64)> = set.into_iter().collect();
    let mut cell = physid_apps::design::run::candidate_cell(cell, &settings);
    let design = |names: Vec<String>, selected: Vec<usize>, throttle| -> PyResult<Design> {
        Ok(Design {
            names,
            selected,
            criterion: criterion
                .parse::<Criterion>()
                .map_err(|e| err(format!("criterion {e}")))?,
            target_rel_se,
            limits: Limits::parse(limits).map_err(|e| err(format!("limits {e}")))?,
            throttle,
            band,
            duration,
            candidates,
            seed,
            threads,
        })
    };
    let r: Designed = match app {
        "shaft" => {
            let chosen = select(&params, &mut cell).map_err(err)?;
            settings.extend(chosen.set);
            let shaft = ShaftDesign {
                monitor: MonitorConfig {
                    method: method
                        .parse::<MonitorMethod>()
                        .map_err(|e| err(format!("method {e}")))?,
                    lambda: lam.unwrap_or(0.98),
                    cutoff_hz,
                    rate_hz,
                    ..MonitorConfig::default()
                },
                cell,
                rate_hz: sample_rate,
            };
            let names = PARAMS.iter().map(|s| s.to_string()).collect();
            let d = design(names, chosen.selected, ThrottleDraw::Linear)?;
            py.detach(|| design_shaft(&shaft, &d, &settings, &|_| {}))
                .map_err(err)?
        }
        "friction" => {
            let names = friction_select(&params).map_err(err)?;
            let mut fd = FrictionDesign::new(cell, sample_rate);
            fd.fit.lambda = lam.unwrap_or(1.0);
            fd.fit.s0 = s0;
            fd.fit.source = TorqueSource::parse(source)
                .ok_or_else(|| err(format!("source '{source}': expected engine or shaft")))?;
            let selected = (0..names.len()).collect();
            let d = design(names, selected, ThrottleDraw::Pressure)?;
            let mut r = py
                .detach(|| design_friction(&fd, &d, &|_| {}))
                .map_err(err)?;
            r.scenario.set.extend(settings);
            r
        }
        "torque" => {
            let designed = torque_select(&params).map_err(err)?;
            let mut names = designed.clone();
            for a in torque_select(&alongside).map_err(err)? {
                if !names.contains(&a) {
                    names.push(a);
                }
            }
            let td = TorqueDesign::new(cell).map_err(err)?;
            let selected = (0..designed.len()).collect();
            let d = design(names, selected, ThrottleDraw::Linear)?;
            let mut r = py.detach(|| design_torque(&td, &d, &|_| {})).map_err(err)?;
            r.scenario.set.extend(settings);
            r
        }
        other => {
            return Err(err(format!(
                "app '{other}': expected shaft, friction or torque"
            )))
        }
    };
    let mut json = serde_json::to_value(&r).map_err(err)?;
    if let Some(o) = json.as_object_mut() {
        let text = r.scenario.to_toml().map_err(err)?;
        o.insert("scenario_toml".into(), text.into());
    }
    let json = json.to_string();
    let n = (r.scenario.duration / 0.05).ceil() as usize;
    let t: Vec<f64> = (0..=n).map(|k| k as f64 * 0.05).collect();
    let mut cols = vec![
        (
            if r.scenario.torque_mode {
                "torque_demand_nm"
            } else {
                "speed_demand_rpm"
            }
            .to_string(),
            t.iter().map(|&x| r.scenario.speed.value(x)).collect(),
        ),
        (
            "throttle_deg".to_string(),
            t.iter().map(|&x| r.scenario.throttle.value(x)).collect(),
        ),
        ("t".to_string(), t),
        ("curve_t".to_string(), r.chosen.curve.t.clone()),
    ];
    for (p, c) in r.params.iter().zip(&r.chosen.curve.std_err) {
        cols.push((p.clone(), c.clone()));
    }
    Ok((json, arrays(py, cols)?))
}
