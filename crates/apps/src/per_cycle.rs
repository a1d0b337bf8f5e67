//! One cycle's figures from its cylinder pressure on a crank-angle grid — the one analysis
//! behind `physid cycles` (a file, [`crate::pressure::CycleAnalyser`]) and the live combustion
//! stage ([`crate::combustion_stage`]): a cycle is the compression before its firing TDC and
//! the expansion after it, its samples at increasing angles from −360° ATDC.
//!
//! * Pegging (the sensor measures pressure changes, not absolute pressure):
//!   - to a pressure at BDC of the intake stroke (−180° ATDC): `p ← p − p(−180°) + p_ref`;
//!   - by a polytropic exponent `n` on compression: the offset `Δ` that makes
//!     `(p + Δ)·V^n` equal at −100° and −60° ATDC, `Δ = (p₂V₂ⁿ − p₁V₁ⁿ)/(V₁ⁿ − V₂ⁿ)`.
//! * IMEP: `∮ p dV / V_d` (trapezoidal rule; net: the whole cycle, the loop closed; gross: from
//!   −180° to 180° ATDC, compression and expansion only); PMEP, the pumping loop's, is
//!   `IMEP_gross − IMEP_net` (Heywood 1988, §2.4: positive when the gas exchange takes work).
//! * Polytropic exponent: the slope of `ln p` against `ln V` by least squares over a window
//!   (−100° … −40° ATDC for compression, 40° … 100° for expansion): `p·V^n = const` ⇒
//!   `ln p = c − n·ln V`.
//! * BMEP and FMEP, when the brake torque is recorded ([`Brake`]): `BMEP = 4π·T̄/(z·V_d)` — the
//!   cycle's crank-angle mean torque `T̄` over 720° of a four-stroke engine of `z` cylinders
//!   (Heywood Eq. 2.19) — and `FMEP = IMEP_net − BMEP`, the friction's (rubbing and
//!   accessories; the pumping is in the net IMEP: total friction is PMEP + FMEP, Heywood §2.4),
//!   the indicated cylinder taken for every cylinder's. Beside it, with a friction model
//!   ([`crate::fmep_model`]), the model's FMEP at the cycle's speed.
//! * A zero-phase low-pass on the pressure when asked ([`PressureLowpass`]): a Butterworth
//!   low-pass through `sosfiltfilt` over the cycle's samples (scipy's, [`physid_signal::filter`]),
//!   which on the uniform crank-angle grid at the cycle's mean speed are a time series at
//!   `f_s = 6·rpm/step`; every figure but knock (which needs the band it would take away) is then
//!   the filtered pressure's.
//! * Heat release, burn angles, misfire and partial burn: [`crate::combustion`]; knock:
//!   [`crate::knock`]; the peak's angle between the samples: [`crate::combustion::peak`].
//!
//! The volume is the slider-crank's (SPEC §2.3, [`physid_models::kinematics::Crank`]).

use serde::{Deserialize, Serialize};

use crate::combustion::{burn, mfb_name, peak, Burn, BurnHistory, Cylinder, HeatRelease};
use crate::fmep_model::FrictionModel;
use crate::knock::{Knock, KnockFigures};
use crate::pressure::{Geometry, Pegging, COMPRESSION_WINDOW, EXPANSION_WINDOW, PEG_ANGLES};
use physid_core::Num;
use physid_signal::filter::{butter, Band};

/// A cycle whose pressure peaks further than this from its TDC [deg] is taken to be a
/// revolution out of phase (a fired or motored cylinder peaks within a few tens of degrees of
/// its firing TDC): no heat release, a note.
pub const PHASE_SUSPECT_DEG: f64 = 90.0;

/// The times of a cycle the figures need [s]: at its first and last samples (the cycle's mean
/// speed: [`PerCycle::figures`]) and at its firing TDC (the first sample at or after 0° ATDC,
/// the cycle's time).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CycleTimes {
    /// At the first sample.
    pub first: f64,
    /// At the last sample.
    pub last: f64,
    /// At the firing TDC.
    pub tdc: f64,
}

