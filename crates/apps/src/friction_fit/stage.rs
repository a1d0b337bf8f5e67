//! Steps 2–4 as a stream stage ([`FrictionStage`]): cycles in, the ranking once enough have
//! come, then DSFC cycle by cycle — what the file verb and the live service both run.

use super::*;

/// What a [`FrictionStage`] reports.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum FrictionOutput {
    /// The estimable coefficients were chosen (once), on the steady cycles so far.
    Selected {
        /// Start time of the last cycle the choice saw [s].
        t_s: f64,
        /// The steady cycles it saw.
        cycles: usize,
        /// The estimable coefficients, in rank order; the others stay at their nominal values.
        estimable: Vec<String>,
    },
    /// A steady cycle through the estimator.
    Cycle(FrictionSample),
    /// A dropout left out (the cycle it cuts, the next judged without a neighbour before it).
    Dropout(Dropout),
}

/// One steady cycle through the estimator.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrictionSample {
    /// Cycle index.
    pub cycle: i64,
    /// Its start time [s].
    pub t_s: f64,
    /// Its mean motoring torque [N·m].
    pub measured_nm: f64,
    /// The one-step-ahead prediction `ψᵀc(k−1)`, made before the estimator saw the cycle [N·m].
    pub predicted_nm: f64,
    /// The nominal model's prediction [N·m].
    pub nominal_nm: f64,
    /// The simulated total friction, when the recording carries it [N·m].
    pub truth_nm: Option<f64>,
    /// The estimable coefficients after the cycle, in the order chosen
    /// ([`FrictionStage::estimable`]).
    pub params: Vec<f64>,
    /// Their standard errors (NaN before the estimator has them).
    pub std_err: Vec<f64>,
}

/// The channels a stage sums over each cycle from samples: speed, manifold pressure, oil
/// temperature, the motoring torque, then (when present) ambient pressure and the truth.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
struct SampleMeans {
    cycles: CycleStream,
    /// Channel names and the units they are summed in.
    channels: Vec<(String, String)>,
    has_p_atm: bool,
    has_truth: bool,
    /// The cycles a chunk completed (scratch, empty between chunks).
    #[serde(skip)]
    done: Vec<CycleSummary>,
}

/// The truth's channels: the total friction is `friction − indicated + reciprocating`.
pub(super) const TRUTH_CHANNELS: [&str; 3] = [
    "true_torque_friction",
    "true_torque_indicated",
    "true_torque_reciprocating",
];

/// The estimator once the coefficients are chosen.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
struct Running {
    ranking: Vec<RankedParam>,
    estimable: Vec<String>,
    free_set: FreeSet,
    est: LinearEstimator,
}

/// The characterisation as a stage (module documentation, steps 1–4): samples (or cycles) in,
/// chosen coefficients and per-cycle predictions out. A cycle is judged steady when the next
/// one has arrived (its manifold pressure is compared with both neighbours'). The coefficients
/// are chosen on the first `select_after` steady cycles — live — or, with `None`, on all of
/// them at [`finish`](Self::finish) — the file verb; the estimator then runs through the
/// cycles so far and every later one as it comes. The result does not depend on how the
/// samples were chunked.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct FrictionStage {
    cfg: FrictionFitConfig,
    select_after: Option<usize>,
    model: FrictionRegression,
    c0: [f64; 20],
    theta_tdc: f64,
    means: Option<SampleMeans>,
    /// The previous complete cycle's mean manifold pressure [kPa] (`None` after a gap).
    before: Option<f64>,
    /// The last cycle, judged when the next arrives.
    pending: Option<FrictionCycle>,
    pub(super) data: CycleMeans,
    running: Option<Running>,
    predicted_nominal: Vec<f64>,
    predicted: Vec<f64>,
}

/// At least this many steady cycles before the coefficients are chosen.
pub const MIN_CYCLES: usize = 20;

