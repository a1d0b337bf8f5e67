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
