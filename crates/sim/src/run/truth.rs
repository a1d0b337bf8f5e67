//! The ground truth of a simulated recording, from its metadata.

use crate::scenario::Fault;
use physid_core::Recording;

/// The true value of a cell parameter at times `t`, from a simulated recording's metadata (its
/// `param.PATH` value and the faults on PATH); `None` for a recording that does not carry it
/// (measured data).
pub fn parameter_truth(rec: &Recording, path: &str, t: &[f64]) -> Option<Vec<f64>> {
    let v0: f64 = rec.meta.get(&format!("param.{path}"))?.parse().ok()?;
    let faults: Vec<Fault> = rec
        .meta
        .get("faults")
        .map(|s| {
            s.split_whitespace()
                .filter_map(|f| Fault::parse(f).ok())
                .filter(|f| f.path == path)
                .collect()
        })
        .unwrap_or_default();
    Some(
        t.iter()
            .map(|&ti| {
                // As `Fault::apply_all`: each fault moves from the base value; a later one on
                // the same path overrides an earlier one once it has started.
                faults.iter().fold(v0, |v, f| match f.progress(ti) {
                    x if x > 0.0 => v0 + (f.value - v0) * x,
                    _ => v,
                })
            })
            .collect(),
    )
}