impl FrictionStage {
    /// A stage; `select_after`: choose the coefficients after that many steady cycles (at least
    /// [`MIN_CYCLES`]), `None`: at the end.
    pub fn new(cfg: FrictionFitConfig, select_after: Option<usize>) -> Result<Self, AppError> {
        if !(cfg.s0.is_finite() && cfg.s0 > 0.0) {
            return Err(AppError::Invalid(format!(
                "S0 scale {} must be a positive number",
                physid_core::Num(cfg.s0)
            )));
        }
        if let Some(n) = select_after.filter(|&n| n < MIN_CYCLES) {
            return Err(AppError::Invalid(format!(
                "choosing the coefficients after {n} cycles: the choice needs at least {MIN_CYCLES}"
            )));
        }
        let model = FrictionRegression::new(cfg.design, cfg.settings);
        if let Some(names) = &cfg.estimate {
            check_estimate(names, &model.nominal())?;
        }
        Ok(Self {
            c0: model.nominal(),
            model,
            cfg,
            select_after,
            theta_tdc: 0.0,
            means: None,
            before: None,
            pending: None,
            data: CycleMeans::default(),
            running: None,
            predicted_nominal: Vec::new(),
            predicted: Vec::new(),
        })
    }

    /// Cycles start at this angle of `theta_en` + k·4π [rad] (default 0); before any sample.
    pub fn set_theta_tdc(&mut self, theta_tdc: f64) -> Result<(), AppError> {
        if self.means.is_some() {
            return Err(AppError::Invalid(
                "the TDC angle is set before the first sample".into(),
            ));
        }
        self.theta_tdc = theta_tdc;
        Ok(())
    }

    /// The steady cycles kept so far, the last one judged (as at the end of the stream) — what
    /// the estimator takes, without running it (the experiment design's regressors).
    pub fn steady_cycles(&mut self) -> Result<&CycleMeans, AppError> {
        self.push_gap(&mut Vec::new())?;
        Ok(&self.data)
    }

    /// The estimable coefficients once chosen.
    pub fn estimable(&self) -> Option<&[String]> {
        self.running.as_ref().map(|r| r.estimable.as_slice())
    }

    /// The estimable coefficients' current values and standard errors (NaN before the
    /// estimator has them), in the order chosen.
    fn current(&self, r: &Running) -> (Vec<f64>, Vec<f64>) {
        let x = r.est.estimate_full();
        let se = r.est.std_errors().ok();
        r.estimable
            .iter()
            .filter_map(|name| {
                let j = REGRESSION_PARAMS.iter().position(|p| p == name)?;
                let pos = r.free_set.free().iter().position(|&i| i == j);
                let s = match (&se, pos) {
                    (Some(s), Some(pos)) => self.c0[j].abs() * s[pos],
                    _ => f64::NAN,
                };
                Some((self.c0[j] * (1.0 + x[j]), s))
            })
            .unzip()
    }

