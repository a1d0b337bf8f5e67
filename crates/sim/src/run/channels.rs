//! The run's channels: the truth the cell gives at each solver step ([`RAW`], one [`Row`]),
//! how each is carried to the output grid ([`Between`]; the cylinder's by its dense output,
//! [`super::dense`]), and the recording's 38 channels with their units and sources
//! ([`OUTPUT`], DESIGN.md's table).

use super::sensors::SensorKind;
use crate::cell::Sample;
use crate::control::inverse_park;
use crate::params::CellParams;
use Between::{Hold, Linear};
use Dense::{Alpha, Engine, Indicated, Pressure, Reciprocating, Temperature};

/// The truth the cell gives at each solver step, in the order of a [`raw_row`] (each is
/// recorded under its name, [`OUTPUT`], but the last three — the cylinder's volume [m³] and
/// `d(p·V)/dt` [W], the reciprocating mass in force [kg] — which the cylinder's dense output
/// needs).
pub(super) const RAW: [&str; 33] = [
    "t",
    "theta_en",
    "theta_dy",
    "omega_en",
    "omega_dy",
    "alpha_en",
    "alpha_dy",
    "torque_shaft",
    "torque_engine",
    "torque_dy",
    "p_cyl",
    "p_int",
    "p_exh",
    "T_int",
    "T_exh",
    "T_oil",
    "throttle",
    "speed_demand",
    "i_a",
    "i_b",
    "i_c",
    "v_a",
    "v_b",
    "v_c",
    "true_torque_indicated",
    "true_torque_reciprocating",
    "true_torque_friction",
    "true_T_cyl",
    "true_shaft_k",
    "true_shaft_b",
    "v_cyl",
    "pv_rate",
    "m_rec",
];

/// The columns the acquisition reads itself: time and the two angles.
pub(super) const T: usize = 0;
pub(super) const THETA_EN: usize = 1;
pub(super) const THETA_DY: usize = 2;

/// One row of truth, [`RAW`]'s columns.
pub(super) type Row = [f64; RAW.len()];

/// The position of `name` in [`RAW`] (the names are this module's own: an unknown one is a
/// bug, caught by every run in the tests).
pub(super) fn raw_index(name: &str) -> usize {
    let i = RAW.iter().position(|&c| c == name);
    debug_assert!(i.is_some(), "no raw column {name}");
    i.unwrap_or(0)
}

/// The truth of sample `s`, the cell running with `p`; `sc` is `(sin, cos)` of the machine
/// frame's angle.
pub(super) fn raw_row(s: &Sample, p: &CellParams, sc: (f64, f64)) -> Row {
    let i = inverse_park(s.i_dq, sc);
    let v = inverse_park(s.v_dq, sc);
    [
        s.t,
        s.theta_en,
        s.theta_dy,
        s.omega_en,
        s.omega_dy,
        s.alpha_en,
        s.alpha_dy,
        s.torque_shaft,
        s.torque_engine,
        s.torque_dy,
        s.gas.p[1],
        s.gas.p[0],
        s.gas.p[2],
        s.temperatures[0],
        s.temperatures[2],
        p.engine.t_oil,
        s.throttle_deg,
        s.demand,
        i[0],
        i[1],
        i[2],
        v[0],
        v[1],
        v[2],
        s.torque_indicated,
        s.torque_reciprocating,
        s.torque_friction,
        s.temperatures[1],
        p.shaft.k,
        p.shaft.b,
        s.gas.v_cyl,
        s.gas.pv_rate,
        p.engine.m_rec,
    ]
}

/// How a raw column is carried from the solver's steps to the output grid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Between {
    /// Linear interpolation (the states and what follows from them).
    Linear,
    /// The value of the step that contains the point: for what the cell holds over a step
    /// (the throttle, the demand, the parameters a fault changes), so that a stepped input or
    /// fault never shows a value between its two levels. A point within 1 % of a step's length
    /// before the next step counts as on it (the crank-angle grid's steps land within 0.1 %).
    Hold,
    /// The cylinder's gas and what follows from it through the indicated torque, from the dense
    /// output ([`super::dense::Cylinder`]); [`Linear`] where there is none (a point on a step,
    /// the engine off).
    Dense(Dense),
}

/// The channels the cylinder's dense output gives between the steps (in the order it keeps
/// them).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Dense {
    /// `p_cyl`, `true_T_cyl`, `true_torque_indicated`, `true_torque_reciprocating`,
    /// `torque_engine`, `alpha_en`.
    Pressure,
    Temperature,
    Indicated,
    Reciprocating,
    Engine,
    Alpha,
}

impl Between {
    /// The value at fraction `f` ∈ [0, 1] of the way from `y0` to `y1`.
    pub(super) fn carry(self, y0: f64, y1: f64, f: f64) -> f64 {
        match self {
            Between::Linear | Between::Dense(_) => y0 + f * (y1 - y0),
            Between::Hold if f >= 0.99 => y1,
            Between::Hold => y0,
        }
    }
}

/// Where an output channel's values come from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Source {
    /// The raw column of the channel's name carried to the grid, measured by a sensor if one
    /// is named.
    Raw(Between, Option<SensorKind>),
    /// The sample's time: the grid itself on a time basis, the interpolated time on a crank
    /// basis.
    Time,
    /// Crank basis: the angle from the first firing TDC [rad], the cycle number, the angle
    /// in the cycle [deg].
    Theta,
    Cycle,
    CrankDeg,
    /// The ambient pressure (crankcase and atmosphere).
    Ambient,
    /// Encoder counts `floor(θ/q)`, the engine's less the pulses lost; the TDC marker.
    CountEn,
    CountDy,
    Tdc,
}