impl CycleTimes {
    /// From the time `t` of each sample at the angles `atdc` [deg ATDC, increasing] (as long,
    /// at least one).
    pub fn of(t: &[f64], atdc: &[f64]) -> Self {
        let n = t.len();
        Self {
            first: t[0],
            last: t[n - 1],
            tdc: t[Self::tdc_index(atdc)],
        }
    }

    /// The index of the firing TDC's sample: the first at or after 0° ATDC (the last when
    /// none is).
    pub fn tdc_index(atdc: &[f64]) -> usize {
        atdc.partition_point(|&a| a < 0.0)
            .min(atdc.len().saturating_sub(1))
    }
}

/// One cycle's figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CycleFigures {
    /// Cycle index (the recording's `cycle`).
    pub cycle: i64,
    /// Time at its firing TDC [s].
    pub t_start_s: f64,
    /// Mean speed over the cycle [rpm].
    pub rpm: f64,
    /// The largest pressure [the channel's unit, pegged].
    pub p_max: f64,
    /// Its angle [deg ATDC].
    pub p_max_deg: f64,
    /// The offset added by pegging [the channel's unit].
    pub peg_offset: f64,
    /// Net IMEP over 720° [Pa] (with the geometry and the pressure in Pa).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub imep_pa: Option<f64>,
    /// Gross IMEP, compression and expansion (−180° … 180° ATDC) [Pa].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub imep_gross_pa: Option<f64>,
    /// Pumping mean effective pressure, gross less net IMEP [Pa].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pmep_pa: Option<f64>,
    /// The crank-angle mean brake torque over the cycle [N·m] (with [`Brake`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub torque_nm: Option<f64>,
    /// Brake mean effective pressure [Pa] (with [`Brake`] and the geometry).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bmep_pa: Option<f64>,
    /// Friction mean effective pressure, net IMEP less BMEP [Pa] (with the pressure in Pa too).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fmep_pa: Option<f64>,
    /// The friction model's FMEP at the cycle's speed, without pumping [Pa] (with a
    /// [`FrictionModel`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fmep_model_pa: Option<f64>,
    /// Polytropic exponent of compression (with the geometry).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub n_compression: Option<f64>,
    /// Polytropic exponent of expansion.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub n_expansion: Option<f64>,
    /// Heat release, burn angles and pressure rise (with the geometry and the pressure in Pa;
    /// [`crate::combustion`]).
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    pub burn: Option<Burn>,
    /// Knock (when asked for, with the pressure in Pa and a fine enough step; [`crate::knock`]).
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    pub knock: Option<KnockFigures>,
    /// What was left out of this cycle's figures, and why.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
}

/// A figure of a cycle as a column: its name, unit, and how it is read from the figures (NaN
/// where not computed; flags 1/0).
pub struct FigureColumn {
    /// The name (`imep`, `mfb50_deg`, …).
    pub name: String,
    /// Its unit.
    pub unit: String,
    /// The value of a cycle.
    pub value: Box<dyn Fn(&CycleFigures) -> f64 + Send + Sync>,
}

