//! The same checks on the stream ([`IntegrityStream`]): chunk by chunk, the encoders' pulses
//! and the TDC marker checked as they come.

use super::*;

/// Revolutions over which an encoder that is not the marker's is checked against the marker.
pub(super) const SPAN_REVS: usize = 10;

/// Crank-angle basis: each step of `crank_deg` is the nominal one `step` (the median), or
/// wraps to the next cycle; a longer step, or a cycle skipped, means samples are missing.
/// `prev`: the sample before the chunk (its angle and cycle), carried from chunk to chunk.
pub(super) fn crank_steps(
    deg: &[f64],
    cycle: Option<&[f64]>,
    step: f64,
    seen: usize,
    prev: &mut Option<(f64, Option<f64>)>,
    c: &mut Collector,
) {
    for (i, &now) in deg.iter().enumerate() {
        let cy = cycle.map(|cy| cy[i]);
        let Some((before, cy_before)) = prev.replace((now, cy)) else {
            continue;
        };
        let d = now - before;
        let next_cycle = match (cy, cy_before) {
            (Some(a), Some(b)) => Some(a - b),
            _ => None,
        };
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
                seen + i,
                format!(
                    "crank angle steps from {before}° to {now}°{}: about {missing} samples missing (step {step}°)",
                    match next_cycle {
                        Some(k) if k > 0.0 => format!(" across {k} cycle(s)"),
                        _ => String::new(),
                    }
                ),
            );
        }
    }
}

/// How an encoder's count is checked.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(super) enum EncoderCheck {
    /// The marker's own encoder, interval by interval: `ppr` pulses between markers, within
    /// `tol` pulses (0 on a time basis; on a crank-angle basis the pulses one grid step spans,
    /// since resampling places the marker and the count to one step). An interval that is off
    /// waits for the next: if the two together hold 2·ppr, the marker between them is displaced
    /// (out of sync); else pulses are missing or too many.
    Pulses {
        tol: f64,
        last_edge: Option<(usize, f64)>,
        /// An off interval: its pulses, its first and last marker.
        waiting: Option<(f64, usize, usize)>,
    },
    /// An encoder that is not the marker's, over spans of [`SPAN_REVS`] marker revolutions:
    /// its count must advance by that many revolutions' pulses, within a twist allowance of
    /// 1/20 revolution (a twist moves the count by a bounded amount each way; lost pulses add
    /// up). A run of spans off by the same sign is one finding, at the first span's start.
    Span {
        edges: VecDeque<(usize, f64)>,
        previous: i8,
    },
    /// Without a marker: only that it never goes back.
    Count,
}

/// One encoder's state.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(super) struct EncoderState {
    name: String,
    ppr: f64,
    prev: Option<f64>,
    check: EncoderCheck,
}

/// The checks of [`check`] that go sample by sample — time going back or repeating (and, with a
/// nominal step, gaps), encoder counts going back, the marker's encoder pulse by pulse between
/// TDC markers, other encoders over spans of marker revolutions — on a stream of chunks, for
/// the live service. [`check`] runs this over the whole recording, so the two find the same;
/// the stream gives each finding as soon as it is certain (a pulse count that is off, once the
/// next interval has shown the marker was not merely displaced), at most [`MAX_PER_KIND`] per
/// kind, and sums up the rest at [`finish`](Self::finish). No allocation per sample.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct IntegrityStream {
    /// The nominal time step [s] for gaps (time basis), `None`: no gap check.
    step: Option<f64>,
    seen: usize,
    prev_t: Option<f64>,
    marker: Option<String>,
    prev_marker: Option<f64>,
    encoders: Vec<EncoderState>,
    pub(super) c: Collector,
}

