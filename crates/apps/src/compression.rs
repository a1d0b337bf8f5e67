//! The chain on a motored pressure trace (`physid compression fit`): the motored-pressure model
//! ([`physid_models::motored`]: compression ratio, TDC offset, sensor offset, polytropic
//! exponent, BDC pressure, loss rate) fitted around every firing TDC of a crank-angle
//! recording.
//!
//! 1. The compression events: around each firing TDC, the samples in the window (default
//!    −120° … 120° ATDC, valves closed) — the compression at the end of one cycle, the expansion
//!    at the start of the next.
//! 2. Starting values from the data: `n = 1.3`, no offsets, no loss, the compression ratio from
//!    the ratio of the peak pressure to the pressure at the window's start
//!    (`p_max/p_a = (V_a/V_c)ⁿ`), the BDC pressure by the polytrope back from `p_a`.
//! 3. All the parameters not held (`--set`) fitted to every event at once (Gauss–Newton), the
//!    identifiability ranking at nominal values (Alg. 5.1, thesis scaling) and the estimable
//!    set (Wu et al. by default): which parameters the trace resolves and which trade off.
//! 4. The estimable ones, the rest held at their starting values:
//!    - fitted to all the events at once — the estimate, with 95 % intervals from the Fisher
//!      information of all of them (Eq. 5.12, σ² from the residuals);
//!    - fitted per event, with intervals from each event's information;
//!    - combined recursively over the events by Gauss–Newton — the first event's own fit,
//!      then each event linearised at the estimate so far (`J_k`, `r_k` there):
//!      `I_k = I_{k−1} + J_kᵀJ_k/σ_k²`, `ϑ̄_k = ϑ̄_{k−1} + I_k⁻¹·J_kᵀr_k/σ_k²` (the extended
//!      Kalman filter of a constant parameter): the on-line track. When one event resolves
//!      the parameters well it ends at the fit of all; when it does not (much noise), its
//!      first linearisations are poor and it lags — the fit of all is the estimate.
//!
//!    The spread of the per-event estimates is reported beside the interval: if it exceeds
//!    it, the parameters change from cycle to cycle or the model misses something.
//! 5. The thermodynamic loss angle: where the fitted trace peaks, `n·d ln V/dα = −k_loss`.

use crate::error::AppError;
use nalgebra::{DMatrix, DVector};
use physid_core::{Basis, GradientEngine, ParamModel, Recording};
use physid_ident::{
    analyse, fit_subset, quantify, Data, IdentConfig, IdentError, RankedParam, Rows, Selection,
};
use physid_models::motored::{Motored, DESCRIPTIONS, PARAMS, UNITS};
use serde::Serialize;

/// What to fit.
#[derive(Debug, Clone)]
pub struct CompressionConfig {
    /// The cylinder-pressure channel.
    pub channel: String,
    /// Stroke [m].
    pub stroke: f64,
    /// Connecting rod [m].
    pub rod: f64,
    /// The fitting window around TDC [deg ATDC].
    pub window_deg: (f64, f64),
    /// Parameters held at a value (not fitted): name and value.
    pub held: Vec<(String, f64)>,
    /// How many of the ranked parameters to fit.
    pub selection: Selection,
}

impl CompressionConfig {
    /// The defaults for a channel and a geometry: window −120° … 120°, nothing held, the Wu
    /// criterion.
    pub fn new(channel: &str, stroke: f64, rod: f64) -> Self {
        Self {
            channel: channel.to_string(),
            stroke,
            rod,
            window_deg: DEFAULT_WINDOW,
            held: Vec::new(),
            selection: Selection::Wu { sigma2: None },
        }
    }

    fn validate(&self) -> Result<(), AppError> {
        let (a, b) = self.window_deg;
        if !(self.stroke.is_finite()
            && self.stroke > 0.0
            && self.rod.is_finite()
            && self.rod > 0.5 * self.stroke)
        {
            return Err(AppError::Invalid(format!(
                "stroke {} m, rod {} m: expected lengths > 0 in metres and a rod longer than half the stroke",
                self.stroke, self.rod
            )));
        }
        if !((-180.0..-10.0).contains(&a) && b > 10.0 && b <= 180.0) {
            return Err(AppError::Invalid(format!(
                "window {a}° … {b}° ATDC: expected from −180° … −10° to 10° … 180° (the valves closed, TDC inside)"
            )));
        }
        for (name, v) in &self.held {
            if !PARAMS.contains(&name.as_str()) {
                return Err(AppError::Invalid(format!(
                    "--set {name}: the motored model's parameters are {}",
                    PARAMS.join(", ")
                )));
            }
            if !v.is_finite() {
                return Err(AppError::Invalid(format!("--set {name}={v}: not a number")));
            }
        }
        Ok(())
    }
}

