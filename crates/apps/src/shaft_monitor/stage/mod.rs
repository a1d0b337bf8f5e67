//! The shaft monitor as a stream stage ([`ShaftStage`]): chunks of samples in, the estimator's
//! samples and the alarms out — what the file verb and the live service both run.

mod input;

use super::dropout::Dropouts;
use super::*;
pub use input::*;
use input::{default_gates, GATED, STILL};

/// One estimator sample of the monitor.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct ShaftSample {
    /// The input sample it was taken at (0 = the stream's first).
    pub index: usize,
    /// Its time [s].
    pub t_s: f64,
    /// K, B, τ0 after it.
    pub estimate: ShaftParams,
    /// Standard errors of K and B (NaN before they can be estimated).
    pub std_err: PerParam,
    /// Whether K, B and τ0 are frozen by the excitation supervisor: reported once the estimator
    /// has held one frozen (or free) for [`FREEZE_HOLD_S`] without a break; all three while
    /// the estimator is held (standstill, a sensor's glitch: [`StepGate`]).
    pub frozen: [bool; 3],
}

/// Below this engine speed [rad/s] (300 rpm, well under any test's operating point) the
/// engine is taken as stopping or standing still: the
/// estimator and the alarm detector are held (every parameter reported frozen) until it turns
/// again — a stopped cell raises no alarm and does not wind the estimator's covariance up.
pub const STANDSTILL_RAD_S: f64 = 300.0 * std::f64::consts::PI / 30.0;

/// The shaft monitor as a stage: chunks of samples in, estimator samples and alarms out, the
/// zero-phase low-pass done on the stream ([`ZeroPhaseStream`]). The file verb
/// ([`monitor_shaft`]) and the live service run this same code; its output does not depend on
/// how the input is chunked, and a sample's estimate leaves [`latency`](Self::latency) samples
/// after it arrived at the most. Allocation-free per sample once the output vectors have room.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct ShaftStage {
    cfg: MonitorConfig,
    pub(super) every: usize,
    pub(super) filters: Option<Box<[ZeroPhaseStream; 3]>>,
    /// Times of the inputs not yet out of the filters.
    times: VecDeque<f64>,
    /// The engine's speed [rad/s] at those times (the standstill hold).
    #[serde(default)]
    speeds: VecDeque<f64>,
    t0: Option<f64>,
    /// Index of the next filtered sample.
    next: usize,
    est: LinearEstimator,
    /// The excitation supervisor's steering of `est` (`--supervise`).
    steering: Option<Steering>,
    det: RelativeErrorDetector,
    /// Times of the detector's last samples (an alarm's onset is at most a dwell back).
    det_times: VecDeque<f64>,
    /// The reported frozen state, and since when the estimator's has differed from it.
    held: [bool; 3],
    differs_since: [Option<f64>; 3],
    model: Shaft,
    /// The steps no shaft makes, taken out of the twist, the relative speed and the torque.
    #[serde(default = "default_gates")]
    gates: [StepGate; 3],
    /// The engine's and the dynamometer's angle sensors, checked for a stop while they turn.
    #[serde(default)]
    still: [StillAngle; 2],
    /// The engine's and the dynamometer's speed sensors, checked for a freeze while their
    /// shafts move.
    #[serde(default)]
    stuck: [StuckSpeed; 2],
    /// The inputs' step [s] (0 in a checkpoint from before: no stop is found).
    #[serde(default)]
    dt: f64,
    /// Whether each input not yet out of the filters is held for a glitch: the samples the
    /// gates held and `guard` on either side (the low-pass's lookahead, which spreads them).
    #[serde(default)]
    suspect: VecDeque<bool>,
    #[serde(default)]
    guard: usize,
    /// Inputs still to be held after the last one the gates held.
    #[serde(default)]
    quarantine: usize,
    /// The samples of the chunk the gates held, and those where an angle stood still.
    #[serde(skip)]
    held_raw: Vec<bool>,
    #[serde(skip)]
    still_raw: Vec<bool>,
    /// The samples of the chunk where a speed stood frozen.
    #[serde(skip)]
    stuck_raw: Vec<bool>,
    raw: [Vec<f64>; 3],
    filtered: [Vec<f64>; 3],
    /// The glitches taken out of the last chunk.
    #[serde(skip)]
    glitches: Vec<ShaftGlitch>,
    /// The signals' dropouts (samples not finite), held at their last values.
    #[serde(default)]
    dropouts: Dropouts,
    /// What a chunk completes, before it goes to a [`Sink`] ([`Stage::push`]).
    #[serde(skip)]
    made: (Vec<ShaftSample>, Vec<ShaftAlarm>),
    /// Built for [`push_regressors`](Self::push_regressors) alone: the torque is not filtered.
    #[serde(skip)]
    regressors_only: bool,
}

