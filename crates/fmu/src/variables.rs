//! The FMU's variables, from the cell's own tables: its physical parameters
//! ([`CellParams::TABLE`], the paths `physid simulate --list-params` gives), the demand
//! inputs, and the recording's channels ([`physid_sim::run::channels`]) as outputs — so that
//! names and units are those of `physid simulate`'s recording. One table serves the
//! modelDescription.xml ([`crate::description`]) and the instance that reads and writes the
//! values ([`crate::instance`]): the value references are the positions in it.

use crate::Cell;
use physid_sim::params::CellParams;
use physid_sim::run::{channels, OutputBasis};
use physid_sim::scenario::FAULT_PATHS;

/// Who sets a variable (FMI's causality).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Causality {
    /// The simulation time.
    Independent,
    /// Set by the importer before initialisation (or during the run when tunable).
    Parameter,
    /// Set by the importer before each step.
    Input,
    /// Computed by the cell.
    Output,
}

/// When a variable may change (FMI's variability).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Variability {
    /// Only before the end of initialisation.
    Fixed,
    /// Between steps too.
    Tunable,
    /// Between steps (a Boolean input).
    Discrete,
    /// Continuously in time.
    Continuous,
}

/// A variable's type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Type {
    /// `Real` (FMI 2), `Float64` (FMI 3).
    Real,
    /// `Boolean`.
    Boolean,
}

/// What a variable stands for in the cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// The time [s].
    Time,
    /// A cell parameter, by its index in [`CellParams::TABLE`].
    Cell(usize),
    /// The output sample rate [Hz].
    SampleRate,
    /// Whether the scenario's own profiles drive the cell (else the `demand.*` inputs).
    FromScenario,
    /// The speed demand [rpm].
    Speed,
    /// The torque demand [N·m].
    Torque,
    /// The throttle opening [deg].
    Throttle,
    /// The dynamometer follows the torque demand (else the speed demand).
    TorqueMode,
    /// A recording channel, by its index among the outputs.
    Channel(usize),
}

/// One variable.
#[derive(Debug, Clone, PartialEq)]
pub struct Variable {
    /// Its name: a parameter's path (`shaft.k`), a channel's name (`omega_en`), `demand.*`.
    pub name: String,
    /// Its value reference: its position in the table.
    pub vr: u32,
    /// Its type.
    pub ty: Type,
    /// Its causality.
    pub causality: Causality,
    /// Its variability.
    pub variability: Variability,
    /// Its unit as physid writes it (`N*m/rad`; empty for a dimensionless one).
    pub unit: &'static str,
    /// One line about it.
    pub description: String,
    /// Its start value (parameters and inputs; `None` for the time and the outputs).
    pub start: Option<f64>,
    /// What it is in the cell.
    pub role: Role,
}

/// The basis the FMU's outputs are sampled on.
pub(crate) fn basis(rate: f64) -> OutputBasis {
    OutputBasis::Time(rate)
}

