//! Cylinder-pressure analysis per cycle on a crank-angle recording (`physid cycles`): peak
//! pressure and its angle, the indicated mean effective pressure (net over 720°, gross over
//! compression and expansion), the polytropic exponents of compression and expansion, the
//! cycle's speed, and the coefficient of variation of IMEP over the cycles — with the pressure
//! referenced (pegged) first when asked.
//!
//! Crank angles here are degrees after the firing TDC (ATDC), −360 … 360; the recording's
//! `crank_deg` (0 … 720 from the firing TDC) maps to them by subtracting 720 above 360.
//!
//! * IMEP: `∮ p dV / V_d` (trapezoidal rule; net: the whole cycle, the loop closed; gross: from
//!   −180° to 180° ATDC, compression and expansion only).
//! * Polytropic exponent: the slope of `ln p` against `ln V` by least squares over a window
//!   (−100° … −40° ATDC for compression, 40° … 100° for expansion): `p·V^n = const` ⇒
//!   `ln p = c − n·ln V`.
//! * Pegging (the sensor measures pressure changes, not absolute pressure), per cycle:
//!   - to a pressure at BDC of the intake stroke (−180° ATDC): `p ← p − p(−180°) + p_ref`;
//!   - by a polytropic exponent `n` on compression: the offset `Δ` that makes
//!     `(p + Δ)·V^n` equal at −100° and −60° ATDC, `Δ = (p₂V₂ⁿ − p₁V₁ⁿ)/(V₁ⁿ − V₂ⁿ)`.
//!
//! The volume is the slider-crank's (SPEC §2.3, [`physid_models::kinematics::Crank`]).

use physid_core::{Basis, Recording};
use physid_models::kinematics::Crank;
use serde::Serialize;

use crate::error::AppError;

/// The cylinder's geometry (SI).
#[derive(Debug, Clone, Copy, PartialEq)]
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
                "geometry: bore {} m, stroke {} m, rod {} m, compression ratio {}: expected lengths > 0 in metres, a rod longer than half the stroke, a ratio > 1",
                self.bore, self.stroke, self.rod, self.compression_ratio
            )))
        }
    }
}

/// How the pressure is referenced.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
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

/// The windows of the polytropic exponents [deg ATDC].
pub const COMPRESSION_WINDOW: (f64, f64) = (-100.0, -40.0);
/// See [`COMPRESSION_WINDOW`].
pub const EXPANSION_WINDOW: (f64, f64) = (40.0, 100.0);
/// The two angles of polytropic pegging [deg ATDC].
pub const PEG_ANGLES: (f64, f64) = (-100.0, -60.0);

/// One cycle's figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CycleFigures {
    /// Cycle index (the recording's `cycle`).
    pub cycle: i64,
    /// Time at its first sample [s].
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
    /// Polytropic exponent of compression (with the geometry).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub n_compression: Option<f64>,
    /// Polytropic exponent of expansion.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub n_expansion: Option<f64>,
}

/// The cycles' figures and their spread.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CycleAnalysis {
    /// The pressure channel and its unit.
    pub channel: String,
    /// See `channel`.
    pub unit: String,
    /// Complete cycles, in order.
    pub cycles: Vec<CycleFigures>,
    /// Coefficient of variation of the net IMEP over the cycles (sample standard deviation
    /// over the mean) [-], with two cycles or more.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cov_imep: Option<f64>,
    /// What was left out and why (partial cycles, IMEP without Pa …), for a person.
    pub notes: Vec<String>,
}

/// A cylinder pressure in Pa peaks above this (a motored engine's compression lifts it well
/// past atmospheric): below it, the values are in another unit labelled Pa.
pub const PA_PLAUSIBLE: f64 = 1e3;

