//! The post-run integrity check of a recording (thesis §4: synchronisation, cycle indexing, no
//! lost samples): a report of findings with their locations.
//!
//! | kind | what |
//! |---|---|
//! | `non_finite` | a NaN or ±inf sample (first per channel) |
//! | `non_monotonic_time` | `t` goes backwards |
//! | `duplicated_samples` | `t` repeats |
//! | `lost_samples` | time basis: a gap in `t` over 1.5 × the median interval (how many samples missing); crank-angle basis: a step in `crank_deg` over 1.5 × the nominal one, or a cycle skipped (on this basis the time step follows the speed and is not checked) |
//! | `pulse_loss` | the marker's encoder: fewer pulses between two TDC markers than pulses per revolution (on a crank-angle basis, by more than the pulses one grid step spans); another encoder: fewer than 10 revolutions' worth over 10 marker revolutions, beyond a twist allowance of 1/20 revolution |
//! | `extra_pulses` | more (electrical noise) |
//! | `out_of_sync` | a TDC marker displaced against its own encoder's count (the next interval compensates) |
//! | `count_backwards` | an encoder count that decreases |
//! | `uneven_pulses` | an encoder whose count steps are not equally spaced in angle — one step per revolution lasting 1.8× the others or more, as a trigger wheel's missing teeth make them ([`crate::encoder::uneven_spacing`], judged on the first 65 536 samples when the pulses are resolved in time) |
//! | `unit_mismatch` | a channel of the table (DESIGN.md) with another unit than its SI one (`T_oil` in °C) |
//! | `speed_angle_mismatch` | time basis: a speed that is not its angle's derivative — `Δθ` against `∫ω dt` off by more than 5 %, a factor of 2π/60, 180/π, 2π, 6 or 60 named as the mislabel it is ([`crate::speed_angle`]) |
//! | `incomplete_cycle` | crank-angle basis: a cycle inside the recording with the wrong number of samples |
//!
//! A TDC marker belongs to one encoder (the engine's): only that encoder is checked pulse by
//! pulse against it. Another encoder on the same shaft line (the dynamometer's) turns with it
//! only up to the shaft's twist, which moves its count against the marker by a few pulses each
//! way: it is checked over spans of ten revolutions, where a twist stays bounded and lost
//! pulses add up.
//!
//! Some things are information, not problems — a recording that starts or ends mid-cycle, or
//! has no marker to index cycles by: they are [`Integrity::notes`] and leave `ok` true.
//!
//! Here: the findings, the options and their collector. `check.rs`: the check of a whole
//! recording; `stream.rs`: the same checks on the stream.

use physid_core::{Basis, Recording, Sink};
use serde::Serialize;
use std::collections::VecDeque;

mod check;
mod stream;

pub use check::*;
pub use stream::*;

/// What kind of problem.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FindingKind {
    /// NaN or ±inf.
    NonFinite,
    /// Time goes backwards.
    NonMonotonicTime,
    /// Time repeats.
    DuplicatedSamples,
    /// A gap in time.
    LostSamples,
    /// Pulses missing between TDC markers.
    PulseLoss,
    /// Pulses too many between TDC markers.
    ExtraPulses,
    /// A marker displaced against the count.
    OutOfSync,
    /// A partial cycle.
    IncompleteCycle,
    /// A standard channel in a non-standard unit.
    UnitMismatch,
    /// A speed that is not its angle's derivative (a units row that lies).
    SpeedAngleMismatch,
    /// An encoder count going backwards.
    CountBackwards,
    /// An encoder's count steps not equally spaced in angle (a wheel with missing teeth).
    UnevenPulses,
    /// Information (a partial cycle at either end, no marker): a note, never a finding.
    Note,
}

/// One finding.
#[derive(Debug, Clone, PartialEq, Serialize, serde::Deserialize)]
pub struct Finding {
    /// The kind.
    pub kind: FindingKind,
    /// Sample index where it is.
    pub index: usize,
    /// What exactly, for a person.
    pub detail: String,
}

/// What to check beyond time and values.
#[derive(Debug, Clone, Default)]
pub struct IntegrityOptions {
    /// Encoder counter channels and their pulses per revolution, e.g. `("count_en", 360)`.
    pub encoders: Vec<(String, u32)>,
    /// The TDC marker channel (once per revolution), e.g. `"tdc"`.
    pub marker: Option<String>,
    /// The encoder the marker belongs to (checked pulse by pulse against it); `None`: the first
    /// of `encoders`.
    pub marker_encoder: Option<String>,
    /// Samples per cycle on a crank-angle basis (720 at one per degree).
    pub samples_per_cycle: Option<usize>,
}

/// The report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Integrity {
    /// Whether nothing was found (notes do not count).
    pub ok: bool,
    /// The findings, at most [`MAX_PER_KIND`] per kind (then one summarising finding).
    pub findings: Vec<Finding>,
    /// Information about the recording that is not a problem (kind `note`).
    pub notes: Vec<Finding>,
}

/// Findings listed per kind before they are summarised.
pub const MAX_PER_KIND: usize = 50;

#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
struct Collector {
    findings: Vec<Finding>,
    notes: Vec<Finding>,
    counts: Vec<(FindingKind, usize, usize)>, // kind, total, first index
}

impl Collector {
    fn note(&mut self, index: usize, detail: String) {
        self.notes.push(Finding {
            kind: FindingKind::Note,
            index,
            detail,
        });
    }

    fn push(&mut self, kind: FindingKind, index: usize, detail: String) {
        match self.counts.iter_mut().find(|c| c.0 == kind) {
            Some(c) => c.1 += 1,
            None => self.counts.push((kind, 1, index)),
        }
        let n = self.counts.iter().find(|c| c.0 == kind).map_or(0, |c| c.1);
        if n <= MAX_PER_KIND {
            self.findings.push(Finding {
                kind,
                index,
                detail,
            });
        }
    }

    fn finish(mut self) -> Integrity {
        for &(kind, total, first) in &self.counts {
            if total > MAX_PER_KIND {
                self.findings.push(summary(kind, total, first));
            }
        }
        self.findings.sort_by_key(|f| f.index);
        Integrity {
            ok: self.findings.is_empty(),
            findings: self.findings,
            notes: self.notes,
        }
    }
}

/// Check a recording: [`IntegrityCheck`] over it, in one chunk.
pub fn check(rec: &Recording, opts: &IntegrityOptions) -> Integrity {
    let mut c = IntegrityCheck::new(opts, rec);
    c.push(rec);
    c.finish()
}
