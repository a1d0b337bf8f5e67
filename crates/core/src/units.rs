//! Units of measure: the labels physid knows, grouped by dimension, each with its affine map to
//! the dimension's SI unit (`si = value·scale + offset`).
//!
//! Test-cell software labels the same unit many ways (`rpm`, `1/min`, `min^-1`; `Nm`, `N·m`;
//! `°C`, `degC`): every spelling in [`UNITS`] is accepted. Two labels convert into each other
//! exactly when they share a dimension. A label physid does not know converts to nothing — the
//! caller refuses it with the labels it would accept ([`known_for`]).

/// One unit label: its dimension and its affine map to the dimension's SI unit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Unit {
    /// The label as written in files (`"rpm"`).
    pub label: &'static str,
    /// The dimension's name (`"angular velocity"`).
    pub dimension: &'static str,
    /// `si = value·scale + offset`.
    pub scale: f64,
    /// See `scale`.
    pub offset: f64,
}

const fn u(label: &'static str, dimension: &'static str, scale: f64, offset: f64) -> Unit {
    Unit {
        label,
        dimension,
        scale,
        offset,
    }
}

const PI: f64 = std::f64::consts::PI;
/// 1 psi in Pa (1 lbf/in² = 4.4482216152605 N / 0.00064516 m², exact by definition).
const PSI: f64 = 4.448_221_615_260_5 / 0.000_645_16;

/// Every label physid knows. The first label of each dimension is its SI unit (scale 1,
/// offset 0).
pub const UNITS: &[Unit] = &[
    u("s", "time", 1.0, 0.0),
    u("ms", "time", 1e-3, 0.0),
    u("us", "time", 1e-6, 0.0),
    u("µs", "time", 1e-6, 0.0),
    u("min", "time", 60.0, 0.0),
    u("h", "time", 3600.0, 0.0),
    u("rad", "angle", 1.0, 0.0),
    u("deg", "angle", PI / 180.0, 0.0),
    u("°", "angle", PI / 180.0, 0.0),
    u("degCA", "angle", PI / 180.0, 0.0),
    u("°CA", "angle", PI / 180.0, 0.0),
    u("rev", "angle", 2.0 * PI, 0.0),
    u("rad/s", "angular velocity", 1.0, 0.0),
    u("rpm", "angular velocity", PI / 30.0, 0.0),
    u("1/min", "angular velocity", PI / 30.0, 0.0),
    u("min^-1", "angular velocity", PI / 30.0, 0.0),
    u("min-1", "angular velocity", PI / 30.0, 0.0),
    u("rev/min", "angular velocity", PI / 30.0, 0.0),
    u("r/min", "angular velocity", PI / 30.0, 0.0),
    u("deg/s", "angular velocity", PI / 180.0, 0.0),
    u("rev/s", "angular velocity", 2.0 * PI, 0.0),
    u("rad/s^2", "angular acceleration", 1.0, 0.0),
    u("rad/s²", "angular acceleration", 1.0, 0.0),
    u("deg/s^2", "angular acceleration", PI / 180.0, 0.0),
    u("rpm/s", "angular acceleration", PI / 30.0, 0.0),
    u("N*m", "torque", 1.0, 0.0),
    u("Nm", "torque", 1.0, 0.0),
    u("N.m", "torque", 1.0, 0.0),
    u("N·m", "torque", 1.0, 0.0),
    u("N m", "torque", 1.0, 0.0),
    u("kN*m", "torque", 1e3, 0.0),
    u("kNm", "torque", 1e3, 0.0),
    u("Pa", "pressure", 1.0, 0.0),
    u("hPa", "pressure", 1e2, 0.0),
    u("kPa", "pressure", 1e3, 0.0),
    u("MPa", "pressure", 1e6, 0.0),
    u("bar", "pressure", 1e5, 0.0),
    u("mbar", "pressure", 1e2, 0.0),
    u("psi", "pressure", PSI, 0.0),
    u("K", "temperature", 1.0, 0.0),
    u("degC", "temperature", 1.0, 273.15),
    u("°C", "temperature", 1.0, 273.15),
    u("C", "temperature", 1.0, 273.15),
    u("deg C", "temperature", 1.0, 273.15),
    // K = (F − 32)·5/9 + 273.15 = F·5/9 + 255.372…
    u("degF", "temperature", 5.0 / 9.0, 273.15 - 32.0 * 5.0 / 9.0),
    u("°F", "temperature", 5.0 / 9.0, 273.15 - 32.0 * 5.0 / 9.0),
    u("m", "length", 1.0, 0.0),
    u("mm", "length", 1e-3, 0.0),
    u("cm", "length", 1e-2, 0.0),
    u("A", "current", 1.0, 0.0),
    u("mA", "current", 1e-3, 0.0),
    u("V", "voltage", 1.0, 0.0),
    u("mV", "voltage", 1e-3, 0.0),
    u("kV", "voltage", 1e3, 0.0),
    u("-", "dimensionless", 1.0, 0.0),
    u("1", "dimensionless", 1.0, 0.0),
    u("count", "dimensionless", 1.0, 0.0),
    u("counts", "dimensionless", 1.0, 0.0),
    u("pulses", "dimensionless", 1.0, 0.0),
];