/// The default fitting window [deg ATDC].
pub const DEFAULT_WINDOW: (f64, f64) = (-120.0, 120.0);

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
struct Sample {
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
const MAX_HELD: usize = 1 << 20;

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
    fn span(&self) -> Option<(usize, usize, f64)> {
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
    fn take(&mut self, at_end: bool) {
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

/// One parameter's result.
#[derive(Debug, Clone, Serialize)]
pub struct ParamEstimate {
    /// Name (as [`PARAMS`]).
    pub name: String,
    /// Unit (`P`: the pressure channel's).
    pub unit: String,
    /// What it is.
    pub description: String,
    /// `fitted`, `held` (given with `--set`) or `unresolved` (the data do not resolve it: held
    /// at its starting value).
    pub status: &'static str,
    /// The value: fitted to all the events at once when fitted.
    pub value: f64,
    /// Its standard error (fitted only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub std_err: Option<f64>,
    /// 95 % interval (fitted only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ci95: Option<(f64, f64)>,
    /// The standard deviation of the per-event estimates over √(events): the spread's own
    /// standard error of the mean (fitted, two events or more).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub between_events_std_err: Option<f64>,
}

/// One event's fit.
#[derive(Debug, Clone, Serialize)]
pub struct EventFit {
    /// The cycle starting at this TDC.
    pub cycle: i64,
    /// Time at TDC [s].
    pub t_s: f64,
    /// Speed [rpm].
    pub rpm: f64,
    /// The fitted parameters' values (in [`CompressionFit::fitted`] order).
    pub values: Vec<f64>,
    /// Their standard errors.
    pub std_err: Vec<f64>,
    /// The recursive estimate after this event (Gauss–Newton over the events so far).
    pub recursive: Vec<f64>,
    /// Its standard errors.
    pub recursive_std_err: Vec<f64>,
    /// RMS of the fit's residual [the channel's unit].
    pub rms_residual: f64,
}

/// One TDC's pressure, measured and fitted.
#[derive(Debug, Clone, Serialize)]
pub struct Trace {
    /// The cycle starting at this TDC.
    pub cycle: i64,
    /// Angles [deg ATDC on the recording].
    pub atdc: Vec<f64>,
    /// The measured pressure.
    pub measured: Vec<f64>,
    /// The model with the estimate.
    pub fitted: Vec<f64>,
}

/// A pair of parameters that trade off in the fit of all of them.
#[derive(Debug, Clone, Serialize)]
pub struct Confounded {
    /// One …
    pub a: String,
    /// … and the other.
    pub b: String,
    /// Their estimates' correlation.
    pub correlation: f64,
}

/// The result of [`compression_fit`].
#[derive(Debug, Clone, Serialize)]
pub struct CompressionFit {
    /// The pressure channel …
    pub channel: String,
    /// … and its unit.
    pub unit: String,
    /// The window [deg ATDC].
    pub window_deg: (f64, f64),
    /// The starting values, every parameter in [`PARAMS`] order.
    pub start: Vec<f64>,
    /// The identifiability ranking of the parameters not held, at the fit of all of them.
    pub ranking: Vec<RankedParam>,
    /// The Wu criterion `J_K` per K, when it decided.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wu_j: Option<Vec<f64>>,
    /// Pairs whose estimates correlate beyond 0.95 in the fit of all the parameters not held
    /// (or `None` when their Fisher information is singular).
    pub confounded: Option<Vec<Confounded>>,
    /// Collinearity index of the fitted set (Brun et al.).
    pub collinearity: f64,
    /// The parameters fitted, in [`PARAMS`] order.
    pub fitted: Vec<String>,
    /// Every parameter's result, in [`PARAMS`] order.
    pub estimates: Vec<ParamEstimate>,
    /// Per event.
    pub events: Vec<EventFit>,
    /// Where the fitted trace peaks [deg ATDC, true]: before TDC by the loss angle.
    pub peak_deg: Option<f64>,
    /// RMS residual over all events [the channel's unit].
    pub rms_residual: f64,
    /// The last TDC fitted: measured and fitted pressure (the estimate).
    pub trace: Trace,
    /// What was left out and why.
    pub notes: Vec<String>,
}

impl CompressionFit {
    /// A parameter's result by name.
    pub fn get(&self, name: &str) -> Option<&ParamEstimate> {
        self.estimates.iter().find(|e| e.name == name)
    }

    /// Every parameter's value, in [`PARAMS`] order.
    pub fn theta(&self) -> Vec<f64> {
        self.estimates.iter().map(|e| e.value).collect()
    }
}

/// Starting values (see the module's doc) from the median over the TDCs of the pressure at the
/// window's start, `p_a`, and of its peak, `p_max`; the window starts at `a0` [deg ATDC].
fn start_values(p_a: Vec<f64>, p_max: Vec<f64>, a0: f64, model: &Motored) -> Vec<f64> {
    let median = |mut v: Vec<f64>| {
        v.sort_unstable_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (p_a, p_max) = (median(p_a), median(p_max));
    let a = a0.to_radians();
    let n0 = 1.3;
    // V_a/V_c = (p_max/p_a)^(1/n) = 1 + (ε − 1)·s(a)/S.
    let crank = model.crank();
    let s_a = crank.s_at(a);
    let ratio = (p_max / p_a).max(1.0 + 1e-6).powf(1.0 / n0);
    let eps = (1.0 + (ratio - 1.0) * crank.stroke() / s_a).clamp(1.5, 100.0);
    let p_bdc = p_a / model.volume_ratio(eps, a).powf(n0);
    vec![eps, 0.0, 0.0, n0, p_bdc, 0.0]
}

/// The angle [deg ATDC, true] where the model's trace peaks: `n·d ln(V(−π)/V)/dα = k` between
/// −30° and TDC (bisection); `None` outside.
pub fn peak_angle(model: &Motored, theta: &[f64]) -> Option<f64> {
    let (eps, n, k) = (theta[0], theta[3], theta[5]);
    let crank = model.crank();
    let s_total = crank.stroke();
    // d ln p/dα = −n·(ε − 1)·s'(α)/(S + (ε − 1)·s(α)) − k.
    let slope = |a: f64| {
        let (s, ds, _) = crank.motion(a);
        -n * (eps - 1.0) * ds / (s_total + (eps - 1.0) * s) - k
    };
    let (mut lo, mut hi) = (-30f64.to_radians(), 0.0);
    if !(slope(lo) > 0.0 && slope(hi) <= 0.0) {
        return None;
    }
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if slope(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some(0.5 * (lo + hi).to_degrees())
}

/// Typical sizes of the parameters that start at 0, for the ranking's relative sensitivities
/// (thesis scaling, Eq. 5.11): a TDC error of 1°, a sensor offset of a tenth of the BDC
/// pressure, a loss of 2 %/rad.
fn nominal_values(start: &[f64], held: &[usize]) -> Vec<f64> {
    let mut v = start.to_vec();
    for (j, typical) in [(1, 1.0), (2, 0.1 * start[4]), (5, 0.02)] {
        if !held.contains(&j) && v[j] == 0.0 {
            v[j] = typical;
        }
    }
    v
}

fn data<'a>(atdc: &'a [f64], p: &'a [f64]) -> Data<'a> {
    Data {
        inputs: vec![atdc],
        y: Some(p),
    }
}

/// Fit the motored model to a crank-angle recording (see the module's doc):
/// [`compression_fit_events`] on its TDCs' windows, held.
pub fn compression_fit(
    rec: &Recording,
    cfg: &CompressionConfig,
) -> Result<CompressionFit, AppError> {
    let events = TdcEvents::new(rec, &cfg.channel, cfg.window_deg, usize::MAX);
    compression_fit_events(&events, cfg)
}

/// A crank-angle recording that can be gone over again and again: a file read again, a
/// recording in memory.
pub trait CrankPasses {
    /// Go over the recording once: `visit` every chunk in order (the first may be the header
    /// alone, without samples). An error of `visit` ends the pass and is returned.
    fn chunks(
        &self,
        visit: &mut dyn FnMut(&Recording) -> Result<(), AppError>,
    ) -> Result<(), AppError>;
}

impl CrankPasses for Recording {
    fn chunks(
        &self,
        visit: &mut dyn FnMut(&Recording) -> Result<(), AppError>,
    ) -> Result<(), AppError> {
        visit(self)
    }
}

/// One TDC's window as a pass over [`TdcEvents`] shows it.
#[derive(Debug, Clone, Copy)]
pub struct Window<'w> {
    /// The cycle that starts at this TDC.
    pub cycle: i64,
    /// The time at TDC [s].
    pub t_s: f64,
    /// Mean speed over the window [rpm].
    pub rpm: f64,
    /// Angles [deg ATDC] …
    pub atdc: &'w [f64],
    /// … and the pressure there.
    pub p: &'w [f64],
}

/// What the first pass over [`TdcEvents`] found.
#[derive(Debug, Clone, Default)]
pub struct FirstPass {
    /// The pressure channel's unit.
    pub unit: String,
    /// What was left out, and a unit that looks wrong.
    pub notes: Vec<String>,
    /// How many TDCs' windows …
    pub events: usize,
    /// … and their samples.
    pub rows: usize,
}

/// The TDCs' windows, held in one pooled buffer: the angle grid once, the pressures one
/// window after another.
#[derive(Debug, Default)]
struct HeldWindows {
    atdc: Vec<f64>,
    at: Vec<(i64, f64, f64)>,
    p: Vec<f64>,
}

#[derive(Debug)]
enum Held {
    NotYet,
    Whole(HeldWindows),
    TooLarge,
}

/// The firing TDCs' windows of a crank-angle recording ([`EventCollector`]) gone over in
/// passes — the fit over all of them is a pass per Gauss–Newton iteration: held after the first
/// pass when they take at most a limit (8 bytes a sample, the angles once), else gathered again
/// from the recording on every pass — so that memory is at most the limit, or a reader's
/// chunk, whatever the recording's length. Each window is one chunk of its [`Rows`] (the
/// motored model's input `atdc`, the pressure as the output).
pub struct TdcEvents<'a> {
    source: &'a dyn CrankPasses,
    channel: String,
    window: (f64, f64),
    hold_bytes: usize,
    held: std::cell::RefCell<Held>,
    first: std::cell::RefCell<Option<FirstPass>>,
}

/// One pass's handling of the windows as they are gathered.
struct Gathering<'v, E> {
    visit: &'v mut dyn FnMut(&Window) -> Result<(), E>,
    keep: Option<HeldWindows>,
    hold_bytes: usize,
    events: usize,
    rows: usize,
    failed: Option<E>,
}

impl<E> Gathering<'_, E> {
    fn take(&mut self, e: TdcEvent) -> Result<(), AppError> {
        self.events += 1;
        self.rows += e.p.len();
        let w = Window {
            cycle: e.cycle,
            t_s: e.t_s,
            rpm: e.rpm,
            atdc: &e.atdc,
            p: &e.p,
        };
        if let Err(err) = (self.visit)(&w) {
            self.failed = Some(err);
            return Err(AppError::Invalid("the pass was stopped".into()));
        }
        if let Some(k) = &mut self.keep {
            let bytes = (k.p.len() + e.p.len() + e.atdc.len()) * 8 + (k.at.len() + 1) * 24;
            if bytes > self.hold_bytes {
                self.keep = None;
            } else {
                if k.atdc.is_empty() {
                    k.atdc = e.atdc;
                }
                k.at.push((e.cycle, e.t_s, e.rpm));
                k.p.extend_from_slice(&e.p);
            }
        }
        Ok(())
    }
}

impl<'a> TdcEvents<'a> {
    /// The windows `window` [deg ATDC] of `channel` around the firing TDCs of `source`, held
    /// after the first pass if they take at most `hold_bytes`.
    pub fn new(
        source: &'a dyn CrankPasses,
        channel: &str,
        window: (f64, f64),
        hold_bytes: usize,
    ) -> Self {
        Self {
            source,
            channel: channel.to_string(),
            window,
            hold_bytes,
            held: std::cell::RefCell::new(Held::NotYet),
            first: std::cell::RefCell::new(None),
        }
    }

