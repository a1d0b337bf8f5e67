//! Step 1, the cycle means: a motored recording's 720° cycles averaged, the unsteady ones
//! skipped ([`cycle_means`], [`CycleMeans`]).

use super::*;

/// Cycle means of a motored recording: the data of the characterisation.
#[derive(Debug, Clone, Default, Serialize, serde::Deserialize)]
pub struct CycleMeans {
    /// Cycle index in the recording.
    pub cycle: Vec<i64>,
    /// Time at the cycle's start [s].
    pub t_s: Vec<f64>,
    /// Mean speed [rpm].
    pub n_rpm: Vec<f64>,
    /// Mean manifold pressure [kPa].
    pub p_int_kpa: Vec<f64>,
    /// Mean ambient pressure [kPa].
    pub p_atm_kpa: Vec<f64>,
    /// Mean oil temperature [°C].
    pub t_oil_c: Vec<f64>,
    /// Mean motoring (total friction) torque [N·m].
    pub tau_nm: Vec<f64>,
    /// The simulated total friction (`true_torque_friction − true_torque_indicated +
    /// true_torque_reciprocating`, cycle mean) when the recording carries it [N·m].
    pub truth_nm: Option<Vec<f64>>,
    /// Complete cycles skipped as not steady.
    pub skipped_unsteady: usize,
}

impl CycleMeans {
    /// The model inputs of cycle `k`: N, p_int, p_atm, T_oil.
    pub fn inputs(&self, k: usize) -> [f64; 4] {
        [
            self.n_rpm[k],
            self.p_int_kpa[k],
            self.p_atm_kpa[k],
            self.t_oil_c[k],
        ]
    }

    /// Number of cycles.
    pub fn len(&self) -> usize {
        self.cycle.len()
    }

    /// No cycles.
    pub fn is_empty(&self) -> bool {
        self.cycle.is_empty()
    }
}

/// One complete cycle's means: the characterisation's data point.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct FrictionCycle {
    /// Cycle index.
    pub cycle: i64,
    /// Time at its start [s].
    pub t_s: f64,
    /// Mean speed [rpm].
    pub n_rpm: f64,
    /// Mean manifold pressure [kPa].
    pub p_int_kpa: f64,
    /// Mean ambient pressure [kPa].
    pub p_atm_kpa: f64,
    /// Mean oil temperature [°C].
    pub t_oil_c: f64,
    /// Mean motoring (total friction) torque [N·m].
    pub tau_nm: f64,
    /// The simulated total friction's mean, when the recording carries it [N·m].
    pub truth_nm: Option<f64>,
    /// `|ω_end − ω_start| / ω̄`: how much the speed changed over the cycle.
    pub speed_change: f64,
}

/// Cycle means of a recording (see the module documentation): what [`friction_fit`] runs on.
pub fn cycle_means(rec: &Recording, cfg: &FrictionFitConfig) -> Result<CycleMeans, AppError> {
    let mut stage = FrictionStage::new(cfg.clone(), None)?;
    feed(&mut stage, rec, cfg, &mut Vec::new())?;
    stage.push_gap(&mut Vec::new())?;
    Ok(stage.data)
}

/// Samples per chunk when a file is streamed through the stage.
const FILE_CHUNK: usize = 4096;

/// Whether a recording goes through the stage as a stream of samples: a time-basis one with
/// `theta_en` (the others are cycles of their crank-angle form).
pub fn streams(rec: &Recording) -> bool {
    rec.basis == Basis::Time && rec.channel("cycle").is_err() && rec.channel("theta_en").is_ok()
}

/// Feed a time-basis stream to a stage, cycles from its first TDC marker
/// ([`from_first_marker`]).
pub(super) fn feed_stream<I, E>(
    stage: &mut FrictionStage,
    chunks: I,
    out: &mut dyn Sink<FrictionOutput>,
) -> Result<(), AppError>
where
    I: IntoIterator<Item = Result<Recording, E>>,
    AppError: From<E>,
{
    let chunks = chunks.into_iter().map(|c| c.map_err(AppError::from));
    let (tdc, chunks) = from_first_marker(chunks, &AcquisitionOptions::default())?;
    let tdc = tdc.unwrap_or(0.0);
    stage.set_theta_tdc(tdc)?;
    for chunk in chunks {
        stage.push(&chunk?, out)?;
    }
    Ok(())
}