impl ShaftStage {
    /// A stage for inputs at `rate_hz` [Hz].
    pub fn new(cfg: &MonitorConfig, rate_hz: f64) -> Result<Self, AppError> {
        Self::with_blocks(cfg, rate_hz, 4)
    }

    /// A stage for [`push_regressors`](Self::push_regressors) alone, where latency does not
    /// matter: the low-pass's backward pass in blocks of its whole lookahead (2 passes per
    /// sample instead of 5). Its regressors equal [`new`](Self::new)'s to the stream filter's
    /// truncation, ≈ 1e-13 of the signal ([`ZeroPhaseStream`]).
    pub fn for_regressors(cfg: &MonitorConfig, rate_hz: f64) -> Result<Self, AppError> {
        let mut s = Self::with_blocks(cfg, rate_hz, 1)?;
        s.regressors_only = true;
        Ok(s)
    }

    /// The low-pass's backward blocks a `per_lookahead`-th of its lookahead.
    fn with_blocks(
        cfg: &MonitorConfig,
        rate_hz: f64,
        per_lookahead: usize,
    ) -> Result<Self, AppError> {
        if !(rate_hz.is_finite() && rate_hz > 0.0) {
            return Err(AppError::Invalid(format!(
                "sample rate {rate_hz} Hz: expected > 0"
            )));
        }
        // The filters, and how far they spread a sample (their lookahead).
        let (filters, guard) = if let Some(sos) = lowpass(cfg, rate_hz)? {
            // Blocks of a quarter of the lookahead: the latency is 1.25 lookaheads (34 ms for
            // the default 500 Hz at 10 kHz) for 5 backward passes per sample instead of 2.
            let lookahead = settling_length(&sos);
            let block = (lookahead / per_lookahead).max(1);
            let f = ZeroPhaseStream::new(&sos, Some(lookahead), Some(block));
            (Some(Box::new([f.clone(), f.clone(), f])), lookahead)
        } else {
            (None, 0)
        };
        let t0 = cfg.theta0;
        let params = ParamSet::new(["K", "B", "tau0"], vec![t0.k, t0.b, t0.tau0])
            .map_err(|e| AppError::Invalid(e.to_string()))?;
        // Vector forgetting forgets K and B, not the offset, in its symmetric form.
        let spec = EstimatorSpec {
            lambda: cfg.lambda,
            lambdas: Some(vec![cfg.lambda, cfg.lambda, 1.0]),
            vf_variant: VfVariant::Symmetric,
            p0: CovSpec::Scaled(cfg.p0),
            ..EstimatorSpec::new(cfg.method.method())
        };
        let est = build_linear(&spec, &params, &params.all_free())
            .map_err(AppError::estim("estimator configuration"))?;
        let steering = if cfg.supervise {
            // The estimator's own memory (λ): what it forgets, the ranking forgets; rows scaled
            // by the healthy values.
            let sup = SupervisorConfig::for_lambda(cfg.lambda);
            let scale = vec![
                cfg.healthy.k.abs().max(1e-12),
                cfg.healthy.b.abs().max(1e-12),
                1.0,
            ];
            let s = Steering::new(&est, scale, sup)
                .map_err(|e| AppError::Invalid(format!("excitation supervisor: {e}")))?;
            Some(s)
        } else {
            None
        };
        let dwell = cfg.dwell.max(1);
        let det = RelativeErrorDetector::new(
            vec!["K".into(), "B".into()],
            vec![cfg.healthy.k, cfg.healthy.b],
            vec![cfg.bound, cfg.bound],
            dwell,
        )
        .map_err(AppError::estim("detector configuration"))?;
        let latency = filters.as_ref().map_or(0, |f| f[0].latency());
        Ok(Self {
            every: ((rate_hz / cfg.rate_hz).round() as usize).max(1),
            cfg: cfg.clone(),
            filters,
            times: VecDeque::with_capacity(latency + FILE_CHUNK),
            speeds: VecDeque::with_capacity(latency + FILE_CHUNK),
            t0: None,
            next: 0,
            est,
            steering,
            det,
            // Room for a usual dwell (the default's 200 samples); a longer one grows with the
            // data (a dwell of 1e12 samples must not ask for 8 TB up front).
            det_times: VecDeque::with_capacity(dwell.min(4096) as usize + 1),
            held: [false; 3],
            differs_since: [None; 3],
            model: Shaft::new(true),
            gates: {
                let hold = (MAX_HOLD_S * rate_hz).round().max(1.0) as usize;
                [
                    StepGate::twist(hold),
                    StepGate::slip(hold),
                    StepGate::torque(cfg.healthy.k, cfg.healthy.b, hold),
                ]
            },
            still: Default::default(),
            stuck: Default::default(),
            dt: 1.0 / rate_hz,
            suspect: VecDeque::with_capacity(latency + FILE_CHUNK),
            guard,
            quarantine: 0,
            held_raw: Vec::new(),
            still_raw: Vec::new(),
            stuck_raw: Vec::new(),
            glitches: Vec::new(),
            dropouts: Dropouts::default(),
            raw: Default::default(),
            filtered: Default::default(),
            made: Default::default(),
            regressors_only: false,
        })
    }