/// Check that `channel` can be a cylinder pressure: its unit a pressure (or one physid does
/// not know, a sensor's own: V, counts), and — in Pa — a peak above [`PA_PLAUSIBLE`]. A unit
/// of another quantity is an error; implausible values in Pa are an error when `need_pa` (the
/// figures would be wrong), else the returned note. Both name the channel and the sample.
pub fn check_unit(
    rec: &Recording,
    channel: &str,
    need_pa: bool,
) -> Result<Option<String>, AppError> {
    let ch = rec.channel(channel)?;
    if let Some(u) = physid_core::units::lookup(&ch.unit) {
        // A sensor's own units: volts, counts.
        if !["pressure", "voltage", "dimensionless"].contains(&u.dimension) {
            return Err(AppError::Invalid(format!(
                "'{channel}' is in '{}' ({}), not a pressure: expected {} — or the sensor's own unit (V) calibrated with --scale {channel}=GAIN,OFFSET",
                ch.unit,
                u.dimension,
                physid_core::units::known_for("Pa")
            )));
        }
    }
    if !(ch.unit.is_empty() || ch.unit == "Pa") {
        return Ok(None);
    }
    let Some((i, peak)) = ch
        .values
        .iter()
        .enumerate()
        .filter(|(_, v)| v.is_finite())
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
    else {
        return Ok(None);
    };
    if peak.abs() >= PA_PLAUSIBLE {
        return Ok(None);
    }
    let text = format!(
        "'{channel}' peaks at {peak} Pa (sample {i}): a cylinder pressure in Pa peaks far above {PA_PLAUSIBLE} Pa, so these are bar, MPa or a sensor's volts labelled Pa — state the unit (--map {channel}=COLUMN:bar) or calibrate into Pa (--scale {channel}=GAIN,OFFSET)"
    );
    if need_pa {
        Err(AppError::Invalid(text))
    } else {
        Ok(Some(text))
    }
}