    /// What the first pass found (making it now if none was made).
    pub fn first_pass(&self) -> Result<FirstPass, AppError> {
        if self.first.borrow().is_none() {
            self.each::<AppError>(&mut |_| Ok(()))?;
        }
        Ok(self.first.borrow().clone().unwrap_or_default())
    }

    /// Whether the windows are held (after a first pass, within the limit).
    pub fn held(&self) -> bool {
        matches!(*self.held.borrow(), Held::Whole(_))
    }

    /// Go over the windows once, in order: `visit` each. An error of `visit` ends the pass
    /// and is returned.
    pub fn each<E: From<AppError>>(
        &self,
        visit: &mut dyn FnMut(&Window) -> Result<(), E>,
    ) -> Result<(), E> {
        if let Held::Whole(h) = &*self.held.borrow() {
            let n = h.atdc.len();
            for (k, &(cycle, t_s, rpm)) in h.at.iter().enumerate() {
                visit(&Window {
                    cycle,
                    t_s,
                    rpm,
                    atdc: &h.atdc,
                    p: &h.p[k * n..(k + 1) * n],
                })?;
            }
            return Ok(());
        }
        let first = matches!(*self.held.borrow(), Held::NotYet);
        let mut g = Gathering {
            visit,
            keep: first.then(HeldWindows::default),
            hold_bytes: self.hold_bytes,
            events: 0,
            rows: 0,
            failed: None,
        };
        let mut collector: Option<EventCollector> = None;
        let mut unit: Option<(String, crate::pressure::UnitCheck)> = None;
        let mut gather = || -> Result<Vec<String>, AppError> {
            self.source.chunks(&mut |chunk| {
                let c = match &mut collector {
                    Some(c) => c,
                    None => {
                        if first {
                            unit = Some((
                                chunk.channel(&self.channel)?.unit.clone(),
                                crate::pressure::UnitCheck::new(chunk, &self.channel)?,
                            ));
                        }
                        collector.insert(EventCollector::new(chunk, &self.channel, self.window)?)
                    }
                };
                if let Some((_, check)) = &mut unit {
                    check.push(chunk.values(&self.channel)?);
                }
                c.push(chunk)?;
                c.drain().try_for_each(|e| g.take(e))
            })?;
            let Some(c) = collector.take() else {
                return Err(AppError::Invalid("the recording has no channels".into()));
            };
            let (rest, mut notes) = c.finish()?;
            rest.into_iter().try_for_each(|e| g.take(e))?;
            if let Some((_, check)) = &unit {
                if let Some(n) = check.finish(false)? {
                    notes.insert(0, n);
                }
            }
            Ok(notes)
        };
        let notes = match gather() {
            Ok(notes) => notes,
            Err(e) => return Err(g.failed.take().unwrap_or_else(|| e.into())),
        };
        if first {
            *self.first.borrow_mut() = Some(FirstPass {
                unit: unit.map(|(u, _)| u).unwrap_or_default(),
                notes,
                events: g.events,
                rows: g.rows,
            });
            *self.held.borrow_mut() = g.keep.map_or(Held::TooLarge, Held::Whole);
        } else if let Some(f) = &*self.first.borrow() {
            if (f.events, f.rows) != (g.events, g.rows) {
                return Err(AppError::Invalid(format!(
                    "the recording changed between passes: {} TDC window(s) of {} samples, then {} of {}",
                    f.events, f.rows, g.events, g.rows
                ))
                .into());
            }
        }
        Ok(())
    }
}

impl Rows for TdcEvents<'_> {
    fn has_y(&self) -> bool {
        true
    }