    /// The reported frozen state at time `t` (see [`ShaftSample::frozen`]).
    fn held(&mut self, t: f64) -> [bool; 3] {
        // Whether K, B and τ0 are frozen now.
        let mut now = [false; 3];
        if let Some(s) = &self.steering {
            for (f, a) in now.iter_mut().zip(s.active()) {
                *f = !a;
            }
        }
        for ((held, since), now) in self.held.iter_mut().zip(&mut self.differs_since).zip(now) {
            if now == *held {
                *since = None;
            } else if t - *since.get_or_insert(t) >= FREEZE_HOLD_S {
                *held = now;
                *since = None;
            }
        }
        self.held
    }

    /// One estimator sample, `at` the input sample it was taken at; steered when supervised.
    fn update(&mut self, phi: &[f64], y: f64, at: usize) -> Result<(), AppError> {
        let estim = |source| AppError::Estim {
            at: format!("sample {at}"),
            source,
        };
        match &mut self.steering {
            None => self.est.update(phi, y).map(|_| ()).map_err(estim),
            Some(s) => s
                .update(&mut self.est, phi, y)
                .map(|_| ())
                .map_err(|e| match e {
                    SupervisorError::Estim(source) => estim(source),
                    SupervisorError::Ident(e) => AppError::Invalid(format!("sample {at}: {e}")),
                }),
        }
    }

    /// The most input samples between a sample's arrival and its estimate: the low-pass's
    /// block and lookahead ([`ZeroPhaseStream::latency`]), 0 without a low-pass.
    pub fn latency(&self) -> usize {
        self.filters.as_ref().map_or(0, |f| f[0].latency())
    }

    /// The current K, B, τ0 (a frozen one at its value when it was frozen).
    pub fn estimate(&self) -> ShaftParams {
        let e = &self.est;
        let mut th = [0.0; 3];
        th.copy_from_slice(e.params().nominal());
        e.free_set().scatter(e.estimate(), &mut th);
        ShaftParams {
            k: th[0],
            b: th[1],
            tau0: th[2],
        }
    }

    /// Whether the data have resolved K, B and τ0 so far: the variance of each free one has
    /// at least halved from P0 ([`physid_estim::resolution`]); a frozen one keeps its value.
    /// Data of no information (every shaft channel scaled by 1e-300: φφᵀ underflows) leave
    /// the estimates at their start, which is no finding about the shaft. Allocation-free.
    pub fn resolved(&self) -> [bool; 3] {
        let e = &self.est;
        let mut r = [true; 3];
        for (k, &i) in e.free_set().free().iter().enumerate() {
            r[i] = e.variance_ratio(k) < physid_estim::resolution::MAX_VARIANCE_RATIO;
        }
        r
    }

