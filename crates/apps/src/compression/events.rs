//! The windows around each firing TDC of a motored pressure trace ([`TdcEvent`]), gathered as
//! the samples come ([`EventCollector`]).

use super::*;

/// The samples around one firing TDC.
#[derive(Debug, Clone)]
pub struct TdcEvent {
    /// The cycle that starts at this TDC.
    pub cycle: i64,
    /// The time at TDC [s].
    pub t_s: f64,
    /// Mean speed over the window [rpm].
    pub rpm: f64,
    /// Angles [deg ATDC] …
    pub atdc: Vec<f64>,
    /// … and the pressure there.
    pub p: Vec<f64>,
}

/// A cycle is fired, not motored, when its mean pressure 60° … 100° after `about` (its TDC, or
/// its peak) exceeds the mean 100° … 60° before by more than this factor: a motored trace is
/// nearly symmetric about TDC — a little lower after it, by its heat and blow-by loss — while
/// combustion leaves the late expansion's pressure well above the early compression's (×1.47
/// on `golden/gen_wiebe.py`'s burn about its peak; nearer the peak a fired trace is symmetric
/// too, so the windows are away from it).
pub const FIRED_RATIO: f64 = 1.2;

/// Whether the pressure `p` at the angles `deg` [deg] is a fired cycle's around `about` [deg]
/// (angles a cycle apart are taken as the same, [`FIRED_RATIO`]); `None` when the samples do
/// not cover both sides, or the pressure before is not positive.
pub fn fired(deg: &[f64], p: &[f64], about: f64) -> Option<bool> {
    let (mut before, mut nb, mut after, mut na) = (0.0, 0usize, 0.0, 0usize);
    for (&d, &v) in deg.iter().zip(p) {
        let rel = (d - about + 360.0).rem_euclid(720.0) - 360.0;
        if (-100.0..=-60.0).contains(&rel) {
            before += v;
            nb += 1;
        } else if (60.0..=100.0).contains(&rel) {
            after += v;
            na += 1;
        }
    }
    if nb == 0 || na == 0 || before <= 0.0 {
        return None;
    }
    Some(after / na as f64 > FIRED_RATIO * before / nb as f64)
}

/// The events of a crank-angle recording: every firing TDC (`crank_deg` 0) with the whole
/// window on consecutive samples; what was left out is said in `notes` ([`EventCollector`] on
/// the whole recording as one chunk).
pub fn events(
    rec: &Recording,
    channel: &str,
    window: (f64, f64),
    notes: &mut Vec<String>,
) -> Result<Vec<TdcEvent>, AppError> {
    let mut c = EventCollector::new(rec, channel, window)?;
    c.push(rec)?;
    let (events, mut said) = c.finish()?;
    notes.append(&mut said);
    Ok(events)
}

/// One sample of a crank-angle recording as the events take it.
#[derive(Debug, Clone, Copy)]
pub(super) struct Sample {
    cycle: f64,
    deg: f64,
    t: f64,
    p: f64,
}

/// The firing TDCs' windows on a stream of crank-angle chunks: it holds the last
/// `before + after + 1` samples and takes each TDC once its window has come — the events, a few
/// hundred numbers per TDC, whatever the recording's length.
#[derive(Debug, Clone)]
pub struct EventCollector {
    channel: String,
    window: (f64, f64),
    step: crate::pressure::FirstAdvance,
    /// The samples from `ring_start` on.
    ring: std::collections::VecDeque<Sample>,
    ring_start: usize,
    /// The next sample to look at as a TDC.
    next: usize,
    seen: usize,
    events: Vec<TdcEvent>,
    short: usize,
    bad: Vec<String>,
}

/// Samples held before the step of `crank_deg` is known (a file whose angle never advances).
pub(super) const MAX_HELD: usize = 1 << 20;

impl EventCollector {
    /// The events of `channel` in crank-angle recordings with `header`'s channels.
    pub fn new(header: &Recording, channel: &str, window: (f64, f64)) -> Result<Self, AppError> {
        if header.basis != Basis::CrankAngle {
            return Err(AppError::Invalid(
                "the recording is on a time basis: convert it with --crank-angle first (or give the engine angle: --wheel, --encoder)".into(),
            ));
        }
        for name in ["cycle", "crank_deg", "t", channel] {
            header.channel(name)?;
        }
        Ok(Self {
            channel: channel.to_string(),
            window,
            step: Default::default(),
            ring: Default::default(),
            ring_start: 0,
            next: 0,
            seen: 0,
            events: Vec::new(),
            short: 0,
            bad: Vec::new(),
        })
    }