impl IntegrityStream {
    /// The checks of `opts` on a recording of `basis`; `step`: the nominal time step [s] (gaps
    /// are steps beyond 1.5 of it).
    pub fn new(opts: &IntegrityOptions, basis: Basis, step: Option<f64>) -> Self {
        let own = opts
            .marker_encoder
            .as_deref()
            .or(opts.encoders.first().map(|e| e.0.as_str()));
        let encoders = opts
            .encoders
            .iter()
            .map(|(name, ppr)| {
                let check = match &opts.marker {
                    Some(_) if Some(name.as_str()) == own => EncoderCheck::Pulses {
                        tol: match (basis, opts.samples_per_cycle) {
                            (Basis::CrankAngle, Some(per)) if per > 0 => {
                                (2.0 * f64::from(*ppr) / per as f64).ceil()
                            }
                            _ => 0.0,
                        },
                        last_edge: None,
                        waiting: None,
                    },
                    Some(_) => EncoderCheck::Span {
                        edges: VecDeque::with_capacity(SPAN_REVS + 1),
                        previous: 0,
                    },
                    None => EncoderCheck::Count,
                };
                EncoderState {
                    name: name.clone(),
                    ppr: f64::from(*ppr),
                    prev: None,
                    check,
                }
            })
            .collect();
        Self {
            step: step.filter(|s| s.is_finite() && *s > 0.0),
            seen: 0,
            prev_t: None,
            marker: opts.marker.clone(),
            prev_marker: None,
            encoders,
            c: Collector::default(),
        }
    }

    /// Take a chunk (its `t`, encoder and marker channels; the ones it lacks are not checked);
    /// the findings it makes certain are appended to `out`.
    pub fn push(&mut self, chunk: &Recording, out: &mut dyn Sink<Finding>) {
        self.scan(chunk);
        for f in self.c.findings.drain(..) {
            out.put(f);
        }
    }

    /// The end of the stream: an interval still waiting is judged, and kinds with more than
    /// [`MAX_PER_KIND`] findings are summed up.
    pub fn finish(&mut self, out: &mut dyn Sink<Finding>) {
        self.finish_checks();
        let counts = std::mem::take(&mut self.c.counts);
        for f in self.c.findings.drain(..) {
            out.put(f);
        }
        for (kind, total, first) in counts {
            if total > MAX_PER_KIND {
                out.put(summary(kind, total, first));
            }
        }
    }

    /// Samples counted so far.
    pub fn samples(&self) -> usize {
        self.seen
    }

    pub(super) fn scan(&mut self, chunk: &Recording) {
        let n = chunk.len();
        if let Ok(t) = chunk.values("t") {
            self.scan_time(t);
        }
        let marker = self.marker.as_ref().and_then(|m| chunk.values(m).ok());
        for e in 0..self.encoders.len() {
            let Ok(counts) = chunk.values(&self.encoders[e].name) else {
                continue;
            };
            let mut prev_marker = self.prev_marker;
            for i in 0..n {
                let index = self.seen + i;
                let edge = marker.is_some_and(|m| {
                    let v = m[i];
                    let rising = v != 0.0 && prev_marker.is_none_or(|p| p == 0.0);
                    prev_marker = Some(v);
                    rising
                });
                self.encoder_sample(e, index, counts[i], edge);
            }
        }
        if let Some(&last) = marker.and_then(|m| m.last()) {
            self.prev_marker = Some(last);
        }
        self.seen += n;
    }

    /// Time going back or repeating; with a nominal step, gaps.
    pub(super) fn scan_time(&mut self, t: &[f64]) {
        for (i, &now) in t.iter().enumerate() {
            let index = self.seen + i;
            if let Some(before) = self.prev_t {
                let dt = now - before;
                if dt < 0.0 {
                    self.c.push(
                        FindingKind::NonMonotonicTime,
                        index,
                        format!("t goes back from {before} s to {now} s"),
                    );
                } else if dt == 0.0 {
                    self.c.push(
                        FindingKind::DuplicatedSamples,
                        index,
                        format!("t = {now} s repeats"),
                    );
                } else if let Some(step) = self.step.filter(|s| dt > 1.5 * s) {
                    let missing = (dt / step).round() as i64 - 1;
                    self.c.push(
                        FindingKind::LostSamples,
                        index,
                        format!(
                            "gap of {dt:.6e} s after t = {before} s: about {missing} samples missing (interval {step:.6e} s)"
                        ),
                    );
                }
            }
            self.prev_t = Some(now);
        }
    }

