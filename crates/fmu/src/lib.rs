//! # physid-fmu — the virtual test cell as an FMU (FMI 2.0 and 3.0 co-simulation)
//!
//! The cell of [`physid_sim`] — motored (or fired) engine gas exchange, the induction-machine
//! dynamometer under field-oriented control, the coupling shaft, the sensors and faults — for
//! the tools engineers exchange models in (Simulink, Dymola, FMPy …):
//!
//! * [`variables`] — the FMU's variables from the cell's own parameter and channel tables;
//! * [`description`] — its `modelDescription.xml`, FMI 2.0 or 3.0, with units;
//! * [`archive`] — the `.fmu`: the description, the shared library, the scenario;
//! * [`instance`] — one co-simulation instance: the scenario's [`Run`](physid_sim::run::Run)
//!   stepped to each communication point, its state saved and restored;
//! * `fmi2`, `fmi3` — the C functions of each standard over the one instance (this library
//!   built as a `cdylib` is the FMU's binary; both sets of functions are in it).
//!
//! What the FMU is exported from is a [`Cell`]: a scenario (its profiles, settings and faults)
//! and the outputs' sample rate. docs/fmu.md says what each FMI function does and the limits.

pub mod archive;
pub mod description;
mod ffi;
mod fmi2;
mod fmi3;
pub mod instance;
mod log;
pub mod variables;

use physid_sim::params::CellParams;
use physid_sim::scenario::Scenario;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::path::Path;

/// The FMU's model identifier: the name of its shared library in `binaries/<platform>/`.
pub const MODEL_IDENTIFIER: &str = "physid_cell";

/// The resource files in the archive's `resources/`: the scenario (a physid scenario file,
/// `physid simulate --scenario` reads it) and the export's own settings.
pub const SCENARIO_FILE: &str = "scenario.toml";
/// See [`SCENARIO_FILE`].
pub const SETTINGS_FILE: &str = "fmu.toml";

/// What an FMU is exported from: a scenario, its `set` holding every parameter setting (the
/// scenario's own and the export's `--set`), and the outputs' sample rate.
#[derive(Debug, Clone, PartialEq)]
pub struct Cell {
    /// The scenario: its profiles drive the cell unless `demand.from_scenario` is false; its
    /// settings are the parameters' start values; its faults happen at their times.
    pub scenario: Scenario,
    /// The outputs' sample rate [Hz].
    pub sample_rate: f64,
}

/// The export's settings, as stored in `resources/fmu.toml`.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Settings {
    /// The FMU's GUID (FMI 2) / instantiation token (FMI 3).
    guid: String,
    /// The outputs' sample rate [Hz].
    sample_rate: f64,
    /// The physid version that exported it.
    physid: String,
}

impl Cell {
    /// A cell from a scenario and a sample rate, checked (the scenario, its settings and
    /// faults, the rate).
    pub fn new(scenario: Scenario, sample_rate: f64) -> Result<Self, String> {
        scenario.validate().map_err(|e| e.to_string())?;
        let max = instance::MAX_SAMPLE_RATE;
        if !(sample_rate > 0.0 && sample_rate <= max) {
            return Err(format!(
                "sample rate {sample_rate} Hz: expected > 0 and at most {max} Hz",
                sample_rate = physid_core::Num(sample_rate)
            ));
        }
        let cell = Self {
            scenario,
            sample_rate,
        };
        cell.params()
            .validate()
            .map_err(|e| format!("scenario '{}': {e}", cell.scenario.name))?;
        Ok(cell)
    }

    /// The cell's parameters: the defaults with the scenario's settings.
    pub fn params(&self) -> CellParams {
        let mut p = CellParams::default();
        for (k, v) in &self.scenario.set {
            // Checked in `new` (every path known, every value finite).
            let _ = p.set(k, *v);
        }
        p
    }

    /// The scenario as a physid scenario file.
    pub fn scenario_toml(&self) -> Result<String, String> {
        toml::to_string(&self.scenario).map_err(|e| format!("the scenario as TOML: {e}"))
    }

    /// The GUID (FMI 2) and instantiation token (FMI 3): a digest of the scenario, the rate
    /// and the version, so that a description and resources from different exports never
    /// meet.
    pub fn guid(&self) -> Result<String, String> {
        let mut h = Sha256::new();
        h.update(self.scenario_toml()?.as_bytes());
        h.update(self.sample_rate.to_le_bytes());
        h.update(env!("CARGO_PKG_VERSION").as_bytes());
        let d = h.finalize();
        let hex: String = d.iter().take(16).map(|b| format!("{b:02x}")).collect();
        Ok(format!(
            "{{{}-{}-{}-{}-{}}}",
            &hex[0..8],
            &hex[8..12],
            &hex[12..16],
            &hex[16..20],
            &hex[20..32]
        ))
    }

    /// The settings file's text.
    fn settings_toml(&self) -> Result<String, String> {
        toml::to_string(&Settings {
            guid: self.guid()?,
            sample_rate: self.sample_rate,
            physid: env!("CARGO_PKG_VERSION").to_string(),
        })
        .map_err(|e| format!("the FMU's settings as TOML: {e}"))
    }

    /// The cell an FMU carries in its resources directory, with its GUID.
    pub fn from_resources(dir: &Path) -> Result<(Self, String), String> {
        let read = |name: &str| {
            let path = dir.join(name);
            std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))
        };
        let settings: Settings = toml::from_str(&read(SETTINGS_FILE)?)
            .map_err(|e| format!("{}: {e}", dir.join(SETTINGS_FILE).display()))?;
        let scenario: Scenario = toml::from_str(&read(SCENARIO_FILE)?)
            .map_err(|e| format!("{}: {e}", dir.join(SCENARIO_FILE).display()))?;
        let cell = Self::new(scenario, settings.sample_rate)
            .map_err(|e| format!("{}: {e}", dir.join(SCENARIO_FILE).display()))?;
        Ok((cell, settings.guid))
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// A scenario written to the resources reads back equal (every float to the last bit, a
    /// recorded profile with its points), with the same GUID.
    #[test]
    fn the_resources_read_back_equal() {
        let mut s = Scenario::load("fig314").unwrap();
        s.speed.segments.push(physid_sim::scenario::Segment {
            t0: 20.0,
            t1: 21.0,
            shape: physid_sim::scenario::Shape::Recorded {
                file: String::new(),
                t: vec![0.0, 0.1, 1.0],
                v: vec![1000.0, 1000.1 / 3.0, 1100.0],
            },
        });
        s.set.insert("shaft.k".into(), 1234.5678901234567);
        s.faults.push("shaft.b=1.3@2+0.5".into());
        let cell = Cell::new(s, 12_345.6).unwrap();
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join(SCENARIO_FILE),
            cell.scenario_toml().unwrap(),
        )
        .unwrap();
        std::fs::write(
            dir.path().join(SETTINGS_FILE),
            cell.settings_toml().unwrap(),
        )
        .unwrap();
        let (back, guid) = Cell::from_resources(dir.path()).unwrap();
        assert_eq!(back, cell);
        assert_eq!(guid, cell.guid().unwrap());
        assert_eq!(guid.len(), 38);
    }

    /// A bad rate or setting is refused with its reason.
    #[test]
    fn a_bad_cell_is_refused() {
        let s = Scenario::load("shaft-steady").unwrap();
        assert!(Cell::new(s.clone(), 0.0)
            .unwrap_err()
            .contains("sample rate"));
        let mut bad = s;
        bad.set.insert("shaft.k".into(), -5.0);
        assert!(Cell::new(bad, 1e4).unwrap_err().contains("shaft.k"));
    }
}
