//! The FMU's `modelDescription.xml`, FMI 2.0 or 3.0 co-simulation, written from the variable
//! table ([`crate::variables`]): every variable with its causality, variability, unit, start
//! value and description; the units in SI base units (`<UnitDefinitions>`); the outputs and
//! initial unknowns (`<ModelStructure>`); the scenario's duration and the sample interval as
//! the default experiment.

use crate::variables::{table, Causality, Type, Variability, Variable};
use crate::{Cell, MODEL_IDENTIFIER};
use std::fmt::Write;

/// The FMI version of an export.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fmi {
    /// FMI 2.0 co-simulation.
    V2,
    /// FMI 3.0 co-simulation.
    V3,
}

impl Fmi {
    /// The directory of the linux x86-64 binary in the archive.
    pub fn platform_dir(self) -> &'static str {
        match self {
            Fmi::V2 => "binaries/linux64",
            Fmi::V3 => "binaries/x86_64-linux",
        }
    }
}

/// A unit's SI base-unit exponents `[kg, m, s, A, K, rad]` and its factor to them.
fn base_unit(unit: &str) -> Option<([i8; 6], f64)> {
    Some(match unit {
        "s" => ([0, 0, 1, 0, 0, 0], 1.0),
        "Hz" => ([0, 0, -1, 0, 0, 0], 1.0),
        "m" => ([0, 1, 0, 0, 0, 0], 1.0),
        "m^2" => ([0, 2, 0, 0, 0, 0], 1.0),
        "m^3" => ([0, 3, 0, 0, 0, 0], 1.0),
        "kg" => ([1, 0, 0, 0, 0, 0], 1.0),
        "kg*m^2" => ([1, 2, 0, 0, 0, 0], 1.0),
        "K" => ([0, 0, 0, 0, 1, 0], 1.0),
        "A" => ([0, 0, 0, 1, 0, 0], 1.0),
        "J" => ([1, 2, -2, 0, 0, 0], 1.0),
        "Pa" => ([1, -1, -2, 0, 0, 0], 1.0),
        "V" => ([1, 2, -3, -1, 0, 0], 1.0),
        "Wb" => ([1, 2, -2, -1, 0, 0], 1.0),
        "ohm" | "V/A" => ([1, 2, -3, -2, 0, 0], 1.0),
        "V/(A*s)" => ([1, 2, -4, -2, 0, 0], 1.0),
        "A/Wb" => ([-1, -2, 2, 2, 0, 0], 1.0),
        "A/(Wb*s)" => ([-1, -2, 1, 2, 0, 0], 1.0),
        "N*m" => ([1, 2, -2, 0, 0, 0], 1.0),
        "N*m/rad" => ([1, 2, -2, 0, 0, -1], 1.0),
        "N*m*s/rad" => ([1, 2, -1, 0, 0, -1], 1.0),
        "A*s/rad" => ([0, 0, 1, 1, 0, -1], 1.0),
        "A/rad" => ([0, 0, 0, 1, 0, -1], 1.0),
        "rad" => ([0, 0, 0, 0, 0, 1], 1.0),
        "deg" => ([0, 0, 0, 0, 0, 1], std::f64::consts::PI / 180.0),
        "rad/s" => ([0, 0, -1, 0, 0, 1], 1.0),
        "rpm" => ([0, 0, -1, 0, 0, 1], std::f64::consts::PI / 30.0),
        "rad/s^2" => ([0, 0, -2, 0, 0, 1], 1.0),
        _ => return None,
    })
}

/// `s` with XML's five special characters escaped, for an attribute.
fn esc(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    out
}

/// A float as xs:double: the shortest text that reads back to the same value.
fn num(v: f64) -> String {
    format!("{v:?}")
}

/// The `<UnitDefinitions>` of every unit the variables use.
fn unit_definitions(vars: &[Variable]) -> Result<String, String> {
    let mut units: Vec<&str> = vars
        .iter()
        .map(|v| v.unit)
        .filter(|u| !u.is_empty())
        .collect();
    units.sort_unstable();
    units.dedup();
    let mut x = String::from("  <UnitDefinitions>\n");
    for u in units {
        let (e, factor) = base_unit(u).ok_or_else(|| {
            format!("the unit '{u}' has no SI definition in the FMU's description (a bug: add it to description::base_unit)")
        })?;
        let mut attrs = String::new();
        for (name, exp) in ["kg", "m", "s", "A", "K", "rad"].iter().zip(e) {
            if exp != 0 {
                let _ = write!(attrs, " {name}=\"{exp}\"");
            }
        }
        if factor != 1.0 {
            let _ = write!(attrs, " factor=\"{}\"", num(factor));
        }
        let _ = writeln!(x, "    <Unit name=\"{}\"><BaseUnit{attrs}/></Unit>", esc(u));
    }
    x.push_str("  </UnitDefinitions>\n");
    Ok(x)
}