    /// One sample of encoder `e` (`edge`: a TDC marker rises here).
    pub(super) fn encoder_sample(&mut self, e: usize, index: usize, count: f64, edge: bool) {
        let Self { encoders, c, .. } = self;
        let enc = &mut encoders[e];
        if let Some(p) = enc.prev {
            if count < p {
                let detail = format!(
                    "'{}' goes back from {p} to {count} at sample {index}",
                    enc.name
                );
                c.push(FindingKind::CountBackwards, index, detail);
            }
        }
        enc.prev = Some(count);
        if !edge {
            return;
        }
        let (name, ppr) = (enc.name.as_str(), enc.ppr);
        match &mut enc.check {
            EncoderCheck::Pulses {
                tol,
                last_edge,
                waiting,
            } => {
                let tol = *tol;
                let Some((at, c0)) = last_edge.replace((index, count)) else {
                    return;
                };
                let d = count - c0;
                if let Some((d0, at0, next0)) = waiting.take() {
                    if (d0 + d - 2.0 * ppr).abs() <= tol {
                        c.push(
                            FindingKind::OutOfSync,
                            next0,
                            format!(
                                "'{name}': the TDC marker at sample {next0} is {:+} pulses off the encoder count",
                                d0 - ppr
                            ),
                        );
                        return;
                    }
                    pulse_finding(c, name, ppr, d0, at0, next0);
                }
                if (d - ppr).abs() > tol {
                    *waiting = Some((d, at, index));
                }
            }
            EncoderCheck::Span { edges, previous } => {
                edges.push_back((index, count));
                if edges.len() <= SPAN_REVS {
                    return;
                }
                let Some((a, ca)) = edges.pop_front() else {
                    return;
                };
                let (b, cb) = (index, count);
                let tol = (ppr / 20.0).max(1.0);
                let d = cb - ca - SPAN_REVS as f64 * ppr;
                let sign = if d > tol {
                    1
                } else if d < -tol {
                    -1
                } else {
                    0
                };
                let report = sign != 0 && sign != *previous;
                *previous = sign;
                if report {
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
                            cb - ca,
                            SPAN_REVS as f64 * ppr,
                            d.abs()
                        ),
                    );
                }
            }
            EncoderCheck::Count => {}
        }
    }

    /// Judge the intervals still waiting (no next interval will come).
    pub(super) fn finish_checks(&mut self) {
        for enc in &mut self.encoders {
            if let EncoderCheck::Pulses { waiting, .. } = &mut enc.check {
                if let Some((d, at, next)) = waiting.take() {
                    pulse_finding(&mut self.c, &enc.name, enc.ppr, d, at, next);
                }
            }
        }
    }
}

/// Pulses missing or too many between the markers at samples `at` and `next`.
pub(super) fn pulse_finding(
    c: &mut Collector,
    name: &str,
    ppr: f64,
    d: f64,
    at: usize,
    next: usize,
) {
    let (kind, what) = if d < ppr {
        (FindingKind::PulseLoss, "missing")
    } else {
        (FindingKind::ExtraPulses, "too many")
    };
    c.push(
        kind,
        at,
        format!(
            "'{name}': {d} pulses between the TDC markers at samples {at} and {next}, expected {ppr} ({} {what})",
            (d - ppr).abs()
        ),
    );
}

/// The finding that sums up a kind found more than [`MAX_PER_KIND`] times.
pub(super) fn summary(kind: FindingKind, total: usize, first: usize) -> Finding {
    Finding {
        kind,
        index: first,
        detail: format!(
            "{total} findings of this kind in all; the first {MAX_PER_KIND} are listed"
        ),
    }
}