/// The columns of a cycle's figures — what `cycles --tracks` writes, Python's `physid.cycles`
/// returns and the live `combustion` event carries: `unit` the pressure's, `mfb` the burn
/// fractions asked for [%], `knock` whether knock was, `brake` whether the brake torque was,
/// `friction` whether a friction model was.
pub fn figure_columns(
    unit: &str,
    mfb: &[f64],
    knock: bool,
    brake: bool,
    friction: bool,
) -> Vec<FigureColumn> {
    fn col(
        name: &str,
        unit: &str,
        value: impl Fn(&CycleFigures) -> f64 + Send + Sync + 'static,
    ) -> FigureColumn {
        FigureColumn {
            name: name.to_string(),
            unit: unit.to_string(),
            value: Box::new(value),
        }
    }
    fn nan(v: Option<f64>) -> f64 {
        v.unwrap_or(f64::NAN)
    }
    fn flag(v: Option<bool>) -> f64 {
        v.map_or(f64::NAN, |b| f64::from(u8::from(b)))
    }
    fn burn(c: &CycleFigures, f: impl Fn(&Burn) -> f64) -> f64 {
        c.burn.as_ref().map_or(f64::NAN, f)
    }
    fn knocked(c: &CycleFigures, f: impl Fn(&KnockFigures) -> f64) -> f64 {
        c.knock.as_ref().map_or(f64::NAN, f)
    }
    let mut columns = vec![
        col("t", "s", |c| c.t_start_s),
        col("cycle", "-", |c| c.cycle as f64),
        col("rpm", "rpm", |c| c.rpm),
        col("p_max", unit, |c| c.p_max),
        col("p_max_deg", "deg", |c| c.p_max_deg),
        col("peg_offset", unit, |c| c.peg_offset),
        col("imep", "Pa", |c| nan(c.imep_pa)),
        col("imep_gross", "Pa", |c| nan(c.imep_gross_pa)),
        col("pmep", "Pa", |c| nan(c.pmep_pa)),
        col("n_compression", "-", |c| nan(c.n_compression)),
        col("n_expansion", "-", |c| nan(c.n_expansion)),
        col("heat_release", "J", |c| burn(c, |b| b.heat_release_j)),
        col("fired", "-", |c| flag(c.burn.as_ref().map(|b| b.fired))),
        col("misfire", "-", |c| flag(c.burn.as_ref().map(|b| b.misfire))),
        col("partial_burn", "-", |c| {
            flag(c.burn.as_ref().map(|b| b.partial_burn))
        }),
    ];
    for &pct in mfb {
        columns.push(col(&mfb_name(pct), "deg", move |c| {
            nan(c.burn.as_ref().and_then(|b| b.mfb(pct)))
        }));
    }
    columns.extend([
        col("dp_max", "Pa/deg", |c| burn(c, |b| b.dp_max_pa_per_deg)),
        col("dp_max_deg", "deg", |c| burn(c, |b| b.dp_max_deg)),
        col("t_max", "K", |c| {
            nan(c.burn.as_ref().and_then(|b| b.t_max_k))
        }),
    ]);
    if brake {
        columns.extend([
            col("torque", "N*m", |c| nan(c.torque_nm)),
            col("bmep", "Pa", |c| nan(c.bmep_pa)),
            col("fmep", "Pa", |c| nan(c.fmep_pa)),
        ]);
    }
    if friction {
        columns.push(col("fmep_model", "Pa", |c| nan(c.fmep_model_pa)));
    }
    if knock {
        columns.extend([
            col("mapo", "Pa", |c| knocked(c, |k| k.mapo_pa)),
            col("mapo_deg", "deg", |c| knocked(c, |k| k.mapo_deg)),
            col("impo", "Pa*deg", |c| knocked(c, |k| k.impo_pa_deg)),
            col("knock", "-", |c| flag(c.knock.map(|k| k.knock))),
        ]);
    }
    columns
}

/// What a cycle's figures are computed with: the geometry (for anything with a volume), the
/// pegging, the heat release and knock settings, and whether the pressure is in Pa.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PerCycleSettings {
    /// The cylinder's geometry.
    pub geometry: Option<Geometry>,
    /// How the pressure is referenced.
    pub peg: Pegging,
    /// The heat release's γ, window and burn fractions.
    pub heat: HeatRelease,
    /// Knock, when asked for.
    pub knock: Option<Knock>,
    /// The pressure is in Pa (IMEP, heat release and knock need it).
    pub in_pa: bool,
    /// The brake torque, when recorded: BMEP and FMEP.
    #[serde(default)]
    pub brake: Option<Brake>,
    /// A zero-phase low-pass on the pressure before the figures (knock's excepted).
    #[serde(default)]
    pub lowpass: Option<PressureLowpass>,
    /// The friction model whose FMEP is given beside the measured.
    #[serde(default)]
    pub friction: Option<FrictionModel>,
}