impl Source {
    /// Whether a channel from this source is recorded on `basis` (the angle from TDC, the
    /// cycle and the crank angle only on a crank basis).
    pub(super) fn on(self, basis: super::OutputBasis) -> bool {
        matches!(basis, super::OutputBasis::Crank(_))
            || !matches!(self, Source::Theta | Source::Cycle | Source::CrankDeg)
    }
}

/// The recording's channels, in order, with their units (DESIGN.md); the crank-basis ones
/// only there.
pub(super) const OUTPUT: [(&str, &str, Source); 38] = [
    ("t", "s", Source::Time),
    ("theta", "rad", Source::Theta),
    ("cycle", "-", Source::Cycle),
    ("crank_deg", "deg", Source::CrankDeg),
    ("theta_en", "rad", Source::Raw(Linear, None)),
    ("theta_dy", "rad", Source::Raw(Linear, None)),
    (
        "omega_en",
        "rad/s",
        Source::Raw(Linear, Some(SensorKind::Speed)),
    ),
    (
        "omega_dy",
        "rad/s",
        Source::Raw(Linear, Some(SensorKind::Speed)),
    ),
    (
        "alpha_en",
        "rad/s^2",
        Source::Raw(Between::Dense(Alpha), None),
    ),
    ("alpha_dy", "rad/s^2", Source::Raw(Linear, None)),
    (
        "torque_shaft",
        "N*m",
        Source::Raw(Linear, Some(SensorKind::TorqueShaft)),
    ),
    (
        "torque_engine",
        "N*m",
        Source::Raw(Between::Dense(Engine), Some(SensorKind::TorqueEngine)),
    ),
    ("torque_dy", "N*m", Source::Raw(Linear, None)),
    (
        "p_cyl",
        "Pa",
        Source::Raw(Between::Dense(Pressure), Some(SensorKind::PCyl)),
    ),
    (
        "p_int",
        "Pa",
        Source::Raw(Linear, Some(SensorKind::PManifold)),
    ),
    (
        "p_exh",
        "Pa",
        Source::Raw(Linear, Some(SensorKind::PManifold)),
    ),
    ("p_crank", "Pa", Source::Ambient),
    ("p_atm", "Pa", Source::Ambient),
    (
        "T_oil",
        "K",
        Source::Raw(Hold, Some(SensorKind::Temperature)),
    ),
    (
        "T_int",
        "K",
        Source::Raw(Linear, Some(SensorKind::Temperature)),
    ),
    (
        "T_exh",
        "K",
        Source::Raw(Linear, Some(SensorKind::Temperature)),
    ),
    ("throttle", "deg", Source::Raw(Hold, None)),
    ("speed_demand", "rad/s", Source::Raw(Hold, None)),
    ("i_a", "A", Source::Raw(Linear, None)),
    ("i_b", "A", Source::Raw(Linear, None)),
    ("i_c", "A", Source::Raw(Linear, None)),
    ("v_a", "V", Source::Raw(Linear, None)),
    ("v_b", "V", Source::Raw(Linear, None)),
    ("v_c", "V", Source::Raw(Linear, None)),
    ("count_en", "-", Source::CountEn),
    ("count_dy", "-", Source::CountDy),
    ("tdc", "-", Source::Tdc),
    // The true torques and T_cyl are states'; the shaft's parameters are held over a step.
    (
        "true_torque_indicated",
        "N*m",
        Source::Raw(Between::Dense(Indicated), None),
    ),
    (
        "true_torque_reciprocating",
        "N*m",
        Source::Raw(Between::Dense(Reciprocating), None),
    ),
    ("true_torque_friction", "N*m", Source::Raw(Linear, None)),
    (
        "true_T_cyl",
        "K",
        Source::Raw(Between::Dense(Temperature), None),
    ),
    ("true_shaft_k", "N*m/rad", Source::Raw(Hold, None)),
    ("true_shaft_b", "N*m*s/rad", Source::Raw(Hold, None)),
];

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// Every raw column is recorded under its own name (the time through `Source::Time`,
    /// which reads it on a crank basis), and every channel taken from a raw column names one.
    #[test]
    fn every_raw_column_is_a_channel() {
        let raw: Vec<&str> = OUTPUT
            .iter()
            .filter(|c| matches!(c.2, Source::Raw(..) | Source::Time))
            .map(|c| c.0)
            .collect();
        let mut sorted = raw.clone();
        sorted.sort_unstable();
        // The last three are the dense output's.
        let mut want = RAW[..RAW.len() - 3].to_vec();
        want.sort_unstable();
        assert_eq!(sorted, want);
        assert_eq!(
            [RAW[T], RAW[THETA_EN], RAW[THETA_DY]],
            ["t", "theta_en", "theta_dy"]
        );
    }

    /// Linear between the steps; held at the containing step's value, a point within 1 % of
    /// a step before the next counting as on it.
    #[test]
    fn carried_linear_and_held() {
        for (f, lin, held) in [
            (0.0, 10.0, 10.0),
            (0.5, 15.0, 10.0),
            (0.985, 19.85, 10.0),
            (0.995, 19.95, 20.0),
            (1.0, 20.0, 20.0),
        ] {
            assert!((Linear.carry(10.0, 20.0, f) - lin).abs() < 1e-12, "{f}");
            assert_eq!(Hold.carry(10.0, 20.0, f), held, "{f}");
        }
    }
}
