//! Helpers shared by the application tests.
#![allow(clippy::unwrap_used, clippy::expect_used, dead_code)]

use physid_core::Recording;
use physid_sim::run::{simulate, OutputBasis, RunOptions};
use physid_sim::scenario::named;

/// Simulate a named scenario for `seconds` (0.5 s settling) with cell parameters `set` and
/// `faults` (`PATH=VALUE@T[+RAMP]`), on the given output basis.
pub fn simulate_scenario(
    scenario: &str,
    set: &[(&str, f64)],
    faults: &[&str],
    seconds: f64,
    basis: OutputBasis,
) -> Recording {
    let mut s = named(scenario).unwrap();
    s.settle = 0.5;
    for f in faults {
        s.faults.push(f.to_string());
    }
    let mut opts = RunOptions {
        duration: Some(seconds),
        basis,
        ..Default::default()
    };
    for (k, v) in set {
        opts.params.set(k, *v).unwrap();
    }
    simulate(&s, &opts, |_| {}).unwrap()
}

/// A golden file of `tests/golden`.
pub fn golden(name: &str) -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/golden")
        .join(name)
}

/// `golden/gen_wiebe.py`'s truth.
pub fn wiebe() -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(golden("wiebe.json")).unwrap()).unwrap()
}

/// One of `gen_wiebe.py`'s crank-angle CSV files (a units row under the names).
pub fn wiebe_csv(name: &str) -> Recording {
    let units_row = physid_io::ReadOptions {
        units_row: true,
        ..Default::default()
    };
    physid_io::read(golden(name), &units_row).unwrap()
}

/// The engine of `gen_wiebe.py`.
pub fn wiebe_geometry(truth: &serde_json::Value) -> physid_apps::pressure::Geometry {
    let f = |k: &str| truth[k].as_f64().unwrap();
    physid_apps::pressure::Geometry {
        bore: f("bore"),
        stroke: f("stroke"),
        rod: f("rod"),
        compression_ratio: f("compression_ratio"),
    }
}
