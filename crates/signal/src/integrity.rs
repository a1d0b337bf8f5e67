//! The post-run integrity check of a recording (thesis §4: synchronisation, cycle indexing, no
//! lost samples): a report of findings with their locations.
//!
//! | kind | what |
//! |---|---|
//! | `non_finite` | a NaN or ±inf sample (first per channel) |
//! | `non_monotonic_time` | `t` goes backwards |
//! | `duplicated_samples` | `t` repeats |
//! | `lost_samples` | a gap in `t` over 1.5 × the median interval (how many samples missing) |
//! | `pulse_loss` | fewer encoder pulses between two TDC markers than pulses per revolution |
//! | `extra_pulses` | more (electrical noise) |
//! | `out_of_sync` | a TDC marker displaced against the encoder count (the next interval compensates) |
//! | `unit_mismatch` | a channel of the table (DESIGN.md) with another unit than its SI one (`T_oil` in °C) |
//! | `incomplete_cycle` | data before the first TDC marker or after the last whole revolution (time basis); a cycle with the wrong number of samples (crank-angle basis) |

use crate::encoder::marker_edges;
use physid_core::{Basis, Recording};
use serde::Serialize;

/// What kind of problem.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
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
}

/// One finding.
#[derive(Debug, Clone, PartialEq, Serialize)]
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
    /// Samples per cycle on a crank-angle basis (720 at one per degree).
    pub samples_per_cycle: Option<usize>,
}

/// The report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Integrity {
    /// Whether nothing was found.
    pub ok: bool,
    /// The findings, at most [`MAX_PER_KIND`] per kind (then one summarising finding).
    pub findings: Vec<Finding>,
}

/// Findings listed per kind before they are summarised.
pub const MAX_PER_KIND: usize = 50;

struct Collector {
    findings: Vec<Finding>,
    counts: Vec<(FindingKind, usize, usize)>, // kind, total, first index
}

impl Collector {
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
        for (kind, total, first) in &self.counts {
            if *total > MAX_PER_KIND {
                self.findings.push(Finding {
                    kind: *kind,
                    index: *first,
                    detail: format!(
                        "{total} findings of this kind in all; the first {MAX_PER_KIND} are listed"
                    ),
                });
            }
        }
        self.findings.sort_by_key(|f| f.index);
        Integrity {
            ok: self.findings.is_empty(),
            findings: self.findings,
        }
    }
}

/// Check a recording.
pub fn check(rec: &Recording, opts: &IntegrityOptions) -> Integrity {
    let mut c = Collector {
        findings: Vec::new(),
        counts: Vec::new(),
    };
    for ch in rec.channels() {
        if let Some(unit) = physid_core::standard_unit(&ch.name) {
            if !ch.unit.is_empty() && ch.unit != unit {
                c.push(
                    FindingKind::UnitMismatch,
                    0,
                    format!(
                        "channel '{}' is in '{}'; physid expects '{unit}' (convert it, or map your column to another name)",
                        ch.name, ch.unit
                    ),
                );
            }
        }
        if let Some(i) = ch.values.iter().position(|v| !v.is_finite()) {
            let n = ch.values.iter().filter(|v| !v.is_finite()).count();
            c.push(
                FindingKind::NonFinite,
                i,
                format!(
                    "channel '{}' is {} at sample {i} ({n} non-finite samples in all)",
                    ch.name, ch.values[i]
                ),
            );
        }
    }
    if let Ok(t) = rec.values("t") {
        check_time(t, &mut c);
    }
    let marker = opts
        .marker
        .as_ref()
        .and_then(|m| rec.values(m).ok())
        .map(marker_edges);
    for (name, ppr) in &opts.encoders {
        if let (Ok(counts), Some(edges)) = (rec.values(name), &marker) {
            check_pulses(name, counts, edges, *ppr, &mut c);
        }
    }
    match rec.basis {
        Basis::Time => {
            if let Some(edges) = &marker {
                match edges.first() {
                    Some(&m0) if m0 > 0 => c.push(
                        FindingKind::IncompleteCycle,
                        0,
                        format!("{m0} samples before the first TDC marker (discarded by cycle indexing)"),
                    ),
                    None => c.push(
                        FindingKind::IncompleteCycle,
                        0,
                        "no TDC marker: cycles cannot be indexed".into(),
                    ),
                    _ => {}
                }
            }
        }
        Basis::CrankAngle => {
            if let (Ok(cycle), Some(per)) = (rec.values("cycle"), opts.samples_per_cycle) {
                let mut start = 0;
                while start < cycle.len() {
                    let mut end = start;
                    while end < cycle.len() && cycle[end] == cycle[start] {
                        end += 1;
                    }
                    if end - start != per {
                        c.push(
                            FindingKind::IncompleteCycle,
                            start,
                            format!(
                                "cycle {} has {} samples, expected {per}",
                                cycle[start],
                                end - start
                            ),
                        );
                    }
                    start = end;
                }
            }
        }
    }
    c.finish()
}

/// The median of the positive steps of a time channel [s] (`None` with no positive step): the
/// nominal sample period, robust to gaps and repeated stamps.
pub fn median_step(t: &[f64]) -> Option<f64> {
    let mut d: Vec<f64> = t
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 0.0)
        .collect();
    if d.is_empty() {
        return None;
    }
    let mid = d.len() / 2;
    d.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
    Some(d[mid])
}

fn check_time(t: &[f64], c: &mut Collector) {
    let Some(median) = median_step(t) else {
        return;
    };
    for (i, w) in t.windows(2).enumerate() {
        let dt = w[1] - w[0];
        if dt < 0.0 {
            c.push(
                FindingKind::NonMonotonicTime,
                i + 1,
                format!("t goes back from {} s to {} s", w[0], w[1]),
            );
        } else if dt == 0.0 {
            c.push(
                FindingKind::DuplicatedSamples,
                i + 1,
                format!("t = {} s repeats", w[1]),
            );
        } else if dt > 1.5 * median {
            let missing = (dt / median).round() as i64 - 1;
            c.push(
                FindingKind::LostSamples,
                i + 1,
                format!(
                    "gap of {dt:.6e} s after t = {} s: about {missing} samples missing (interval {median:.6e} s)",
                    w[0]
                ),
            );
        }
    }
}

fn check_pulses(name: &str, counts: &[f64], edges: &[usize], ppr: u32, c: &mut Collector) {
    let ppr = ppr as f64;
    let d: Vec<f64> = edges
        .windows(2)
        .map(|w| counts[w[1]] - counts[w[0]])
        .collect();
    let mut j = 0;
    while j < d.len() {
        let (at, next) = (edges[j], edges[j + 1]);
        if d[j] == ppr {
            j += 1;
            continue;
        }
        if j + 1 < d.len() && d[j] + d[j + 1] == 2.0 * ppr {
            c.push(
                FindingKind::OutOfSync,
                next,
                format!(
                    "'{name}': the TDC marker at sample {next} is {:+} pulses off the encoder count",
                    d[j] - ppr
                ),
            );
            j += 2;
            continue;
        }
        let (kind, what) = if d[j] < ppr {
            (FindingKind::PulseLoss, "missing")
        } else {
            (FindingKind::ExtraPulses, "too many")
        };
        c.push(
            kind,
            at,
            format!(
                "'{name}': {} pulses between the TDC markers at samples {at} and {next}, expected {ppr} ({} {what})",
                d[j],
                (d[j] - ppr).abs()
            ),
        );
        j += 1;
    }
}
