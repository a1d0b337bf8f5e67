//! One window of the live twin (see the module docs): the channels' noise while it is learnt;
//! then the window's information added to the epoch's and the estimate solved (the excitation
//! supervisor, the isolation of a large residual); the estimate's alarm; the residual's alarm
//! and the jump it names; the window reported; the twin turned to the stream's crank angle,
//! the buffers moved on and, when the estimate has moved, a new epoch.

use super::*;

/// What a window makes of the adapted parameters: their values and standard errors (NaN where
/// not estimated), those frozen, and whether a new epoch begins from the values.
struct Estimate {
    values: Vec<f64>,
    std_err: Vec<f64>,
    frozen: Vec<String>,
    rebase: bool,
}

impl TwinStage {
    /// The window of `n` samples from the buffers, ending at `t_end` [s]: the noise, the
    /// estimate, the alarms; a new epoch when the estimate has moved.
    pub(super) fn window(
        &mut self,
        n: usize,
        t_end: f64,
        out: &mut dyn physid_core::Sink<TwinOut>,
    ) -> Result<(), AppError> {
        let mut runs = self
            .runs
            .take()
            .ok_or_else(|| AppError::Invalid("twin: no run".into()))?;
        let done = self.window_with(&mut runs, n, t_end, out);
        self.runs = Some(runs);
        done
    }

    fn window_with(
        &mut self,
        runs: &mut Runs,
        n: usize,
        t_end: f64,
        out: &mut dyn physid_core::Sink<TwinOut>,
    ) -> Result<(), AppError> {
        let r: Vec<Vec<f64>> = self
            .measured
            .iter()
            .zip(&runs.out[0])
            .map(|(m, y)| m[..n].iter().zip(&y[..n]).map(|(a, b)| a - b).collect())
            .collect();
        let t_rel = self.compared as f64 / self.rate_hz;
        let settled = (self.compared - self.epoch_start) as f64 / self.rate_hz >= self.cfg.settle_s;
        // Each channel's residual RMS over the window in units of its noise (NaN before the
        // noise is known), and the largest.
        let residual: Vec<f64> = r
            .iter()
            .enumerate()
            .map(|(c, rc)| {
                let rms = (rc.iter().map(|x| x * x).sum::<f64>() / n as f64).sqrt();
                rms / self.sigma.get(c).copied().unwrap_or(f64::NAN)
            })
            .collect();
        let worst = residual.iter().fold(0.0f64, |a, &x| a.max(x));
        let noise_known =
            t_rel >= self.cfg.warmup_s && self.noise_windows >= self.cfg.sigma_windows;
        let p = self.cfg.adapt.len();
        let mut est = Estimate {
            values: self.values.clone(),
            std_err: vec![f64::NAN; p],
            frozen: Vec::new(),
            rebase: false,
        };
        if t_rel < self.cfg.warmup_s {
            // The twin's own start.
        } else if self.noise_windows < self.cfg.sigma_windows {
            self.learn_noise(&r, n);
        } else if settled {
            self.adapt(runs, &r, worst, &mut est);
            self.estimate_alarms(&est, worst, t_end, out);
        }
        if noise_known {
            self.residual_alarm(runs, &r, worst, t_end, &mut est, out)?;
        }
        if t_rel >= self.cfg.warmup_s {
            self.put_window(runs, n, t_end, residual, &est, out);
        }
        self.move_on(runs, n, r, t_rel >= self.cfg.warmup_s, est)
    }

    /// A window of the noise's learning: per channel the residual's sum of squares `r`, the
    /// measured values' sum and sum of squares, the count; σ after the last of them.
    fn learn_noise(&mut self, r: &[Vec<f64>], n: usize) {
        if self.sigma_acc.len() != r.len() {
            self.sigma_acc = vec![[0.0; 4]; r.len()];
        }
        for ((acc, rc), m) in self.sigma_acc.iter_mut().zip(r).zip(&self.measured) {
            acc[0] += rc.iter().map(|x| x * x).sum::<f64>();
            acc[1] += m[..n].iter().sum::<f64>();
            acc[2] += m[..n].iter().map(|x| x * x).sum::<f64>();
            acc[3] += n as f64;
        }
        self.noise_windows += 1;
        if self.noise_windows == self.cfg.sigma_windows {
            // The residual's RMS, at least 1 % of the channel's own spread: a channel the
            // twin matches closer than that (a noiseless one) counts as matched to it.
            self.sigma = self
                .sigma_acc
                .iter()
                .map(|a| {
                    let mean = a[1] / a[3];
                    let spread = (a[2] / a[3] - mean * mean).max(0.0).sqrt();
                    (a[0] / a[3])
                        .sqrt()
                        .max(MODEL_FLOOR * spread)
                        .max(f64::MIN_POSITIVE)
                })
                .collect();
        }
    }

