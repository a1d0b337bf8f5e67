//! `physid demo`: the chain on the built-in virtual test cell, as typed results.
//!
//! 1. Shaft monitoring (ch. 6): the T01 scenario with a stiffness fault (1250 → 1100 N·m/rad at
//!    5 s), tracked by RLS; the alarm must name K.
//! 2. Friction design ranking (§7.2, Table 7.1) over the thesis's 27 operating points.
//! 3. Cyclic-torque identifiability (§8, Table 8.1): which of the 15 parameters of Eq. 8.2 the
//!    steady-speed (T1) and the ramp (T2) recordings support. (Eq. 8.2 with the thesis's
//!    closed forms is invariant under r → λr, L → λL, b → b/√λ, M_rec → M_rec/λ²: only
//!    three of those four are ever identifiable together — the analysis finds that.)

use crate::friction_rank::{friction_rank, RankGrid, RankTable};
use crate::shaft_monitor::{monitor_shaft, MonitorConfig, MonitorMethod, ShaftMonitor};
use physid_core::Recording;
use physid_ident::{analyse, Analysis, Cutoff, Data, IdentConfig};
use physid_models::cyclic_torque::CyclicTorque;
use physid_models::friction::thesis_preset;
use physid_models::friction_fit::fit_friction_cubic;
use physid_sim::params::CellParams;
use physid_sim::run::{simulate, OutputBasis, RunOptions};
use physid_sim::scenario::{named, Fault};
use thiserror::Error;

/// Errors of the demo (each names its stage).
#[derive(Debug, Error)]
#[error("{stage}: {detail}")]
pub struct DemoError {
    /// The stage.
    pub stage: &'static str,
    /// What went wrong.
    pub detail: String,
}

fn err(stage: &'static str) -> impl Fn(String) -> DemoError {
    move |detail| DemoError { stage, detail }
}

/// One cyclic-torque identifiability result.
#[derive(Debug, Clone)]
pub struct TorqueIdent {
    /// Scenario.
    pub scenario: String,
    /// The analysis.
    pub analysis: Analysis,
    /// Estimable count (thesis cut-off: repeat).
    pub estimable: usize,
}

/// The demo's results.
#[derive(Debug, Clone)]
pub struct Demo {
    /// The shaft recording (simulated).
    pub shaft_recording: Recording,
    /// The shaft monitor's configuration and result (RLS).
    pub shaft: (MonitorConfig, ShaftMonitor),
    /// The three estimators on the same recording (thesis Fig. 6.9's comparison).
    pub shaft_methods: Vec<ShaftMonitor>,
    /// The injected fault.
    pub fault: String,
    /// The friction ranking.
    pub friction: RankTable,
    /// Cyclic-torque identifiability on T1 and T2.
    pub torque: Vec<TorqueIdent>,
}

/// The relative cut-off of the cyclic-torque ranking: residuals below 1e-6 of the first are
/// at the level of the measured oil temperature's noise (0.1 K on 363 K, squared), which is all
/// that separates the temperature terms of the friction cubic at a constant oil temperature.
pub const TORQUE_CUTOFF: f64 = 1e-6;

/// The cyclic-torque model's nominal parameters for this engine: the cell's geometry and
/// reciprocating mass, the friction cubic fitted to the mean-value model (thesis preset) over
/// 500–1500 rpm and 20–100 °C.
pub fn cyclic_torque_nominal(p: &CellParams) -> Result<[f64; 15], String> {
    let (d, st) = thesis_preset();
    let n: Vec<f64> = (0..11).map(|k| 500.0 + 100.0 * k as f64).collect();
    let t: Vec<f64> = (0..9).map(|k| 20.0 + 10.0 * k as f64).collect();
    let fit = fit_friction_cubic(&d, &st, 101.0, 101.0, &n, &t).map_err(|e| e.to_string())?;
    let e = &p.engine;
    let mut v = [0.0; 15];
    v[..5].copy_from_slice(&[e.m_rec, e.bore, e.rod, e.crank_radius, e.pin_offset]);
    v[5..].copy_from_slice(&fit.coefficients);
    Ok(v)
}

