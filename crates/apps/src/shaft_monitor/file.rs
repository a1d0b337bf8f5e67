//! The file verb: a recording (in memory or read a chunk at a time) through the stage, its
//! rate and time basis checked, its tracks kept within a bound ([`monitor_shaft`],
//! [`monitor_shaft_tracked`]).

use super::*;

/// The channels the monitor reads: its inputs, then the simulated truth when the recording
/// carries it.
pub const SHAFT_CHANNELS: [&str; 6] = [
    "t",
    "theta_dy",
    "theta_en",
    "omega_dy",
    "omega_en",
    "torque_shaft",
];
/// The true K and B of a simulated recording (optional).
pub const SHAFT_TRUTH: [&str; 2] = ["true_shaft_k", "true_shaft_b"];

/// Estimator samples kept in a [`ShaftMonitor`]'s tracks: beyond this, every other one is
/// dropped (the tracks' step doubles), so a long recording's tracks take bounded memory
/// (2¹⁷ samples: 65 s at the default 2 kHz in full). The alarms, the NMSE, the ±5 % times and
/// the frozen time are taken on every sample all the same.
pub const TRACK_MAX: usize = 1 << 17;

/// Run the monitor on a time-basis recording with `theta_dy`, `theta_en`, `omega_dy`,
/// `omega_en`, `torque_shaft` and `t` (and `true_shaft_k`/`true_shaft_b` if simulated).
///
/// A crank-angle recording (one sample per crank step, so its time step follows the speed) is
/// first resampled to a uniform time basis at its mean sample rate.
pub fn monitor_shaft(rec: &Recording, cfg: &MonitorConfig) -> Result<ShaftMonitor, AppError> {
    let resampled = on_time_basis(rec)?;
    let rec = resampled.as_ref().unwrap_or(rec);
    let n = rec.len();
    let chunks = (0..n.max(1))
        .step_by(FILE_CHUNK)
        .map(|start| Ok::<_, AppError>(rec.slice(start..start + FILE_CHUNK)));
    monitor_shaft_stream(chunks, cfg)
}

/// The monitor over a stream of time-basis chunks (a file read as it comes,
/// `physid_io::ChunkReader`): the stage the live service runs, with what the file verb reports
/// accumulated as the samples pass — memory bounded however long the stream ([`TRACK_MAX`]).
/// The sample rate is the mean step of the first [`NOMINAL_SAMPLES`] samples (held until they
/// have come, however the stream is chunked); every step is held to it within 0.1 %.
pub fn monitor_shaft_stream<E>(
    chunks: impl IntoIterator<Item = Result<Recording, E>>,
    cfg: &MonitorConfig,
) -> Result<ShaftMonitor, AppError>
where
    AppError: From<E>,
{
    monitor_shaft_tracked(chunks, cfg, &mut |_, _| Ok(()))
}

/// What a [`monitor_shaft_tracked`] run hands on as it goes: the estimator samples just taken
/// (every one, not thinned) and the alarms raised so far; an `Err` stops the run with it.
pub type ShaftSink<'a> = dyn FnMut(&[ShaftSample], &[ShaftAlarm]) -> Result<(), String> + 'a;

/// [`monitor_shaft_stream`], every estimator sample handed to `sink` as it is taken (the
/// tracks written to a file as they come: `monitor shaft --tracks`).
pub fn monitor_shaft_tracked<E>(
    chunks: impl IntoIterator<Item = Result<Recording, E>>,
    cfg: &MonitorConfig,
    sink: &mut ShaftSink,
) -> Result<ShaftMonitor, AppError>
where
    AppError: From<E>,
{
    let mut chunks = chunks.into_iter();
    // The first samples, enough to know the rate.
    let mut first: Option<Recording> = None;
    while first.as_ref().map_or(0, Recording::len) < NOMINAL_SAMPLES {
        let Some(next) = chunks.next() else {
            break;
        };
        let next = next?;
        first = Some(match first.take() {
            None => next,
            Some(mut f) => {
                f.append(&next)?;
                f
            }
        });
    }
    let first = first.unwrap_or_else(|| Recording::new(Basis::Time));
    let t = ShaftInputs::of(&first)?.t;
    if t.len() < 100 {
        return Err(AppError::Invalid(format!(
            "{} samples: the monitor needs at least 100",
            t.len()
        )));
    }
    let dt = uniform_step(&t[..t.len().min(NOMINAL_SAMPLES)])?;
    let mut acc = Accumulated::new(cfg, t[0], dt)?;
    acc.push(&first, sink)?;
    for chunk in chunks {
        acc.push(&chunk?, sink)?;
    }
    acc.finish(sink)
}

