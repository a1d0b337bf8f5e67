//! The friction model's FMEP beside the measured one: each cycle's `FMEP = IMEP_net − BMEP`
//! ([`crate::per_cycle`]) next to what the project's mean-value friction model (Patton /
//! Sandoval–Heywood, SPEC §2.5, [`physid_models::friction`]) predicts at the cycle's speed —
//! the comparison a friction study or a condition monitor wants (a measured FMEP above the
//! model's is friction the engine has and its model has not).
//!
//! The model's FMEP is its mechanical part, `cfmep + rfmep + vfmep + afmep`, **without** its
//! pumping term: the measured FMEP comes from the net IMEP, which holds the pumping loop already
//! (Heywood §2.4; SPEC §2.3's fix). The operating point other than the speed — intake manifold
//! and ambient pressure, oil temperature — is given (a steady test point); its defaults are an
//! unthrottled engine with its oil at the model's reference, 90 °C.

use crate::friction_fit::{friction_preset, FRICTION_PRESETS};
use physid_models::friction::{fmep, set_by_name, Design, OperatingPoint, Settings};
use serde::{Deserialize, Serialize};

/// The intake manifold and ambient pressure [kPa] when none is given (the thesis code's
/// ambient; unthrottled).
pub const DEFAULT_P_KPA: f64 = 101.0;

/// The oil temperature [°C] when none is given: the model's reference (SPEC §2.5).
pub const DEFAULT_T_OIL_C: f64 = 90.0;

/// The model and the operating point it is evaluated at, but for the speed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrictionModel {
    /// The preset it was made from (`thesis`, `sandoval2002`, `cell`), for the record.
    pub preset: String,
    /// The design parameters (mm).
    pub design: Design<f64>,
    /// Oil, valvetrain and counts.
    pub settings: Settings,
    /// Intake manifold pressure [kPa].
    pub p_int_kpa: f64,
    /// Ambient pressure [kPa].
    pub p_atm_kpa: f64,
    /// Oil temperature [°C].
    pub t_oil_c: f64,
}

impl FrictionModel {
    /// The model of `preset` (`thesis`, `sandoval2002` or `cell`, as `physid friction` takes
    /// it) with the overrides `set` (`NAME=VALUE`, as `--set` takes them) at the operating
    /// point given (checked).
    pub fn new(
        preset: &str,
        set: &[String],
        p_int_kpa: f64,
        p_atm_kpa: f64,
        t_oil_c: f64,
    ) -> Result<Self, String> {
        let (mut design, mut settings) = friction_preset(preset).ok_or_else(|| {
            format!(
                "--friction-model {preset}: no such preset; the presets are {}",
                FRICTION_PRESETS.join(", ")
            )
        })?;
        for s in set {
            let (name, value) = s.split_once('=').ok_or_else(|| {
                format!("--friction-set {s}: expected NAME=VALUE, e.g. --friction-set B=56")
            })?;
            set_by_name(&mut design, &mut settings, name.trim(), value)
                .map_err(|e| format!("--friction-set {e}"))?;
        }
        let model = Self {
            preset: preset.to_string(),
            design,
            settings,
            p_int_kpa,
            p_atm_kpa,
            t_oil_c,
        };
        model.validate()?;
        Ok(model)
    }

    fn at(&self, rpm: f64) -> OperatingPoint {
        OperatingPoint {
            n_rpm: rpm,
            p_int_kpa: self.p_int_kpa,
            p_atm_kpa: self.p_atm_kpa,
            t_oil_c: self.t_oil_c,
        }
    }

    /// Refused when the operating point is outside the model's domain (checked at 1000 rpm:
    /// the speed is each cycle's).
    pub fn validate(&self) -> Result<(), String> {
        self.at(1000.0)
            .validate()
            .map_err(|e| format!("--friction-model {}: {e}", self.preset))
    }

    /// The model's FMEP without pumping [Pa] at `rpm`; why not (for the cycle's notes) at a
    /// speed outside its domain.
    pub fn fmep_pa(&self, rpm: f64) -> Result<f64, String> {
        let op = self.at(rpm);
        op.validate()
            .map_err(|e| format!("fmep_model left out: {e}"))?;
        Ok(fmep(&self.design, &self.settings, &op).mechanical() * 1e3)
    }
}
