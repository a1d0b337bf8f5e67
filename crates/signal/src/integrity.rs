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
//! | `unit_mismatch` | a channel of the table (DESIGN.md) with another unit than its SI one (`T_oil` in °C) |
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
    /// An encoder count going backwards.
    CountBackwards,
    /// Information (a partial cycle at either end, no marker): a note, never a finding.
    Note,
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
            notes: self.notes,
        }
    }
}

/// Check a recording.
pub fn check(rec: &Recording, opts: &IntegrityOptions) -> Integrity {
    let mut c = Collector {
        findings: Vec::new(),
        notes: Vec::new(),
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
        check_time(t, rec.basis == Basis::Time, &mut c);
    }
    let marker = opts
        .marker
        .as_ref()
        .and_then(|m| rec.values(m).ok())
        .map(marker_edges);
    let own = opts
        .marker_encoder
        .as_deref()
        .or(opts.encoders.first().map(|e| e.0.as_str()));
    for (name, ppr) in &opts.encoders {
        let Ok(counts) = rec.values(name) else {
            continue;
        };
        check_backwards(name, counts, &mut c);
        match &marker {
            Some(edges) if Some(name.as_str()) == own => {
                let tol = match (rec.basis, opts.samples_per_cycle) {
                    (Basis::CrankAngle, Some(per)) if per > 0 => {
                        (2.0 * f64::from(*ppr) / per as f64).ceil()
                    }
                    _ => 0.0,
                };
                check_pulses(name, counts, edges, *ppr, tol, &mut c)
            }
            Some(edges) => check_span(name, counts, edges, *ppr, &mut c),
            None => {}
        }
    }
    match rec.basis {
        Basis::Time => {
            if let Some(edges) = &marker {
                match edges.first() {
                    Some(&m0) if m0 > 0 => c.note(
                        0,
                        format!("the recording starts mid-revolution: {m0} samples before the first TDC marker (left out by cycle indexing)"),
                    ),
                    None => c.note(0, "no TDC marker: cycles cannot be indexed".into()),
                    _ => {}
                }
            }
        }
        Basis::CrankAngle => {
            if let Ok(deg) = rec.values("crank_deg") {
                check_crank_steps(deg, rec.values("cycle").ok(), &mut c);
            }
            if let (Ok(cycle), Some(per)) = (rec.values("cycle"), opts.samples_per_cycle) {
                let mut start = 0;
                while start < cycle.len() {
                    let mut end = start;
                    while end < cycle.len() && cycle[end] == cycle[start] {
                        end += 1;
                    }
                    if end - start != per {
                        let detail = format!(
                            "cycle {} has {} samples, expected {per}",
                            cycle[start],
                            end - start
                        );
                        if start == 0 || end == cycle.len() {
                            c.note(
                                start,
                                format!(
                                    "{detail} (the recording {} mid-cycle)",
                                    if start == 0 { "starts" } else { "ends" }
                                ),
                            );
                        } else {
                            c.push(FindingKind::IncompleteCycle, start, detail);
                        }
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

/// Time going back or repeating; on a time basis also gaps (on a crank-angle basis the time
/// step follows the speed).
fn check_time(t: &[f64], uniform: bool, c: &mut Collector) {
    let median = median_step(t).unwrap_or(f64::INFINITY);
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
        } else if uniform && dt > 1.5 * median {
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

/// The marker's own encoder, interval by interval: `ppr` pulses between markers, within `tol`
/// pulses (0 on a time basis; on a crank-angle basis the pulses one grid step spans, since
/// resampling places the marker and the count to one step).
fn check_pulses(
    name: &str,
    counts: &[f64],
    edges: &[usize],
    ppr: u32,
    tol: f64,
    c: &mut Collector,
) {
    let ppr = ppr as f64;
    let d: Vec<f64> = edges
        .windows(2)
        .map(|w| counts[w[1]] - counts[w[0]])
        .collect();
    let mut j = 0;
    while j < d.len() {
        let (at, next) = (edges[j], edges[j + 1]);
        if (d[j] - ppr).abs() <= tol {
            j += 1;
            continue;
        }
        if j + 1 < d.len() && (d[j] + d[j + 1] - 2.0 * ppr).abs() <= tol {
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

/// A count that decreases (an encoder runs one way on a test bed; a reversal or a counter
/// reset is worth a look).
fn check_backwards(name: &str, counts: &[f64], c: &mut Collector) {
    for (i, w) in counts.windows(2).enumerate() {
        if w[1] < w[0] {
            c.push(
                FindingKind::CountBackwards,
                i + 1,
                format!(
                    "'{name}' goes back from {} to {} at sample {}",
                    w[0],
                    w[1],
                    i + 1
                ),
            );
        }
    }
}

/// Revolutions over which an encoder that is not the marker's is checked against the marker.
const SPAN_REVS: usize = 10;

/// An encoder that is not the marker's, over spans of [`SPAN_REVS`] marker revolutions: its
/// count must advance by that many revolutions' pulses, within a twist allowance of 1/20
/// revolution (a twist moves the count by a bounded amount each way; lost pulses add up).
fn check_span(name: &str, counts: &[f64], edges: &[usize], ppr: u32, c: &mut Collector) {
    let ppr = f64::from(ppr);
    let tol = (ppr / 20.0).max(1.0);
    // Spans start at every marker; a run of spans off by the same sign is one finding, at the
    // first span's start (the span where the loss first shows, which holds its start).
    let mut previous = 0i8;
    for j in 0..edges.len().saturating_sub(SPAN_REVS) {
        let (a, b) = (edges[j], edges[j + SPAN_REVS]);
        let d = counts[b] - counts[a] - SPAN_REVS as f64 * ppr;
        let sign = if d > tol {
            1
        } else if d < -tol {
            -1
        } else {
            0
        };
        if sign != 0 && sign != previous {
            let (kind, what) = if sign < 0 {
                (FindingKind::PulseLoss, "missing")
            } else {
                (FindingKind::ExtraPulses, "too many")
            };
            c.push(
                kind,
                a,
                format!(
                    "'{name}': {} pulses over the {SPAN_REVS} revolutions between the TDC markers at samples {a} and {b}, expected {} ({} {what}, beyond the shaft-twist allowance of {tol})",
                    counts[b] - counts[a],
                    SPAN_REVS as f64 * ppr,
                    d.abs()
                ),
            );
        }
        previous = sign;
    }
}

/// Crank-angle basis: each step of `crank_deg` is the nominal one (the most common), or wraps
/// to the next cycle; a longer step, or a cycle skipped, means samples are missing.
fn check_crank_steps(deg: &[f64], cycle: Option<&[f64]>, c: &mut Collector) {
    let Some(step) = median_step(deg) else {
        return;
    };
    for i in 1..deg.len() {
        let d = deg[i] - deg[i - 1];
        let next_cycle = cycle.map(|cy| cy[i] - cy[i - 1]);
        let missing = match next_cycle {
            Some(k) if k > 0.0 => {
                // Across a cycle boundary: the step is d + 720° per cycle moved on.
                let total = d + 720.0 * k;
                (total / step).round() as i64 - 1
            }
            _ if d > 0.0 => (d / step).round() as i64 - 1,
            _ => 0,
        };
        if missing > 0 {
            c.push(
                FindingKind::LostSamples,
                i,
                format!(
                    "crank angle steps from {}° to {}°{}: about {missing} samples missing (step {step}°)",
                    deg[i - 1],
                    deg[i],
                    match next_cycle {
                        Some(k) if k > 0.0 => format!(" across {k} cycle(s)"),
                        _ => String::new(),
                    }
                ),
            );
        }
    }
}
