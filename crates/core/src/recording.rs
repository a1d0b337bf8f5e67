//! A recording: named channels with SI units on a time or crank-angle basis.
//!
//! Every producer (simulator, file reader) and consumer (estimators, applications) speaks this
//! type; file formats are adapters at the edge (`physid-io`).

use crate::units;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, HashMap};

/// The channel-name table (DESIGN.md): `(name, SI unit, meaning)`. Producers use these names;
/// users' own names are mapped onto them (`--map name=column`).
pub const CHANNEL_TABLE: &[(&str, &str, &str)] = &[
    ("t", "s", "time"),
    ("theta_en", "rad", "engine angle, continuous"),
    ("theta_dy", "rad", "dynamometer angle, continuous"),
    ("omega_en", "rad/s", "engine speed"),
    ("omega_dy", "rad/s", "dynamometer speed"),
    ("alpha_en", "rad/s^2", "engine acceleration"),
    ("alpha_dy", "rad/s^2", "dynamometer acceleration"),
    ("torque_shaft", "N*m", "in-line shaft torque"),
    ("torque_engine", "N*m", "engine torque (mount load cell)"),
    (
        "torque_dy",
        "N*m",
        "dynamometer electromagnetic torque (simulation)",
    ),
    ("p_cyl", "Pa", "cylinder pressure"),
    ("p_int", "Pa", "intake manifold pressure"),
    ("p_exh", "Pa", "exhaust pressure"),
    ("p_crank", "Pa", "crank-case pressure"),
    ("p_atm", "Pa", "ambient pressure"),
    ("T_oil", "K", "oil temperature"),
    ("T_int", "K", "intake temperature"),
    ("T_exh", "K", "exhaust temperature"),
    ("throttle", "deg", "throttle angle"),
    ("speed_demand", "rad/s", "dynamometer speed demand"),
    ("i_a", "A", "dynamometer phase current a"),
    ("i_b", "A", "dynamometer phase current b"),
    ("i_c", "A", "dynamometer phase current c"),
    ("v_a", "V", "dynamometer phase voltage a"),
    ("v_b", "V", "dynamometer phase voltage b"),
    ("v_c", "V", "dynamometer phase voltage c"),
    ("count_en", "-", "engine encoder, cumulative pulses"),
    ("count_dy", "-", "dynamometer encoder, cumulative pulses"),
    ("tdc", "-", "TDC marker (non-zero on its pulse)"),
    ("cycle", "-", "cycle index (crank-angle basis)"),
    ("crank_deg", "deg", "crank angle in the cycle"),
    (
        "theta",
        "rad",
        "crank angle from the first TDC (crank-angle basis)",
    ),
];

/// The SI unit the channel table gives a name, if it is in the table.
pub fn standard_unit(name: &str) -> Option<&'static str> {
    CHANNEL_TABLE
        .iter()
        .find(|(n, _, _)| *n == name)
        .map(|(_, u, _)| *u)
}

/// What the samples of a recording are indexed by.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Basis {
    /// Samples in time (a `t` channel in seconds, usually).
    #[default]
    Time,
    /// One sample per crank-angle increment (`cycle`, `crank_deg` channels).
    CrankAngle,
}

/// One named channel: its unit (SI string such as `"rad/s"`, `"N*m"`, or `""` when unknown) and
/// its samples.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Channel {
    /// Channel name (DESIGN.md channel table, or the user's own name).
    pub name: String,
    /// Unit as an SI string; empty when the source did not say.
    pub unit: String,
    /// The samples.
    pub values: Vec<f64>,
}

/// Errors about a recording's shape or contents.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RecordingError {
    /// A channel that the recording does not have (the list of those there are is cut after
    /// [`LISTED_CHANNELS`] names: a file may have 100 000).
    #[error("no channel '{name}'; the channels are: {}", listed(available))]
    MissingChannel {
        /// The name asked for.
        name: String,
        /// The channels there are, comma separated.
        available: String,
    },
    /// Channels of different lengths.
    #[error("channel '{name}' has {len} samples but the recording has {expected}")]
    LengthMismatch {
        /// Channel name.
        name: String,
        /// Its length.
        len: usize,
        /// The recording's length.
        expected: usize,
    },
    /// Two channels with one name.
    #[error("channel '{0}' appears twice")]
    DuplicateChannel(String),
    /// A channel in a unit that cannot be converted to the one asked for.
    #[error("channel '{name}' is in '{unit}', which physid cannot convert to '{wanted}' (units it converts: {known}); state the right unit with --map {name}=COLUMN:UNIT, or map the column to another name")]
    Unit {
        /// Channel name.
        name: String,
        /// Its unit.
        unit: String,
        /// The unit asked for.
        wanted: String,
        /// The units that convert to it.
        known: String,
    },
}

