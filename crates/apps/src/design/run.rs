//! A candidate on the virtual cell without sensor noise, chunk by chunk ([`run_noiseless`]),
//! within the cell's envelope: a candidate the cell cannot follow (its drive's current or
//! voltage limit) is left out of a design, with the speed it reached.

use crate::error::AppError;
use physid_core::Recording;
use physid_sim::params::CellParams;

/// The solver's step [deg] a design's candidates run at unless `solver.step_deg` is set: 2°,
/// half the steps of `physid simulate`'s 1°. With the crank angle's column in its Jacobian the
/// cell's pressures are within 2.2e-4 / 4.2e-4 of the converged solution's peak at 2° (full /
/// shut throttle), closer than the 1° step's 5.8e-4 / 1.9e-3 before that column
/// (docs/simulate.md); a design's predicted standard errors move by under 0.2 % and it chooses
/// the same candidate (`tests/design.rs`, BENCHMARKS.md).
pub const CANDIDATE_STEP_DEG: f64 = 2.0;

/// The cell a design runs its candidates on: `cell` with the `settings` given for it (the
/// `--set` pairs), at [`CANDIDATE_STEP_DEG`] unless they set `solver.step_deg`.
pub fn candidate_cell(mut cell: CellParams, settings: &[(String, f64)]) -> CellParams {
    if !settings.iter().any(|(k, _)| k == "solver.step_deg") {
        cell.step_deg = CANDIDATE_STEP_DEG;
    }
    cell
}
use physid_sim::run::{OutputBasis, Run, RunOptions};
use physid_sim::scenario::Scenario;

/// Run `scenario` on `cell` with the sensor settings `quiet` (their noise) at 0 — the
/// scenario's own noise settings too — recording `keep` (and `omega_en`, `speed_demand`) on
/// `basis` (a sample rate or a crank-angle step), each second's chunk handed to `take`; refused
/// once the engine's speed leaves its demand ([`Envelope`]) — in torque mode, once it leaves
/// the scenario's speed range (the run stops there).
pub fn run_noiseless(
    cell: &CellParams,
    quiet: &[&str],
    scenario: &Scenario,
    basis: OutputBasis,
    keep: &[&str],
    mut take: impl FnMut(&Recording) -> Result<(), AppError>,
) -> Result<(), AppError> {
    let mut params = cell.clone();
    for path in quiet {
        params.set(path, 0.0)?;
    }
    let mut scenario = scenario.clone();
    // The scenario's own settings apply over the cell's; its noise too must go.
    scenario
        .set
        .retain(|k, _| !k.ends_with(".noise") && !k.ends_with(".quantum"));
    let opts = RunOptions {
        params,
        basis,
        stream: true,
        ..RunOptions::default()
    };
    let mut run = Run::new(&scenario, &opts)?;
    let mut kept: Vec<&str> = keep.to_vec();
    for c in ["omega_en", "speed_demand"] {
        if !kept.contains(&c) {
            kept.push(c);
        }
    }
    run.keep_channels(&kept)?;
    let mut envelope = Envelope::default();
    let mut t = 0.0;
    while !run.is_done() {
        t += 1.0;
        run.step_until(t)?;
        let chunk = run.drain()?;
        // A torque demand holds no speed to follow: the run itself stops where the engine
        // leaves the scenario's speed range.
        if !chunk.is_empty() && !run.torque_mode() {
            envelope.check(
                chunk.values("t")?,
                chunk.values("omega_en")?,
                chunk.values("speed_demand")?,
            )?;
        }
        if !chunk.is_empty() {
            take(&chunk)?;
        }
    }
    Ok(())
}

/// How far the engine's speed may stay from the demand, and for how long [s], before a test
/// is outside the cell's envelope: the drive cannot hold it (its current or voltage limit).
const ENVELOPE_GAP: f64 = 0.1;
const ENVELOPE_FOR_S: f64 = 1.0;

/// Whether the cell follows the speed demand: a test whose engine speed stays more than
/// [`ENVELOPE_GAP`] from the demand for [`ENVELOPE_FOR_S`] asks for what the cell cannot do
/// (the speed the design would judge is not the one the test names).
#[derive(Debug, Default)]
struct Envelope {
    /// Since when the speed has been off the demand.
    off_since: Option<f64>,
}

impl Envelope {
    /// The next samples: time [s], the engine's speed and its demand [rad/s].
    fn check(&mut self, t: &[f64], omega: &[f64], demand: &[f64]) -> Result<(), AppError> {
        let rpm = 30.0 / std::f64::consts::PI;
        for ((&t, &w), &d) in t.iter().zip(omega).zip(demand) {
            if (w - d).abs() <= ENVELOPE_GAP * d.abs().max(1.0) {
                self.off_since = None;
                continue;
            }
            let since = *self.off_since.get_or_insert(t);
            if t - since >= ENVELOPE_FOR_S {
                return Err(AppError::Invalid(format!(
                    "outside the cell's envelope: from {since:.1} s the engine runs at {:.0} rpm against a demand of {:.0} rpm (the drive's limits)",
                    w * rpm,
                    d * rpm
                )));
            }
        }
        Ok(())
    }
}