/// The cyclic-torque model's data columns from a crank-angle recording of the cell.
pub fn torque_data(rec: &Recording) -> Result<(Vec<Vec<f64>>, Vec<f64>), String> {
    let get = |n: &str| rec.values(n).map(|v| v.to_vec()).map_err(|e| e.to_string());
    let t_oil_c: Vec<f64> = get("T_oil")?.iter().map(|k| k - 273.15).collect();
    Ok((
        vec![
            get("theta_en")?,
            get("omega_en")?,
            get("alpha_en")?,
            get("p_cyl")?,
            get("p_crank")?,
            t_oil_c,
        ],
        get("torque_engine")?,
    ))
}

/// Run the demo; `progress(stage, fraction)`.
pub fn run_demo(mut progress: impl FnMut(&str, f64)) -> Result<Demo, DemoError> {
    // 1. Shaft.
    let fault = "shaft.k=1100@5".to_string();
    let mut s = named("shaft-steady").ok_or_else(|| err("shaft")("no scenario".into()))?;
    s.settle = 0.5;
    let opts = RunOptions {
        duration: Some(8.0),
        faults: vec![Fault::parse(&fault).map_err(err("shaft"))?],
        ..Default::default()
    };
    let rec = simulate(&s, &opts, |f| {
        progress("simulating T01 with a shaft fault", 0.4 * f)
    })
    .map_err(|e| err("shaft")(e.to_string()))?;
    let cfg = MonitorConfig::default();
    let mon = monitor_shaft(&rec, &cfg).map_err(|e| err("shaft")(e.to_string()))?;
    let mut shaft_methods = Vec::new();
    for method in [
        MonitorMethod::Rls,
        MonitorMethod::Rlsvf,
        MonitorMethod::Dsfc,
    ] {
        let c = MonitorConfig {
            method,
            ..cfg.clone()
        };
        shaft_methods.push(monitor_shaft(&rec, &c).map_err(|e| err("shaft")(e.to_string()))?);
    }
    progress("friction ranking", 0.45);
    // 2. Friction ranking.
    let (d, st) = thesis_preset();
    let friction = friction_rank(&d, &st, &RankGrid::default(), &[])
        .map_err(|e| err("friction")(e.to_string()))?;
    // 3. Cyclic-torque identifiability, T1 vs T2.
    let nominal = cyclic_torque_nominal(&CellParams::default()).map_err(err("torque"))?;
    let model = CyclicTorque::default();
    let mut torque = Vec::new();
    for (k, name) in ["torque-steady", "torque-ramp"].iter().enumerate() {
        let mut sc = named(name).ok_or_else(|| err("torque")(format!("no scenario {name}")))?;
        sc.settle = 0.5;
        let o = RunOptions {
            duration: Some(3.0),
            basis: OutputBasis::Crank(1.0),
            ..Default::default()
        };
        let r = simulate(&sc, &o, |f| {
            progress(&format!("simulating {name}"), 0.5 + 0.25 * (k as f64 + f))
        })
        .map_err(|e| err("torque")(e.to_string()))?;
        let (cols, y) = torque_data(&r).map_err(err("torque"))?;
        let data = Data {
            inputs: cols.iter().map(|c| c.as_slice()).collect(),
            y: Some(&y),
        };
        // δ's nominal value is 0: its relative sensitivity is undefined, and the engine's
        // pin offset is known by design — held fixed.
        let free: Vec<usize> = (0..15).filter(|&j| j != 4).collect();
        let a = analyse(&model, &data, &nominal, &free, IdentConfig::default())
            .map_err(|e| err("torque")(e.to_string()))?;
        let estimable = a.estimable(Cutoff::Relative(TORQUE_CUTOFF));
        torque.push(TorqueIdent {
            scenario: name.to_string(),
            analysis: a,
            estimable,
        });
    }
    progress("done", 1.0);
    Ok(Demo {
        shaft_recording: rec,
        shaft: (cfg, mon),
        shaft_methods,
        fault,
        friction,
        torque,
    })
}
