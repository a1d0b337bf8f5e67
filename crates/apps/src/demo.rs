//! `physid demo`: the chain on the built-in virtual test cell, as typed results.
//!
//! 1. Shaft monitoring (ch. 6): the T01 scenario with a stiffness fault (1250 → 1100 N·m/rad at
//!    5 s), tracked by RLS; the alarm must name K.
//! 2. Friction design ranking (§7.2, Table 7.1) over the thesis's 27 operating points.
//! 3. Friction characterisation (§7.3): the `friction-sweep` tests (the engine has 0.45 of the
//!    nominal model's mechanical friction) → identifiability of c1 … c20 → DSFC → prediction
//!    error.
//! 4. Cyclic-torque identifiability (§8, Table 8.1): which of the 15 parameters of Eq. 8.2 the
//!    steady-speed (T1) and the ramp (T2) recordings support. (Eq. 8.2 with the thesis's
//!    closed forms is invariant under r → λr, L → λL, b → b/√λ, M_rec → M_rec/λ²: only
//!    three of those four are ever identifiable together — the analysis finds that.)
//! 5. Cyclic-torque estimation (§8): an engine whose reciprocating mass is 5 % above nominal on
//!    the ramp test, the crank radius known by design, the UKF on the estimable subset.

use crate::friction_fit::{friction_fit, FrictionFit, FrictionFitConfig};
use crate::friction_rank::{friction_rank, RankGrid, RankTable};
use crate::shaft_monitor::{monitor_shaft, MonitorConfig, MonitorMethod, ShaftMonitor};
use crate::torque_fit::{
    cyclic_torque_nominal, torque_fit, torque_identifiability, TorqueData, TorqueFit,
    TorqueFitConfig,
};
use physid_core::Recording;
use physid_ident::Analysis;
use physid_models::friction::thesis_preset;
use physid_sim::engine::Engine;
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

fn err<E: std::fmt::Display>(stage: &'static str) -> impl Fn(E) -> DemoError {
    move |detail| DemoError {
        stage,
        detail: detail.to_string(),
    }
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
    /// The friction characterisation's configuration and result.
    pub friction_fit: (FrictionFitConfig, FrictionFit),
    /// Cyclic-torque identifiability on T1 and T2.
    pub torque: Vec<TorqueIdent>,
    /// The cyclic-torque fit: configuration, result, and the engine's true M_rec, b, L, r.
    pub torque_fit: (TorqueFitConfig, TorqueFit, [f64; 4]),
    /// The test cell's solver (`solver.order`) every recording was simulated with.
    pub solver_order: f64,
}

/// Run the demo with the test cell's solver `solver_order` (`solver.order`: 2, the default, or
/// 4, the RK4 reference); `progress(stage, fraction)`.
pub fn run_demo(solver_order: f64, mut progress: impl FnMut(&str, f64)) -> Result<Demo, DemoError> {
    let cell = CellParams {
        order: solver_order,
        ..CellParams::default()
    };
    cell.validate().map_err(err("test cell"))?;
    let defaults = || RunOptions {
        params: cell.clone(),
        ..Default::default()
    };
    // 1. Shaft.
    let fault = "shaft.k=1100@5".to_string();
    let mut s = named("shaft-steady").ok_or_else(|| err("shaft")("no scenario"))?;
    s.settle = 0.5;
    let opts = RunOptions {
        duration: Some(8.0),
        faults: vec![Fault::parse(&fault).map_err(err("shaft"))?],
        ..defaults()
    };
    let rec = simulate(&s, &opts, |f| {
        progress("simulating T01 with a shaft fault", 0.4 * f)
    })
    .map_err(|e| err("shaft")(e.to_string()))?;
    let cfg = MonitorConfig::default();
    let mon = monitor_shaft(&rec, &cfg).map_err(|e| err("shaft")(e.to_string()))?;
    let mut shaft_methods = Vec::new();
    for method in [
        MonitorMethod::Rlsf,
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
    // 3. Friction characterisation on the four friction-sweep tests.
    let sweep = named("friction-sweep").ok_or_else(|| err("friction")("no scenario"))?;
    let o = RunOptions {
        basis: OutputBasis::Crank(1.0),
        ..defaults()
    };
    let rec_f = simulate(&sweep, &o, |f| {
        progress("simulating the friction sweep", 0.45 + 0.3 * f)
    })
    .map_err(|e| err("friction")(e.to_string()))?;
    let (design, settings) = Engine::new(&cell.engine, &cell.ambient).friction_model();
    let fcfg = FrictionFitConfig::new(design, settings);
    let ffit = friction_fit(&rec_f, &fcfg).map_err(|e| err("friction")(e.to_string()))?;
    // 4. Cyclic-torque identifiability, T1 vs T2.
    let nominal = cyclic_torque_nominal(&cell).map_err(err("torque"))?;
    let tcfg = TorqueFitConfig::new(nominal);
    let mut torque = Vec::new();
    for (k, name) in ["torque-steady", "torque-ramp"].iter().enumerate() {
        let mut sc = named(name).ok_or_else(|| err("torque")(format!("no scenario {name}")))?;
        sc.settle = 0.5;
        let o = RunOptions {
            duration: Some(3.0),
            basis: OutputBasis::Crank(1.0),
            ..defaults()
        };
        let r = simulate(&sc, &o, |f| {
            progress(&format!("simulating {name}"), 0.75 + 0.08 * (k as f64 + f))
        })
        .map_err(|e| err("torque")(e.to_string()))?;
        let data = TorqueData::from_recording(&r).map_err(|e| err("torque")(e.to_string()))?;
        // δ's nominal value is 0: its relative sensitivity is undefined, and the engine's
        // pin offset is known by design — held fixed.
        let (analysis, est) =
            torque_identifiability(&data, &tcfg.nominal, &tcfg.fixed, &tcfg.selection)
                .map_err(|e| err("torque")(e.to_string()))?;
        torque.push(TorqueIdent {
            scenario: name.to_string(),
            analysis,
            estimable: est.len(),
        });
    }
    // 5. Cyclic-torque estimation: an engine 5 % heavier in M_rec on the ramp, r known.
    let mut sc = named("torque-ramp").ok_or_else(|| err("torque")("no scenario"))?;
    sc.settle = 0.5;
    let mut o = RunOptions {
        basis: OutputBasis::Crank(1.0),
        ..defaults()
    };
    let e = &cell.engine;
    let truth = [e.m_rec * 1.05, e.bore, e.rod, e.crank_radius];
    o.params
        .set("engine.m_rec", truth[0])
        .map_err(|e| err("torque")(e.to_string()))?;
    let r = simulate(&sc, &o, |f| {
        progress("simulating an engine off the line", 0.91 + 0.07 * f)
    })
    .map_err(|e| err("torque")(e.to_string()))?;
    let mut fit_cfg = tcfg.clone();
    fit_cfg.fixed.push("r".into());
    let tfit = torque_fit(&r, &fit_cfg).map_err(|e| err("torque")(e.to_string()))?;
    progress("done", 1.0);
    Ok(Demo {
        shaft_recording: rec,
        shaft: (cfg, mon),
        shaft_methods,
        fault,
        friction,
        friction_fit: (fcfg, ffit),
        torque,
        torque_fit: (fit_cfg, tfit, truth),
        solver_order,
    })
}