/// How many channel names an error lists before it says how many there are in all.
pub const LISTED_CHANNELS: usize = 40;

/// A comma-separated list of names, cut after [`LISTED_CHANNELS`] with the count in all.
fn listed(names: &str) -> std::borrow::Cow<'_, str> {
    match names.match_indices(", ").nth(LISTED_CHANNELS - 1) {
        Some((cut, _)) => format!(
            "{} … ({} in all)",
            &names[..cut],
            names.matches(", ").count() + 1
        )
        .into(),
        None => names.into(),
    }
}

/// Named channels of equal length on one basis, with free-form metadata. A channel is found
/// by name in constant time (a file of 100 000 columns is read in linear time).
#[derive(Debug, Clone, Serialize, Deserialize, Default)]
#[serde(from = "Stored")]
pub struct Recording {
    /// Time or crank-angle basis.
    pub basis: Basis,
    channels: Vec<Channel>,
    /// Free-form metadata (source file, scenario, …).
    pub meta: BTreeMap<String, String>,
    /// Where each channel is in `channels`, by name (names never change once pushed).
    #[serde(skip)]
    index: HashMap<String, usize>,
}

/// A recording as serialised: its index is built again when read.
#[derive(Deserialize)]
struct Stored {
    basis: Basis,
    channels: Vec<Channel>,
    meta: BTreeMap<String, String>,
}

impl From<Stored> for Recording {
    fn from(s: Stored) -> Self {
        let index = s
            .channels
            .iter()
            .enumerate()
            .map(|(i, c)| (c.name.clone(), i))
            .collect();
        Self {
            basis: s.basis,
            channels: s.channels,
            meta: s.meta,
            index,
        }
    }
}

impl PartialEq for Recording {
    fn eq(&self, other: &Self) -> bool {
        self.basis == other.basis && self.channels == other.channels && self.meta == other.meta
    }
}

impl Recording {
    /// An empty recording on a basis.
    pub fn new(basis: Basis) -> Self {
        Self {
            basis,
            channels: Vec::new(),
            meta: BTreeMap::new(),
            index: HashMap::new(),
        }
    }

    /// Add a channel; its length must equal the recording's, its name must be new.
    pub fn push(&mut self, channel: Channel) -> Result<(), RecordingError> {
        if self.index.contains_key(&channel.name) {
            return Err(RecordingError::DuplicateChannel(channel.name));
        }
        if let Some(first) = self.channels.first() {
            if first.values.len() != channel.values.len() {
                return Err(RecordingError::LengthMismatch {
                    name: channel.name,
                    len: channel.values.len(),
                    expected: first.values.len(),
                });
            }
        }
        self.index.insert(channel.name.clone(), self.channels.len());
        self.channels.push(channel);
        Ok(())
    }