    /// Their standard errors (NaN before they can be estimated, and while frozen).
    pub fn std_err(&self) -> ShaftParams {
        let e = &self.est;
        let n = e.free_set().free().len();
        let mut free = [0.0; 3];
        let mut se = [f64::NAN; 3];
        if e.std_errors_into(&mut free[..n]).is_ok() {
            e.free_set().scatter(&free[..n], &mut se);
        }
        ShaftParams {
            k: se[0],
            b: se[1],
            tau0: se[2],
        }
    }

    /// The angle sensors found stopped ([`StillAngle`]), the speed sensors found frozen
    /// ([`StuckSpeed`]) and what was taken out of the twist, the relative speed and the torque
    /// as a sensor's glitch ([`StepGate`]), for a person.
    pub fn glitch_findings(&self) -> impl Iterator<Item = String> + '_ {
        let still = self
            .still
            .iter()
            .zip(STILL)
            .filter_map(|(s, (angle, speed))| s.finding(angle, speed));
        let steps = self
            .gates
            .iter()
            .zip(GATED)
            .filter_map(|(g, (what, unit))| g.finding(what, unit));
        let stuck = self
            .stuck
            .iter()
            .zip(STILL)
            .filter_map(|(s, (angle, speed))| s.finding(speed, angle));
        still
            .chain(stuck)
            .chain(steps)
            .chain(self.dropouts.findings())
    }

    /// Take a chunk; append the estimator samples and alarms it completes. A chunk with
    /// columns of different lengths or a time that is not finite is refused, naming the
    /// sample; a signal's sample that is not a number is held as a dropout ([`Dropouts`]).
    pub fn push_inputs(
        &mut self,
        x: &ShaftInputs,
        samples: &mut Vec<ShaftSample>,
        alarms: &mut Vec<ShaftAlarm>,
    ) -> Result<(), AppError> {
        self.filter_chunk(x)?;
        self.consume(samples, alarms)
    }

    /// Take a chunk and append the estimator's regressors `φ = [Δθ, Δω, 1]` it completes,
    /// with their times — what [`push_inputs`](Self::push_inputs) would update the estimator
    /// with, the samples held (standstill, a sensor's glitch) left out; no estimator runs (an
    /// experiment design's information, `crate::design`). On a stage built by
    /// [`for_regressors`](Self::for_regressors), whose push_inputs would not have the torque.
    pub fn push_regressors(
        &mut self,
        x: &ShaftInputs,
        rows: &mut Vec<RegressorRow>,
    ) -> Result<(), AppError> {
        self.filter_chunk(x)?;
        self.regressors(rows);
        Ok(())
    }

    /// The end of the stream for [`push_regressors`](Self::push_regressors).
    pub fn finish_regressors(&mut self, rows: &mut Vec<RegressorRow>) -> Result<(), AppError> {
        self.flush_filters()?;
        self.regressors(rows);
        Ok(())
    }

    /// The regressors of the filtered samples on the estimator's grid.
    fn regressors(&mut self, rows: &mut Vec<RegressorRow>) {
        let mut phi = [0.0; 3];
        for k in 0..self.filtered[0].len() {
            let Some((_, t, hold)) = self.on_grid() else {
                continue;
            };
            if !hold {
                let [dth, dw, _] = &self.filtered;
                self.model.regressor(&[dth[k], 0.0, dw[k], 0.0], &mut phi);
                rows.push(RegressorRow { t_s: t, phi });
            }
        }
    }

    /// The end of the stream: the last samples out of the filters.
    pub fn finish_into(
        &mut self,
        samples: &mut Vec<ShaftSample>,
        alarms: &mut Vec<ShaftAlarm>,
    ) -> Result<(), AppError> {
        self.flush_filters()?;
        self.consume(samples, alarms)
    }

    /// Estimator updates at the filtered samples on the estimator's grid.
    fn consume(
        &mut self,
        samples: &mut Vec<ShaftSample>,
        alarms: &mut Vec<ShaftAlarm>,
    ) -> Result<(), AppError> {
        let mut phi = [0.0; 3];
        let t0 = self.t0.unwrap_or(0.0);
        for k in 0..self.filtered[0].len() {
            let Some((i, t, hold)) = self.on_grid() else {
                continue;
            };
            if !hold {
                let [dth, dw, tq] = &self.filtered;
                self.model.regressor(&[dth[k], 0.0, dw[k], 0.0], &mut phi);
                self.update(&phi, tq[k], i)?;
            }
            let (estimate, se) = (self.estimate(), self.std_err());
            samples.push(ShaftSample {
                index: i,
                t_s: t,
                estimate,
                std_err: PerParam { k: se.k, b: se.b },
                frozen: if hold { [true; 3] } else { self.held(t) },
            });
            // The detector waits for data that resolve K and B (an unresolved estimate is its
            // starting value, not the shaft's).
            let [rk, rb, _] = self.resolved();
            if !hold && t - t0 >= self.cfg.settle_s && rk && rb {
                if self.det_times.len() > self.cfg.dwell.max(1) as usize {
                    self.det_times.pop_front();
                }
                self.det_times.push_back(t);
                let before = self.det.alarms().len();
                self.det
                    .update(&[estimate.k, estimate.b])
                    .map_err(|e| AppError::Estim {
                        at: format!("sample {i}"),
                        source: e,
                    })?;
                for a in &self.det.alarms()[before..] {
                    let back = (a.raised_sample - a.onset_sample) as usize;
                    let at = self.det_times.len() - 1;
                    alarms.push(ShaftAlarm {
                        param: a.name.clone(),
                        t_start_s: self.det_times[at.saturating_sub(back)],
                        t_raised_s: t,
                        relative_error: a.relative_error,
                        change: -a.relative_error,
                    });
                }
            }
        }
        Ok(())
    }
}

