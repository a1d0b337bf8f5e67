//! What a designed test gives the cyclic-torque fit (Application 3, thesis ch. 8): the 1°
//! samples of Eq. 8.2 from the virtual cell run without noise, each sample's regressor — the
//! model's exact sensitivity to the chosen parameters in the filter's scaled coordinates,
//! `ϑ0_j·∂τ/∂ϑ_j` (`ϑ = ϑ0·(1 + x)`) at the nominal values — and the noise its residual carries.
//!
//! The noise, per sample: the engine load cell's white noise `σ_τ` (and its quantisation,
//! `q²/12`), and the cylinder-pressure transducer's `σ_p` through the indicated torque's arm,
//! `∂τ/∂p_cyl = A_p·r·G(θ)` ([`CyclicTorque::pressure_arm`]) — a pressure error enters the model
//! as an input, so near the firing TDC, where the arm is 0, it does not count and at mid-stroke it
//! does. The oil temperature's noise (0.1 K, lagged) moves the friction cubic by a few parts in
//! 10⁴ of a slowly varying term and is left out. The filter (UKF, no forgetting, a constant R2)
//! weighs every sample alike, so its estimates' covariance is the sandwich
//! `A⁻¹·S·A⁻¹` of [`information`](super::information) with `A = Σφφᵀ`, `S = Σσ²φφᵀ`.

use super::run::run_noiseless;
use super::{Design, Designed, Estimator, Evaluation};
use crate::cell::cyclic_torque_nominal;
use crate::error::AppError;
use crate::torque_fit::{TorqueData, TorqueFitConfig};
use physid_core::{GradientEngine, ParamModel};
use physid_models::cyclic_torque::{CyclicTorque, PARAMS};
use physid_sim::params::{CellParams, SensorParams};
use physid_sim::run::OutputBasis;
use physid_sim::scenario::{named, Scenario};

/// The channels Eq. 8.2 reads from a crank-angle recording.
const CHANNELS: [&str; 7] = [
    "theta",
    "omega_en",
    "alpha_en",
    "p_cyl",
    "p_crank",
    "T_oil",
    "torque_engine",
];

/// The samples of one test as the filter takes them: their times, each one's regressor
/// (`p` values, one after another) and noise level.
#[derive(Debug, Clone, Default)]
pub struct Samples {
    /// Times [s].
    pub t: Vec<f64>,
    /// `ϑ0_j·∂τ/∂ϑ_j` of each chosen parameter [N·m], sample after sample.
    pub phi: Vec<f64>,
    /// The standard deviation of the sample's noise [N·m].
    pub sigma: Vec<f64>,
}

/// A cyclic-torque fit to design a test for.
#[derive(Debug, Clone)]
pub struct TorqueDesign {
    /// The fit as it will run on the test's recording (nominal values, fixed parameters, P0;
    /// its UKF without forgetting).
    pub fit: TorqueFitConfig,
    /// The cell the test runs on.
    pub cell: CellParams,
    /// The crank-angle step of the samples [deg] (the thesis's: 1°).
    pub step_deg: f64,
}

/// A sensor's noise variance per sample: white noise and quantisation.
fn variance(s: &SensorParams) -> f64 {
    s.noise * s.noise + s.quantum * s.quantum / 12.0
}

impl TorqueDesign {
    /// The fit the thesis runs (its UKF on 1° samples, δ held) at the cell's engine's nominal
    /// values.
    pub fn new(cell: CellParams) -> Result<Self, AppError> {
        Ok(Self {
            fit: TorqueFitConfig::new(cyclic_torque_nominal(&cell)?),
            cell,
            step_deg: 1.0,
        })
    }

    /// The chosen parameters as indices into [`PARAMS`], refused as the fit refuses them.
    pub fn check(&self, params: &[String]) -> Result<Vec<usize>, AppError> {
        let mut fit = self.fit.clone();
        fit.estimate = Some(params.to_vec());
        let idx = fit.chosen()?.unwrap_or_default();
        if !(self.step_deg.is_finite() && self.step_deg > 0.0 && self.step_deg <= 10.0) {
            return Err(AppError::Invalid(format!(
                "crank-angle step {}°: expected within (0, 10]",
                physid_core::Num(self.step_deg)
            )));
        }
        if !(self.fit.p0.is_finite() && self.fit.p0 > 0.0) {
            return Err(AppError::Invalid(format!(
                "P0 scale {}: expected > 0",
                physid_core::Num(self.fit.p0)
            )));
        }
        Ok(idx)
    }

