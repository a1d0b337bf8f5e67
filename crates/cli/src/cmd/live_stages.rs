//! The application stages a live run adds to the shaft monitor, the cycle statistics and the
//! integrity checks — the friction characterisation, the cyclic-torque estimation and the
//! combustion analysis — as flags shared by `physid live` and `physid worker` (a fleet's
//! workers run them on every cell).

use miette::{miette, Result};
use physid_apps::friction_fit::{
    friction_preset, FrictionFitConfig, TorqueSource, FRICTION_PRESETS, MIN_CYCLES,
};
use physid_apps::torque_fit::{cyclic_torque_nominal, TorqueFitConfig};
use physid_apps::twin::live::TwinConfig;
use physid_live::{CombustionLive, FrictionLive, LiveConfig, TorqueLive};
use physid_sim::params::CellParams;

/// The friction and cyclic-torque stages' flags.
#[derive(clap::Args)]
pub struct StageFlags {
    /// Characterise the engine's friction on the stream (a motored engine, e.g. the
    /// friction-sweep scenario) with this friction model preset: thesis, sandoval2002 or cell
    /// (the virtual cell's engine).
    #[arg(long, value_name = "PRESET")]
    friction: Option<String>,
    /// Choose the estimable friction coefficients after this many steady cycles.
    #[arg(long, value_name = "N", default_value_t = 100, requires = "friction")]
    friction_after: usize,
    /// The motoring torque for the friction characterisation: engine (−torque_engine) or
    /// shaft (+torque_shaft).
    #[arg(
        long,
        value_name = "engine|shaft",
        default_value = "engine",
        requires = "friction"
    )]
    friction_source: String,
    /// Estimate the cyclic engine torque model's parameters on the stream (thesis ch. 8: a
    /// motored engine, e.g. the torque-ramp scenario), UKF from the virtual cell's nominal
    /// values, as `physid torque fit`.
    #[arg(long)]
    torque: bool,
    /// Choose the estimable cyclic-torque parameters after this many cycles.
    #[arg(long, value_name = "N", default_value_t = 10, requires = "torque")]
    torque_after: usize,
    /// Parameters held at their nominal values, as `torque fit --fix`.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "delta",
        requires = "torque"
    )]
    torque_fix: Vec<String>,
    /// Let a parameter drift, as `torque fit --track`: NAME=VARIANCE per sample in scaled
    /// coordinates, e.g. M_rec=1e-6 to follow a reciprocating-mass change.
    #[arg(long, value_delimiter = ',', requires = "torque")]
    torque_track: Vec<String>,
    /// Analyse each cycle's combustion on the stream, as `physid cycles` does a file, from
    /// this cylinder-pressure channel (p_cyl when none is named): `combustion` events. The
    /// geometry is the virtual cell's engine unless --bore, --stroke, --rod and
    /// --compression-ratio give it.
    #[arg(long, value_name = "CHANNEL", num_args = 0..=1, default_missing_value = "p_cyl")]
    combustion: Option<String>,
    /// The cylinder's geometry for --combustion (`live`: the crank's lengths for --tdc-from
    /// too).
    #[command(flatten)]
    geometry: super::GeometryArgs,
    /// Pegging, heat release, burn fractions, knock for --combustion.
    #[command(flatten)]
    combustion_args: super::combustion_args::CombustionArgs,
    /// The crank-angle step [deg] the pressure is taken onto for --combustion.
    #[arg(long, default_value_t = 0.1)]
    step_deg: f64,
    /// Run the self-calibrated twin beside the stream: the cell of this scenario file's `set`
    /// (DIR/cell.toml of `physid twin calibrate --out DIR`), stepped with the stream's speed demand and throttle,
    /// adapting its live parameters, `twin` events and alarms naming the parameter that moved
    /// (docs/twin.md). The stream needs t, theta_en, speed_demand, throttle on a time basis.
    #[arg(long, value_name = "FILE")]
    twin: Option<std::path::PathBuf>,
    /// The twin's adapted parameters (of shaft.k, shaft.b, engine.m_rec, engine.friction_scale).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "shaft.k,shaft.b,engine.m_rec,engine.friction_scale",
        requires = "twin"
    )]
    twin_adapt: Vec<String>,
    /// The channels the twin compares [default: those of omega_en, omega_dy, torque_shaft,
    /// p_int the stream has].
    #[arg(long, value_delimiter = ',', requires = "twin")]
    twin_channels: Vec<String>,
}

