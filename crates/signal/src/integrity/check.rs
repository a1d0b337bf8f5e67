//! The integrity check of a whole recording ([`IntegrityCheck`], [`check`]): non-finite values,
//! time going back or jumping, the `cycle` channel's runs, the crank-angle steps.

use super::*;

/// Samples the nominal steps are taken over: the time step's median ([`median_step`]) on a
/// time basis, the crank-angle step's on a crank-angle basis — of the first this many samples,
/// whether the recording comes whole or in chunks.
pub const NOMINAL_SAMPLES: usize = 65_536;

/// A channel's non-finite samples: the first (index, value) and how many.
#[derive(Debug, Clone)]
pub(super) struct NonFinite {
    name: String,
    first: Option<(usize, f64)>,
    count: usize,
}

/// Runs of one `cycle` value on a crank-angle basis: their lengths against the samples per
/// cycle.
#[derive(Debug, Clone, Default)]
pub(super) struct CycleRuns {
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
    pub(super) fn start(&mut self) {
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
    pub(super) fn scan(&mut self, chunk: &Recording) {
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
pub(super) fn cycle_run(
    (value, start, len): (f64, usize, usize),
    per: usize,
    last: bool,
    c: &mut Collector,
) {
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

/// The mean of the positive steps of `t` within half a median step of the median (gaps and
/// repeated stamps left out): the sampling's step where its time stamps are rounded — at
/// 72 046 Hz stamped to 1 µs the steps alternate 13 and 14 µs, whose median is one of them
/// (71 428.571 Hz) and whose mean is the rate's.
pub fn mean_step(t: &[f64]) -> Option<f64> {
    let median = median_step(t)?;
    let (mut sum, mut n) = (0.0, 0usize);
    for w in t.windows(2) {
        let d = w[1] - w[0];
        if d > 0.5 * median && d < 1.5 * median {
            sum += d;
            n += 1;
        }
    }
    (n > 0).then(|| sum / n as f64)
}

/// Time stamps whose steps differ from their median by more than this fraction on average
/// are jittered (rounded): the sample rate is the mean step's ([`mean_step`]), and said.
pub const JITTER: f64 = 1e-3;