    /// The window's information `SᵀWS` and score `SᵀWr` added to the epoch's with forgetting,
    /// and the estimate `u·(1 + (SᵀWS)⁻¹SᵀWr)` over the parameters the excitation resolves
    /// (the least resolved frozen while any is above its limit); while the residual `worst`
    /// is beyond `isolate_above` of the noise, only the parameter whose change alone explains
    /// most of the window's residual moves.
    fn adapt(&mut self, runs: &Runs, r: &[Vec<f64>], worst: f64, est: &mut Estimate) {
        let p = self.cfg.adapt.len();
        let lambda = self.cfg.forgetting;
        for v in self.info.iter_mut().chain(self.score.iter_mut()) {
            *v *= lambda;
        }
        if self.info.len() != p * p {
            self.info = vec![0.0; p * p];
            self.score = vec![0.0; p];
        }
        // This window's own score, information diagonal and residual (isolation, below).
        let (mut g_w, mut f_w, mut rr_w) = ([0.0; 4], [0.0; 4], 0.0);
        for (c, rc) in r.iter().enumerate() {
            let w2 = 1.0 / (self.sigma[c] * self.sigma[c]);
            rr_w += w2 * rc.iter().map(|x| x * x).sum::<f64>();
            for (k, rk) in rc.iter().enumerate() {
                // At most the four live parameters: no allocation per sample.
                let mut s = [0.0; 4];
                for (j, sj) in s.iter_mut().enumerate().take(p) {
                    *sj = (runs.out[j + 1][c][k] - runs.out[0][c][k]) / self.cfg.rel_step;
                }
                for a in 0..p {
                    g_w[a] += w2 * s[a] * rk;
                    f_w[a] += w2 * s[a] * s[a];
                    self.score[a] += w2 * s[a] * rk;
                    for b in 0..p {
                        self.info[a * p + b] += w2 * s[a] * s[b];
                    }
                }
            }
        }
        let f = DMatrix::from_row_slice(p, p, &self.info);
        let g = DVector::from_column_slice(&self.score);
        // The excitation supervisor: the least resolved frozen while any is above its limit.
        let mut active: Vec<usize> = (0..p).collect();
        // Isolation: while the twin is far from the stream (a residual beyond `isolate_above`
        // of its noise), only the one parameter whose change alone explains most of the
        // window's residual moves (the others, linearised that far away, would take shares of
        // it and leave the twin's state wrong for seconds).
        if worst > self.cfg.isolate_above {
            let explained = |j: usize| g_w[j] * g_w[j] / (f_w[j] * rr_w).max(f64::MIN_POSITIVE);
            if let Some(best) = (0..p).max_by(|&a, &b| explained(a).total_cmp(&explained(b))) {
                for j in (0..p).filter(|&j| j != best) {
                    est.frozen.push(self.cfg.adapt[j].clone());
                }
                active = vec![best];
            }
        }
        let solved = loop {
            if active.is_empty() {
                break None;
            }
            let fa = f.select_rows(&active).select_columns(&active);
            let Some(cov) = fa.cholesky().map(|c| c.inverse()) else {
                est.frozen
                    .push(self.cfg.adapt[active.remove(active.len() - 1)].clone());
                continue;
            };
            let se: Vec<f64> = (0..active.len()).map(|i| cov[(i, i)].sqrt()).collect();
            let (least, &s) = se
                .iter()
                .enumerate()
                .max_by(|a, b| a.1.total_cmp(b.1))
                .unwrap_or((0, &0.0));
            if s > self.cfg.max_window_rel_se {
                est.frozen
                    .push(self.cfg.adapt[active.remove(least)].clone());
                continue;
            }
            let ga = DVector::from_iterator(active.len(), active.iter().map(|&j| g[j]));
            break Some((&cov * ga, se));
        };
        if let Some((delta, se)) = solved {
            for (i, &j) in active.iter().enumerate() {
                let d = delta[i].clamp(-0.5, 0.5);
                est.values[j] = self.values[j] * (1.0 + d);
                est.std_err[j] = se[i] * self.values[j];
                est.rebase |= d.abs() > self.cfg.rebase_change.max(4.0 * se[i]);
            }
        }
    }