    fn pass(
        &self,
        visit: &mut dyn FnMut(&Data) -> Result<(), IdentError>,
    ) -> Result<(), IdentError> {
        self.each(&mut |w| {
            visit(&Data {
                inputs: vec![w.atdc],
                y: Some(w.p),
            })
        })
    }
}

/// The fit over the TDCs' windows (steps 2–5 of the module's doc), a pass over them for the
/// starting values, one per Gauss–Newton iteration and one for the fit per event.
pub fn compression_fit_events(
    events: &TdcEvents,
    cfg: &CompressionConfig,
) -> Result<CompressionFit, AppError> {
    cfg.validate()?;
    // The first pass: the pressures the starting values take, per TDC.
    let (mut p_a, mut p_max, mut a0) = (Vec::new(), Vec::new(), f64::NAN);
    events.each::<AppError>(&mut |w| {
        p_a.push(w.p[0]);
        p_max.push(w.p.iter().copied().fold(f64::MIN, f64::max));
        a0 = w.atdc[0];
        Ok(())
    })?;
    let FirstPass {
        unit,
        mut notes,
        rows,
        events: n_events,
    } = events.first_pass()?;
    if p_a.is_empty() {
        return Err(AppError::Invalid(format!(
            "no firing TDC with the whole window {}° … {}° ATDC of '{}' in the recording",
            cfg.window_deg.0, cfg.window_deg.1, cfg.channel
        )));
    }
    let model = Motored::new(cfg.stroke, cfg.rod);
    let mut start = start_values(p_a, p_max, a0, &model);
    for (name, v) in &cfg.held {
        let j = PARAMS.iter().position(|p| p == name).unwrap_or(0);
        start[j] = *v;
    }
    let held: Vec<usize> = cfg
        .held
        .iter()
        .filter_map(|(n, _)| PARAMS.iter().position(|p| p == n))
        .collect();
    let free: Vec<usize> = (0..PARAMS.len()).filter(|j| !held.contains(j)).collect();
    if free.is_empty() {
        return Err(AppError::Invalid(
            "every parameter is held with --set: nothing to fit".into(),
        ));
    }
    // All events at once: the windows as rows, a pass per Gauss–Newton iteration.
    let pooled = events;
    let full = fit_subset(&model, pooled, &start, &free, 100)?;
    // The ranking at nominal values, as the thesis ranks: the starting values with the three
    // that start at 0 (and so would have no relative sensitivity) at a typical size — the Wu
    // criterion fits the top K from there (from the full fit, every K would fit alike).
    let nominal = nominal_values(&start, &held);
    let analysis = analyse(&model, pooled, &nominal, &free, IdentConfig::default())?;
    let (k, wu) = cfg.selection.resolve(&model, pooled, &analysis)?;
    let ranking = analysis.ranked(k);
    let mut fitted: Vec<usize> = analysis.top(k).iter().map(|&i| free[i]).collect();
    fitted.sort_unstable();
    if fitted.is_empty() {
        return Err(AppError::Invalid(
            "the identifiability analysis finds no parameter the data resolve".into(),
        ));
    }
    let collinearity = analysis.collinearity(
        &fitted
            .iter()
            .filter_map(|j| free.iter().position(|f| f == j))
            .collect::<Vec<_>>(),
    );
    let dof = rows.saturating_sub(free.len()).max(1);
    let confounded = quantify(
        &full.gram,
        (full.rss / dof as f64).max(f64::MIN_POSITIVE),
        &free.iter().map(|&j| full.theta[j]).collect::<Vec<_>>(),
        rows,
    )
    .ok()
    .map(|q| {
        let mut pairs = Vec::new();
        for a in 0..free.len() {
            for b in a + 1..free.len() {
                let r = q.correlation[(a, b)];
                if r.abs() > 0.95 {
                    pairs.push(Confounded {
                        a: PARAMS[free[a]].into(),
                        b: PARAMS[free[b]].into(),
                        correlation: r,
                    });
                }
            }
        }
        pairs
    });
    // The fitted set on all events, the rest at their starting values: where each event starts.
    let pooled_fit = fit_subset(&model, pooled, &start, &fitted, 100)?;
    let kf = fitted.len();
    let mut info = DMatrix::<f64>::zeros(kf, kf);
    let mut fused: Option<Vec<f64>> = None;
    let mut fused_se = vec![f64::NAN; kf];
    let mut fits = Vec::with_capacity(n_events);
    let mut rss_total = 0.0;
    let mut engine = GradientEngine::new(PARAMS.len());
    let mut g = vec![0.0; kf];
    // The last TDC fitted: its cycle, angles and pressures.
    let mut last = (0_i64, Vec::new(), Vec::new());
    events.each::<AppError>(&mut |e| {
        let (atdc, p) = (e.atdc, e.p);
        let f = fit_subset(&model, &data(atdc, p), &pooled_fit.theta, &fitted, 50)?;
        rss_total += f.rss;
        let n = atdc.len();
        let sigma2 = (f.rss / n.saturating_sub(kf).max(1) as f64).max(f64::MIN_POSITIVE);
        let values: Vec<f64> = fitted.iter().map(|&j| f.theta[j]).collect();
        let Ok(q) = quantify(&f.gram, sigma2, &values, n) else {
            notes.push(format!(
                "the TDC of cycle {} (t = {:.4} s): the fitted parameters' information is singular there; left out",
                e.cycle, e.t_s
            ));
            return Ok(());
        };
        // Recursive Gauss–Newton: the first TDC's own fit, then each TDC linearised at the
        // estimate so far.
        let theta = match fused.take() {
            None => {
                info = q.fim.clone();
                f.theta.clone()
            }
            Some(mut th) => {
                let mut jtj = DMatrix::<f64>::zeros(kf, kf);
                let mut jtr = DVector::<f64>::zeros(kf);
                for (&a, &y) in atdc.iter().zip(p) {
                    let h = engine.value_and_gradient(&model, &[a], &th, &fitted, &mut g);
                    let gv = DVector::from_column_slice(&g);
                    jtj += &gv * gv.transpose();
                    jtr += gv * (y - h);
                }
                info += jtj / sigma2;
                if let Some(ch) = info.clone().cholesky() {
                    let step = ch.solve(&(jtr / sigma2));
                    for (i, &j) in fitted.iter().enumerate() {
                        th[j] += step[i];
                    }
                }
                th
            }
        };
        if let Some(ch) = info.clone().cholesky() {
            let cov = ch.inverse();
            for (i, se) in fused_se.iter_mut().enumerate() {
                *se = cov[(i, i)].sqrt();
            }
        }
        let fused_now: Vec<f64> = fitted.iter().map(|&j| theta[j]).collect();
        fused = Some(theta);
        fits.push(EventFit {
            cycle: e.cycle,
            t_s: e.t_s,
            rpm: e.rpm,
            values,
            std_err: q.std_err.clone(),
            recursive: fused_now,
            recursive_std_err: fused_se.clone(),
            rms_residual: (f.rss / n as f64).sqrt(),
        });
        last.0 = e.cycle;
        last.1.clear();
        last.1.extend_from_slice(atdc);
        last.2.clear();
        last.2.extend_from_slice(p);
        Ok(())
    })?;
    if fused.is_none() {
        return Err(AppError::Invalid(
            "no TDC could be fitted: every event's information is singular".into(),
        ));
    };
    // The estimate: the fit over all the TDCs at once, its intervals from their information.
    let batch_values: Vec<f64> = fitted.iter().map(|&j| pooled_fit.theta[j]).collect();
    let batch = quantify(
        &pooled_fit.gram,
        (pooled_fit.rss / rows.saturating_sub(kf).max(1) as f64).max(f64::MIN_POSITIVE),
        &batch_values,
        rows,
    )?;
    let estimates = (0..PARAMS.len())
        .map(|j| {
            let base = ParamEstimate {
                name: PARAMS[j].into(),
                unit: if UNITS[j] == "P" {
                    unit.clone()
                } else {
                    UNITS[j].into()
                },
                description: DESCRIPTIONS[j].into(),
                status: if held.contains(&j) {
                    "held"
                } else {
                    "unresolved"
                },
                value: start[j],
                std_err: None,
                ci95: None,
                between_events_std_err: None,
            };
            match fitted.iter().position(|&f| f == j) {
                None => base,
                Some(i) => {
                    let v = pooled_fit.theta[j];
                    let per: Vec<f64> = fits.iter().map(|f| f.values[i]).collect();
                    let m = per.len() as f64;
                    let between = (per.len() >= 2).then(|| {
                        let mean = per.iter().sum::<f64>() / m;
                        (per.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (m - 1.0) / m).sqrt()
                    });
                    ParamEstimate {
                        status: "fitted",
                        value: v,
                        std_err: Some(batch.std_err[i]),
                        ci95: Some(batch.ci95[i]),
                        between_events_std_err: between,
                        ..base
                    }
                }
            }
        })
        .collect::<Vec<_>>();
    let theta: Vec<f64> = estimates.iter().map(|e| e.value).collect();
    let (cycle, atdc, measured) = last;
    let trace = Trace {
        cycle,
        fitted: atdc
            .iter()
            .map(|&a| model.eval::<f64>(&[a], &theta))
            .collect(),
        atdc,
        measured,
    };
    let wu_j = wu.map(|(_, j)| j);
    Ok(CompressionFit {
        channel: cfg.channel.clone(),
        unit,
        window_deg: cfg.window_deg,
        start,
        ranking,
        wu_j,
        confounded,
        collinearity,
        fitted: fitted.iter().map(|&j| PARAMS[j].to_string()).collect(),
        peak_deg: peak_angle(&model, &theta),
        estimates,
        events: fits,
        rms_residual: (rss_total / rows as f64).sqrt(),
        trace,
        notes,
    })
}