fn causality(c: Causality) -> &'static str {
    match c {
        Causality::Independent => "independent",
        Causality::Parameter => "parameter",
        Causality::Input => "input",
        Causality::Output => "output",
    }
}

fn variability(v: Variability) -> &'static str {
    match v {
        Variability::Fixed => "fixed",
        Variability::Tunable => "tunable",
        Variability::Discrete => "discrete",
        Variability::Continuous => "continuous",
    }
}

/// The `initial` attribute: exact for what has a start value, calculated for the outputs.
fn initial(v: &Variable) -> &'static str {
    match v.causality {
        Causality::Independent | Causality::Input => "",
        Causality::Parameter => " initial=\"exact\"",
        Causality::Output => " initial=\"calculated\"",
    }
}

/// A start value as the type writes it.
fn start(v: &Variable) -> String {
    match (v.start, v.ty) {
        (None, _) => String::new(),
        (Some(s), Type::Real) => format!(" start=\"{}\"", num(s)),
        (Some(s), Type::Boolean) => format!(" start=\"{}\"", s != 0.0),
    }
}

/// The `modelDescription.xml` of `cell` for FMI `fmi`.
pub fn model_description(cell: &Cell, fmi: Fmi) -> Result<String, String> {
    let vars = table(cell);
    let s = &cell.scenario;
    let name = format!("physid virtual test cell: {}", s.name);
    let about = if s.description.is_empty() {
        "physid's virtual transient engine test cell".to_string()
    } else {
        format!(
            "physid's virtual transient engine test cell; {}",
            s.description
        )
    };
    let tool = format!("physid {}", env!("CARGO_PKG_VERSION"));
    let guid = cell.guid()?;
    let mut x = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    match fmi {
        Fmi::V2 => {
            let _ = writeln!(
                x,
                "<fmiModelDescription fmiVersion=\"2.0\" modelName=\"{}\" guid=\"{guid}\" description=\"{}\" generationTool=\"{}\" variableNamingConvention=\"flat\" numberOfEventIndicators=\"0\">",
                esc(&name),
                esc(&about),
                esc(&tool)
            );
            let _ = writeln!(
                x,
                "  <CoSimulation modelIdentifier=\"{MODEL_IDENTIFIER}\" canHandleVariableCommunicationStepSize=\"true\" canInterpolateInputs=\"false\" canRunAsynchronuously=\"false\" canBeInstantiatedOnlyOncePerProcess=\"false\" canNotUseMemoryManagementFunctions=\"true\" canGetAndSetFMUstate=\"true\" canSerializeFMUstate=\"false\" providesDirectionalDerivative=\"false\"/>"
            );
        }
        Fmi::V3 => {
            let _ = writeln!(
                x,
                "<fmiModelDescription fmiVersion=\"3.0\" modelName=\"{}\" instantiationToken=\"{guid}\" description=\"{}\" generationTool=\"{}\" variableNamingConvention=\"flat\">",
                esc(&name),
                esc(&about),
                esc(&tool)
            );
            let _ = writeln!(
                x,
                "  <CoSimulation modelIdentifier=\"{MODEL_IDENTIFIER}\" canHandleVariableCommunicationStepSize=\"true\" canBeInstantiatedOnlyOncePerProcess=\"false\" canGetAndSetFMUState=\"true\" canSerializeFMUState=\"false\" providesDirectionalDerivatives=\"false\" providesAdjointDerivatives=\"false\" hasEventMode=\"false\" providesIntermediateUpdate=\"false\" canReturnEarlyAfterIntermediateUpdate=\"false\"/>"
            );
        }
    }
    x.push_str(&unit_definitions(&vars)?);
    x.push_str("  <LogCategories>\n    <Category name=\"logStatusError\" description=\"a call refused or failed: what, and why\"/>\n    <Category name=\"logStatusWarning\" description=\"a call that went on with a caveat\"/>\n  </LogCategories>\n");
    let _ = writeln!(
        x,
        "  <DefaultExperiment startTime=\"0.0\" stopTime=\"{}\" stepSize=\"{}\"/>",
        num(s.duration),
        num(1.0 / cell.sample_rate)
    );
    x.push_str("  <ModelVariables>\n");
    for v in &vars {
        let unit = if v.unit.is_empty() || v.ty == Type::Boolean {
            String::new()
        } else {
            format!(" unit=\"{}\"", esc(v.unit))
        };
        let head = format!(
            "name=\"{}\" valueReference=\"{}\" description=\"{}\" causality=\"{}\" variability=\"{}\"{}",
            esc(&v.name),
            v.vr,
            esc(&v.description),
            causality(v.causality),
            variability(v.variability),
            initial(v)
        );
        match fmi {
            Fmi::V2 => {
                let ty = match v.ty {
                    Type::Real => "Real",
                    Type::Boolean => "Boolean",
                };
                let _ = writeln!(
                    x,
                    "    <ScalarVariable {head}><{ty}{unit}{}/></ScalarVariable>",
                    start(v)
                );
            }
            Fmi::V3 => {
                let ty = match v.ty {
                    Type::Real => "Float64",
                    Type::Boolean => "Boolean",
                };
                let _ = writeln!(x, "    <{ty} {head}{unit}{}/>", start(v));
            }
        }
    }
    x.push_str("  </ModelVariables>\n  <ModelStructure>\n");
    let outputs: Vec<&Variable> = vars
        .iter()
        .filter(|v| v.causality == Causality::Output)
        .collect();
    match fmi {
        Fmi::V2 => {
            // FMI 2 refers to a variable by its 1-based place in <ModelVariables>.
            x.push_str("    <Outputs>\n");
            for v in &outputs {
                let _ = writeln!(x, "      <Unknown index=\"{}\"/>", v.vr + 1);
            }
            x.push_str("    </Outputs>\n    <InitialUnknowns>\n");
            for v in &outputs {
                let _ = writeln!(x, "      <Unknown index=\"{}\"/>", v.vr + 1);
            }
            x.push_str("    </InitialUnknowns>\n");
        }
        Fmi::V3 => {
            for v in &outputs {
                let _ = writeln!(x, "    <Output valueReference=\"{}\"/>", v.vr);
            }
            for v in &outputs {
                let _ = writeln!(x, "    <InitialUnknown valueReference=\"{}\"/>", v.vr);
            }
        }
    }
    x.push_str("  </ModelStructure>\n</fmiModelDescription>\n");
    Ok(x)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use physid_sim::scenario::Scenario;

    /// Both descriptions name every variable once, define every unit they use, and escape
    /// what XML needs escaped.
    #[test]
    fn both_versions_are_complete() {
        let mut s = Scenario::load("shaft-steady").unwrap();
        s.description = "a <test> & \"quotes\"".into();
        let cell = Cell::new(s, 10_000.0).unwrap();
        let n = table(&cell).len();
        for fmi in [Fmi::V2, Fmi::V3] {
            let x = model_description(&cell, fmi).unwrap();
            assert!(x.contains("a &lt;test&gt; &amp; &quot;quotes&quot;"));
            let vars = match fmi {
                Fmi::V2 => x.matches("<ScalarVariable ").count(),
                Fmi::V3 => x.matches("<Float64 ").count() + x.matches("<Boolean ").count(),
            };
            assert_eq!(vars, n);
            for u in x
                .split("unit=\"")
                .skip(1)
                .map(|r| &r[..r.find('"').unwrap()])
            {
                assert!(x.contains(&format!("<Unit name=\"{u}\">")), "{u}");
            }
        }
    }

    /// The units' SI definitions hold by their own arithmetic: N·m/rad·rad = N·m, V/A = ohm,
    /// rpm = 2π/60 rad/s.
    #[test]
    fn units_compose() {
        let add = |a: [i8; 6], b: [i8; 6]| std::array::from_fn::<i8, 6, _>(|i| a[i] + b[i]);
        let u = |s| base_unit(s).unwrap().0;
        assert_eq!(add(u("N*m/rad"), u("rad")), u("N*m"));
        assert_eq!(add(u("N*m*s/rad"), u("rad/s")), u("N*m"));
        assert_eq!(add(u("Wb"), u("Hz")), u("V"));
        assert_eq!(add(u("V/A"), u("A")), u("V"));
        assert_eq!(add(u("A/Wb"), u("Wb")), u("A"));
        assert_eq!(add(u("J"), add(u("m^3"), [0; 6]).map(|e| -e)), u("Pa"));
        assert!((base_unit("rpm").unwrap().1 - 2.0 * std::f64::consts::PI / 60.0).abs() < 1e-17);
    }
}