/// The figures of every complete cycle of `p` in a crank-angle recording (channels `cycle`,
/// `crank_deg`, `t`), optionally with the geometry and pegging.
pub fn analyse(
    rec: &Recording,
    p_channel: &str,
    geometry: Option<&Geometry>,
    peg: Pegging,
) -> Result<CycleAnalysis, AppError> {
    if rec.basis != Basis::CrankAngle {
        return Err(AppError::Invalid(
            "the recording is on a time basis: convert it with --crank-angle first (or give the engine angle: --wheel, --encoder)".into(),
        ));
    }
    if let Some(g) = geometry {
        g.validate()?;
    }
    let mut notes = Vec::new();
    notes.extend(check_unit(rec, p_channel, geometry.is_some())?);
    let ch = rec.channel(p_channel).map_err(AppError::from)?;
    let (cycle, deg, t) = (
        rec.values("cycle").map_err(AppError::from)?,
        rec.values("crank_deg").map_err(AppError::from)?,
        rec.values("t").map_err(AppError::from)?,
    );
    let p = &ch.values;
    if let Some(i) = p.iter().position(|v| !v.is_finite()) {
        return Err(AppError::Invalid(format!(
            "'{p_channel}' is {} at sample {i}: the pressure must be finite",
            p[i]
        )));
    }
    let step = deg
        .windows(2)
        .map(|w| w[1] - w[0])
        .find(|d| *d > 0.0)
        .ok_or_else(|| AppError::Invalid("crank_deg never advances".into()))?;
    let per_cycle = (720.0 / step).round() as usize;
    let in_pa = ch.unit == "Pa";
    if geometry.is_some() && !in_pa {
        notes.push(format!(
            "'{p_channel}' is in '{}', not Pa: no IMEP (calibrate it with --scale {p_channel}=GAIN,OFFSET into Pa)",
            ch.unit
        ));
    }
    if matches!(peg, Pegging::Polytropic(_)) && geometry.is_none() {
        return Err(AppError::Invalid(
            "polytropic pegging needs the geometry (--bore, --stroke, --rod, --compression-ratio)"
                .into(),
        ));
    }
    let crank = geometry.map(Geometry::crank);
    let vd = crank.map(|c| c.piston_area() * c.stroke());
    let mut cycles = Vec::new();
    let mut partial = 0;
    let (mut pc, mut vol, mut atdc) = (Vec::new(), Vec::new(), Vec::new());
    for (c, run) in physid_signal::crank::cycle_runs(cycle) {
        let (start, end) = (run.start, run.end);
        if !(c >= 0.0 && end - start == per_cycle) {
            partial += 1;
            continue;
        }
        atdc.clear();
        atdc.extend(
            deg[start..end]
                .iter()
                .map(|&d| if d >= 360.0 { d - 720.0 } else { d }),
        );
        vol.clear();
        if let Some(k) = &crank {
            vol.extend(atdc.iter().map(|a| k.volume(a.to_radians())));
        }
        pc.clear();
        pc.extend_from_slice(&p[start..end]);
        let offset = match peg {
            Pegging::None => 0.0,
            Pegging::Bdc(p_ref) => p_ref - at(&atdc, &pc, -180.0),
            Pegging::Polytropic(n) => {
                let (a1, a2) = PEG_ANGLES;
                let (p1, p2) = (at(&atdc, &pc, a1), at(&atdc, &pc, a2));
                let (v1, v2) = (at(&atdc, &vol, a1).powf(n), at(&atdc, &vol, a2).powf(n));
                (p2 * v2 - p1 * v1) / (v1 - v2)
            }
        };
        for x in pc.iter_mut() {
            *x += offset;
        }
        let (k_max, &p_max) = pc
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .unwrap_or((0, &f64::NAN));
        let span = t[end - 1] - t[start];
        let rpm = 2.0 * 60.0 / (span * per_cycle as f64 / (per_cycle - 1) as f64);
        let (imep, gross, nc, ne) = match vd {
            Some(vd) => {
                // In crank-angle order from −360° ATDC (crank_deg 360) round to 360°.
                let order: Vec<usize> = (0..atdc.len())
                    .filter(|&i| atdc[i] < 0.0)
                    .chain((0..atdc.len()).filter(|&i| atdc[i] >= 0.0))
                    .collect();
                let work = |from: f64, to: f64, closed: bool| {
                    let idx: Vec<usize> = order
                        .iter()
                        .copied()
                        .filter(|&i| atdc[i] >= from && atdc[i] <= to)
                        .collect();
                    let mut w = 0.0;
                    for k in 0..idx.len() {
                        let (i, j) = match (k + 1 < idx.len(), closed) {
                            (true, _) => (idx[k], idx[k + 1]),
                            (false, true) => (idx[k], idx[0]),
                            (false, false) => break,
                        };
                        w += 0.5 * (pc[i] + pc[j]) * (vol[j] - vol[i]);
                    }
                    w / vd
                };
                (
                    in_pa.then(|| work(-360.0, 360.0, true)),
                    in_pa.then(|| work(-180.0, 180.0, false)),
                    polytropic(&atdc, &pc, &vol, COMPRESSION_WINDOW),
                    polytropic(&atdc, &pc, &vol, EXPANSION_WINDOW),
                )
            }
            None => (None, None, None, None),
        };
        cycles.push(CycleFigures {
            cycle: c as i64,
            t_start_s: t[start],
            rpm,
            p_max,
            p_max_deg: atdc[k_max],
            peg_offset: offset,
            imep_pa: imep,
            imep_gross_pa: gross,
            n_compression: nc,
            n_expansion: ne,
        });
    }
    if partial > 0 {
        notes.push(format!(
            "{partial} partial cycle(s) left out (fewer than {per_cycle} samples)"
        ));
    }
    let imeps: Vec<f64> = cycles.iter().filter_map(|c| c.imep_pa).collect();
    let cov_imep = (imeps.len() >= 2).then(|| {
        let n = imeps.len() as f64;
        let mean = imeps.iter().sum::<f64>() / n;
        let var = imeps.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1.0);
        var.sqrt() / mean.abs()
    });
    Ok(CycleAnalysis {
        channel: p_channel.to_string(),
        unit: ch.unit.clone(),
        cycles,
        cov_imep,
        notes,
    })
}

/// `y` at the angle `a` [deg ATDC], linearly between the samples around it (the cycle's
/// angles `x` are not in order across ±360°: the two nearest on either side are used).
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
/// squares; `None` when a pressure there is not positive or fewer than 3 samples.
fn polytropic(atdc: &[f64], p: &[f64], v: &[f64], (from, to): (f64, f64)) -> Option<f64> {
    let (mut n, mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for i in (0..atdc.len()).filter(|&i| atdc[i] >= from && atdc[i] <= to) {
        if p[i] <= 0.0 {
            return None;
        }
        let (x, y) = (v[i].ln(), p[i].ln());
        n += 1.0;
        sx += x;
        sy += y;
        sxx += x * x;
        sxy += x * y;
    }
    let den = n * sxx - sx * sx;
    (n >= 3.0 && den > 0.0).then(|| -(n * sxy - sx * sy) / den)
}
