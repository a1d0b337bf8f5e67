//! The filter over the chosen parameters ([`TorqueFilter`]) and the live stream stage
//! ([`TorqueStage`]): the choice on its first cycles, then the filter cycle by cycle.

use super::*;

/// What a [`TorqueStage`] reports.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum TorqueOutput {
    /// The estimable parameters were chosen (once), on the samples so far.
    Selected {
        /// Time of the last sample the choice saw [s].
        t_s: f64,
        /// The samples it saw.
        samples: usize,
        /// The estimable parameters, in rank order; the others stay at their nominal values.
        estimable: Vec<String>,
    },
    /// Another 720 samples (a cycle's worth) through the filter.
    Cycle(TorqueCycle),
    /// A dropout left out with the cycle it cuts (the live stage).
    Dropout(Dropout),
}

/// A cycle's worth of samples through the filter.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TorqueCycle {
    /// Time of its last sample [s].
    pub t_s: f64,
    /// The estimates after it, in the order chosen ([`TorqueStage::estimable`]).
    pub params: Vec<f64>,
    /// Their standard errors.
    pub std_err: Vec<f64>,
    /// RMS of the one-step prediction errors over the cycle [N·m].
    pub rms_error_nm: f64,
    /// RMS of the measured torque over the cycle [N·m].
    pub rms_measured_nm: f64,
}

/// The file verb's tracks: a point every `every` samples, thinned as they grow.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(super) struct Tracks {
    every: usize,
    t: Vec<f64>,
    measured: Vec<f64>,
    predicted: Vec<f64>,
    params: Vec<Track>,
}

impl Tracks {
    /// A point: the sample's time, measurement and prediction, the estimates.
    pub(super) fn push(&mut self, (t, y, predicted): (f64, f64, f64), v: &[f64], se: &[f64]) {
        self.t.push(t);
        self.measured.push(y);
        self.predicted.push(predicted);
        for (k, tr) in self.params.iter_mut().enumerate() {
            tr.value.push(v[k]);
            tr.std_err.push(se[k]);
        }
    }

    /// Every other point dropped beyond twice [`TRACK_POINTS`]; the step doubles.
    pub(super) fn bound(&mut self) {
        use crate::halve;
        if self.t.len() < 2 * TRACK_POINTS {
            return;
        }
        halve(&mut self.t);
        halve(&mut self.measured);
        halve(&mut self.predicted);
        for tr in &mut self.params {
            halve(&mut tr.value);
            halve(&mut tr.std_err);
        }
        self.every *= 2;
    }
}

/// Step 2, once the parameters are chosen: the filter over the estimable ones, a sample at a
/// time, a [`TorqueOutput::Cycle`] every 720 samples, and — for the file verb — bounded tracks.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(super) struct TorqueFilter {
    est: NonlinearEstimator<CyclicTorque>,
    analysis: Analysis,
    /// The estimated parameters in rank order, and in the estimator's (index) order.
    estimable: Vec<usize>,
    order: Vec<usize>,
    r2: f64,
    tracks: Option<Tracks>,
    /// Samples through the filter.
    filtered: usize,
    /// The cycle in progress: sums of squared errors and measurements.
    sse: f64,
    ssy: f64,
    /// The last sample filtered: its time, measurement and one-step prediction.
    last: (f64, f64, f64),
}

