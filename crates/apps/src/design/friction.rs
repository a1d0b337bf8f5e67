//! What a designed test gives the friction characterisation (Application 2, thesis §7.3): the
//! steady cycles its stage keeps from the virtual cell run without noise, each cycle's
//! regressor `c0_i·ψ_i` of the chosen coefficients (DSFC estimates their relative deviations
//! `x`, `c = c0·(1 + x)`, Eq. 7.10's scaling), and the noise its cycle-mean motoring torque
//! carries.
//!
//! The noise: the torque transducer's white noise `σ` (and its quantisation, `q²/12`) averaged
//! over a cycle by its crank-angle mean — `σ²/n` for the `n = f_s·4π/ω` samples of a cycle at
//! speed ω, so a slow cycle is a quieter one — independent from cycle to cycle. The other
//! channels' noise (manifold pressure, oil temperature) averages out of the regressors to
//! second order and is left out (the prediction check, tests/design.rs, holds without it).

use super::run::run_noiseless;
use super::{Design, Designed, Estimator, Evaluation};
use crate::error::AppError;
use crate::friction_fit::{check_estimate, FrictionFitConfig, FrictionStage, TorqueSource};
use crate::stage::Stage;
use physid_models::friction::{FrictionRegression, OperatingPoint, REGRESSION_PARAMS};
use physid_sim::engine::Engine;
use physid_sim::params::CellParams;
use physid_sim::run::OutputBasis;
use physid_sim::scenario::{named, Scenario};
use std::f64::consts::PI;

/// The channels the friction stage reads from a time-basis recording, besides `t` and the
/// motoring torque's.
const INPUTS: [&str; 5] = ["theta_en", "omega_en", "p_int", "p_atm", "T_oil"];

/// One steady cycle as the estimator takes it.
#[derive(Debug, Clone, PartialEq)]
pub struct CycleRow {
    /// The cycle's start [s].
    pub t_s: f64,
    /// `c0_i·ψ_i` of each chosen coefficient [N·m].
    pub phi: Vec<f64>,
    /// The standard deviation of its mean motoring torque's noise [N·m].
    pub sigma: f64,
}

/// A friction characterisation to design a test for.
#[derive(Debug, Clone)]
pub struct FrictionDesign {
    /// The fit as it will run on the test's recording (the engine's design and settings, the
    /// torque source, S0, λ, what is a steady cycle).
    pub fit: FrictionFitConfig,
    /// The cell the test runs on.
    pub cell: CellParams,
    /// The recording's sample rate [Hz].
    pub rate_hz: f64,
}

impl FrictionDesign {
    /// The fit the thesis runs (§7.3: S0 = 10·I, λ = 1, the load cell's torque) on the cell's
    /// own engine.
    pub fn new(cell: CellParams, rate_hz: f64) -> Self {
        let (d, st) = Engine::new(&cell.engine, &cell.ambient).friction_model();
        Self {
            fit: FrictionFitConfig::new(d, st),
            cell,
            rate_hz,
        }
    }

    /// The nominal coefficients `c0` (the engine's model).
    pub fn nominal(&self) -> [f64; 20] {
        FrictionRegression::new(self.fit.design, self.fit.settings).nominal()
    }

    /// Refuse what the design does not describe.
    pub fn check(&self, coefficients: &[String]) -> Result<(), AppError> {
        check_estimate(coefficients, &self.nominal())?;
        super::check_rate(self.rate_hz)?;
        if !(self.fit.s0.is_finite() && self.fit.s0 > 0.0) {
            return Err(AppError::Invalid(format!(
                "S0 scale {}: expected > 0",
                physid_core::Num(self.fit.s0)
            )));
        }
        Ok(())
    }

    /// The torque channel's sensor and its settings' paths.
    fn sensor(&self) -> (&physid_sim::params::SensorParams, &'static str) {
        match self.fit.source {
            TorqueSource::Engine => (&self.cell.sensors.torque_engine, "torque_engine"),
            TorqueSource::Shaft => (&self.cell.sensors.torque_shaft, "torque_shaft"),
        }
    }

    /// The variance of one sample's noise on the motoring torque [N²·m²]: white noise and
    /// quantisation.
    pub fn sample_noise_variance(&self) -> f64 {
        let (s, _) = self.sensor();
        s.noise * s.noise + s.quantum * s.quantum / 12.0
    }