/// Feed a whole recording to a stage: a time-basis recording with `theta_en` as a stream of
/// chunks (cycles from its first TDC marker), any other one as the cycles of its crank-angle
/// form. The dropouts the cycle means left out (the stage's own go to `out`).
pub(super) fn feed(
    stage: &mut FrictionStage,
    rec: &Recording,
    cfg: &FrictionFitConfig,
    out: &mut dyn Sink<FrictionOutput>,
) -> Result<Vec<Dropout>, AppError> {
    if streams(rec) {
        let n = rec.len();
        let chunks = (0..n)
            .step_by(FILE_CHUNK)
            .map(|start| Ok::<_, AppError>(rec.slice(start..start + FILE_CHUNK)));
        feed_stream(stage, chunks, out)?;
        return Ok(Vec::new());
    }
    let converted;
    let rec = if rec.basis == Basis::Time && rec.values("cycle").is_err() {
        converted = to_crank_angle(rec, &AcquisitionOptions::default(), 1.0)?;
        &converted
    } else {
        rec
    };
    let (cycles, dropouts) = crank_angle_cycles(rec, cfg)?;
    for c in cycles {
        match c {
            Some(c) => stage.push_cycle(c, out)?,
            None => stage.push_gap(out)?,
        }
    }
    Ok(dropouts)
}

/// The cycles of a crank-angle recording (sample means over each complete cycle); `None`
/// where incomplete cycles, or cycles cut by a dropout, interrupt the run of complete ones;
/// the dropouts.
fn crank_angle_cycles(rec: &Recording, cfg: &FrictionFitConfig) -> Result<CycleRuns, AppError> {
    let mut runs = CrankRuns::default();
    runs.push(rec, cfg)?;
    runs.finish(cfg.source.channel().1)
}

/// A crank-angle recording's cycles (`None`: a gap) and its dropouts.
pub(super) type CycleRuns = (Vec<Option<FrictionCycle>>, Vec<Dropout>);

/// Sums over each run of equal `cycle` values of a crank-angle recording, taken a chunk at a
/// time ([`crank_angle_cycles`] is one chunk): a few numbers per cycle, whatever the
/// recording's length. The sums run in sample order, so the means are those of the whole
/// recording bit for bit. A sample that is not a number (a sensor's dropout) makes its run's
/// sums not a number: that cycle is left out, as a gap, and the dropout told once.
#[derive(Default)]
pub(super) struct CrankRuns {
    /// Finished runs and the one still open (the last).
    runs: Vec<Run>,
    /// Samples per run of each non-negative whole cycle number (`cycle_stats`' counts), the
    /// last one open.
    counts: Vec<(i64, usize)>,
    samples: usize,
    truth: Option<bool>,
    dropouts: DropoutLog,
}

/// One run: its cycle value, its first time and speed, sums and its last speed.
struct Run {
    cycle: f64,
    t0: f64,
    n: usize,
    omega: (f64, f64, f64),
    p_int: f64,
    p_atm: f64,
    t_oil: f64,
    tau: f64,
    truth: f64,
}

