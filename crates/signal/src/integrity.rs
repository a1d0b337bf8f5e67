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

use physid_core::{Basis, Recording};
use serde::Serialize;
use std::collections::VecDeque;

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

/// Samples the nominal steps are taken over: the time step's median ([`median_step`]) on a
/// time basis, the crank-angle step's on a crank-angle basis — of the first this many samples,
/// whether the recording comes whole or in chunks.
pub const NOMINAL_SAMPLES: usize = 65_536;

/// A channel's non-finite samples: the first (index, value) and how many.
#[derive(Debug, Clone)]
struct NonFinite {
    name: String,
    first: Option<(usize, f64)>,
    count: usize,
}

/// Runs of one `cycle` value on a crank-angle basis: their lengths against the samples per
/// cycle.
#[derive(Debug, Clone, Default)]
struct CycleRuns {
    /// The current run: its value, first sample and length.
    run: Option<(f64, usize, usize)>,
}

/// The whole post-run check ([`check`]) as a stream of chunks, for a file read as it comes:
/// the sample-by-sample checks of [`IntegrityStream`], plus the units, the non-finite samples,
/// the crank-angle steps and cycle lengths, and the notes about how the recording starts and
/// ends. Memory does not grow with the recording (the findings are capped per kind; the first
/// [`NOMINAL_SAMPLES`] are held until the nominal steps are known from them).
#[derive(Debug, Clone)]
pub struct IntegrityCheck {
    opts: IntegrityOptions,
    basis: Basis,
    /// Created with the first chunk, which gives the nominal time step.
    stream: Option<IntegrityStream>,
    /// Findings made before the stream exists (units).
    early: Collector,
    non_finite: Vec<NonFinite>,
    /// The chunks held until [`NOMINAL_SAMPLES`] have come, and their samples.
    pending: Vec<Recording>,
    pending_rows: usize,
    crank_step: Option<f64>,
    prev_crank: Option<(f64, Option<f64>)>,
    runs: CycleRuns,
    /// The first rising edge of the marker (its index), and the marker's last value.
    first_edge: Option<usize>,
    prev_marker: Option<f64>,
    has_marker: bool,
    seen: usize,
    /// Each angle and its speed ([`crate::speed_angle`]).
    speed_angle: Vec<crate::speed_angle::SpeedAngle>,
}

impl IntegrityCheck {
    /// The checks of `opts` on a recording with `header`'s channels, units and basis.
    pub fn new(opts: &IntegrityOptions, header: &Recording) -> Self {
        let mut early = Collector::default();
        for ch in header.channels() {
            if let Some(unit) = physid_core::standard_unit(&ch.name) {
                if !ch.unit.is_empty() && ch.unit != unit {
                    early.push(
                        FindingKind::UnitMismatch,
                        0,
                        format!(
                            "channel '{}' is in '{}'; physid expects '{unit}' (convert it, or map your column to another name)",
                            ch.name, ch.unit
                        ),
                    );
                }
            }
        }
        Self {
            opts: opts.clone(),
            basis: header.basis,
            stream: None,
            early,
            non_finite: header
                .channels()
                .iter()
                .map(|c| NonFinite {
                    name: c.name.clone(),
                    first: None,
                    count: 0,
                })
                .collect(),
            pending: Vec::new(),
            pending_rows: 0,
            crank_step: None,
            prev_crank: None,
            runs: CycleRuns::default(),
            first_edge: None,
            prev_marker: None,
            has_marker: opts
                .marker
                .as_ref()
                .is_some_and(|m| header.channel(m).is_ok()),
            seen: 0,
            speed_angle: crate::speed_angle::SpeedAngle::pairs(header, &opts.encoders),
        }
    }

    /// Take the next chunk (the header's channels). The first [`NOMINAL_SAMPLES`] are held
    /// until the nominal steps are known from them (whatever the chunks' sizes).
    pub fn push(&mut self, chunk: &Recording) {
        if self.stream.is_some() {
            self.scan(chunk);
            return;
        }
        self.pending_rows += chunk.len();
        self.pending.push(chunk.clone());
        if self.pending_rows >= NOMINAL_SAMPLES {
            self.start();
        }
    }

    /// The nominal steps from the samples held, then the checks over them.
    fn start(&mut self) {
        let pending = std::mem::take(&mut self.pending);
        let head = |name: &str| -> Vec<f64> {
            let mut v = Vec::new();
            for c in &pending {
                if let Ok(x) = c.values(name) {
                    let room = NOMINAL_SAMPLES.saturating_sub(v.len());
                    v.extend_from_slice(&x[..x.len().min(room)]);
                }
            }
            v
        };
        let step = match self.basis {
            Basis::Time => median_step(&head("t")),
            Basis::CrankAngle => None,
        };
        if self.basis == Basis::CrankAngle {
            self.crank_step = median_step(&head("crank_deg"));
        }
        let mut s = IntegrityStream::new(&self.opts, self.basis, step);
        s.c = std::mem::take(&mut self.early);
        if self.basis == Basis::Time {
            let t = head("t");
            for (name, ppr) in &self.opts.encoders {
                if let Some(why) = crate::encoder::uneven_spacing(&t, &head(name), *ppr) {
                    s.c.push(
                        FindingKind::UnevenPulses,
                        0,
                        format!("'{name}' ({ppr} pulses per revolution): {why}"),
                    );
                }
            }
        }
        self.stream = Some(s);
        for c in &pending {
            self.scan(c);
        }
    }