impl TorqueFilter {
    /// Choose the parameters on `rows` (step 1: the analysis, the selection, and — without a
    /// given R2 — the batch fit of the chosen ones for its residual variance) and set up the
    /// filter on them; `tracks`: record the file verb's tracks.
    pub(super) fn choose<R: Rows + ?Sized>(
        cfg: &TorqueFitConfig,
        rows: &R,
        tracks: bool,
    ) -> Result<Self, AppError> {
        let chosen = cfg.chosen()?;
        let (analysis, ranked) =
            torque_identifiability(rows, &cfg.nominal, &cfg.fixed, &cfg.selection)?;
        let estimable = chosen.unwrap_or(ranked);
        if estimable.is_empty() {
            return Err(AppError::Invalid(
                "no parameter is estimable on this recording".into(),
            ));
        }
        if let Some(&j) = estimable.iter().find(|&&j| cfg.nominal[j] == 0.0) {
            return Err(AppError::Invalid(format!(
                "'{}' has nominal value 0: scaled coordinates ϑ = ϑ0·(1 + x) cannot move it — give it a non-zero nominal value or fix it",
                PARAMS[j]
            )));
        }
        let model = CyclicTorque::default();
        let n = analysis.rows;
        let r2 = match cfg.r2 {
            Some(v) => v,
            None => {
                let fit = fit_subset(&model, rows, &cfg.nominal, &estimable, 20)?;
                // An exact fit (noise-free data) leaves no residual; a filter told the torque
                // is measured exactly collapses its covariance within samples. No torque is
                // measured finer than R2_FLOOR of its RMS.
                let (mut ssy, mut count) = (0.0, 0usize);
                rows.pass(&mut |d| {
                    let y = d.y.unwrap_or_default();
                    ssy += y.iter().map(|v| v * v).sum::<f64>();
                    count += y.len();
                    Ok(())
                })?;
                let floor = R2_FLOOR * R2_FLOOR * ssy / count.max(1) as f64;
                (fit.rss / (n - estimable.len()).max(1) as f64)
                    .max(floor)
                    .max(f64::MIN_POSITIVE)
            }
        };
        let params = ParamSet::new(PARAMS, cfg.nominal.to_vec())
            .map_err(|e| AppError::Invalid(e.to_string()))?;
        let names: Vec<&str> = estimable.iter().map(|&j| PARAMS[j]).collect();
        let free = params
            .free(&names)
            .map_err(|e| AppError::Invalid(e.to_string()))?;
        let mut r1 = vec![0.0; free.free().len()];
        for (name, v) in &cfg.track {
            let pos = free
                .free()
                .iter()
                .position(|&j| PARAMS[j] == name.as_str())
                .ok_or_else(|| {
                    AppError::Invalid(format!(
                        "track {name}: it is not among the estimated parameters ({})",
                        names.join(", ")
                    ))
                })?;
            r1[pos] = *v;
        }
        let spec = EstimatorSpec {
            p0: CovSpec::Scaled(cfg.p0),
            r1: CovSpec::Diagonal(r1),
            r2,
            scaled: true,
            ..EstimatorSpec::new(cfg.method)
        };
        let est = spec
            .nl_config()
            .and_then(|nl| NonlinearEstimator::new(model, &params, &free, &nl))
            .map_err(AppError::estim("estimator configuration"))?;
        // The estimator's order is the parameters' (free set) order.
        let order: Vec<usize> = free.free().to_vec();
        let tracks = tracks.then(|| Tracks {
            every: 1,
            t: Vec::new(),
            measured: Vec::new(),
            predicted: Vec::new(),
            params: order
                .iter()
                .map(|&j| Track {
                    param: PARAMS[j].into(),
                    value: Vec::new(),
                    std_err: Vec::new(),
                })
                .collect(),
        });
        Ok(Self {
            est,
            analysis,
            estimable,
            order,
            r2,
            tracks,
            filtered: 0,
            sse: 0.0,
            ssy: 0.0,
            last: (f64::NAN, f64::NAN, f64::NAN),
        })
    }

    /// The analysis's ranking, each marked estimable when it is estimated (the top ones, or
    /// those chosen beforehand wherever they rank).
    fn ranking(&self) -> Vec<RankedParam> {
        let names = self.names();
        let mut ranking = self.analysis.ranked(self.estimable.len());
        for r in &mut ranking {
            r.estimable = names.contains(&r.param.as_str());
        }
        ranking
    }