    /// The estimate's alarm: an estimate away from its calibrated value, beyond the band, for
    /// a dwell of estimates that agree with one another within half the band — a value the
    /// twin has settled at. (While a large residual is being explained, the other parameters
    /// take a share of it for a window or two, each time another.)
    fn estimate_alarms(
        &mut self,
        est: &Estimate,
        worst: f64,
        t_end: f64,
        out: &mut dyn physid_core::Sink<TwinOut>,
    ) {
        for j in 0..self.cfg.adapt.len() {
            if !est.std_err[j].is_finite() {
                continue;
            }
            let change = est.values[j] / self.calibrated[j] - 1.0;
            let band = self
                .cfg
                .alarm_change
                .max(self.cfg.alarm_sigmas * est.std_err[j] / est.values[j]);
            let dwell = self.cfg.dwell.max(1);
            let wch = &mut self.watch[j];
            if change.abs() > band {
                if wch.out == 0 {
                    wch.since = t_end;
                }
                wch.out += 1;
                if wch.recent.len() == dwell {
                    wch.recent.remove(0);
                }
                wch.recent.push(change);
                let (lo, hi) = wch
                    .recent
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &c| {
                        (l.min(c), h.max(c))
                    });
                let settled = wch.recent.len() == dwell && hi - lo < 0.5 * self.cfg.alarm_change;
                if settled && !wch.raised {
                    wch.raised = true;
                    out.put(TwinOut::Alarm(TwinAlarm {
                        param: self.cfg.adapt[j].clone(),
                        t_s: t_end,
                        t_start_s: wch.since,
                        change,
                    }));
                }
            } else {
                wch.out = 0;
                wch.recent.clear();
                // Re-armed once back within the band with the residuals within theirs.
                if worst <= self.cfg.isolate_above {
                    wch.raised = false;
                }
            }
        }
    }

    /// The residual's alarm: beyond its band for a dwell of windows, a parameter named — in
    /// the excursion's first window the jump that explains it, which the twin then takes (and
    /// only it).
    fn residual_alarm(
        &mut self,
        runs: &mut Runs,
        r: &[Vec<f64>],
        worst: f64,
        t_end: f64,
        est: &mut Estimate,
        out: &mut dyn physid_core::Sink<TwinOut>,
    ) -> Result<(), AppError> {
        let p = self.cfg.adapt.len();
        let ex = &mut self.excursion;
        let armed = ex.matched >= self.cfg.sigma_windows.max(1);
        if worst <= self.cfg.isolate_above {
            *ex = Excursion {
                matched: if ex.out == 0 { ex.matched + 1 } else { 1 },
                ..Excursion::default()
            };
            return Ok(());
        }
        if ex.out == 0 {
            ex.since = t_end;
        }
        ex.out += 1;
        if ex.out == 1 && armed {
            // The excursion's first window: which parameter's jump, at which quarter of the
            // window, explains it.
            ex.pick = jump_pick(
                runs,
                &self.channels,
                r,
                &self.sigma,
                self.compared,
                &self.cfg.adapt,
                self.cfg.rel_step,
            )?;
            // The twin takes that jump, and only it: the epoch's copies, linearised about a
            // change made long ago, would spread the jump's transient over the other
            // parameters (a K jump inside a window taken as friction).
            if let Some((j, d)) = ex.pick {
                est.values.clone_from(&self.values);
                est.values[j] = self.values[j] * (1.0 + d.clamp(-0.5, 0.5));
                for (i, s) in est.std_err.iter_mut().enumerate() {
                    if i != j {
                        *s = f64::NAN;
                    }
                }
                est.frozen = (0..p)
                    .filter(|&i| i != j)
                    .map(|i| self.cfg.adapt[i].clone())
                    .collect();
                est.rebase = d.abs() > self.cfg.rebase_change;
            }
        }
        if let (false, true, true, Some((j, change))) =
            (ex.raised, armed, ex.out >= self.cfg.dwell.max(1), ex.pick)
        {
            if change.abs() >= self.cfg.alarm_change {
                ex.raised = true;
                self.watch[j].raised = true;
                out.put(TwinOut::Alarm(TwinAlarm {
                    param: self.cfg.adapt[j].clone(),
                    t_s: t_end,
                    t_start_s: ex.since,
                    change,
                }));
            }
        }
        Ok(())
    }

    /// The window reported: the estimate, the residuals (in units of the noise), the
    /// measured and the twin's means.
    fn put_window(
        &self,
        runs: &Runs,
        n: usize,
        t_end: f64,
        residual: Vec<f64>,
        est: &Estimate,
        out: &mut dyn physid_core::Sink<TwinOut>,
    ) {
        let named = |v: Vec<f64>| self.channels.iter().cloned().zip(v).collect();
        let mean = |v: &[f64]| v[..n].iter().sum::<f64>() / n as f64;
        out.put(TwinOut::Window(TwinWindow {
            t_s: t_end,
            params: self
                .cfg
                .adapt
                .iter()
                .cloned()
                .zip(est.values.iter().copied())
                .collect(),
            std_err: est.std_err.clone(),
            frozen: est.frozen.clone(),
            residual: named(residual),
            measured: named(self.measured.iter().map(|m| mean(m)).collect()),
            twin: named(runs.out[0].iter().map(|o| mean(o)).collect()),
        }));
    }

    /// After the window: the twin turned to the stream's crank angle (once `warm`), the
    /// buffers moved on by its `n` samples, a new epoch from `est` when it has moved, and what
    /// the replays of the next window need (its residuals `r`, the snapshots).
    fn move_on(
        &mut self,
        runs: &mut Runs,
        n: usize,
        r: Vec<Vec<f64>>,
        warm: bool,
        est: Estimate,
    ) -> Result<(), AppError> {
        // The twin's crank angle against the stream's at the window's last sample (modulo a
        // cycle): a parameter's change leaves the two apart by what the speeds' transients
        // integrate to, which no parameter explains — the twin and its copies are turned
        // alike (their differences, the sensitivities, stay).
        let gap = (self.theta[n - 1] - runs.theta[n - 1]).rem_euclid(4.0 * PI);
        let gap = if gap > 2.0 * PI { gap - 4.0 * PI } else { gap };
        let turn = if warm && gap.abs() > self.cfg.phase_tolerance {
            for run in &mut runs.runs {
                run.turn(gap);
            }
            for x in &mut runs.theta {
                *x += gap;
            }
            gap
        } else {
            0.0
        };
        // This window, for the replays of the next one.
        runs.prev = Some(PrevWindow {
            first: self.compared,
            y: runs.out[0].iter().map(|o| o[..n].to_vec()).collect(),
            r,
        });
        // The buffers move on.
        for m in &mut self.measured {
            m.drain(..n);
        }
        self.theta.drain(..n);
        runs.theta.drain(..n);
        for o in runs.out.iter_mut().flat_map(|r| r.iter_mut()) {
            o.drain(..n);
        }
        self.compared += n;
        if est.rebase {
            // A new epoch: the twin takes the estimate, the copies start again from it, and
            // the switch's transient settles before the next estimate.
            self.values = est.values;
            for (p, v) in self.cfg.adapt.iter().zip(&self.values) {
                runs.runs[0].set_live_parameter(p, *v)?;
            }
            fork(runs, &self.cfg.adapt, &self.values, self.cfg.rel_step)?;
            self.epoch_start = self.compared;
            self.info.clear();
            self.score.clear();
        }
        // The snapshots and inputs of the window before this one go; what was done to the
        // twin now is kept for the replays through it; the next window starts from the twin
        // as it is now (turned, updated).
        let cut = runs.window_start;
        runs.snaps.retain(|s| s.stepped >= cut);
        runs.boundaries.retain(|b| b.stepped > cut);
        runs.inputs.drain(..cut.saturating_sub(runs.inputs_from));
        runs.inputs_from = runs.inputs_from.max(cut);
        runs.boundaries.push(Boundary {
            stepped: runs.stepped,
            turn,
            values: self.values.clone(),
        });
        runs.window_start = runs.stepped;
        runs.snaps.push(Snap {
            stepped: runs.stepped,
            placed: runs.placed,
            values: self.values.clone(),
            run: runs.runs[0].clone(),
        });
        Ok(())
    }
}