    /// One chunk through every check.
    fn scan(&mut self, chunk: &Recording) {
        let n = chunk.len();
        for p in &mut self.speed_angle {
            p.push(chunk);
        }
        if let Some(stream) = self.stream.as_mut() {
            stream.scan(chunk);
        }
        for nf in &mut self.non_finite {
            let Ok(v) = chunk.values(&nf.name) else {
                continue;
            };
            for (i, x) in v.iter().enumerate() {
                if !x.is_finite() {
                    nf.first.get_or_insert((self.seen + i, *x));
                    nf.count += 1;
                }
            }
        }
        if let Some(m) = self.opts.marker.as_ref().and_then(|m| chunk.values(m).ok()) {
            if self.first_edge.is_none() {
                let mut prev = self.prev_marker;
                for (i, &v) in m.iter().enumerate() {
                    if v != 0.0 && prev.is_none_or(|p| p == 0.0) {
                        self.first_edge = Some(self.seen + i);
                        break;
                    }
                    prev = Some(v);
                }
            }
            self.prev_marker = m.last().copied().or(self.prev_marker);
        }
        if self.basis == Basis::CrankAngle {
            let cycle = chunk.values("cycle").ok();
            if let Ok(deg) = chunk.values("crank_deg") {
                if let (Some(stream), Some(step)) = (self.stream.as_mut(), self.crank_step) {
                    crank_steps(
                        deg,
                        cycle,
                        step,
                        self.seen,
                        &mut self.prev_crank,
                        &mut stream.c,
                    );
                }
            }
            if let (Some(cycle), Some(per), Some(stream)) =
                (cycle, self.opts.samples_per_cycle, self.stream.as_mut())
            {
                for (i, &v) in cycle.iter().enumerate() {
                    match &mut self.runs.run {
                        Some((value, _, len)) if *value == v => *len += 1,
                        run => {
                            if let Some(done) = run.take() {
                                cycle_run(done, per, false, &mut stream.c);
                            }
                            *run = Some((v, self.seen + i, 1));
                        }
                    }
                }
            }
        }
        self.seen += n;
    }

    /// The end of the recording: what waits for it judged, the report.
    pub fn finish(mut self) -> Integrity {
        if self.stream.is_none() {
            self.start();
        }
        let mut stream = self
            .stream
            .take()
            .unwrap_or_else(|| IntegrityStream::new(&self.opts, self.basis, None));
        stream.finish_checks();
        let mut c = std::mem::take(&mut stream.c);
        for p in &self.speed_angle {
            if let Some(detail) = p.finding() {
                c.push(FindingKind::SpeedAngleMismatch, 0, detail);
            }
        }
        for nf in &self.non_finite {
            if let Some((i, v)) = nf.first {
                c.push(
                    FindingKind::NonFinite,
                    i,
                    format!(
                        "channel '{}' is {v} at sample {i} ({} non-finite samples in all)",
                        nf.name, nf.count
                    ),
                );
            }
        }
        match self.basis {
            Basis::Time if self.has_marker => match self.first_edge {
                Some(m0) if m0 > 0 => c.note(
                    0,
                    format!("the recording starts mid-revolution: {m0} samples before the first TDC marker (left out by cycle indexing)"),
                ),
                None => c.note(0, "no TDC marker: cycles cannot be indexed".into()),
                _ => {}
            },
            Basis::CrankAngle => {
                if let (Some(done), Some(per)) = (self.runs.run.take(), self.opts.samples_per_cycle)
                {
                    cycle_run(done, per, true, &mut c);
                }
            }
            Basis::Time => {}
        }
        c.finish()
    }
}

/// A run of one cycle value ended (`last`: by the end of the recording): its length against
/// `per` samples per cycle — a finding inside the recording, a note at either end.
fn cycle_run((value, start, len): (f64, usize, usize), per: usize, last: bool, c: &mut Collector) {
    if len == per {
        return;
    }
    let detail = format!("cycle {value} has {len} samples, expected {per}");
    if start == 0 || last {
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

/// Revolutions over which an encoder that is not the marker's is checked against the marker.
const SPAN_REVS: usize = 10;

/// Crank-angle basis: each step of `crank_deg` is the nominal one `step` (the median), or
/// wraps to the next cycle; a longer step, or a cycle skipped, means samples are missing.
/// `prev`: the sample before the chunk (its angle and cycle), carried from chunk to chunk.
fn crank_steps(
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
enum EncoderCheck {
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
struct EncoderState {
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
    c: Collector,
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
    pub fn push(&mut self, chunk: &Recording, out: &mut Vec<Finding>) {
        self.scan(chunk);
        out.append(&mut self.c.findings);
    }

    /// The end of the stream: an interval still waiting is judged, and kinds with more than
    /// [`MAX_PER_KIND`] findings are summed up.
    pub fn finish(mut self, out: &mut Vec<Finding>) {
        self.finish_checks();
        let counts = std::mem::take(&mut self.c.counts);
        out.append(&mut self.c.findings);
        for (kind, total, first) in counts {
            if total > MAX_PER_KIND {
                out.push(summary(kind, total, first));
            }
        }
    }

    /// Samples counted so far.
    pub fn samples(&self) -> usize {
        self.seen
    }

    fn scan(&mut self, chunk: &Recording) {
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
    fn scan_time(&mut self, t: &[f64]) {
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
    fn encoder_sample(&mut self, e: usize, index: usize, count: f64, edge: bool) {
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
    fn finish_checks(&mut self) {
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
fn pulse_finding(c: &mut Collector, name: &str, ppr: f64, d: f64, at: usize, next: usize) {
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
fn summary(kind: FindingKind, total: usize, first: usize) -> Finding {
    Finding {
        kind,
        index: first,
        detail: format!(
            "{total} findings of this kind in all; the first {MAX_PER_KIND} are listed"
        ),
    }
}