impl CrankRuns {
    pub(super) fn push(
        &mut self,
        rec: &Recording,
        cfg: &FrictionFitConfig,
    ) -> Result<(), AppError> {
        let cycle = rec.values("cycle")?;
        let (tq_name, _) = cfg.source.channel();
        let omega = rec.values_in("omega_en", "rad/s")?;
        let p_int = rec.values_in("p_int", "Pa")?;
        let t_oil = rec.values_in("T_oil", "K")?;
        let tau = rec.values_in(tq_name, "N*m")?;
        let t = rec.values("t")?;
        let p_atm = match (rec.values_in("p_atm", "Pa"), cfg.p_atm_kpa) {
            (Ok(v), _) => v,
            (Err(_), Some(kpa)) => vec![kpa * 1e3; cycle.len()],
            (Err(e), None) => return Err(e.into()),
        };
        let truth = match (
            rec.values("true_torque_friction"),
            rec.values("true_torque_indicated"),
            rec.values("true_torque_reciprocating"),
        ) {
            (Ok(f), Ok(i), Ok(r)) => Some(
                f.iter()
                    .zip(i)
                    .zip(r)
                    .map(|((f, i), r)| f - i + r)
                    .collect::<Vec<f64>>(),
            ),
            _ => None,
        };
        // The truth is there in every chunk or in none.
        if *self.truth.get_or_insert(truth.is_some()) != truth.is_some() {
            return Err(AppError::Invalid(
                "the simulated truth's channels come and go between chunks".into(),
            ));
        }
        self.dropouts.see(
            &[
                ("omega_en", &omega),
                ("p_int", &p_int),
                ("T_oil", &t_oil),
                (tq_name, &tau),
                ("p_atm", &p_atm),
            ],
            t,
        );
        for i in 0..cycle.len() {
            let c = cycle[i];
            if c >= 0.0 && c.is_finite() {
                let ci = c as i64;
                match self.counts.last_mut() {
                    Some((last, k)) if *last == ci => *k += 1,
                    _ => self.counts.push((ci, 1)),
                }
            }
            let tr = truth.as_ref().map_or(0.0, |v| v[i]);
            match self.runs.last_mut() {
                // NaN never equals itself: each NaN sample is a run of its own, as in
                // `cycle_runs`.
                Some(r) if r.cycle == c => {
                    r.n += 1;
                    r.omega.1 += omega[i];
                    r.omega.2 = omega[i];
                    r.p_int += p_int[i];
                    r.p_atm += p_atm[i];
                    r.t_oil += t_oil[i];
                    r.tau += tau[i];
                    r.truth += tr;
                }
                _ => self.runs.push(Run {
                    cycle: c,
                    t0: t[i],
                    n: 1,
                    omega: (omega[i], omega[i], omega[i]),
                    p_int: p_int[i],
                    p_atm: p_atm[i],
                    t_oil: t_oil[i],
                    tau: tau[i],
                    truth: tr,
                }),
            }
        }
        self.samples += cycle.len();
        Ok(())
    }

    /// The cycles, once every chunk is in: a complete cycle has the most common count of
    /// samples.
    /// `sign`: the torque source's sign (the motoring torque from the engine's load cell is
    /// its negative).
    pub(super) fn finish(self, sign: f64) -> Result<CycleRuns, AppError> {
        let mut counts: Vec<usize> = self.counts.iter().map(|(_, k)| *k).collect();
        counts.sort_unstable();
        let per_cycle = counts.get(counts.len() / 2).copied().unwrap_or(0);
        if per_cycle < 8 {
            return Err(AppError::Invalid(format!(
                "{} complete cycles with {per_cycle} samples each: the fit needs a crank-angle \
                 recording with several samples per cycle",
                counts.len()
            )));
        }
        let cycles = self
            .runs
            .iter()
            .map(|r| {
                // A dropout's run: its sums are not numbers.
                let finite = [r.omega.1, r.p_int, r.p_atm, r.t_oil, r.tau]
                    .iter()
                    .all(|s| s.is_finite());
                (r.cycle >= 0.0 && r.n == per_cycle && finite).then(|| {
                    let n = r.n as f64;
                    let w = r.omega.1 / n;
                    FrictionCycle {
                        cycle: r.cycle as i64,
                        t_s: r.t0,
                        n_rpm: w * 30.0 / std::f64::consts::PI,
                        p_int_kpa: r.p_int / n / 1e3,
                        p_atm_kpa: r.p_atm / n / 1e3,
                        t_oil_c: r.t_oil / n - 273.15,
                        tau_nm: sign * (r.tau / n),
                        truth_nm: self.truth.unwrap_or(false).then_some(r.truth / n),
                        speed_change: (r.omega.2 - r.omega.0).abs()
                            / w.abs().max(f64::MIN_POSITIVE),
                    }
                })
            })
            .collect();
        Ok((cycles, self.dropouts.found))
    }
}