    /// The steady cycles the fit would keep from `scenario` run on the cell without noise,
    /// as the estimator takes them for `coefficients`.
    pub fn regressors(
        &self,
        scenario: &Scenario,
        coefficients: &[String],
    ) -> Result<Vec<CycleRow>, AppError> {
        let c0 = self.nominal();
        check_estimate(coefficients, &c0)?;
        let idx: Vec<usize> = coefficients
            .iter()
            .filter_map(|c| REGRESSION_PARAMS.iter().position(|p| p == c))
            .collect();
        let mut fit = self.fit.clone();
        fit.estimate = Some(coefficients.to_vec());
        let mut stage = FrictionStage::new(fit, None)?;
        let (_, channel) = self.sensor();
        let mut keep: Vec<&str> = INPUTS.to_vec();
        keep.push(channel);
        let quiet = [
            "sensors.torque_engine.noise",
            "sensors.torque_shaft.noise",
            "sensors.torque_shaft.quantum",
            "sensors.p_manifold.noise",
            "sensors.temperature.noise",
            "sensors.speed.noise",
        ];
        let mut out = Vec::new();
        let basis = OutputBasis::Time(self.rate_hz);
        run_noiseless(&self.cell, &quiet, scenario, basis, &keep, |chunk| {
            stage.push(chunk, &mut out)?;
            out.clear();
            Ok(())
        })?;
        let data = stage.steady_cycles()?;
        let model = FrictionRegression::new(self.fit.design, self.fit.settings);
        let var = self.sample_noise_variance();
        Ok((0..data.len())
            .map(|k| {
                let u = data.inputs(k);
                let psi = model.regressor(&OperatingPoint {
                    n_rpm: u[0],
                    p_int_kpa: u[1],
                    p_atm_kpa: u[2],
                    t_oil_c: u[3],
                });
                // Samples in the cycle: 4π over ω at the recording's rate.
                let n = self.rate_hz * 4.0 * PI / (u[0] * PI / 30.0);
                CycleRow {
                    t_s: data.t_s[k],
                    phi: idx.iter().map(|&j| c0[j] * psi[j]).collect(),
                    sigma: (var / n.max(1.0)).sqrt(),
                }
            })
            .collect())
    }

    /// `scenario` judged for the design's parameters (its `names`, coefficients).
    pub fn evaluate(&self, design: &Design, scenario: &Scenario) -> Result<Evaluation, AppError> {
        let rows = self.regressors(scenario, &design.names)?;
        if rows.len() < design.names.len() {
            return Err(AppError::Invalid(format!(
                "{} steady cycles for {} coefficients: the test holds too few cycles steady (speed and manifold pressure within the fit's 1 % over a cycle)",
                rows.len(),
                design.names.len()
            )));
        }
        let c0 = self.nominal();
        let scales: Vec<f64> = design
            .names
            .iter()
            .map(|c| {
                REGRESSION_PARAMS
                    .iter()
                    .position(|p| p == c)
                    .map_or(1.0, |j| c0[j].abs())
            })
            .collect();
        design.evaluate(
            rows.iter().map(|r| (r.t_s, &r.phi[..], r.sigma)),
            &Estimator {
                scales: &scales,
                units: &scales,
                lambda: self.fit.lambda,
                p0: self.fit.s0 * self.fit.s0,
                noise: &[1.0],
                settle_s: self.fit.transient_s,
            },
        )
    }
}

/// The coefficients `items` (`c1` … `c20`) a design is for; their nominal values are the
/// engine's model's (they are not set here).
pub fn select(items: &[String]) -> Result<Vec<String>, AppError> {
    super::plain_names(
        items,
        "a friction coefficient's nominal value is the engine model's (set the engine with --set engine.…)",
    )
}

/// Design a test for the friction characterisation of `design.names`: its candidates judged,
/// the thesis's four motored sweeps (`friction-sweep`, cut to the design's duration)
/// alongside. `progress` is told how many candidates are done.
pub fn design_friction(
    friction: &FrictionDesign,
    design: &Design,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<Designed, AppError> {
    friction.check(&design.names)?;
    design.check()?;
    let baselines: Vec<Scenario> = named("friction-sweep").into_iter().collect();
    design.run(&|s| friction.evaluate(design, s), &baselines, progress)
}