    /// Number of samples (0 for a recording without channels).
    pub fn len(&self) -> usize {
        self.channels.first().map_or(0, |c| c.values.len())
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Samples `range` of every channel, with the basis and metadata (`range` is clamped to
    /// the recording).
    pub fn slice(&self, range: std::ops::Range<usize>) -> Recording {
        let end = range.end.min(self.len());
        let start = range.start.min(end);
        Recording {
            basis: self.basis,
            channels: self
                .channels
                .iter()
                .map(|c| Channel {
                    name: c.name.clone(),
                    unit: c.unit.clone(),
                    values: c.values[start..end].to_vec(),
                })
                .collect(),
            meta: self.meta.clone(),
            index: self.index.clone(),
        }
    }

    /// Room for `rows` more samples in every channel, exactly (no doubling).
    pub fn reserve_exact(&mut self, rows: usize) {
        for c in &mut self.channels {
            c.values.reserve_exact(rows);
        }
    }

    /// `other`'s samples after this recording's, channel by channel (by name; `other` must
    /// have every channel of this one).
    pub fn append(&mut self, other: &Recording) -> Result<(), RecordingError> {
        let sources = self
            .channels
            .iter()
            .map(|c| other.values(&c.name).map(|v| v.len()))
            .collect::<Result<Vec<_>, _>>()?;
        if let Some((c, &len)) = self
            .channels
            .iter()
            .zip(&sources)
            .find(|(_, &l)| l != other.len())
        {
            return Err(RecordingError::LengthMismatch {
                name: c.name.clone(),
                len,
                expected: other.len(),
            });
        }
        for c in &mut self.channels {
            c.values.extend_from_slice(other.values(&c.name)?);
        }
        Ok(())
    }

    /// All channels in order.
    pub fn channels(&self) -> &[Channel] {
        &self.channels
    }

    /// The channel names in order.
    pub fn names(&self) -> Vec<&str> {
        self.channels.iter().map(|c| c.name.as_str()).collect()
    }

    /// A channel by name, or an error listing the channels there are.
    pub fn channel(&self, name: &str) -> Result<&Channel, RecordingError> {
        self.index
            .get(name)
            .map(|&i| &self.channels[i])
            .ok_or_else(|| RecordingError::MissingChannel {
                name: name.to_string(),
                available: self.names().join(", "),
            })
    }

    /// The samples of a channel by name.
    pub fn values(&self, name: &str) -> Result<&[f64], RecordingError> {
        self.channel(name).map(|c| c.values.as_slice())
    }

    /// The samples of a channel in `unit`, converted from the channel's own unit when both are
    /// labels of one dimension ([`crate::units`]: rpm ↔ rad/s, deg ↔ rad, bar/kPa ↔ Pa,
    /// °C ↔ K, mm ↔ m, …). A channel without a unit is taken to be in `unit` already; any other
    /// unit is an error naming the channel and the labels that would convert.
    pub fn values_in(&self, name: &str, unit: &str) -> Result<Vec<f64>, RecordingError> {
        let ch = self.channel(name)?;
        if ch.unit.is_empty() || ch.unit == unit {
            return Ok(ch.values.clone());
        }
        match units::conversion(&ch.unit, unit) {
            Some((scale, offset)) => Ok(ch.values.iter().map(|v| v * scale + offset).collect()),
            None => Err(RecordingError::Unit {
                name: name.into(),
                unit: ch.unit.clone(),
                wanted: unit.into(),
                known: units::known_for(unit),
            }),
        }
    }

    /// Convert every channel of the channel table ([`CHANNEL_TABLE`]) to its SI unit in place,
    /// so that every consumer gets `omega_en` in rad/s whatever the file said. A channel with
    /// no unit is taken to be in SI already and left unlabelled; a unit that does not convert
    /// is an error naming the channel. Returns what was converted, `(channel, from, to)`.
    pub fn to_standard_units(&mut self) -> Result<Vec<(String, String, String)>, RecordingError> {
        let mut done = Vec::new();
        for ch in &mut self.channels {
            let Some(si) = standard_unit(&ch.name) else {
                continue;
            };
            if ch.unit.is_empty() || ch.unit == si {
                continue;
            }
            let Some((scale, offset)) = units::conversion(&ch.unit, si) else {
                return Err(RecordingError::Unit {
                    name: ch.name.clone(),
                    unit: ch.unit.clone(),
                    wanted: si.into(),
                    known: units::known_for(si),
                });
            };
            if (scale, offset) != (1.0, 0.0) {
                for v in &mut ch.values {
                    *v = *v * scale + offset;
                }
            }
            done.push((
                ch.name.clone(),
                std::mem::replace(&mut ch.unit, si.into()),
                si.into(),
            ));
        }
        Ok(done)
    }

    /// Replace a channel's samples (same length).
    pub fn replace_values(&mut self, name: &str, values: Vec<f64>) -> Result<(), RecordingError> {
        let expected = self.len();
        let Some(&i) = self.index.get(name) else {
            return Err(RecordingError::MissingChannel {
                name: name.into(),
                available: self.names().join(", "),
            });
        };
        let ch = &mut self.channels[i];
        if values.len() != expected {
            return Err(RecordingError::LengthMismatch {
                name: name.into(),
                len: values.len(),
                expected,
            });
        }
        ch.values = values;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Channels are found by name through the index, also in a recording read back from its
    /// serialised form and in a slice; a duplicate name is still refused.
    #[test]
    fn channels_are_found_by_name_however_the_recording_was_made() {
        let mut r = Recording::new(Basis::Time);
        for k in 0..1000 {
            r.push(ch(&format!("c{k}"), vec![k as f64; 2])).unwrap();
        }
        assert!(matches!(
            r.push(ch("c7", vec![0.0; 2])),
            Err(RecordingError::DuplicateChannel(n)) if n == "c7"
        ));
        let text = serde_json::to_string(&r).unwrap();
        assert!(!text.contains("index"));
        let back: Recording = serde_json::from_str(&text).unwrap();
        assert_eq!(back, r);
        assert_eq!(back.values("c999").unwrap(), &[999.0, 999.0]);
        assert_eq!(r.slice(1..2).values("c3").unwrap(), &[3.0]);
        let mut back = back;
        back.replace_values("c5", vec![1.0, 2.0]).unwrap();
        assert_eq!(back.values("c5").unwrap(), &[1.0, 2.0]);
        let e = back.values("nope").unwrap_err().to_string();
        assert!(
            e.ends_with("the channels are: c0, c1, c2, c3, c4, c5, c6, c7, c8, c9, c10, c11, c12, c13, c14, c15, c16, c17, c18, c19, c20, c21, c22, c23, c24, c25, c26, c27, c28, c29, c30, c31, c32, c33, c34, c35, c36, c37, c38, c39 … (1000 in all)"),
            "{e}"
        );
        assert!(r.slice(0..1).values("x").is_err());
    }

    fn ch(name: &str, v: Vec<f64>) -> Channel {
        Channel {
            name: name.into(),
            unit: "rad".into(),
            values: v,
        }
    }

    #[test]
    fn values_in_converts_known_units_and_names_the_rest() {
        let mut r = Recording::new(Basis::Time);
        for (name, unit, v) in [
            ("p_int", "kPa", 70.0),
            ("T_oil", "degC", 90.0),
            ("omega_en", "rpm", 1000.0),
            ("p_exh", "", 1.5e5),
            ("torque_shaft", "lbf*ft", 1.0),
        ] {
            r.push(Channel {
                name: name.into(),
                unit: unit.into(),
                values: vec![v],
            })
            .unwrap();
        }
        assert_eq!(r.values_in("p_int", "Pa").unwrap(), vec![70e3]);
        assert_eq!(r.values_in("T_oil", "K").unwrap(), vec![363.15]);
        // 1000 rpm = 104.719755… rad/s (1000·2π/60).
        assert!((r.values_in("omega_en", "rad/s").unwrap()[0] - 104.71975511965977).abs() < 1e-12);
        assert_eq!(r.values_in("p_exh", "Pa").unwrap(), vec![1.5e5]);
        // And back: K → °C, Pa → kPa.
        let mut k = Recording::new(Basis::Time);
        for (name, unit, v) in [("T_oil", "K", 363.15), ("p_cyl", "Pa", 2.5e5)] {
            k.push(Channel {
                name: name.into(),
                unit: unit.into(),
                values: vec![v],
            })
            .unwrap();
        }
        assert!((k.values_in("T_oil", "degC").unwrap()[0] - 90.0).abs() < 1e-12);
        assert_eq!(k.values_in("p_cyl", "kPa").unwrap(), vec![250.0]);
        let e = r.values_in("torque_shaft", "N*m").unwrap_err().to_string();
        assert!(
            e.contains("'torque_shaft' is in 'lbf*ft'") && e.contains("kN*m"),
            "{e}"
        );
    }

    #[test]
    fn standard_channels_come_to_si_and_others_stay() {
        let mut r = Recording::new(Basis::Time);
        for (name, unit, v) in [
            ("t", "ms", 250.0),
            ("theta_en", "deg", 90.0),
            ("omega_en", "rpm", 1500.0),
            ("T_oil", "°C", 90.0),
            ("p_int", "bar", 0.7),
            ("p_cyl", "", 1e5),
            ("throttle", "deg", 30.0),
            ("EngSpeed", "rpm", 1500.0),
        ] {
            r.push(Channel {
                name: name.into(),
                unit: unit.into(),
                values: vec![v],
            })
            .unwrap();
        }
        let done = r.to_standard_units().unwrap();
        assert_eq!(done.len(), 5, "{done:?}");
        assert_eq!(r.values("t").unwrap(), [0.25]);
        assert!((r.values("theta_en").unwrap()[0] - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
        assert!((r.values("omega_en").unwrap()[0] - 50.0 * std::f64::consts::PI).abs() < 1e-12);
        assert!((r.values("T_oil").unwrap()[0] - 363.15).abs() < 1e-12);
        assert!((r.values("p_int").unwrap()[0] - 70_000.0).abs() < 1e-9);
        assert_eq!(r.channel("omega_en").unwrap().unit, "rad/s");
        // Unlabelled stays unlabelled; the throttle's SI is deg; a user's own name is untouched.
        assert_eq!(r.channel("p_cyl").unwrap().unit, "");
        assert_eq!(r.values("throttle").unwrap(), [30.0]);
        assert_eq!(r.values("EngSpeed").unwrap(), [1500.0]);
        let mut bad = Recording::new(Basis::Time);
        bad.push(Channel {
            name: "torque_shaft".into(),
            unit: "lbf*ft".into(),
            values: vec![1.0],
        })
        .unwrap();
        let e = bad.to_standard_units().unwrap_err().to_string();
        assert!(
            e.contains("'torque_shaft' is in 'lbf*ft'") && e.contains("kNm"),
            "{e}"
        );
    }

    #[test]
    fn a_slice_keeps_names_units_basis_and_is_clamped() {
        let mut r = Recording::new(Basis::CrankAngle);
        r.push(ch("t", vec![0.0, 1.0, 2.0, 3.0])).unwrap();
        r.push(ch("x", vec![10.0, 11.0, 12.0, 13.0])).unwrap();
        let s = r.slice(1..3);
        assert_eq!((s.basis, s.names()), (Basis::CrankAngle, vec!["t", "x"]));
        assert_eq!(s.values("x").unwrap(), &[11.0, 12.0]);
        assert_eq!(s.channel("x").unwrap().unit, r.channel("x").unwrap().unit);
        assert_eq!(r.slice(3..9).values("t").unwrap(), &[3.0]);
        assert!(r.slice(7..9).is_empty());
    }

    #[test]
    fn channels_by_name_and_errors() {
        let mut r = Recording::new(Basis::Time);
        r.push(ch("t", vec![0.0, 1.0])).unwrap();
        r.push(ch("x", vec![2.0, 3.0])).unwrap();
        assert_eq!(r.len(), 2);
        assert_eq!(r.values("x").unwrap(), &[2.0, 3.0]);
        assert_eq!(
            r.values("y").unwrap_err().to_string(),
            "no channel 'y'; the channels are: t, x"
        );
        assert!(matches!(
            r.push(ch("z", vec![1.0])),
            Err(RecordingError::LengthMismatch { .. })
        ));
        assert!(matches!(
            r.push(ch("x", vec![1.0, 2.0])),
            Err(RecordingError::DuplicateChannel(_))
        ));
    }

    #[test]
    fn replace_values_checks_name_and_length() {
        let mut r = Recording::new(Basis::Time);
        r.push(ch("a", vec![1.0, 2.0])).unwrap();
        r.replace_values("a", vec![3.0, 4.0]).unwrap();
        assert_eq!(r.values("a").unwrap(), [3.0, 4.0]);
        assert!(matches!(
            r.replace_values("a", vec![1.0]),
            Err(RecordingError::LengthMismatch {
                len: 1,
                expected: 2,
                ..
            })
        ));
        assert!(matches!(
            r.replace_values("b", vec![1.0, 2.0]),
            Err(RecordingError::MissingChannel { .. })
        ));
    }
}
