//! The built-in virtual test cell as the applications see it: the values they start from (the
//! cell engine's friction model, the cyclic-torque model's nominal parameters) and the truth a
//! simulated recording carries. The one module of the applications that reads `physid-sim` for
//! values rather than to run it (the demo and pipeline files run the cell).

use crate::error::AppError;
use physid_core::Recording;
use physid_models::friction::{thesis_preset, Design, Settings};
use physid_models::friction_fit::fit_friction_cubic;
pub use physid_sim::params::CellParams;

/// The `cell` friction preset: the friction model of the built-in virtual test cell's engine.
pub fn cell_friction_model() -> (Design<f64>, Settings) {
    let p = CellParams::default();
    physid_sim::engine::Engine::new(&p.engine, &p.ambient).friction_model()
}

/// The cyclic-torque model's nominal parameters for the virtual test cell's engine: its
/// geometry and reciprocating mass, the friction cubic fitted to the mean-value model (thesis
/// preset) over 500–1500 rpm and 20–100 °C (Fig. 8.1).
pub fn cyclic_torque_nominal(p: &CellParams) -> Result<[f64; 15], AppError> {
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

/// The true value of the cell parameter at `path` (a `--list-params` path, e.g. `engine.m_rec`)
/// at the times `t` of a simulated recording that carries it (its faults applied); `None` for a
/// recording that does not.
pub fn truth(rec: &Recording, path: &str, t: &[f64]) -> Option<Vec<f64>> {
    physid_sim::run::parameter_truth(rec, path, t)
}