impl StageFlags {
    /// The crank's lengths and compression ratio given.
    pub fn crank(&self) -> &super::CrankArgs {
        &self.geometry.crank
    }

    /// The stages asked for, added to `cfg`; a preset, a source or a count out of range is
    /// refused with what is expected.
    pub fn apply(&self, cfg: &mut LiveConfig) -> Result<()> {
        if let Some(preset) = &self.friction {
            let (d, st) = friction_preset(preset).ok_or_else(|| {
                miette!(
                    "--friction '{preset}': the presets are {}",
                    FRICTION_PRESETS.join(", ")
                )
            })?;
            let mut fit = FrictionFitConfig::new(d, st);
            fit.source = TorqueSource::parse(&self.friction_source).ok_or_else(|| {
                miette!(
                    "--friction-source '{}': expected engine or shaft",
                    self.friction_source
                )
            })?;
            if self.friction_after < MIN_CYCLES {
                return Err(miette!(
                    "--friction-after {}: the choice needs at least {MIN_CYCLES} cycles",
                    self.friction_after
                ));
            }
            cfg.friction = Some(FrictionLive {
                fit,
                select_after: self.friction_after,
            });
        }
        if self.torque {
            let nominal =
                cyclic_torque_nominal(&CellParams::default()).map_err(|e| miette!("{e}"))?;
            let mut fit = TorqueFitConfig::new(nominal);
            fit.fixed = self
                .torque_fix
                .iter()
                .map(|s| s.trim().to_string())
                .collect();
            let (names, values) = super::named_values(&self.torque_track, "--torque-track")?;
            fit.track = names.into_iter().zip(values).collect();
            if self.torque_after == 0 {
                return Err(miette!(
                    "--torque-after 0: the choice needs at least one cycle"
                ));
            }
            cfg.torque = Some(TorqueLive {
                fit,
                select_after_cycles: self.torque_after,
            });
        }
        if let Some(path) = &self.twin {
            let scenario = physid_sim::scenario::Scenario::load(&path.to_string_lossy())
                .map_err(|e| miette!("--twin {}: {e}", path.display()))?;
            let mut twin = TwinConfig::new(
                scenario.set.into_iter().collect(),
                self.twin_adapt
                    .iter()
                    .map(|s| s.trim().to_string())
                    .collect(),
            );
            if !self.twin_channels.is_empty() {
                twin.channels = self.twin_channels.clone();
            }
            twin.validate()
                .map_err(|e| miette!("--twin {}: {e}", path.display()))?;
            cfg.twin = Some(twin);
        }
        match &self.combustion {
            Some(channel) => {
                // The virtual cell's engine unless given.
                let geometry = self.geometry.full()?.unwrap_or_else(|| {
                    let e = CellParams::default().engine;
                    physid_apps::pressure::Geometry {
                        bore: e.bore,
                        stroke: 2.0 * e.crank_radius,
                        rod: e.rod,
                        compression_ratio: e.kappa,
                    }
                });
                cfg.combustion = Some(CombustionLive {
                    channel: channel.clone(),
                    settings: self.combustion_args.settings(Some(geometry))?,
                    step_deg: self.step_deg,
                });
            }
            None if self.geometry.bore.is_some()
                || self.combustion_args.any_given()
                || self.step_deg != 0.1 =>
            {
                return Err(miette!(
                    "--bore, --peg, --gamma, --mfb, --knock and --step-deg set the combustion analysis: add --combustion"
                ));
            }
            None => {}
        }
        Ok(())
    }
}
