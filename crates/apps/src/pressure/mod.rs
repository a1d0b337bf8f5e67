//! Cylinder-pressure analysis per cycle on a crank-angle recording (`physid cycles`): peak
//! pressure and its angle, the indicated mean effective pressure (net over 720°, gross over
//! compression and expansion), the polytropic exponents of compression and expansion, the
//! cycle's speed, and the coefficient of variation of IMEP over the cycles — with the pressure
//! referenced (pegged) first when asked.
//!
//! Crank angles here are degrees after the firing TDC (ATDC), −360 … 360. A cycle is the
//! compression before its firing TDC and the expansion after it: on the recording — whose
//! `cycle` counts blocks from one firing TDC to the next, `crank_deg` 0 … 720 — the second half
//! of the block before (`crank_deg` − 720) and the first half of its own. So each cycle's heat
//! release, burn angles and IMEP are one combustion's, and the first block's TDC, with no
//! compression recorded before it, gives no cycle (said in the notes).
//!
//! Each cycle's figures — pegging, IMEP, exponents, heat release, burn angles, knock — are
//! [`crate::per_cycle`]'s, the same as the live stage's; here the recording's blocks become
//! cycles and the cycles' spread is taken.
//!
//! The volume is the slider-crank's (SPEC §2.3, [`physid_models::kinematics::Crank`]).//!
//! Here: the geometry, the pegging and the result; `analyser.rs`: the chunks made into cycles.

mod analyser;

pub use analyser::CycleAnalyser;

use physid_core::{Basis, Recording};
use physid_models::kinematics::Crank;
use serde::{Deserialize, Serialize};

use crate::combustion::HeatRelease;
use crate::error::AppError;
use crate::fmep_model::FrictionModel;
use crate::knock::Knock;
pub use crate::per_cycle::CycleFigures;
use crate::per_cycle::{figure_columns, CycleTimes, PerCycle, PerCycleSettings};
pub use crate::per_cycle::{Brake, PressureLowpass};
pub use crate::pressure_unit::{check_unit, UnitCheck, PA_PLAUSIBLE};
use crate::stage::{Dropout, DropoutLog};

/// The cylinder's geometry (SI).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Geometry {
    /// Bore [m].
    pub bore: f64,
    /// Stroke [m] (twice the crank radius, no pin offset).
    pub stroke: f64,
    /// Connecting rod [m].
    pub rod: f64,
    /// Compression ratio [-].
    pub compression_ratio: f64,
}

impl Geometry {
    /// The slider crank.
    pub fn crank(&self) -> Crank<f64> {
        Crank {
            r: 0.5 * self.stroke,
            l: self.rod,
            delta: 0.0,
            bore: self.bore,
            kappa: self.compression_ratio,
        }
    }

    /// Check the numbers: positive, a rod longer than the crank radius, a ratio above 1.
    pub fn validate(&self) -> Result<(), AppError> {
        let ok = [self.bore, self.stroke, self.rod]
            .iter()
            .all(|v| v.is_finite() && *v > 0.0)
            && self.rod > 0.5 * self.stroke
            && self.compression_ratio.is_finite()
            && self.compression_ratio > 1.0;
        if ok {
            Ok(())
        } else {
            Err(AppError::Invalid(format!(
                "geometry: bore {:?} m, stroke {:?} m, rod {:?} m, compression ratio {:?}: expected lengths > 0 in metres, a rod longer than half the stroke, a ratio > 1",
                self.bore, self.stroke, self.rod, self.compression_ratio
            )))
        }
    }
}

/// How the pressure is referenced.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub enum Pegging {
    /// As measured.
    #[default]
    None,
    /// To this pressure [the channel's unit] at BDC of the intake stroke (−180° ATDC).
    Bdc(f64),
    /// By this polytropic exponent on compression (between −100° and −60° ATDC; needs the
    /// geometry).
    Polytropic(f64),
}

impl Pegging {
    /// `bdc=P` (P in the channel's unit) or `polytropic=N` (1 < N < 2), as `--peg` and
    /// Python's `peg` take it; `None` as measured.
    pub fn parse(s: Option<&str>) -> Result<Self, AppError> {
        let Some(s) = s else {
            return Ok(Pegging::None);
        };
        let bad = || {
            AppError::Invalid(format!(
                "--peg '{s}': expected bdc=PRESSURE or polytropic=EXPONENT, e.g. bdc=1e5, polytropic=1.32"
            ))
        };
        let (kind, value) = s.split_once('=').ok_or_else(bad)?;
        let v: f64 = value
            .trim()
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(bad)?;
        match kind.trim() {
            "bdc" => Ok(Pegging::Bdc(v)),
            "polytropic" if v > 1.0 && v < 2.0 => Ok(Pegging::Polytropic(v)),
            "polytropic" => Err(AppError::Invalid(format!(
                "--peg polytropic={v}: expected an exponent between 1 and 2"
            ))),
            _ => Err(bad()),
        }
    }
}

/// The windows of the polytropic exponents [deg ATDC].
pub const COMPRESSION_WINDOW: (f64, f64) = (-100.0, -40.0);
/// See [`COMPRESSION_WINDOW`].
pub const EXPANSION_WINDOW: (f64, f64) = (40.0, 100.0);
/// The two angles of polytropic pegging [deg ATDC].
pub const PEG_ANGLES: (f64, f64) = (-100.0, -60.0);