/// The unit a label names (exact spelling, surrounding blanks ignored).
pub fn lookup(label: &str) -> Option<&'static Unit> {
    let label = label.trim();
    UNITS.iter().find(|u| u.label == label)
}

/// `(scale, offset)` with `to = from_value·scale + offset`, when both labels are known and share
/// a dimension (identical labels convert by identity even when unknown).
pub fn conversion(from: &str, to: &str) -> Option<(f64, f64)> {
    if from.trim() == to.trim() {
        return Some((1.0, 0.0));
    }
    let (f, t) = (lookup(from)?, lookup(to)?);
    if f.dimension != t.dimension {
        return None;
    }
    // si = v·f.scale + f.offset; to = (si − t.offset)/t.scale.
    Some((f.scale / t.scale, (f.offset - t.offset) / t.scale))
}

/// The labels that convert to `to`, comma separated (for error messages).
pub fn known_for(to: &str) -> String {
    match lookup(to) {
        Some(t) => UNITS
            .iter()
            .filter(|u| u.dimension == t.dimension)
            .map(|u| u.label)
            .collect::<Vec<_>>()
            .join(", "),
        None => to.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_dimension_starts_with_its_si_unit_and_labels_are_unique() {
        let mut seen = std::collections::HashSet::new();
        for (i, u) in UNITS.iter().enumerate() {
            assert!(seen.insert(u.label), "{} twice", u.label);
            if UNITS[..i].iter().all(|v| v.dimension != u.dimension) {
                assert_eq!((u.scale, u.offset), (1.0, 0.0), "{}", u.label);
            }
        }
    }

    #[test]
    fn conversions_against_definitions() {
        let c = |f: &str, t: &str, v: f64| {
            let (s, o) = conversion(f, t).unwrap();
            v * s + o
        };
        // 1000 rpm = 1000·2π/60 rad/s.
        assert!((c("rpm", "rad/s", 1000.0) - 104.719_755_119_659_77).abs() < 1e-12);
        assert!((c("1/min", "rpm", 1234.5) - 1234.5).abs() < 1e-12);
        assert!((c("deg", "rad", 180.0) - PI).abs() < 1e-15);
        assert!((c("rad", "deg", PI) - 180.0).abs() < 1e-12);
        assert_eq!(c("bar", "Pa", 1.013_25), 101_325.0);
        assert!((c("Pa", "kPa", 101_325.0) - 101.325).abs() < 1e-12);
        assert!((c("°C", "K", 90.0) - 363.15).abs() < 1e-12);
        assert!((c("K", "degC", 363.15) - 90.0).abs() < 1e-12);
        // 212 °F is 100 °C; −40 °F is −40 °C.
        assert!((c("°F", "degC", 212.0) - 100.0).abs() < 1e-12);
        assert!((c("degF", "K", -40.0) - 233.15).abs() < 1e-12);
        // 1 psi = 6894.757293168361 Pa (NIST).
        assert!((c("psi", "Pa", 1.0) - 6_894.757_293_168_361).abs() < 1e-9);
        assert!((c("mm", "m", 86.0) - 0.086).abs() < 1e-16);
        assert_eq!(c("kNm", "N*m", 1.5), 1500.0);
        assert_eq!(c("ms", "s", 250.0), 0.25);
        assert!(conversion("deg", "rad/s").is_none());
        assert!(conversion("lbf*ft", "N*m").is_none());
        assert!(conversion("furlong", "furlong").is_some());
        assert!(known_for("Pa").contains("bar") && known_for("Pa").contains("psi"));
    }
}