    /// The estimable parameters' names, in rank order.
    pub(super) fn names(&self) -> Vec<&'static str> {
        self.estimable.iter().map(|&j| PARAMS[j]).collect()
    }

    /// One sample through the filter (step 2); a track point every `every`, a
    /// [`TorqueOutput::Cycle`] every 720.
    pub(super) fn step(
        &mut self,
        u: &[f64; 6],
        y: f64,
        t: f64,
        out: &mut dyn Sink<TorqueOutput>,
    ) -> Result<(), AppError> {
        let i = self.filtered;
        let step = self
            .est
            .update(u, y)
            .map_err(|e| AppError::estim(format!("sample {i}"))(e))?;
        self.filtered += 1;
        self.sse += step.prediction_error * step.prediction_error;
        self.ssy += y * y;
        self.last = (t, y, y - step.prediction_error);
        // The tracks are the file verb's; live, the cycle outputs carry them.
        if let Some(tr) = self.tracks.as_mut() {
            if i.is_multiple_of(tr.every) {
                tr.push(self.last, &self.est.estimate(), &self.est.std_errors());
                tr.bound();
            }
        }
        if self.filtered.is_multiple_of(PER_CYCLE) {
            // In rank order, as chosen.
            let (v, se) = (self.est.estimate(), self.est.std_errors());
            let at = |j: usize| self.order.iter().position(|&i| i == j).unwrap_or(0);
            out.put(TorqueOutput::Cycle(TorqueCycle {
                t_s: t,
                params: self.estimable.iter().map(|&j| v[at(j)]).collect(),
                std_err: self.estimable.iter().map(|&j| se[at(j)]).collect(),
                rms_error_nm: (self.sse / PER_CYCLE as f64).sqrt(),
                rms_measured_nm: (self.ssy / PER_CYCLE as f64).sqrt(),
            }));
            self.sse = 0.0;
            self.ssy = 0.0;
        }
        Ok(())
    }

    /// The file verb's result once every sample has been filtered (step 3): the final
    /// estimates, and — a pass over `src`'s `n` samples — the prediction of the nominal and the
    /// final model (NMSE, NRMSE) and the last two cycles at full resolution.
    pub(super) fn result(
        mut self,
        cfg: &TorqueFitConfig,
        src: &Degrees,
        n: usize,
    ) -> Result<TorqueFit, AppError> {
        let mut tracks = self
            .tracks
            .take()
            .ok_or_else(|| AppError::Invalid("the filter kept no tracks".into()))?;
        // The last point of the tracks is the last sample.
        if !(self.filtered - 1).is_multiple_of(tracks.every) {
            tracks.push(self.last, &self.est.estimate(), &self.est.std_errors());
        }
        let final_full = self.est.estimate_full();
        let se = self.est.std_errors();
        let std_err: Vec<Option<f64>> = (0..15)
            .map(|j| self.order.iter().position(|&i| i == j).map(|k| se[k]))
            .collect();
        let model = CyclicTorque::default();
        let (mut before, mut after) = (Prediction::default(), Prediction::default());
        let w = n.saturating_sub(2 * PER_CYCLE);
        let mut last_cycles: [Vec<f64>; 4] = Default::default();
        for v in &mut last_cycles {
            v.reserve_exact(n - w);
        }
        let (mut i, mut u) = (0, [0.0; 6]);
        src.samples::<AppError>(&mut |d| {
            for k in 0..d.y.len() {
                d.row(k, &mut u);
                let (y, b, a) = (
                    d.y[k],
                    model.eval::<f64>(&u, &cfg.nominal),
                    model.eval::<f64>(&u, &final_full),
                );
                before.push(y, b);
                after.push(y, a);
                if i >= w {
                    for (col, v) in last_cycles.iter_mut().zip([d.t[k], y, b, a]) {
                        col.push(v);
                    }
                }
                i += 1;
            }
            Ok(())
        })?;
        Ok(TorqueFit {
            method: cfg.method.as_str(),
            ranking: self.ranking(),
            estimable: self.names().iter().map(|s| s.to_string()).collect(),
            nominal: cfg.nominal.to_vec(),
            params: final_full,
            std_err,
            r2: self.r2,
            repairs: self.est.repairs(),
            t: tracks.t,
            tracks: tracks.params,
            measured: tracks.measured,
            predicted: tracks.predicted,
            nmse_before: before.nmse().unwrap_or(f64::NAN),
            nmse_after: after.nmse().unwrap_or(f64::NAN),
            nrmse_before: before.nrmse().unwrap_or(f64::NAN),
            nrmse_after: after.nrmse().unwrap_or(f64::NAN),
            last_cycles,
            samples: n,
            cycles: Vec::new(),
            dropouts: Vec::new(),
        })
    }
}

/// The samples a live stage keeps until it chooses, and the filter after.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(super) struct Choosing {
    cfg: TorqueFitConfig,
    select_after: usize,
    data: TorqueData,
    filter: Option<TorqueFilter>,
}