/// One estimator update's data ([`ShaftStage::push_regressors`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegressorRow {
    /// Time [s].
    pub t_s: f64,
    /// `[Δθ, Δω, 1]` filtered (Eq. 6.1's regressor).
    pub phi: [f64; 3],
}

/// What the shaft monitor makes.
#[derive(Debug, Clone, PartialEq)]
pub enum ShaftOutput {
    /// An estimator sample.
    Sample(ShaftSample),
    /// An alarm raised.
    Alarm(ShaftAlarm),
    /// A sensor's glitch taken out of the twist or the relative speed.
    Glitch(ShaftGlitch),
}

impl ShaftStage {
    /// The glitches of the last chunk, the samples, then the alarms, made since the last
    /// call, to `out`.
    fn hand_on(&mut self, out: &mut dyn Sink<ShaftOutput>) {
        for g in self.glitches.drain(..) {
            out.put(ShaftOutput::Glitch(g));
        }
        for s in self.made.0.drain(..) {
            out.put(ShaftOutput::Sample(s));
        }
        for a in self.made.1.drain(..) {
            out.put(ShaftOutput::Alarm(a));
        }
    }
}

impl Stage for ShaftStage {
    type Out = ShaftOutput;

    /// A chunk with `t`, `theta_dy`, `theta_en`, `omega_dy`, `omega_en`, `torque_shaft`: the
    /// glitches taken out of it, the estimator samples it completes, then the alarms.
    fn push(&mut self, chunk: &Recording, out: &mut dyn Sink<ShaftOutput>) -> Result<(), AppError> {
        let mut made = std::mem::take(&mut self.made);
        let pushed =
            ShaftInputs::of(chunk).and_then(|x| self.push_inputs(&x, &mut made.0, &mut made.1));
        self.made = made;
        self.hand_on(out);
        pushed
    }

    /// The last samples out of the filters, then the alarms.
    fn finish(&mut self, out: &mut dyn Sink<ShaftOutput>) -> Result<(), AppError> {
        let mut made = std::mem::take(&mut self.made);
        let finished = self.finish_into(&mut made.0, &mut made.1);
        self.made = made;
        self.hand_on(out);
        finished
    }
}