/// The pressure's zero-phase low-pass (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PressureLowpass {
    /// The cut-off [Hz].
    pub cutoff_hz: f64,
    /// The Butterworth order.
    pub order: usize,
}

/// The low-pass's order when none is given.
pub const LOWPASS_ORDER: usize = 4;

impl PressureLowpass {
    /// Refused unless the cut-off is a frequency and the order 1 … 10.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.cutoff_hz > 0.0 && self.cutoff_hz.is_finite() && (1..=10).contains(&self.order)) {
            return Err(format!(
                "--pressure-lowpass {} Hz, order {}: expected a cut-off > 0 Hz and an order of 1 to 10",
                physid_core::Num(self.cutoff_hz),
                self.order
            ));
        }
        Ok(())
    }

    /// `p` filtered in place (`atdc` its uniform grid, `rpm` the cycle's speed); why not when
    /// the grid cannot carry the cut-off.
    fn apply(&self, atdc: &[f64], p: &mut [f64], rpm: f64) -> Result<(), String> {
        let n = atdc.len();
        let step = (atdc[n - 1] - atdc[0]) / (n - 1) as f64;
        let fs = 6.0 * rpm / step;
        if !(fs.is_finite() && self.cutoff_hz < 0.5 * fs) {
            return Err(format!(
                "pressure low-pass left out: {}° steps at {rpm:.0} rpm sample at {fs:.0} Hz, whose Nyquist frequency is below the {} Hz cut-off",
                Num(step),
                Num(self.cutoff_hz)
            ));
        }
        let sos = butter(self.order, &[self.cutoff_hz], Band::Lowpass, fs)
            .map_err(|e| format!("pressure low-pass left out: {e}"))?
            .to_sos();
        let y = sos
            .sosfiltfilt(p)
            .map_err(|e| format!("pressure low-pass left out: {e}"))?;
        p.copy_from_slice(&y);
        Ok(())
    }
}

/// The engine's brake torque channel and its cylinders (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Brake {
    /// The torque channel [N·m].
    pub channel: String,
    /// The engine's cylinders, the indicated one's IMEP taken for each.
    pub cylinders: u32,
}

impl Brake {
    /// Refused without a channel or with no cylinder.
    pub fn validate(&self) -> Result<(), String> {
        if self.channel.is_empty() || self.cylinders == 0 {
            return Err(format!(
                "--brake-torque '{}' with --cylinders {}: expected the brake torque's channel and at least one cylinder",
                self.channel, self.cylinders
            ));
        }
        Ok(())
    }
}

/// The analysis of one cycle after another: the settings, the misfire history, and scratch
/// reused from cycle to cycle.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct PerCycle {
    settings: PerCycleSettings,
    history: BurnHistory,
    /// Scratch: the pegged pressure, the volume and its logarithm.
    #[serde(skip)]
    pc: Vec<f64>,
    #[serde(skip)]
    vol: Vec<f64>,
    #[serde(skip)]
    ln_vol: Vec<f64>,
    /// The pegged pressure before the low-pass (for knock).
    #[serde(skip)]
    unfiltered: Vec<f64>,
    /// The angles `vol` is at.
    #[serde(skip)]
    vol_atdc: Vec<f64>,
    /// The last cycle's compression exponent (its wall heat's motored pressure).
    #[serde(skip)]
    last_n: Option<f64>,
}

impl PerCycle {
    /// The analysis with these settings.
    pub fn new(settings: PerCycleSettings) -> Self {
        Self {
            settings,
            history: BurnHistory::default(),
            pc: Vec::new(),
            vol: Vec::new(),
            ln_vol: Vec::new(),
            unfiltered: Vec::new(),
            vol_atdc: Vec::new(),
            last_n: None,
        }
    }

    /// The settings.
    pub fn settings(&self) -> &PerCycleSettings {
        &self.settings
    }

    /// The last cycle's pressure as pegged (and filtered) and its volume (empty without the
    /// geometry).
    pub fn pegged(&self) -> (&[f64], &[f64]) {
        (&self.pc, &self.vol)
    }