/// Whether an estimate has stayed within ±5 % of the truth, as the samples pass.
#[derive(Debug, Clone, Copy)]
enum Within {
    /// Never outside so far.
    Always,
    /// Outside at the last sample.
    Out,
    /// Inside since this time [s].
    Since(f64),
}

impl Within {
    fn step(self, t: f64, inside: bool) -> Self {
        match (self, inside) {
            (_, false) => Self::Out,
            (Self::Out, true) => Self::Since(t),
            (s, true) => s,
        }
    }

    fn time(self, t_first: f64) -> Option<f64> {
        match self {
            Self::Always => Some(t_first),
            Self::Out => None,
            Self::Since(t) => Some(t),
        }
    }
}

/// The file verb's view of a stage's samples, accumulated as they pass.
struct Accumulated {
    cfg: MonitorConfig,
    stage: ShaftStage,
    t0: f64,
    /// The step held to the first chunks' rate.
    steps: StepCheck,
    /// Input samples seen.
    seen: usize,
    samples: Vec<ShaftSample>,
    alarms: Vec<ShaftAlarm>,
    out: ShaftMonitor,
    /// Estimator samples taken; one in `stride` is kept in the tracks.
    taken: usize,
    stride: usize,
    /// Truth of the input samples not yet reached by the stage's output: `(first index, K, B)`.
    truth: Option<(usize, VecDeque<(f64, f64)>)>,
    /// Sums for the NMSE (Eq. 6.4) after settling: n, Σ(y−ŷ)², Σy, Σŷ per parameter.
    sums: [(f64, f64, f64, f64); 2],
    within: [Within; 2],
    t_first: Option<f64>,
    frozen_count: [usize; 2],
    /// Each angle and its speed, checked as they pass (from the first chunk).
    speed_angle: Option<Vec<SpeedAngle>>,
}

impl Accumulated {
    fn new(cfg: &MonitorConfig, t0: f64, dt: f64) -> Result<Self, AppError> {
        let stage = ShaftStage::new(cfg, 1.0 / dt)?;
        Ok(Self {
            cfg: cfg.clone(),
            t0,
            steps: StepCheck::new(dt),
            seen: 0,
            samples: Vec::with_capacity(FILE_CHUNK),
            alarms: Vec::new(),
            out: ShaftMonitor {
                method: cfg.method.name(),
                input_rate_hz: 1.0 / dt,
                lowpass_hz: stage.filters.is_some().then_some(cfg.cutoff_hz),
                every: stage.every,
                t: Vec::new(),
                k: Vec::new(),
                b: Vec::new(),
                tau0: Vec::new(),
                std_err: Vec::new(),
                final_estimate: cfg.theta0,
                final_std_err: cfg.theta0,
                unresolved: Vec::new(),
                warnings: Vec::new(),
                alarms: Vec::new(),
                truth: None,
                nmse: None,
                within_5pct_s: None,
                frozen_s: None,
                frozen: Vec::new(),
            },
            stage,
            taken: 0,
            stride: 1,
            truth: None,
            sums: [(0.0, 0.0, 0.0, 0.0); 2],
            within: [Within::Always; 2],
            t_first: None,
            frozen_count: [0; 2],
            speed_angle: None,
        })
    }

    fn push(&mut self, chunk: &Recording, sink: &mut ShaftSink) -> Result<(), AppError> {
        let x = ShaftInputs::of(chunk)?;
        for p in self
            .speed_angle
            .get_or_insert_with(|| SpeedAngle::pairs(chunk, &[]))
        {
            p.push(chunk);
        }
        // The step held to the first chunks' rate, across chunk boundaries too.
        self.steps.check(x.t)?;
        if let (Ok(tk), Ok(tb)) = (chunk.values(SHAFT_TRUTH[0]), chunk.values(SHAFT_TRUTH[1])) {
            let (_, q) = self
                .truth
                .get_or_insert_with(|| (self.seen, VecDeque::new()));
            q.extend(tk.iter().copied().zip(tb.iter().copied()));
        }
        self.seen += x.t.len();
        self.stage
            .push_inputs(&x, &mut self.samples, &mut self.alarms)?;
        sink(&self.samples, &self.alarms).map_err(AppError::Invalid)?;
        self.take();
        Ok(())
    }