    /// A chunk of time-basis samples with `t`, `theta_en` [rad], `omega_en`, `p_int`, `T_oil`,
    /// the motoring torque, `p_atm` (or the configured constant) and, optionally, the truth.
    fn push_chunk(
        &mut self,
        chunk: &Recording,
        out: &mut dyn Sink<FrictionOutput>,
    ) -> Result<(), AppError> {
        if chunk.is_empty() {
            return Ok(());
        }
        if self.means.is_none() {
            self.means = Some(self.sample_means(chunk)?);
        }
        let Some(m) = self.means.as_mut() else {
            return Ok(());
        };
        let cols = m
            .channels
            .iter()
            .map(|(name, unit)| chunk.values_in(name, unit))
            .collect::<Result<Vec<_>, _>>()?;
        let views: Vec<&[f64]> = cols.iter().map(|c| c.as_slice()).collect();
        m.done.clear();
        m.cycles
            .push_past_dropouts(
                chunk.values("t")?,
                chunk.values("theta_en")?,
                &views,
                &mut m.done,
            )
            .map_err(|e| AppError::Invalid(e.to_string()))?;
        for d in m.cycles.dropouts() {
            let names: Vec<&str> = m.channels.iter().map(|(n, _)| n.as_str()).collect();
            out.put(FrictionOutput::Dropout(Dropout::of_cycles(d, &names, 0)));
        }
        let sign = self.cfg.source.channel().1;
        let p_atm_default = self.cfg.p_atm_kpa.map(|kpa| kpa * 1e3);
        let done = std::mem::take(&mut m.done);
        let (has_p_atm, has_truth) = (m.has_p_atm, m.has_truth);
        for c in &done {
            // A cycle left out before this one (a dropout): the one before judged without a
            // neighbour after it, this one without one before.
            if self
                .pending
                .as_ref()
                .is_some_and(|p| p.cycle + 1 != c.cycle)
            {
                self.push_gap(out)?;
            }
            let w = c.mean[0];
            let mut k = 4;
            let p_atm = if has_p_atm {
                k += 1;
                c.mean[4]
            } else {
                p_atm_default.unwrap_or(f64::NAN)
            };
            let truth = has_truth.then(|| c.mean[k] - c.mean[k + 1] + c.mean[k + 2]);
            self.push_cycle(
                FrictionCycle {
                    cycle: c.cycle,
                    t_s: c.t_start_s,
                    n_rpm: w * 30.0 / std::f64::consts::PI,
                    p_int_kpa: c.mean[1] / 1e3,
                    p_atm_kpa: p_atm / 1e3,
                    t_oil_c: c.mean[2] - 273.15,
                    tau_nm: sign * c.mean[3],
                    truth_nm: truth,
                    speed_change: (c.end[0] - c.start[0]).abs() / w.abs().max(f64::MIN_POSITIVE),
                },
                out,
            )?;
        }
        if let Some(m) = self.means.as_mut() {
            m.done = done;
        }
        Ok(())
    }

    /// The channels to sum, from the first chunk.
    fn sample_means(&self, chunk: &Recording) -> Result<SampleMeans, AppError> {
        let (tq, _) = self.cfg.source.channel();
        let mut channels = vec![
            ("omega_en", "rad/s"),
            ("p_int", "Pa"),
            ("T_oil", "K"),
            (tq, "N*m"),
        ];
        for (name, _) in &channels {
            chunk.channel(name)?;
        }
        chunk.channel("theta_en")?;
        let has_p_atm = chunk.channel("p_atm").is_ok();
        if has_p_atm {
            channels.push(("p_atm", "Pa"));
        } else if self.cfg.p_atm_kpa.is_none() {
            chunk.channel("p_atm")?;
        }
        let has_truth = TRUTH_CHANNELS.iter().all(|c| chunk.channel(c).is_ok());
        if has_truth {
            channels.extend(TRUTH_CHANNELS.map(|c| (c, "N*m")));
        }
        Ok(SampleMeans {
            cycles: CycleStream::new(channels.len(), self.theta_tdc, None)
                .map_err(|e| AppError::Invalid(e.to_string()))?,
            channels: channels
                .into_iter()
                .map(|(n, u)| (n.to_string(), u.to_string()))
                .collect(),
            has_p_atm,
            has_truth,
            done: Vec::new(),
        })
    }

    /// One complete cycle (the one before it judged now).
    pub fn push_cycle(
        &mut self,
        c: FrictionCycle,
        out: &mut dyn Sink<FrictionOutput>,
    ) -> Result<(), AppError> {
        if let Some(p) = self.pending.take() {
            self.judge(p, Some(c.p_int_kpa), out)?;
        }
        self.pending = Some(c);
        Ok(())
    }

    /// An incomplete cycle: the last one is judged without a successor.
    pub fn push_gap(&mut self, out: &mut dyn Sink<FrictionOutput>) -> Result<(), AppError> {
        if let Some(p) = self.pending.take() {
            self.judge(p, None, out)?;
        }
        self.before = None;
        Ok(())
    }