impl Choosing {
    /// One sample: kept until the choice, filtered after.
    pub(super) fn take(
        &mut self,
        u: &[f64; 6],
        y: f64,
        t: f64,
        out: &mut dyn Sink<TorqueOutput>,
    ) -> Result<(), AppError> {
        if let Some(f) = self.filter.as_mut() {
            return f.step(u, y, t, out);
        }
        self.data.push(u, y, t);
        if self.data.y.len() >= self.select_after {
            self.select(out)?;
        }
        Ok(())
    }

    /// Choose the parameters on the samples kept, filter them, and drop them.
    pub(super) fn select(&mut self, out: &mut dyn Sink<TorqueOutput>) -> Result<(), AppError> {
        let n = self.data.y.len();
        at_least_a_cycle(n)?;
        let mut f = TorqueFilter::choose(&self.cfg, &self.data, false)?;
        out.put(TorqueOutput::Selected {
            t_s: self.data.t[n - 1],
            samples: n,
            estimable: f.names().iter().map(|s| s.to_string()).collect(),
        });
        let data = std::mem::replace(&mut self.data, TorqueData::with_capacity(0));
        let mut u = [0.0; 6];
        for i in 0..n {
            data.row(i, &mut u);
            f.step(&u, data.y[i], data.t[i], out)?;
        }
        self.filter = Some(f);
        Ok(())
    }
}

/// Application 3 live: time-basis chunks in, resampled on the stream to one sample per crank
/// degree (the same [`DegreeCurves`] every pass of the file verb runs), the parameters chosen
/// on the first `select_after` samples ([`TorqueFilter::choose`], as the file verb chooses on
/// all), then a cycle's estimates at a time out. The samples are kept until the choice and
/// dropped after it: memory stays bounded.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct TorqueStage {
    curves: DegreeCurves,
    choosing: Choosing,
}

impl TorqueStage {
    /// A stage that chooses after `select_after` samples (at least a cycle).
    pub fn new(cfg: TorqueFitConfig, select_after: usize) -> Result<Self, AppError> {
        if !(cfg.p0.is_finite() && cfg.p0 > 0.0) {
            return Err(AppError::Invalid(format!(
                "P0 scale {} must be a positive number",
                physid_core::Num(cfg.p0)
            )));
        }
        if select_after < PER_CYCLE {
            return Err(AppError::Invalid(format!(
                "choosing the parameters after {select_after} samples: the choice needs at least one cycle ({PER_CYCLE})"
            )));
        }
        Ok(Self {
            curves: DegreeCurves::new(0.0),
            choosing: Choosing {
                cfg,
                select_after,
                data: TorqueData::with_capacity(0),
                filter: None,
            },
        })
    }

    /// Cycles start at this angle of `theta_en` + k·4π [rad] (default 0); before any sample.
    pub fn set_theta_tdc(&mut self, theta_tdc: f64) -> Result<(), AppError> {
        if self.curves.curves.is_some() {
            return Err(AppError::Invalid(
                "the TDC angle is set before the first sample".into(),
            ));
        }
        self.curves.theta_tdc = theta_tdc;
        Ok(())
    }

    /// The estimable parameters once chosen, in rank order.
    pub fn estimable(&self) -> Option<Vec<&'static str>> {
        self.choosing.filter.as_ref().map(TorqueFilter::names)
    }
}

impl Stage for TorqueStage {
    type Out = TorqueOutput;

    /// A chunk of time-basis samples with `t`, `theta_en`, `omega_en`, `alpha_en`, `p_cyl`,
    /// `p_crank`, `T_oil` and `torque_engine`: each complete cycle resampled to one sample per
    /// crank degree and taken.
    fn push(
        &mut self,
        chunk: &Recording,
        out: &mut dyn Sink<TorqueOutput>,
    ) -> Result<(), AppError> {
        let choosing = &mut self.choosing;
        self.curves
            .push::<AppError>(chunk, &mut |u, y, t| choosing.take(u, y, t, out))?;
        for d in self.curves.dropouts() {
            out.put(TorqueOutput::Dropout(d));
        }
        Ok(())
    }

    /// The end of the stream: the parameters chosen on all of it if they were not yet.
    fn finish(&mut self, out: &mut dyn Sink<TorqueOutput>) -> Result<(), AppError> {
        if self.choosing.filter.is_none() {
            self.choosing.select(out)?;
        }
        Ok(())
    }
}