/// The cycles' figures and their spread.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CycleAnalysis {
    /// The pressure channel and its unit.
    pub channel: String,
    /// See `channel`.
    pub unit: String,
    /// Complete cycles, in order.
    pub cycles: Vec<CycleFigures>,
    /// Coefficient of variation of the net IMEP (sample standard deviation over the mean) [-],
    /// with two cycles or more: over the fired cycles when some fired, else over all.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cov_imep: Option<f64>,
    /// Lowest normalised value of the net IMEP over the fired cycles (the smallest over the
    /// mean) [-], with two fired cycles or more.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lnv_imep: Option<f64>,
    /// What was left out and why (partial cycles, IMEP without Pa …), for a person.
    pub notes: Vec<String>,
    /// The samples that were not a number (a sensor's dropout), each left out with the cycles
    /// it cuts.
    pub dropouts: Vec<Dropout>,
    /// The burn fractions whose angles were asked for [%].
    #[serde(skip)]
    pub mfb: Vec<f64>,
    /// Whether knock was asked for.
    #[serde(skip)]
    pub knock: bool,
    /// Whether the brake torque was given (BMEP, FMEP).
    #[serde(skip)]
    pub brake: bool,
    /// Whether a friction model was given (its FMEP beside the measured).
    #[serde(skip)]
    pub friction: bool,
    /// The ensemble mean of the complete cycles' pressure, crank angle by crank angle (cycle
    /// averaging), analysed as one cycle (its `cycle` the number averaged, its `t_start_s` the
    /// mean time from a cycle's start at −360° to its TDC), with two cycles or more of one
    /// length.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mean_cycle: Option<CycleFigures>,
    /// The mean cycle's and the chosen cycle's curves, for a report.
    #[serde(skip)]
    pub curves: Option<CycleCurves>,
}

/// A cycle's curves against crank angle: what a report draws.
#[derive(Debug, Clone, PartialEq)]
pub struct CycleCurve {
    /// The cycle (the mean's: the number averaged).
    pub cycle: i64,
    /// The pressure, pegged [the channel's unit].
    pub p: Vec<f64>,
    /// The apparent heat release from the window's start [J] on `heat_deg` (with the geometry
    /// and the pressure in Pa).
    pub heat: Vec<f64>,
}

/// The curves of the mean cycle and of one chosen cycle on the cycle's angles.
#[derive(Debug, Clone, PartialEq)]
pub struct CycleCurves {
    /// The angles [deg ATDC].
    pub atdc: Vec<f64>,
    /// The volume there [m³] (empty without the geometry).
    pub volume: Vec<f64>,
    /// The heat release window's angles [deg ATDC].
    pub heat_deg: Vec<f64>,
    /// The ensemble mean.
    pub mean: Option<CycleCurve>,
    /// The chosen cycle.
    pub chosen: Option<CycleCurve>,
}

impl CycleAnalysis {
    /// A row per cycle as columns — name, unit, values (NaN where not computed): what
    /// `cycles --tracks` writes and Python's `physid.cycles` returns.
    pub fn columns(&self) -> Vec<(String, String, Vec<f64>)> {
        figure_columns(&self.unit, &self.mfb, self.knock, self.brake, self.friction)
            .into_iter()
            .map(|c| {
                let values = self.cycles.iter().map(&c.value).collect();
                (c.name, c.unit, values)
            })
            .collect()
    }
}

/// The figures of every complete cycle of `p` in a crank-angle recording (channels `cycle`,
/// `crank_deg`, `t`), optionally with the geometry and pegging: [`CycleAnalyser`] on the whole
/// recording as one chunk.
pub fn analyse(
    rec: &Recording,
    p_channel: &str,
    geometry: Option<&Geometry>,
    peg: Pegging,
) -> Result<CycleAnalysis, AppError> {
    let mut a = CycleAnalyser::new(rec, p_channel, geometry, peg)?;
    a.push(rec)?;
    a.finish()
}

/// The step of a crank-angle recording's `crank_deg`: its first advance, found as the samples
/// come.
#[derive(Debug, Clone, Copy, Default)]
pub struct FirstAdvance {
    step: Option<f64>,
    last: Option<f64>,
}

impl FirstAdvance {
    /// The next sample's `crank_deg`.
    pub fn see(&mut self, deg: f64) {
        if self.step.is_none() {
            self.step = self.last.map(|l| deg - l).filter(|d| *d > 0.0);
        }
        self.last = Some(deg);
    }

    /// The step, once `crank_deg` has advanced.
    pub fn step(&self) -> Option<f64> {
        self.step
    }
}

/// The brake torque channel `name` of `header`: refused unless its unit is a torque's (N·m, as
/// `N*m`, `N.m`, `Nm` or `N·m`).
pub fn check_torque_unit(header: &Recording, name: &str) -> Result<(), AppError> {
    let unit = &header.channel(name)?.unit;
    if ["N*m", "N.m", "Nm", "N·m", "N m"].contains(&unit.as_str()) {
        Ok(())
    } else {
        Err(AppError::Invalid(format!(
            "--brake-torque {name}: its unit is '{unit}', expected a torque in N*m (give it with --map {name}={name}:N*m or convert with --scale)"
        )))
    }
}