/// The TDC found on a motored pressure trace ([`tdc_from_pressure`]).
#[derive(Debug, Clone, Serialize)]
pub struct TdcFromPressure {
    /// The crank angle from the sensor's reference to the firing TDC [deg], in [0, 360).
    pub tdc_offset_deg: f64,
    /// Its 95 % interval [deg] (from the fit over all the TDCs).
    pub ci95: (f64, f64),
    /// Where the pressure peaks [deg ATDC] on the fitted trace: before TDC by the loss angle.
    pub peak_deg: Option<f64>,
    /// The fit it came from (on the recording with the TDC where the pressure peaks).
    pub fit: CompressionFit,
}

/// Place the firing TDC from a motored cylinder-pressure trace: decode the raw angle sensor
/// of `opts` with its reference as TDC, move the TDC to where `channel` peaks (the median over
/// the cycles), then fit the motored model there ([`compression_fit`]) — whose `tdc_shift`, fitted
/// with the loss rate, is where the true TDC lies: `offset = peak + tdc_shift`, not the peak (the
/// peak comes early by the thermodynamic loss angle). Which revolution fires comes from
/// `opts`' `phase_from`, or from `channel` when none is given. [`tdc_from_pressure_in`] on the
/// recording held whole.
pub fn tdc_from_pressure(
    rec: &Recording,
    opts: &crate::acquisition::AcquisitionOptions,
    cfg: &CompressionConfig,
    step_deg: f64,
) -> Result<TdcFromPressure, AppError> {
    use crate::acquisition::to_crank_angle_decoded;
    let read = |o: &crate::acquisition::AcquisitionOptions,
                visit: &mut dyn FnMut(&Recording) -> Result<(), AppError>| {
        visit(&to_crank_angle_decoded(rec, o, step_deg)?.0)
    };
    tdc_from_pressure_in(&read, opts, cfg, step_deg, usize::MAX)
}