    /// Keep a steady cycle (module documentation, step 1), skip another.
    fn judge(
        &mut self,
        c: FrictionCycle,
        after: Option<f64>,
        out: &mut dyn Sink<FrictionOutput>,
    ) -> Result<(), AppError> {
        let moved = |q: Option<f64>| {
            q.is_some_and(|q| (c.p_int_kpa - q).abs() / q > self.cfg.max_pressure_change)
        };
        // A throttle step inside this cycle shows as a jump to the next cycle's pressure.
        let steady =
            c.speed_change <= self.cfg.max_speed_change && !moved(self.before) && !moved(after);
        self.before = Some(c.p_int_kpa);
        if !steady {
            self.data.skipped_unsteady += 1;
            return Ok(());
        }
        OperatingPoint {
            n_rpm: c.n_rpm,
            p_int_kpa: c.p_int_kpa,
            p_atm_kpa: c.p_atm_kpa,
            t_oil_c: c.t_oil_c,
        }
        .validate()
        .map_err(|e| {
            AppError::Invalid(format!(
                "cycle {} (t = {:.3} s): {e} — the fit needs a motored, turning engine",
                c.cycle, c.t_s
            ))
        })?;
        let d = &mut self.data;
        if d.is_empty() {
            d.truth_nm = c.truth_nm.map(|_| Vec::new());
        }
        d.cycle.push(c.cycle);
        d.t_s.push(c.t_s);
        d.n_rpm.push(c.n_rpm);
        d.p_int_kpa.push(c.p_int_kpa);
        d.p_atm_kpa.push(c.p_atm_kpa);
        d.t_oil_c.push(c.t_oil_c);
        d.tau_nm.push(c.tau_nm);
        if let Some(v) = d.truth_nm.as_mut() {
            v.push(c.truth_nm.unwrap_or(f64::NAN));
        }
        let kept = d.len();
        if self.running.is_some() {
            self.step(kept - 1, out)
        } else if self.select_after.is_some_and(|n| kept >= n) {
            self.select(out)
        } else {
            Ok(())
        }
    }

    /// The regressor of kept cycle `k`.
    fn psi(&self, k: usize) -> [f64; 20] {
        let u = self.data.inputs(k);
        self.model.regressor(&OperatingPoint {
            n_rpm: u[0],
            p_int_kpa: u[1],
            p_atm_kpa: u[2],
            t_oil_c: u[3],
        })
    }