    /// The samples of `scenario` run on the cell without noise, as the filter takes them for
    /// `params` (names in [`PARAMS`]).
    pub fn samples(&self, scenario: &Scenario, params: &[String]) -> Result<Samples, AppError> {
        let free = self.check(params)?;
        let s = &self.cell.sensors;
        let (var_tau, var_p) = (variance(&s.torque_engine), variance(&s.p_cyl));
        let quiet = [
            "sensors.torque_engine.noise",
            "sensors.p_cyl.noise",
            "sensors.p_cyl.quantum",
            "sensors.temperature.noise",
            "sensors.speed.noise",
        ];
        let model = CyclicTorque::default();
        let nominal = self.fit.nominal;
        let mut engine = GradientEngine::new(PARAMS.len());
        let mut grad = vec![0.0; free.len()];
        let mut u = [0.0; 6];
        let mut out = Samples::default();
        let mut offset = 0;
        let basis = OutputBasis::Crank(self.step_deg);
        run_noiseless(&self.cell, &quiet, scenario, basis, &CHANNELS, |chunk| {
            let data = TorqueData::from_crank_angle(chunk, offset)?;
            for i in 0..data.y.len() {
                for (k, col) in data.inputs.iter().enumerate() {
                    u[k] = col[i];
                }
                model.value_and_gradient_with(&mut engine, &u, &nominal, &free, &mut grad);
                out.t.push(data.t[i]);
                out.phi
                    .extend(grad.iter().zip(&free).map(|(g, &j)| g * nominal[j]));
                let arm = model.pressure_arm(u[0], &nominal);
                out.sigma.push((var_tau + arm * arm * var_p).sqrt());
            }
            offset += data.y.len();
            Ok(())
        })?;
        Ok(out)
    }

    /// `scenario` judged for the design's parameters (its `names`).
    pub fn evaluate(&self, design: &Design, scenario: &Scenario) -> Result<Evaluation, AppError> {
        let free = self.check(&design.names)?;
        let s = self.samples(scenario, &design.names)?;
        let p = free.len();
        if s.t.len() < p {
            return Err(AppError::Invalid(format!(
                "{} samples for {p} parameters: the test is too short",
                s.t.len()
            )));
        }
        let units: Vec<f64> = free.iter().map(|&j| self.fit.nominal[j]).collect();
        let scales: Vec<f64> = units.iter().map(|u| u.abs()).collect();
        design.evaluate(
            s.t.iter()
                .zip(s.phi.chunks_exact(p))
                .zip(&s.sigma)
                .map(|((&t, phi), &sigma)| (t, phi, sigma)),
            &Estimator {
                scales: &scales,
                units: &units,
                lambda: 1.0,
                p0: self.fit.p0,
                noise: &[1.0],
                settle_s: 0.0,
            },
        )
    }
}

/// The parameters `items` (names in [`PARAMS`]) a design is for; their nominal values are the
/// cell engine's (they are not set here).
pub fn select(items: &[String]) -> Result<Vec<String>, AppError> {
    super::plain_names(
        items,
        "the cyclic-torque model's nominal values are the cell engine's (set them with --set engine.m_rec=…, engine.bore=…)",
    )
}

/// Design a test for the cyclic-torque fit of `design.names`: its candidates judged, the
/// thesis's steady (T1) and ramp (T2) tests, cut to the design's duration, alongside.
/// `progress` is told how many candidates are done.
pub fn design_torque(
    torque: &TorqueDesign,
    design: &Design,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<Designed, AppError> {
    torque.check(&design.names)?;
    design.check()?;
    let baselines: Vec<Scenario> = ["torque-steady", "torque-ramp"]
        .into_iter()
        .filter_map(named)
        .collect();
    design.run(&|s| torque.evaluate(design, s), &baselines, progress)
}