/// One pass over a time-basis recording put on a crank-angle basis with the options given:
/// every chunk to `visit`.
pub type CrankRead<'r> = dyn Fn(
        &crate::acquisition::AcquisitionOptions,
        &mut dyn FnMut(&Recording) -> Result<(), AppError>,
    ) -> Result<(), AppError>
    + 'r;

/// [`tdc_from_pressure`] on a recording read in passes — `read` puts it on a crank-angle basis
/// (every `step_deg`) with the options given, a chunk at a time: a pass for the pressure's peak
/// in every cycle ([`PeakAngles`]), then the motored fit's passes over the TDCs' windows, held
/// when they take at most `hold_bytes` ([`TdcEvents`]).
pub fn tdc_from_pressure_in(
    read: &CrankRead,
    opts: &crate::acquisition::AcquisitionOptions,
    cfg: &CompressionConfig,
    step_deg: f64,
    hold_bytes: usize,
) -> Result<TdcFromPressure, AppError> {
    cfg.validate()?;
    let Some(spec) = &opts.sensor else {
        return Err(AppError::Invalid(format!(
            "--tdc-from {}: the TDC is placed on a raw angle sensor's reference: give --wheel or --quadrature",
            cfg.channel
        )));
    };
    let mut opts = opts.clone();
    let mut spec = spec.clone();
    spec.tdc_offset_deg = 0.0;
    spec.phase_from.get_or_insert_with(|| cfg.channel.clone());
    opts.sensor = Some(spec.clone());
    // 1. The peak's angle after the reference, the median over the complete cycles.
    let mut peaks = PeakAngles::new(&cfg.channel, step_deg);
    read(&opts, &mut |chunk| peaks.push(chunk))?;
    let peak = peaks.finish()?;
    // 2. The model fitted with the TDC at the peak.
    spec.tdc_offset_deg = peak;
    opts.sensor = Some(spec);
    struct Passes<'r> {
        read: &'r CrankRead<'r>,
        opts: crate::acquisition::AcquisitionOptions,
    }
    impl CrankPasses for Passes<'_> {
        fn chunks(
            &self,
            visit: &mut dyn FnMut(&Recording) -> Result<(), AppError>,
        ) -> Result<(), AppError> {
            (self.read)(&self.opts, visit)
        }
    }
    let passes = Passes { read, opts };
    let events = TdcEvents::new(&passes, &cfg.channel, cfg.window_deg, hold_bytes);
    let fit = compression_fit_events(&events, cfg)?;
    let tdc = fit
        .get("tdc_shift")
        .filter(|e| e.status == "fitted")
        .cloned()
        .ok_or_else(|| {
            AppError::Invalid(format!(
                "--tdc-from {}: the pressure trace does not resolve the TDC (the identifiability analysis left it out: ranking {})",
                cfg.channel,
                fit.ranking
                    .iter()
                    .map(|r| r.param.as_str())
                    .collect::<Vec<_>>()
                    .join(" > ")
            ))
        })?;
    let (lo, hi) = tdc.ci95.unwrap_or((tdc.value, tdc.value));
    let offset = peak + tdc.value;
    let wrap = offset.rem_euclid(360.0) - offset;
    Ok(TdcFromPressure {
        tdc_offset_deg: offset + wrap,
        ci95: (peak + lo + wrap, peak + hi + wrap),
        peak_deg: fit.peak_deg,
        fit,
    })
}