/// Every variable of the FMU exported from `cell`, in value-reference order.
pub fn table(cell: &Cell) -> Vec<Variable> {
    let params = cell.params();
    let scenario = &cell.scenario;
    let mut vars = Vec::new();
    let mut push = |name: &str,
                    ty: Type,
                    causality: Causality,
                    variability: Variability,
                    unit: &'static str,
                    description: String,
                    start: Option<f64>,
                    role: Role| {
        vars.push(Variable {
            name: name.to_string(),
            vr: vars.len() as u32,
            ty,
            causality,
            variability,
            unit: if unit == "-" { "" } else { unit },
            description,
            start,
            role,
        });
    };
    use Causality::*;
    use Variability::*;
    push(
        "time",
        Type::Real,
        Independent,
        Continuous,
        "s",
        "simulation time (the recording's t)".into(),
        None,
        Role::Time,
    );
    for (k, (path, unit, source)) in CellParams::TABLE.iter().enumerate() {
        let tunable = FAULT_PATHS.contains(path);
        push(
            path,
            Type::Real,
            Parameter,
            if tunable { Tunable } else { Fixed },
            unit,
            if tunable {
                format!("{source}; set during the run: a fault from that time on")
            } else {
                (*source).to_string()
            },
            params.get(path),
            Role::Cell(k),
        );
    }
    push(
        "sample_rate",
        Type::Real,
        Parameter,
        Fixed,
        "Hz",
        "the outputs' sample rate: at a communication point they hold the last sample at or before it".into(),
        Some(cell.sample_rate),
        Role::SampleRate,
    );
    push(
        "demand.from_scenario",
        Type::Boolean,
        Parameter,
        Tunable,
        "",
        format!(
            "true: the scenario '{}' drives the cell (its speed and throttle profiles); false: the demand.* inputs",
            scenario.name
        ),
        Some(1.0),
        Role::FromScenario,
    );
    let (speed0, throttle0) = (scenario.speed.value(0.0), scenario.throttle.value(0.0));
    push(
        "demand.speed",
        Type::Real,
        Input,
        Continuous,
        "rpm",
        "the dynamometer's speed demand (when demand.torque_mode is false)".into(),
        Some(if scenario.torque_mode { 1000.0 } else { speed0 }),
        Role::Speed,
    );
    push(
        "demand.torque",
        Type::Real,
        Input,
        Continuous,
        "N*m",
        "the dynamometer's torque demand (when demand.torque_mode is true)".into(),
        Some(if scenario.torque_mode { speed0 } else { 0.0 }),
        Role::Torque,
    );
    push(
        "demand.throttle",
        Type::Real,
        Input,
        Continuous,
        "deg",
        "the throttle opening above closed (90: wide open)".into(),
        Some(throttle0),
        Role::Throttle,
    );
    push(
        "demand.torque_mode",
        Type::Boolean,
        Input,
        Discrete,
        "",
        "the dynamometer follows demand.torque (else demand.speed)".into(),
        Some(f64::from(u8::from(scenario.torque_mode))),
        Role::TorqueMode,
    );
    for (k, (name, unit)) in channels(basis(cell.sample_rate))
        .filter(|c| c.0 != "t")
        .enumerate()
    {
        push(
            name,
            Type::Real,
            Output,
            Continuous,
            unit,
            format!("the recording's channel {name}"),
            None,
            Role::Channel(k),
        );
    }
    vars
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use physid_sim::scenario::Scenario;

    /// Every cell parameter and every recorded channel but the time is a variable, under its
    /// own name and unit; value references are positions.
    #[test]
    fn every_parameter_and_channel_under_its_name() {
        let cell = Cell::new(Scenario::load("shaft-steady").unwrap(), 10_000.0).unwrap();
        let vars = table(&cell);
        for (k, v) in vars.iter().enumerate() {
            assert_eq!(v.vr as usize, k);
        }
        for (path, unit, _) in CellParams::TABLE {
            let v = vars.iter().find(|v| v.name == *path).unwrap();
            assert_eq!(v.causality, Causality::Parameter);
            assert_eq!(v.unit, if *unit == "-" { "" } else { *unit });
            assert_eq!(v.start, CellParams::default().get(path));
        }
        let outputs: Vec<&str> = vars
            .iter()
            .filter(|v| v.causality == Causality::Output)
            .map(|v| v.name.as_str())
            .collect();
        let recorded: Vec<&str> = channels(OutputBasis::Time(1.0))
            .map(|c| c.0)
            .filter(|&n| n != "t")
            .collect();
        assert_eq!(outputs, recorded);
        assert!(outputs.contains(&"omega_en") && outputs.contains(&"torque_shaft"));
        let names: std::collections::HashSet<&str> = vars.iter().map(|v| v.name.as_str()).collect();
        assert_eq!(names.len(), vars.len(), "names are unique");
    }
}