    /// Choose the estimable coefficients on the cycles so far (steps 2–3), then run the
    /// estimator through them.
    fn select(&mut self, out: &mut dyn Sink<FrictionOutput>) -> Result<(), AppError> {
        let data = &self.data;
        if data.len() < MIN_CYCLES {
            return Err(AppError::Invalid(format!(
                "{} steady cycles ({} skipped as not steady): the fit needs at least {MIN_CYCLES}",
                data.len(),
                data.skipped_unsteady
            )));
        }
        let c0 = self.c0;
        let model = &self.model;
        // Identifiability over the coefficients with a non-zero nominal value (a zero one — the
        // valvetrain's absent follower type — has no relative sensitivity and stays fixed).
        let free: Vec<usize> = (0..20).filter(|&j| c0[j] != 0.0).collect();
        let cols: [&[f64]; 4] = [&data.n_rpm, &data.p_int_kpa, &data.p_atm_kpa, &data.t_oil_c];
        let ident_data = Data {
            inputs: cols.to_vec(),
            y: Some(&data.tau_nm),
        };
        let analysis = analyse(model, &ident_data, &c0, &free, IdentConfig::default())?;
        let (k, _) = match &self.cfg.estimate {
            Some(names) => (names.len(), None),
            None => self.cfg.selection.resolve(model, &ident_data, &analysis)?,
        };
        let mut ranking = analysis.ranked(k);
        for j in (0..20).filter(|j| !free.contains(j)) {
            ranking.push(RankedParam {
                param: REGRESSION_PARAMS[j].into(),
                rank: ranking.len() + 1,
                relative_residual: 0.0,
                estimable: false,
            });
        }
        if k == 0 {
            return Err(AppError::Invalid(
                "no coefficient is estimable on this data: another experiment is needed (speeds and manifold pressures varied)".into(),
            ));
        }
        let estimable: Vec<String> = match &self.cfg.estimate {
            Some(names) => {
                // Chosen beforehand: the ranking still says where each one stands.
                for r in &mut ranking {
                    r.estimable = names.contains(&r.param);
                }
                names.clone()
            }
            None => analysis
                .top(k)
                .iter()
                .map(|&i| REGRESSION_PARAMS[free[i]].to_string())
                .collect(),
        };
        // DSFC in relative coordinates: y − ψᵀc0 = Σ (c0_i ψ_i)·x_i.
        let rel = ParamSet::new(REGRESSION_PARAMS, vec![0.0; 20])
            .map_err(|e| AppError::Invalid(e.to_string()))?;
        let free_set = rel
            .free(&estimable)
            .map_err(|e| AppError::Invalid(e.to_string()))?;
        let spec = EstimatorSpec {
            lambda: self.cfg.lambda,
            p0: CovSpec::Scaled(self.cfg.s0 * self.cfg.s0),
            ..EstimatorSpec::new(MethodName::Dsfc)
        };
        let est = build_linear(&spec, &rel, &free_set)
            .map_err(AppError::estim("estimator configuration"))?;
        let n = data.len();
        out.put(FrictionOutput::Selected {
            t_s: data.t_s[n - 1],
            cycles: n,
            estimable: estimable.clone(),
        });
        self.running = Some(Running {
            ranking,
            estimable,
            free_set,
            est,
        });
        for k in 0..n {
            self.step(k, out)?;
        }
        Ok(())
    }

    /// Kept cycle `k` through the estimator (step 4: predicted before the update).
    fn step(&mut self, k: usize, out: &mut dyn Sink<FrictionOutput>) -> Result<(), AppError> {
        let psi = self.psi(k);
        let c0 = &self.c0;
        let nominal: f64 = psi.iter().zip(c0).map(|(p, c)| p * c).sum();
        let mut scaled = [0.0; 20];
        for j in 0..20 {
            scaled[j] = c0[j] * psi[j];
        }
        let d = &self.data;
        let Some(r) = self.running.as_mut() else {
            return Ok(());
        };
        let step = r
            .est
            .update(&scaled, d.tau_nm[k] - nominal)
            .map_err(|e| AppError::estim(format!("cycle {}", d.cycle[k]))(e))?;
        let predicted = d.tau_nm[k] - step.prediction_error;
        let (params, std_err) = match &self.running {
            Some(r) => self.current(r),
            None => Default::default(),
        };
        let d = &self.data;
        self.predicted_nominal.push(nominal);
        self.predicted.push(predicted);
        out.put(FrictionOutput::Cycle(FrictionSample {
            params,
            std_err,
            cycle: d.cycle[k],
            t_s: d.t_s[k],
            measured_nm: d.tau_nm[k],
            predicted_nm: predicted,
            nominal_nm: nominal,
            truth_nm: d.truth_nm.as_ref().map(|v| v[k]),
        }));
        Ok(())
    }