/// The angle [deg after the reference] where a channel peaks in every complete cycle of a
/// crank-angle recording (`720/step` samples, cycle ≥ 0; the last of equal peaks), a chunk at a
/// time; the median of them, unwrapped around the first so that peaks either side of 0°/720°
/// agree, modulo 360° ([`tdc_from_pressure`]'s first step). Holds a number per cycle.
#[derive(Debug, Clone)]
pub struct PeakAngles {
    channel: String,
    per: usize,
    /// The cycle being gone over.
    run: Option<CycleRun>,
    peaks: Vec<f64>,
}

/// A cycle as [`PeakAngles`] goes over it: its number, samples, and its highest finite sample's
/// value and angle.
#[derive(Debug, Clone, Copy)]
struct CycleRun {
    cycle: f64,
    samples: usize,
    best: Option<(f64, f64)>,
}

impl PeakAngles {
    /// The peaks of `channel` on a recording of a sample every `step_deg`.
    pub fn new(channel: &str, step_deg: f64) -> Self {
        Self {
            channel: channel.to_string(),
            per: (720.0 / step_deg).round() as usize,
            run: None,
            peaks: Vec::new(),
        }
    }

    /// The next chunk (`cycle`, `crank_deg` and the channel).
    pub fn push(&mut self, chunk: &Recording) -> Result<(), AppError> {
        let (cycle, deg) = (chunk.values("cycle")?, chunk.values("crank_deg")?);
        let p = chunk.values(&self.channel)?;
        for i in 0..cycle.len() {
            match &mut self.run {
                Some(r) if r.cycle == cycle[i] => {
                    r.samples += 1;
                    if p[i].is_finite() && r.best.is_none_or(|(b, _)| p[i].total_cmp(&b).is_ge()) {
                        r.best = Some((p[i], deg[i]));
                    }
                }
                _ => {
                    self.close();
                    self.run = Some(CycleRun {
                        cycle: cycle[i],
                        samples: 1,
                        best: p[i].is_finite().then_some((p[i], deg[i])),
                    });
                }
            }
        }
        Ok(())
    }

    /// The cycle gone over: its peak, when it is complete.
    fn close(&mut self) {
        if let Some(CycleRun {
            cycle,
            samples,
            best: Some((_, at)),
        }) = self.run.take()
        {
            if cycle >= 0.0 && samples == self.per {
                self.peaks.push(at);
            }
        }
    }

    /// The median peak angle [deg], in [0, 360).
    pub fn finish(mut self) -> Result<f64, AppError> {
        self.close();
        let peaks = &mut self.peaks;
        if peaks.is_empty() {
            return Err(AppError::Invalid(format!(
                "--tdc-from {}: no complete cycle to find the pressure's peak in",
                self.channel
            )));
        }
        let first = peaks[0];
        for x in peaks.iter_mut() {
            *x = first + (*x - first + 360.0).rem_euclid(720.0) - 360.0;
        }
        peaks.sort_unstable_by(f64::total_cmp);
        Ok(peaks[peaks.len() / 2].rem_euclid(360.0))
    }
}