    /// The last cycle's apparent heat release ([`crate::combustion::apparent_heat`]) at its
    /// angles `atdc` and speed `rpm`: with the geometry and the pressure in Pa.
    pub fn last_heat(&self, atdc: &[f64], rpm: f64) -> Option<crate::combustion::Apparent> {
        let s = &self.settings;
        let g = s.geometry.as_ref().filter(|_| s.in_pa)?;
        if self.vol.len() != self.pc.len() || atdc.len() != self.pc.len() {
            return None;
        }
        let cyl = Cylinder {
            bore: g.bore,
            stroke: g.stroke,
            rpm,
            n_compression: self.last_n,
        };
        crate::combustion::apparent_heat(&s.heat, atdc, &self.pc, &self.vol, &cyl)
    }

    /// The figures of cycle `cycle`: its samples at the angles `atdc` [deg ATDC, increasing,
    /// from −360°, evenly spaced where the torque is given] and the pressures `p` (at least two
    /// samples, and one at or after TDC), the times `t` of its first and last samples and its
    /// TDC's; the brake torque there [N·m] when the settings have [`Brake`]. Cycles are given
    /// in order: misfires are told from the ones before.
    ///
    /// The cycle's mean speed is `120 / (Δt·n/(n − 1))` [rpm], `Δt` from the first sample to
    /// the last of the `n`: the time of `n` steps, 720° on an even grid.
    pub fn figures(
        &mut self,
        cycle: i64,
        t: CycleTimes,
        atdc: &[f64],
        p: &[f64],
        torque: Option<&[f64]>,
    ) -> CycleFigures {
        let s = &self.settings;
        let crank = s.geometry.as_ref().map(Geometry::crank);
        // The volume at the cycle's angles: kept while the angles are the same (a grid).
        if !same(&self.vol_atdc, atdc) || self.vol.len() != atdc.len() {
            self.vol.clear();
            self.ln_vol.clear();
            if let Some(k) = &crank {
                self.vol
                    .extend(atdc.iter().map(|a| k.volume(a.to_radians())));
                self.ln_vol.extend(self.vol.iter().map(|v| v.ln()));
                self.vol_atdc.clear();
                self.vol_atdc.extend_from_slice(atdc);
            }
        }
        let (pc, vol, ln_vol) = (&mut self.pc, &self.vol, &self.ln_vol);
        pc.clear();
        pc.extend_from_slice(p);
        let offset = match s.peg {
            Pegging::None => 0.0,
            Pegging::Bdc(p_ref) => p_ref - at(atdc, pc, -180.0),
            Pegging::Polytropic(n) => {
                let (a1, a2) = PEG_ANGLES;
                let (p1, p2) = (at(atdc, pc, a1), at(atdc, pc, a2));
                let (v1, v2) = (at(atdc, vol, a1).powf(n), at(atdc, vol, a2).powf(n));
                (p2 * v2 - p1 * v1) / (v1 - v2)
            }
        };
        if offset != 0.0 {
            for x in pc.iter_mut() {
                *x += offset;
            }
        }
        let n = atdc.len();
        let span = t.last - t.first;
        let rpm = 2.0 * 60.0 / (span * n as f64 / (n - 1) as f64);
        let mut notes = Vec::new();
        let unfiltered = &mut self.unfiltered;
        unfiltered.clear();
        if let Some(lp) = &s.lowpass {
            if s.knock.is_some() {
                unfiltered.extend_from_slice(pc);
            }
            if let Err(why) = lp.apply(atdc, pc, rpm) {
                notes.push(why);
            }
        }
        let (p_max, p_max_deg) = peak(atdc, pc).unwrap_or((f64::NAN, f64::NAN));
        let mut figures = CycleFigures {
            cycle,
            // The firing TDC's: the first sample of the expansion.
            t_start_s: t.tdc,
            rpm,
            p_max,
            p_max_deg,
            peg_offset: offset,
            imep_pa: None,
            imep_gross_pa: None,
            pmep_pa: None,
            // The crank-angle mean on an even grid: the samples' mean.
            torque_nm: torque
                .filter(|_| s.brake.is_some())
                .map(|q| q.iter().sum::<f64>() / q.len() as f64),
            bmep_pa: None,
            fmep_pa: None,
            fmep_model_pa: s
                .friction
                .as_ref()
                .and_then(|m| m.fmep_pa(rpm).map_err(|why| notes.push(why)).ok()),
            n_compression: None,
            n_expansion: None,
            burn: None,
            knock: None,
            notes: Vec::new(),
        };
        if let Some(k) = &crank {
            let vd = k.piston_area() * k.stroke();
            if let (Some(b), Some(t)) = (&s.brake, figures.torque_nm) {
                figures.bmep_pa = Some(4.0 * std::f64::consts::PI * t / (b.cylinders as f64 * vd));
            }
            let mut exponent = |window: (f64, f64), name: &str| {
                polytropic(atdc, pc, ln_vol, window)
                    .map_err(|why| {
                        notes.push(format!(
                            "{name} left out: {why} between {}° and {}° ATDC",
                            window.0, window.1
                        ))
                    })
                    .ok()
            };
            figures.n_compression = exponent(COMPRESSION_WINDOW, "n_compression");
            self.last_n = figures.n_compression;
            figures.n_expansion = exponent(EXPANSION_WINDOW, "n_expansion");
            if s.in_pa {
                let (net, gross) = work(atdc, pc, vol);
                let (net, gross) = (net / vd, gross / vd);
                figures.imep_pa = Some(net);
                figures.imep_gross_pa = Some(gross);
                figures.pmep_pa = Some(gross - net);
                figures.fmep_pa = figures.bmep_pa.map(|b| net - b);
                if p_max_deg.abs() > PHASE_SUSPECT_DEG {
                    notes.push(format!(
                        "no heat release: the pressure peaks more than {PHASE_SUSPECT_DEG}° from TDC — the firing TDC is likely a revolution off (--phase-from p_cyl tells which revolution fires)"
                    ));
                } else {
                    let g = s
                        .geometry
                        .as_ref()
                        .map_or((0.0, 0.0), |g| (g.bore, g.stroke));
                    let cyl = Cylinder {
                        bore: g.0,
                        stroke: g.1,
                        rpm,
                        n_compression: figures.n_compression,
                    };
                    figures.burn = burn(&s.heat, atdc, pc, vol, vd, p_max, &cyl).map(|mut b| {
                        self.history.flag(&mut b);
                        b
                    });
                }
            }
        }
        if let (Some(k), true) = (&s.knock, s.in_pa) {
            let p_knock = if unfiltered.is_empty() {
                &*pc
            } else {
                &*unfiltered
            };
            match k.figures(atdc, p_knock, rpm) {
                Ok(f) => figures.knock = Some(f),
                Err(why) => notes.push(why),
            }
        }
        figures.notes = notes;
        figures
    }
}