    /// Samples before and after TDC in the window.
    pub(super) fn span(&self) -> Option<(usize, usize, f64)> {
        let step = self.step.step()?;
        Some((
            (-self.window.0 / step).round() as usize,
            (self.window.1 / step).round() as usize,
            step,
        ))
    }

    /// The next chunk of the recording.
    pub fn push(&mut self, chunk: &Recording) -> Result<(), AppError> {
        let (cycle, deg, t, p) = (
            chunk.values("cycle")?,
            chunk.values("crank_deg")?,
            chunk.values("t")?,
            chunk.values(&self.channel)?,
        );
        for i in 0..cycle.len() {
            self.step.see(deg[i]);
            self.ring.push_back(Sample {
                cycle: cycle[i],
                deg: deg[i],
                t: t[i],
                p: p[i],
            });
            self.seen += 1;
            if self.step.step().is_none() && self.ring.len() > MAX_HELD {
                return Err(AppError::Invalid(format!(
                    "crank_deg does not advance over its first {MAX_HELD} samples"
                )));
            }
            self.take(false);
        }
        Ok(())
    }

    /// Look at every sample whose window has come (all that are left `at_end`).
    pub(super) fn take(&mut self, at_end: bool) {
        let Some((before, after, step)) = self.span() else {
            return;
        };
        while self.next < self.seen && (at_end || self.next + after < self.seen) {
            let i = self.next;
            self.next += 1;
            let s = self.ring[i - self.ring_start];
            if !(s.deg.abs() < 1e-6 * step && s.cycle >= 0.0) {
                continue;
            }
            if i < before || i + after >= self.seen {
                self.short += 1;
                continue;
            }
            let w = (i - before - self.ring_start)..=(i + after - self.ring_start);
            let contiguous = self.ring.range(w.clone()).enumerate().all(|(k, x)| {
                let want = (k as f64 - before as f64) * step;
                let a = if x.deg >= 360.0 { x.deg - 720.0 } else { x.deg };
                (a - want).abs() < 1e-3 * step
            });
            if !contiguous {
                self.short += 1;
                continue;
            }
            if let Some((k, x)) = self
                .ring
                .range(w.clone())
                .enumerate()
                .find(|(_, x)| !x.p.is_finite())
            {
                self.bad
                    .push(format!("sample {} ({})", i - before + k, x.p));
                continue;
            }
            let (first, last) = (self.ring[*w.start()], self.ring[*w.end()]);
            self.events.push(TdcEvent {
                cycle: s.cycle as i64,
                t_s: s.t,
                rpm: (after + before) as f64 * step / 6.0 / (last.t - first.t),
                atdc: (0..=before + after)
                    .map(|k| (k as f64 - before as f64) * step)
                    .collect(),
                p: self.ring.range(w).map(|x| x.p).collect(),
            });
        }
        // Keep what a later TDC's window can reach back to.
        let keep_from = self.next.saturating_sub(before);
        while self.ring_start < keep_from {
            self.ring.pop_front();
            self.ring_start += 1;
        }
    }

    /// The events found so far and not yet taken, in order.
    pub fn drain(&mut self) -> impl Iterator<Item = TdcEvent> + '_ {
        self.events.drain(..)
    }

    /// The end of the recording: the events not yet taken, and what was left out (for
    /// `notes`).
    pub fn finish(mut self) -> Result<(Vec<TdcEvent>, Vec<String>), AppError> {
        if self.step.step().is_none() {
            return Err(AppError::Invalid("crank_deg never advances".into()));
        }
        self.take(true);
        let mut notes = Vec::new();
        if self.short > 0 {
            notes.push(format!(
                "{} TDC(s) without the whole window {}° … {}° ATDC on consecutive samples left out",
                self.short, self.window.0, self.window.1
            ));
        }
        if !self.bad.is_empty() {
            notes.push(format!(
                "{} TDC(s) left out for a pressure that is not finite: '{}' at {}",
                self.bad.len(),
                self.channel,
                self.bad.join(", ")
            ));
        }
        Ok((self.events, notes))
    }
}
