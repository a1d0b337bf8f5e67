//! The flags of the per-cycle combustion analysis — pegging, heat release, burn fractions,
//! knock, the brake torque — shared by `physid cycles` (a file) and `physid live` / `worker` (`--combustion`, the
//! stream): one meaning, one parser.

use miette::{miette, Result};
use physid_apps::combustion::{BurnMethod, GasTemperature, HeatRelease, WallHeat, WOSCHNI_C1};
use physid_apps::fmep_model::FrictionModel;
use physid_apps::knock::Knock;
use physid_apps::per_cycle::{Brake, PerCycleSettings, PressureLowpass, LOWPASS_ORDER};
use physid_apps::pressure::{Geometry, Pegging};

/// Pegging, heat release, burn fractions and knock.
#[derive(clap::Args, Clone, Debug)]
pub struct CombustionArgs {
    /// Pressure referencing per cycle: `bdc=P` (P, in the channel's unit, at BDC of the intake
    /// stroke) or `polytropic=N` (the offset that makes p·V^N constant on compression).
    #[arg(long, value_name = "bdc=P|polytropic=N")]
    pub peg: Option<String>,
    /// The ratio of specific heats of the single-zone heat release (constant; with the
    /// geometry and the pressure in Pa).
    #[arg(long, default_value_t = physid_apps::combustion::DEFAULT_GAMMA)]
    pub gamma: f64,
    /// γ(T) of air at the mean gas temperature instead of the constant --gamma, and the peak
    /// mean gas temperature: the ideal gas trapped at intake valve closing, IVC_DEG [deg ATDC]
    /// at T_IVC [K].
    #[arg(
        long,
        value_name = "IVC_DEG,T_IVC",
        value_delimiter = ',',
        allow_hyphen_values = true
    )]
    pub gas_temperature: Option<Vec<f64>>,
    /// The gross heat release: the wall heat added, Woschni's at the mean gas temperature
    /// (C1 = 2.28, C2 from the start of combustion) to walls at this temperature [K]; needs
    /// --gas-temperature.
    #[arg(long, value_name = "T_WALL", requires = "gas_temperature")]
    pub wall_heat: Option<f64>,
    /// Woschni's combustion term C2 [m/(s·K)] of the wall heat (0: the motored form, the
    /// virtual cell's).
    #[arg(long, value_name = "C2", default_value_t = physid_apps::combustion::WOSCHNI_C2, requires = "wall_heat")]
    pub woschni_c2: f64,
    /// The burn fractions whose crank angles are given [%] (mfbK_deg for each K).
    #[arg(long, value_delimiter = ',', default_values_t = physid_apps::combustion::MFB)]
    pub mfb: Vec<f64>,
    /// How the burn angles are found: `heat`, from the apparent heat release, or `rw`,
    /// Rassweiler & Withrow's pressure-rise method (docs/data.md).
    #[arg(long, value_name = "heat|rw", default_value = "heat")]
    pub mfb_method: String,
    /// Rassweiler–Withrow's polytropic exponent (with --mfb-method rw; without it each cycle's
    /// compression exponent, else --gamma).
    #[arg(long, value_name = "N")]
    pub rw_exponent: Option<f64>,
    /// A zero-phase Butterworth low-pass (order 4) on each cycle's pressure before its figures
    /// — all but knock's — at this cut-off [Hz], at the cycle's mean speed.
    #[arg(long, value_name = "HZ")]
    pub pressure_lowpass: Option<f64>,
    /// The engine's brake torque channel [N·m]: each cycle's mean torque, BMEP and FMEP (net
    /// IMEP less BMEP; with the geometry).
    #[arg(long, value_name = "CHANNEL")]
    pub brake_torque: Option<String>,
    /// The engine's cylinders (BMEP over their displacement; the indicated cylinder's IMEP
    /// taken for each).
    #[arg(long, value_name = "N", default_value_t = 1, requires = "brake_torque")]
    pub cylinders: u32,
    /// Each cycle's FMEP from the mean-value friction model (Patton / Sandoval–Heywood,
    /// without its pumping term) at the cycle's speed, beside the measured (column
    /// fmep_model): the preset thesis, sandoval2002 or cell, as `physid friction` takes it.
    #[arg(long, value_name = "PRESET")]
    pub friction_model: Option<String>,
    /// Override a design parameter or setting of the friction model (as `physid friction
    /// --set`: B, S, kappa, Di, De, Lv, Db, Lb, r in mm; oil, valvetrain, …); repeatable.
    #[arg(long, value_name = "NAME=VALUE", requires = "friction_model")]
    pub friction_set: Vec<String>,
    /// The friction model's intake manifold pressure [kPa] (default: the ambient, an
    /// unthrottled engine).
    #[arg(long, value_name = "KPA", requires = "friction_model")]
    pub friction_p_int: Option<f64>,
    /// The friction model's ambient pressure [kPa].
    #[arg(long, value_name = "KPA", default_value_t = physid_apps::fmep_model::DEFAULT_P_KPA, requires = "friction_model")]
    pub friction_p_atm: f64,
    /// The friction model's oil temperature [°C] (default: its reference, 90 °C).
    #[arg(long, value_name = "DEG_C", default_value_t = physid_apps::fmep_model::DEFAULT_T_OIL_C, requires = "friction_model", allow_negative_numbers = true)]
    pub friction_oil_temp: f64,

    /// Knock per cycle: the pressure band-passed (zero phase), its maximum amplitude (MAPO) and
    /// integral of modulus (IMPO) in a window after TDC, a flag above a threshold (with the
    /// geometry not needed, the pressure in Pa, a step fine enough for the band).
    #[arg(long)]
    pub knock: bool,
    /// The knock band [Hz].
    #[arg(
        long,
        value_name = "LOW,HIGH",
        value_delimiter = ',',
        requires = "knock"
    )]
    pub knock_band: Option<Vec<f64>>,
    /// The knock window [deg ATDC].
    #[arg(
        long,
        value_name = "FROM,TO",
        value_delimiter = ',',
        requires = "knock",
        allow_hyphen_values = true
    )]
    pub knock_window: Option<Vec<f64>>,
    /// A cycle knocks when its MAPO exceeds this [Pa] (set it for the engine).
    #[arg(long, value_name = "PA", default_value_t = physid_apps::knock::DEFAULT_THRESHOLD_PA)]
    pub knock_threshold: f64,
}