/// The cycle's work `∮ p dV` over its samples within −360° … 360° ATDC, the loop closed back to
/// the first sample (net), and `∫ p dV` over those within −180° … 180° (gross, compression and
/// expansion) — trapezoidal, in one pass: the net is the sum of the gross's steps and those
/// either side.
fn work(atdc: &[f64], p: &[f64], v: &[f64]) -> (f64, f64) {
    let index = |a: f64, inclusive: bool| {
        if inclusive {
            atdc.partition_point(|&x| x <= a)
        } else {
            atdc.partition_point(|&x| x < a)
        }
    };
    let (i0, i1) = (index(-360.0, false), index(360.0, true));
    if i1 <= i0 {
        return (0.0, 0.0);
    }
    let (g0, g1) = (index(-180.0, false), index(180.0, true));
    let gross = if g1 > g0 { steps(p, v, g0, g1) } else { 0.0 };
    let (g0, g1) = (g0.clamp(i0, i1), g1.clamp(i0, i1));
    // The net: before the gross's first sample, the gross's steps, after its last — each step
    // once (the steps across the joins are in the outer parts).
    let net = if g1 > g0 {
        steps(p, v, i0, g0 + 1) + gross + steps(p, v, g1 - 1, i1)
    } else {
        steps(p, v, i0, i1)
    } + 0.5 * (p[i1 - 1] + p[i0]) * (v[i0] - v[i1 - 1]);
    (net, gross)
}