    /// The stage's new samples into the tracks and sums.
    fn take(&mut self) {
        let samples = std::mem::take(&mut self.samples);
        for s in &samples {
            self.t_first.get_or_insert(s.t_s);
            for j in 0..2 {
                if s.frozen[j] {
                    self.frozen_count[j] += 1;
                }
            }
            let truth = self.truth.as_mut().and_then(|(base, q)| {
                while *base < s.index && !q.is_empty() {
                    q.pop_front();
                    *base += 1;
                }
                q.front().copied().filter(|_| *base == s.index)
            });
            if let Some((k, b)) = truth {
                let est = [s.estimate.k, s.estimate.b];
                for (j, truth) in [k, b].into_iter().enumerate() {
                    let outside = ((est[j] - truth) / truth).abs() > 0.05;
                    self.within[j] = self.within[j].step(s.t_s, !outside);
                    if s.t_s - self.t0 >= self.cfg.settle_s {
                        let m = &mut self.sums[j];
                        m.0 += 1.0;
                        m.1 += (truth - est[j]) * (truth - est[j]);
                        m.2 += truth;
                        m.3 += est[j];
                    }
                }
            }
            if self.taken.is_multiple_of(self.stride) {
                let o = &mut self.out;
                o.t.push(s.t_s);
                o.k.push(s.estimate.k);
                o.b.push(s.estimate.b);
                o.tau0.push(s.estimate.tau0);
                o.std_err.push([s.std_err.k, s.std_err.b]);
                if self.cfg.supervise {
                    o.frozen.push(s.frozen);
                }
                if let Some((k, b)) = truth {
                    let (tk, tb) = o.truth.get_or_insert_with(Default::default);
                    tk.push(k);
                    tb.push(b);
                }
                if o.t.len() > TRACK_MAX {
                    self.thin();
                }
            }
            self.taken += 1;
        }
        self.samples = samples;
        self.samples.clear();
    }

    /// Every other sample of the tracks dropped; the step doubles.
    fn thin(&mut self) {
        use crate::halve;
        let o = &mut self.out;
        halve(&mut o.t);
        halve(&mut o.k);
        halve(&mut o.b);
        halve(&mut o.tau0);
        halve(&mut o.std_err);
        halve(&mut o.frozen);
        if let Some((tk, tb)) = &mut o.truth {
            halve(tk);
            halve(tb);
        }
        self.stride *= 2;
    }

    fn finish(mut self, sink: &mut ShaftSink) -> Result<ShaftMonitor, AppError> {
        self.stage
            .finish_into(&mut self.samples, &mut self.alarms)?;
        sink(&self.samples, &self.alarms).map_err(AppError::Invalid)?;
        self.take();
        let mut out = self.out;
        out.final_estimate = self.stage.estimate();
        out.final_std_err = self.stage.std_err();
        let resolved = self.stage.resolved();
        for ((name, r), se) in ["K", "B", "tau0"].into_iter().zip(resolved).zip([
            &mut out.final_std_err.k,
            &mut out.final_std_err.b,
            &mut out.final_std_err.tau0,
        ]) {
            if !r {
                out.unresolved.push(name);
                *se = f64::NAN;
            }
        }
        out.alarms = self.alarms;
        out.warnings = self
            .speed_angle
            .iter()
            .flatten()
            .filter_map(SpeedAngle::finding)
            .chain(self.stage.glitch_findings())
            .collect();
        if self.cfg.supervise {
            let step = 1.0 / self.cfg.rate_hz;
            out.frozen_s = Some(PerParam {
                k: self.frozen_count[0] as f64 * step,
                b: self.frozen_count[1] as f64 * step,
            });
        }
        if out.truth.is_some() {
            // NMSE (Eq. 6.4) of each track against the truth after settling.
            let nmse = |(n, sq, y, p): (f64, f64, f64, f64)| {
                let den = (y / n) * (p / n);
                if n > 0.0 && den != 0.0 {
                    (sq / n) / den
                } else {
                    f64::NAN
                }
            };
            out.nmse = Some(PerParam {
                k: nmse(self.sums[0]),
                b: nmse(self.sums[1]),
            });
            let t_first = self.t_first.unwrap_or(self.t0);
            out.within_5pct_s = Some([self.within[0].time(t_first), self.within[1].time(t_first)]);
        }
        Ok(out)
    }
}