impl CombustionArgs {
    /// The knock settings asked for.
    pub fn knock(&self) -> Result<Option<Knock>> {
        let d = Knock::default();
        if !self.knock {
            return Ok(None);
        }
        Ok(Some(Knock {
            band_hz: pair("--knock-band", &self.knock_band)?.unwrap_or(d.band_hz),
            window: pair("--knock-window", &self.knock_window)?.unwrap_or(d.window),
            threshold_pa: self.knock_threshold,
        }))
    }

    /// The settings with `geometry`, checked (the pressure taken to be in Pa; a stage or an
    /// analyser sets that from the channel's unit).
    pub fn settings(&self, geometry: Option<Geometry>) -> Result<PerCycleSettings> {
        let heat = HeatRelease {
            gamma: self.gamma,
            mfb: self.mfb.clone(),
            temperature: pair("--gas-temperature", &self.gas_temperature)?
                .map(|(ivc_deg, t_ivc_k)| GasTemperature { ivc_deg, t_ivc_k }),
            wall: self.wall_heat.map(|t_wall_k| WallHeat {
                t_wall_k,
                c1: WOSCHNI_C1,
                c2: self.woschni_c2,
            }),
            method: BurnMethod::parse(&self.mfb_method, self.rw_exponent)
                .map_err(|e| miette!("{e}"))?,
            ..HeatRelease::default()
        };
        heat.validate().map_err(|e| miette!("{e}"))?;
        let knock = self.knock()?;
        if let Some(k) = &knock {
            k.validate().map_err(|e| miette!("--knock: {e}"))?;
        }
        let brake = self.brake_torque.as_ref().map(|channel| Brake {
            channel: channel.clone(),
            cylinders: self.cylinders,
        });
        if let Some(b) = &brake {
            b.validate().map_err(|e| miette!("{e}"))?;
        }
        let lowpass = self.pressure_lowpass.map(|cutoff_hz| PressureLowpass {
            cutoff_hz,
            order: LOWPASS_ORDER,
        });
        if let Some(lp) = &lowpass {
            lp.validate().map_err(|e| miette!("{e}"))?;
        }
        let friction = match &self.friction_model {
            Some(preset) => Some(
                FrictionModel::new(
                    preset,
                    &self.friction_set,
                    self.friction_p_int.unwrap_or(self.friction_p_atm),
                    self.friction_p_atm,
                    self.friction_oil_temp,
                )
                .map_err(|e| miette!("{e}"))?,
            ),
            None => None,
        };
        Ok(PerCycleSettings {
            geometry,
            peg: Pegging::parse(self.peg.as_deref()).map_err(|e| miette!("{e}"))?,
            heat,
            knock,
            in_pa: true,
            brake,
            lowpass,
            friction,
        })
    }

    /// Whether any flag differs from its default (`live` refuses them without `--combustion`).
    pub fn any_given(&self) -> bool {
        self.peg.is_some()
            || self.gamma != physid_apps::combustion::DEFAULT_GAMMA
            || self.mfb != physid_apps::combustion::MFB
            || self.gas_temperature.is_some()
            || self.mfb_method != "heat"
            || self.rw_exponent.is_some()
            || self.brake_torque.is_some()
            || self.pressure_lowpass.is_some()
            || self.friction_model.is_some()
            || self.knock
    }
}

/// Two numbers given as `A,B` to `flag`, if given.
fn pair(flag: &str, v: &Option<Vec<f64>>) -> Result<Option<(f64, f64)>> {
    match v.as_deref() {
        None => Ok(None),
        Some([a, b]) => Ok(Some((*a, *b))),
        Some(other) => Err(miette!(
            "{flag}: {} number(s) given, expected two separated by a comma (A,B)",
            other.len()
        )),
    }
}