    /// The end of the stream: the last cycle judged, the coefficients chosen if they were not,
    /// and the result (once: the stage has given its predictions up to it).
    pub fn fit(&mut self, out: &mut dyn Sink<FrictionOutput>) -> Result<FrictionFit, AppError> {
        self.push_gap(out)?;
        if self.running.is_none() {
            self.select(out)?;
        }
        let Some(r) = self.running.as_ref() else {
            return Err(AppError::Invalid("no coefficients were chosen".into()));
        };
        let (c0, data) = (self.c0, &self.data);
        let n = data.len();
        let x = r.est.estimate_full();
        let params: Vec<f64> = (0..20).map(|j| c0[j] * (1.0 + x[j])).collect();
        let se_x = r.est.std_errors().ok();
        let std_err: Vec<Option<f64>> = (0..20)
            .map(|j| {
                // The estimator's free parameters are in coefficient order.
                let pos = r.free_set.free().iter().position(|&i| i == j)?;
                se_x.as_ref().map(|s| c0[j].abs() * s[pos])
            })
            .collect();
        let predicted_final: Vec<f64> = (0..n)
            .map(|k| self.psi(k).iter().zip(&params).map(|(p, c)| p * c).sum())
            .collect();
        let pct = |pred: &[f64], reference: &[f64]| -> Vec<f64> {
            pred.iter()
                .zip(reference)
                .map(|(p, r)| 100.0 * (p - r) / r)
                .collect()
        };
        let predicted = std::mem::take(&mut self.predicted);
        let predicted_nominal = std::mem::take(&mut self.predicted_nominal);
        let error_pct = pct(&predicted, &data.tau_nm);
        let truth_error_pct = data.truth_nm.as_ref().map(|tr| pct(&predicted, tr));
        let after = data
            .t_s
            .iter()
            .position(|&t| t - data.t_s[0] >= self.cfg.transient_s)
            .unwrap_or(n);
        let max_abs = |v: &[f64]| v[after..].iter().fold(0.0f64, |m, e| m.max(e.abs()));
        Ok(FrictionFit {
            ranking: r.ranking.clone(),
            estimable: r.estimable.clone(),
            nominal: c0.to_vec(),
            std_err,
            final_error_pct: error_pct[n - 1],
            max_error_after_transient_pct: max_abs(&error_pct),
            max_truth_error_after_transient_pct: truth_error_pct.as_deref().map(max_abs),
            nmse_nominal: nmse(&data.tau_nm, &predicted_nominal).unwrap_or(f64::NAN),
            nmse_final: nmse(&data.tau_nm, &predicted_final).unwrap_or(f64::NAN),
            dropouts: Vec::new(),
            params,
            predicted_nominal,
            predicted,
            predicted_final,
            error_pct,
            truth_error_pct,
            data: data.clone(),
            cycles: Vec::new(),
        })
    }
}

/// Coefficients chosen beforehand ([`FrictionFitConfig::estimate`]): known names, each once,
/// each with a non-zero nominal value (the estimator works in deviations relative to it).
pub fn check_estimate(names: &[String], c0: &[f64; 20]) -> Result<(), AppError> {
    if names.is_empty() {
        return Err(AppError::Invalid(
            "no coefficient chosen to estimate".into(),
        ));
    }
    for (k, name) in names.iter().enumerate() {
        let j = REGRESSION_PARAMS
            .iter()
            .position(|p| p == name)
            .ok_or_else(|| {
                AppError::Invalid(format!(
                    "coefficient '{name}': expected one of {}",
                    REGRESSION_PARAMS.join(", ")
                ))
            })?;
        if names[..k].contains(name) {
            return Err(AppError::Invalid(format!(
                "coefficient '{name}' is chosen twice"
            )));
        }
        if c0[j] == 0.0 {
            return Err(AppError::Invalid(format!(
                "coefficient '{name}' is 0 in this engine's model (its valvetrain has no such term): it has no relative deviation to estimate"
            )));
        }
    }
    Ok(())
}

impl Stage for FrictionStage {
    type Out = FrictionOutput;

    /// A chunk of time-basis samples with `t`, `theta_en` [rad], `omega_en`, `p_int`, `T_oil`,
    /// the motoring torque, `p_atm` (or the configured constant) and, optionally, the truth.
    fn push(
        &mut self,
        chunk: &Recording,
        out: &mut dyn Sink<FrictionOutput>,
    ) -> Result<(), AppError> {
        self.push_chunk(chunk, out)
    }

    /// The last cycle judged and the coefficients chosen if they were not ([`Self::fit`] also
    /// gives the result).
    fn finish(&mut self, out: &mut dyn Sink<FrictionOutput>) -> Result<(), AppError> {
        self.fit(out).map(|_| ())
    }
}