/// Whether two slices are equal, element by element (without stopping at the first
/// difference: one pass the compiler vectorises — the grid is compared each cycle).
fn same(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(true, |ok, (x, y)| ok & (x == y))
}

/// `Σ ½(p_k + p_{k+1})(V_{k+1} − V_k)` over the samples `i0 … i1 − 1` (none with fewer than two).
fn steps(p: &[f64], v: &[f64], i0: usize, i1: usize) -> f64 {
    if i1 < i0 + 2 {
        return 0.0;
    }
    // Eight partial sums, a step's at `k mod 8` (one vector register's lanes): the additions
    // need not wait for one another.
    const LANES: usize = 8;
    let (ps, vs) = (&p[i0..i1], &v[i0..i1]);
    let step = |(p0, p1, v0, v1): (&f64, &f64, &f64, &f64)| 0.5 * (p0 + p1) * (v1 - v0);
    let n = ps.len() - 1;
    let whole = n - n % LANES;
    let mut sum = [0.0; LANES];
    for k in (0..whole).step_by(LANES) {
        let (p0, p1, v0, v1) = (
            &ps[k..k + LANES],
            &ps[k + 1..k + 1 + LANES],
            &vs[k..k + LANES],
            &vs[k + 1..k + 1 + LANES],
        );
        for l in 0..LANES {
            sum[l] += step((&p0[l], &p1[l], &v0[l], &v1[l]));
        }
    }
    for k in whole..n {
        sum[0] += step((&ps[k], &ps[k + 1], &vs[k], &vs[k + 1]));
    }
    ((sum[0] + sum[1]) + (sum[2] + sum[3])) + ((sum[4] + sum[5]) + (sum[6] + sum[7]))
}

/// `y` at the angle `a` [deg ATDC], linearly between the samples around it (the two nearest
/// on either side, whatever their order).
fn at(x: &[f64], y: &[f64], a: f64) -> f64 {
    let (mut lo, mut hi) = (None::<usize>, None::<usize>);
    for (i, &xi) in x.iter().enumerate() {
        if xi <= a && lo.is_none_or(|l| xi > x[l]) {
            lo = Some(i);
        }
        if xi >= a && hi.is_none_or(|h| xi < x[h]) {
            hi = Some(i);
        }
    }
    match (lo, hi) {
        (Some(l), Some(h)) if x[h] > x[l] => y[l] + (a - x[l]) / (x[h] - x[l]) * (y[h] - y[l]),
        (Some(l), _) => y[l],
        (_, Some(h)) => y[h],
        _ => f64::NAN,
    }
}

/// The polytropic exponent over a window [deg ATDC]: `−slope` of `ln p` on `ln V` by least
/// squares (`ln_v` the volume's logarithm at the increasing angles `atdc`); refused (why) when
/// a pressure there is not positive or with fewer than 3 samples.
fn polytropic(
    atdc: &[f64],
    p: &[f64],
    ln_v: &[f64],
    (from, to): (f64, f64),
) -> Result<f64, &'static str> {
    let (i0, i1) = (
        atdc.partition_point(|&a| a < from),
        atdc.partition_point(|&a| a <= to),
    );
    let (mut n, mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for i in i0..i1.max(i0) {
        if p[i] <= 0.0 {
            return Err("the pressure is not positive (an unpegged sensor's? --peg bdc=P or --peg polytropic=N references it)");
        }
        let (x, y) = (ln_v[i], p[i].ln());
        n += 1.0;
        sx += x;
        sy += y;
        sxx += x * x;
        sxy += x * y;
    }
    let den = n * sxx - sx * sx;
    if n >= 3.0 && den > 0.0 {
        Ok(-(n * sxy - sx * sy) / den)
    } else {
        Err("fewer than 3 samples")
    }
}
