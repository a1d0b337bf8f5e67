//! Quadrature encoders: the shaft's angle, both ways, from the two channels A and B of an
//! incremental encoder (a quarter of a line apart) and its optional index Z (one pulse per
//! revolution) — digital or analog signals.
//!
//! * Each channel through a comparator with hysteresis: the level midway between the 2nd and
//!   98th percentiles of its first [`START_SAMPLES`](crate::wheel::START_SAMPLES) samples (Z:
//!   its smallest and largest sample over the whole signal, [`IndexRange`] — a first pass on a
//!   stream), ±20 % of their distance; each transition's time interpolated between the samples
//!   either side.
//! * ×4 decoding: every transition of A or B moves the count by one quarter line, forward when
//!   the Gray sequence (A, B) = 00 → 10 → 11 → 01 runs that way (A leads), back otherwise. Both
//!   channels changing between two samples is a transition the samples could not resolve: an
//!   integrity finding at its sample (the count may be off by two there).
//! * A sample where A or B is not finite (NaN, ±∞) is a dropout ([`Dropouts`](crate::wheel::Dropouts), a finding at
//!   each run): skipped whole (Z with it), no transition interpolated across it. At the first
//!   sample after it the state of (A, B) gives the count the dropout hid modulo 4; the speed
//!   before it (the last four transitions, no faster than the time since the last) gives the
//!   rest — the count nearest the expected one, ties the way the shaft last turned. Exact while
//!   the shaft's mean speed over the dropout stays within the bounds the `pulse_loss` finding at
//!   that sample states (±2 counts of the expected). With an index, the transitions after it
//!   are held (two revolutions at most) until the next index pulse turning forward checks the
//!   count: whole lines off a whole revolution (within a count) are corrected from the
//!   dropout on, with a finding. An index pulse later out of place (below) tells a count wrong
//!   all the same. Z not finite alone: skipped, an index pulse it hides is not seen.
//! * Z: the count at each rising edge of the index while turning forward; the angle is 0 at the
//!   first, and every later one must come a whole revolution (4·lines counts) from it — else a
//!   finding at its sample with the counts found.
//! * The angle at any time by the same monotone cubic as [`crate::wheel`] (its extrema, where
//!   the shaft turns back, stay flat).

mod comparator;
mod decoder;
mod index;

pub use decoder::*;
pub use index::*;

use crate::integrity::Finding;
use crate::wheel::{pchip_at, WheelError};
use std::f64::consts::TAU;

/// The decoded encoder.
#[derive(Debug, Clone, PartialEq)]
pub struct QuadratureAngles {
    /// Lines per revolution.
    pub lines: u32,
    /// Transition times [s].
    pub t: Vec<f64>,
    /// The angle at each transition [rad]: 0 at the first index pulse turning forward (or at
    /// the first transition without Z).
    pub angle: Vec<f64>,
    /// The times of the index pulses turning forward [s].
    pub index_t: Vec<f64>,
    /// Transitions going backward (the shaft turning back).
    pub backward: usize,
    /// Unresolved transitions and index pulses out of place, at their sample.
    pub findings: Vec<Finding>,
}

impl QuadratureAngles {
    /// The angle at the times `at` [s] (increasing); NaN before the first transition and after
    /// the last.
    pub fn angle_at(&self, at: &[f64]) -> Vec<f64> {
        pchip_at(&self.t, &self.angle, at)
    }
}

/// Decode A/B (and Z) sampled at the times `t` [s]; `lines` per revolution; `names` the
/// channels (for the findings and errors): [`QuadratureDecoder`] and [`IndexZero`] over the
/// whole signal.
pub fn decode(
    t: &[f64],
    a: &[f64],
    b: &[f64],
    z: Option<&[f64]>,
    lines: u32,
    names: [&str; 3],
) -> Result<QuadratureAngles, WheelError> {
    if lines == 0 {
        return Err(WheelError::Invalid(
            "an encoder needs 1 line or more".into(),
        ));
    }
    for (name, x) in [(names[0], a), (names[1], b)]
        .into_iter()
        .chain(z.map(|z| (names[2], z)))
    {
        if x.len() != t.len() {
            return Err(WheelError::Invalid(format!(
                "'{name}' has {} samples, the time {}",
                x.len(),
                t.len()
            )));
        }
    }
    let z_range = z.map(|z| {
        let mut r = IndexRange::default();
        r.push(z);
        r.range
    });
    let mut d = QuadratureDecoder::new(names, z_range, lines);
    d.push(t, a, b, z.unwrap_or(&[]));
    d.finish()?;
    let mut zero = IndexZero::new(lines, names[2]);
    let (mut tt, mut edges, mut index_t) = (Vec::new(), Vec::new(), Vec::new());
    // Transitions and pulses in time order (a pulse placed once the transitions after it came).
    while let Some(tr) = d.pop() {
        tt.push(tr.t);
        edges.push(tr.edge);
        zero.transition(tr);
    }
    while let Some(p) = d.pop_pulse() {
        index_t.push(p.t);
        zero.pulse(p);
    }
    let (zero, _, mut out_of_place) = zero.finish();
    let q = TAU / (4.0 * lines as f64);
    let angle: Vec<f64> = edges.iter().map(|&c| c as f64 * q - zero).collect();
    let mut findings = d.take_findings();
    findings.append(&mut out_of_place);
    findings.sort_by_key(|f| f.index);
    Ok(QuadratureAngles {
        lines,
        angle,
        t: tt,
        index_t,
        backward: d.backward(),
        findings,
    })
}
