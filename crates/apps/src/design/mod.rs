//! Experiment design (issue 45; the thesis's procedure starts with the choice of tests whose
//! data make the wanted parameters identifiable, ch. 5–8): which profile of the cell's inputs,
//! within its limits, makes the wanted parameters estimable by the application's recursive
//! estimator, to what standard error, in how long.
//!
//! The method: candidates are drawn from profile families ([`profile`]) and each is run on the
//! virtual cell without noise; the application's own stage turns the run into its estimator's
//! regressors; the information recursion *with the estimator's forgetting*
//! ([`information::ForgettingInformation`]) and the noise's autocovariance after the stage's
//! filtering give the predicted covariance of the estimates at every moment of the test. A
//! criterion (D, A, E, or the time to a target standard error) ranks the candidates over the
//! test after the estimator's start-up; the orthogonal method on the summed information of
//! every candidate tells the parameters no admissible profile reveals. Candidates run on every
//! core. By concern: `information.rs` (the recursion, criteria, the ranking, structural
//! zeros), `profile.rs` (limits and families), `run.rs` (a candidate on the cell, within its
//! envelope), `shaft.rs` (Application 1), `friction.rs` (Application 2), `torque.rs` (Application 3).

pub mod friction;
pub mod information;
pub mod profile;
pub mod run;
pub mod shaft;
pub mod torque;

use crate::error::AppError;
use information::{collinear_pairs, structural_zeros, Criterion, ForgettingInformation};
use nalgebra::DMatrix;
use physid_sim::scenario::Scenario;
use profile::{Family, Limits, ThrottleDraw, FAMILIES};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// How the predicted standard errors are sampled along a test [s].
pub const CURVE_STEP_S: f64 = 0.1;

/// A correlation of two estimates this close to ±1 is reported as a collinear pair.
pub const COLLINEAR: f64 = 0.95;

/// A parameter whose information, after the others', is below this fraction of the most
/// informative one's over every candidate is structurally unidentifiable (Alg. 5.1's cut-off).
pub const STRUCTURAL_CUT: f64 = 1e-10;

/// The longest candidate test [s]: an hour, six times the thesis's longest test (its 10-minute
/// transient). Each candidate's regressors are held while it is judged, one worker's at a
/// time on each core; docs/design.md gives the memory this takes.
pub const MAX_DURATION_S: f64 = 3600.0;

/// The most candidate profiles a design judges: 200 take about 40 s on this 2-core machine, so
/// 100 000 take most of a day; more is a typo.
pub const MAX_CANDIDATES: usize = 100_000;

/// The highest sample rate a design's recordings are simulated at [Hz]: ten times the thesis's
/// 108 kHz.
pub const MAX_RATE_HZ: f64 = 1.08e6;

/// A design's recording rate: 0 < rate ≤ [`MAX_RATE_HZ`].
pub(crate) fn check_rate(rate_hz: f64) -> Result<(), AppError> {
    if rate_hz.is_finite() && rate_hz > 0.0 && rate_hz <= MAX_RATE_HZ {
        Ok(())
    } else {
        Err(AppError::Invalid(format!(
            "recording rate {rate_hz:e} Hz: expected > 0 and at most {MAX_RATE_HZ:e} Hz (ten \
             times the thesis's 108 kHz)"
        )))
    }
}

/// What to design for.
#[derive(Debug, Clone)]
pub struct Design {
    /// The application's parameters, in its estimator's order.
    pub names: Vec<String>,
    /// The indices of the ones the design is for.
    pub selected: Vec<usize>,
    /// How candidates are ranked.
    pub criterion: Criterion,
    /// The relative standard error each selected parameter should reach (the time criterion's
    /// target; reported for the others).
    pub target_rel_se: Option<f64>,
    /// The cell's limits.
    pub limits: Limits,
    /// How the candidates' throttle is drawn (the application's).
    pub throttle: ThrottleDraw,
    /// The band a multisine candidate's frequencies are drawn in [Hz]
    /// ([`profile::MULTISINE_BAND`] by default).
    pub band: (f64, f64),
    /// Each candidate's duration [s].
    pub duration: f64,
    /// How many candidates.
    pub candidates: usize,
    /// Their random draws' seed.
    pub seed: u64,
    /// Worker threads (0: every core).
    pub threads: usize,
}

/// The predicted standard errors along a test.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Curve {
    /// Times [s] from the recording's start: every [`CURVE_STEP_S`] and the test's last
    /// estimator sample.
    pub t: Vec<f64>,
    /// Per selected parameter, its predicted standard error at those times (its unit).
    pub std_err: Vec<Vec<f64>>,
}

/// A profile judged.
#[derive(Debug, Clone, Serialize)]
pub struct Evaluation {
    /// The scenario's name.
    pub name: String,
    /// Its family (`None` for a thesis test).
    pub family: Option<Family>,
    /// Whether it keeps to the limits.
    pub within_limits: bool,
    /// The criterion's mean over the test after the estimator's start-up — its value at the
    /// test's end for an estimator without forgetting (λ = 1) — smaller is better; for the
    /// time criterion, the D value.
    pub score: f64,
    /// The predicted standard error of each selected parameter at the test's end (its unit).
    pub std_err: Vec<f64>,
    /// The same relative to the nominal values.
    pub rel_std_err: Vec<f64>,
    /// The median over the test after start-up of each relative standard error (what a
    /// monitor with forgetting holds most of the time).
    pub median_rel_std_err: Vec<f64>,
    /// When every selected relative standard error falls below the target and stays there
    /// to the end [s] (`None`: never, or no target).
    pub time_to_target_s: Option<f64>,
    /// The curve.
    pub curve: Curve,
    /// The identifiability ranking along the test (Alg. 5.1 on the information the estimator
    /// holds then), at every tenth of the design's duration and at the test's end.
    pub identifiability: Vec<RankingAt>,
    /// The summed information `Σ φφᵀ` in relative coordinates (every parameter).
    #[serde(skip)]
    pub information: DMatrix<f64>,
    /// The predicted covariance at the end (every parameter, their units).
    #[serde(skip)]
    pub covariance: Option<DMatrix<f64>>,
}

/// How an application's estimator sees a test ([`Design::evaluate`]).
#[derive(Debug, Clone, Copy)]
pub struct Estimator<'a> {
    /// Each parameter's nominal value: the standard errors are judged relative to it.
    pub scales: &'a [f64],
    /// Each estimator coordinate's unit: the parameter is `units·x` (1 when the estimator
    /// works in the parameters' own units, the nominal value when in relative deviations).
    pub units: &'a [f64],
    /// Its forgetting factor λ.
    pub lambda: f64,
    /// Its initial covariance `P0 = p0·I` (in its coordinates).
    pub p0: f64,
    /// The autocovariance of its output's noise at its rate, `r(0..)`.
    pub noise: &'a [f64],
    /// Its start-up, left out of the criterion [s].
    pub settle_s: f64,
}

/// The parameters `items` a design is for, by name only (each once, in order): a value
/// (`NAME=VALUE`) is refused with `why` — where the application's nominal values come from.
pub fn plain_names(items: &[String], why: &str) -> Result<Vec<String>, AppError> {
    let mut names: Vec<String> = Vec::new();
    for item in items {
        let name = item.trim();
        if name.contains('=') {
            return Err(AppError::Invalid(format!("--params {name}: {why}")));
        }
        if !names.iter().any(|n| n == name) {
            names.push(name.to_string());
        }
    }
    Ok(names)
}

/// A covariance in the estimator's coordinates `x` made the parameters' `units·x`.
fn in_units(mut c: DMatrix<f64>, units: &[f64]) -> DMatrix<f64> {
    for i in 0..c.nrows() {
        for j in 0..c.ncols() {
            c[(i, j)] *= units[i] * units[j];
        }
    }
    c
}

/// The identifiability ranking at one moment of a test.
#[derive(Debug, Clone, Serialize)]
pub struct RankingAt {
    /// The moment [s of the recording].
    pub t_s: f64,
    /// Every parameter in the orthogonal method's order, with its information left after those
    /// before it, relative to the first's (a relative residual, thesis Table 6.1's column).
    pub ranked: Vec<(String, f64)>,
}

/// A pair of nearly collinear estimates in the chosen test.
#[derive(Debug, Clone, Serialize)]
pub struct Collinear {
    /// The two parameters.
    pub params: [String; 2],
    /// The correlation of their estimates at the test's end.
    pub correlation: f64,
}

/// The result of a design.
#[derive(Debug, Clone, Serialize)]
pub struct Designed {
    /// The parameters designed for.
    pub params: Vec<String>,
    /// The criterion.
    pub criterion: Criterion,
    /// The chosen profile.
    pub scenario: Scenario,
    /// Its evaluation.
    pub chosen: Evaluation,
    /// `{"K": σ, …}`: the predicted standard errors at the end of the chosen test (where the
    /// time criterion cuts it).
    pub predicted_std_err: std::collections::BTreeMap<String, f64>,
    /// The thesis's own tests for this application, over the same duration, judged the same
    /// way.
    pub baselines: Vec<Evaluation>,
    /// Every candidate's name, family and score, best first.
    pub ranking: Vec<(String, Family, f64)>,
    /// Candidates the cell could not run, with why.
    pub failed: Vec<(String, String)>,
    /// Parameters no candidate reveals (structurally unidentifiable on the admissible
    /// inputs): estimated alongside, not designed for (a design for one is refused).
    pub unidentifiable: Vec<String>,
    /// Pairs whose estimates stay nearly collinear in the chosen test (|ρ| ≥ 0.95).
    pub collinear: Vec<Collinear>,
    /// Candidates judged (run within the limits and the cell's envelope).
    pub evaluated: usize,
    /// Wall time [s].
    pub elapsed_s: f64,
}

impl Design {
    /// Check the request.
    pub fn check(&self) -> Result<(), AppError> {
        self.limits.check().map_err(AppError::Invalid)?;
        if self.selected.is_empty() {
            return Err(AppError::Invalid("design: no parameters chosen".into()));
        }
        if !(self.duration.is_finite() && (1.0..=MAX_DURATION_S).contains(&self.duration)) {
            return Err(AppError::Invalid(format!(
                "design: duration {} s: expected 1–{MAX_DURATION_S} s (a candidate's regressors are held while it is judged)",
                physid_core::Num(self.duration)
            )));
        }
        for (k, i) in self.selected.iter().enumerate() {
            if self.selected[..k].contains(i) {
                return Err(AppError::Invalid(format!(
                    "design: parameter '{}' chosen twice",
                    self.names.get(*i).map_or("?", String::as_str)
                )));
            }
        }
        let (lo, hi) = self.band;
        if !(lo.is_finite() && hi.is_finite() && 0.0 < lo && lo <= hi) {
            return Err(AppError::Invalid(format!(
                "design: multisine band {}:{} Hz: expected 0 < low ≤ high",
                physid_core::Num(lo),
                physid_core::Num(hi)
            )));
        }
        if !(1..=MAX_CANDIDATES).contains(&self.candidates) {
            return Err(AppError::Invalid(format!(
                "design: --candidates {}: expected 1–{MAX_CANDIDATES} (200 take about 40 s here)",
                self.candidates
            )));
        }
        if self.criterion == Criterion::Time && self.target_rel_se.is_none() {
            return Err(AppError::Invalid(
                "design: the time criterion needs --target-rel-se".into(),
            ));
        }
        if let Some(t) = self.target_rel_se {
            if !(t.is_finite() && t > 0.0) {
                return Err(AppError::Invalid(format!(
                    "design: target relative standard error {}: expected > 0",
                    physid_core::Num(t)
                )));
            }
        }
        Ok(())
    }

    /// Judge the regressors `(t, φ, σ)` of one test (`σ`: the noise's level on that output,
    /// 1 for a stationary noise) as `est` sees them: the information recursion with its
    /// forgetting, the standard errors relative to its nominal values, the criterion's mean
    /// after its start-up.
    pub fn evaluate<'a>(
        &self,
        rows: impl Iterator<Item = (f64, &'a [f64], f64)>,
        est: &Estimator<'_>,
    ) -> Result<Evaluation, AppError> {
        let p = self.names.len();
        let Estimator {
            scales,
            units,
            lambda,
            p0,
            noise,
            settle_s,
        } = *est;
        if scales.len() != p || units.len() != p {
            return Err(AppError::Invalid(format!(
                "design: {p} parameters but {} nominal values and {} units",
                scales.len(),
                units.len()
            )));
        }
        let mut info =
            ForgettingInformation::new(p, lambda, p0, noise).map_err(AppError::Invalid)?;
        let mut sum = vec![0.0; p * p];
        let mut curve = Curve {
            t: Vec::new(),
            std_err: vec![Vec::new(); self.selected.len()],
        };
        let mut scores = Vec::new();
        let mut ranking = Vec::new();
        let rank_every = self.duration / 10.0;
        let mut next_rank = f64::INFINITY;
        let (mut t0, mut next) = (None, f64::NEG_INFINITY);
        let mut last_t = f64::NEG_INFINITY;
        let mut rel = vec![0.0; p];
        for (t, phi, sigma) in rows {
            info.push_scaled(phi, sigma);
            for ((r, f), (s, u)) in rel.iter_mut().zip(phi).zip(scales.iter().zip(units)) {
                *r = f * s / u;
            }
            for (row, &ri) in sum.chunks_exact_mut(p).zip(&rel) {
                for (c, &rj) in row.iter_mut().zip(&rel) {
                    *c += ri * rj;
                }
            }
            let start = *t0.get_or_insert_with(|| {
                next_rank = t + rank_every;
                t
            });
            last_t = t;
            if t >= next_rank {
                next_rank += rank_every;
                ranking.push(self.rank_at(t, &info, scales, units));
            }
            if t >= next {
                next = t + CURVE_STEP_S;
                let cov = info.covariance().map(|c| in_units(c, units));
                // Before the data resolve every parameter the curve has no point: it starts
                // at the first moment they do; a later moment that does not resolve them all
                // has an unbounded error.
                if cov.is_some() || !curve.t.is_empty() {
                    curve.t.push(t);
                    for (c, &i) in curve.std_err.iter_mut().zip(&self.selected) {
                        c.push(
                            cov.as_ref()
                                .map_or(f64::INFINITY, |m| m[(i, i)].max(0.0).sqrt()),
                        );
                    }
                }
                if t - start >= settle_s {
                    scores.push(cov.as_ref().map_or(f64::INFINITY, |m| {
                        self.criterion.value(&self.relative(m, scales))
                    }));
                }
            }
        }
        if ranking.last().is_none_or(|r: &RankingAt| r.t_s < last_t) && t0.is_some() {
            ranking.push(self.rank_at(last_t, &info, scales, units));
        }
        let covariance = info.covariance().map(|c| in_units(c, units));
        let std_err: Vec<f64> = self
            .selected
            .iter()
            .map(|&i| {
                covariance
                    .as_ref()
                    .map_or(f64::INFINITY, |m| m[(i, i)].max(0.0).sqrt())
            })
            .collect();
        // The curve ends at the test's end: the standard errors above.
        if covariance.is_some() && curve.t.last().is_some_and(|&l| l < last_t) {
            curve.t.push(last_t);
            for (c, s) in curve.std_err.iter_mut().zip(&std_err) {
                c.push(*s);
            }
        }
        let rel_std_err: Vec<f64> = std_err
            .iter()
            .zip(&self.selected)
            .map(|(s, &i)| s / scales[i].abs())
            .collect();
        // The test's start: its first regressor's time.
        let first = t0.unwrap_or(0.0);
        let after: Vec<usize> = (0..curve.t.len())
            .filter(|&k| curve.t[k] - first >= settle_s)
            .collect();
        let median_rel_std_err = self
            .selected
            .iter()
            .enumerate()
            .map(|(c, &i)| {
                let mut v: Vec<f64> = after
                    .iter()
                    .map(|&k| curve.std_err[c][k] / scales[i].abs())
                    .collect();
                v.sort_by(f64::total_cmp);
                v.get(v.len() / 2).copied().unwrap_or(f64::INFINITY)
            })
            .collect();
        let time_to_target_s = self.target_rel_se.and_then(|target| {
            // The last curve point where some selected one is above target; the next one on.
            let above = |k: usize| {
                self.selected.iter().enumerate().any(|(c, &i)| {
                    let rel = curve.std_err[c][k] / scales[i].abs();
                    rel.is_nan() || rel > target
                })
            };
            match (0..curve.t.len()).rev().find(|&k| above(k)) {
                None => curve.t.first().map(|t| t - first),
                Some(k) if k + 1 < curve.t.len() => Some(curve.t[k + 1] - first),
                Some(_) => None,
            }
        });
        // Without forgetting the estimate at the end is the result (a characterisation): the
        // criterion is its value there. With forgetting, what the estimator holds along the
        // test (a monitor): the criterion's mean after its start-up.
        let score = if lambda == 1.0 {
            covariance.as_ref().map_or(f64::INFINITY, |m| {
                self.criterion.value(&self.relative(m, scales))
            })
        } else if scores.is_empty() {
            f64::INFINITY
        } else {
            scores.iter().sum::<f64>() / scores.len() as f64
        };
        Ok(Evaluation {
            name: String::new(),
            family: None,
            within_limits: true,
            score,
            std_err,
            rel_std_err,
            median_rel_std_err,
            time_to_target_s,
            curve,
            identifiability: ranking,
            information: DMatrix::from_row_slice(p, p, &sum),
            covariance,
        })
    }

    /// The ranking at `t` of the information `info` holds, in relative coordinates.
    fn rank_at(
        &self,
        t: f64,
        info: &ForgettingInformation,
        scales: &[f64],
        units: &[f64],
    ) -> RankingAt {
        let mut d = info.data_information();
        let f: Vec<f64> = scales.iter().zip(units).map(|(s, u)| s / u).collect();
        for i in 0..d.nrows() {
            for j in 0..d.ncols() {
                d[(i, j)] *= f[i] * f[j];
            }
        }
        RankingAt {
            t_s: t,
            ranked: information::ranking(&d)
                .into_iter()
                .map(|(j, r)| (self.names[j].clone(), r))
                .collect(),
        }
    }

    /// The selected parameters' covariance relative to their nominal values.
    fn relative(&self, cov: &DMatrix<f64>, scales: &[f64]) -> DMatrix<f64> {
        let s = self.selected.len();
        DMatrix::from_fn(s, s, |a, b| {
            let (i, j) = (self.selected[a], self.selected[b]);
            cov[(i, j)] / (scales[i] * scales[j]).abs()
        })
    }

    /// Whether `a` is a better test than `b` by the criterion.
    fn better(&self, a: &Evaluation, b: &Evaluation) -> bool {
        if self.criterion == Criterion::Time {
            let ta = a.time_to_target_s.unwrap_or(f64::INFINITY);
            let tb = b.time_to_target_s.unwrap_or(f64::INFINITY);
            if ta != tb {
                return ta < tb;
            }
        }
        a.score < b.score
    }

    /// The candidates' scenarios, drawn from the families in turn.
    pub fn candidates(&self) -> Vec<Scenario> {
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        (0..self.candidates)
            .map(|k| {
                let fam = FAMILIES[k % FAMILIES.len()];
                profile::draw(
                    &mut rng,
                    fam,
                    &self.limits,
                    self.duration,
                    &format!("design-{}-{k}", fam.name()),
                    self.throttle,
                    self.band,
                )
            })
            .collect()
    }

    /// Run the design: every candidate judged by `judge` on the worker threads, the best
    /// chosen, the `baselines` (the thesis's tests, cut to the design's duration) judged
    /// alongside. `progress` is told how many candidates are done.
    pub fn run(
        &self,
        judge: &(dyn Fn(&Scenario) -> Result<Evaluation, AppError> + Sync),
        baselines: &[Scenario],
        progress: &(dyn Fn(usize) + Sync),
    ) -> Result<Designed, AppError> {
        self.check()?;
        let clock = std::time::Instant::now();
        let cands = self.candidates();
        // The thesis's tests, cut to the design's duration, judged on the same workers after
        // the candidates.
        let jobs: Vec<Scenario> = cands
            .iter()
            .cloned()
            .chain(baselines.iter().map(|b| Scenario {
                duration: self.duration,
                ..b.clone()
            }))
            .collect();
        let next = AtomicUsize::new(0);
        let results: Mutex<Vec<(usize, Result<Evaluation, AppError>)>> = Mutex::new(Vec::new());
        let threads = if self.threads == 0 {
            std::thread::available_parallelism().map_or(1, |n| n.get())
        } else {
            self.threads
        }
        .min(jobs.len())
        .max(1);
        std::thread::scope(|s| {
            for _ in 0..threads {
                s.spawn(|| loop {
                    let k = next.fetch_add(1, Ordering::Relaxed);
                    let Some(sc) = jobs.get(k) else { break };
                    let r = judge(sc).map(|mut e| {
                        e.name = sc.name.clone();
                        e.family = (k < cands.len()).then(|| FAMILIES[k % FAMILIES.len()]);
                        e.within_limits = self.limits.admit(sc);
                        e
                    });
                    let mut g = results.lock().unwrap_or_else(|e| e.into_inner());
                    g.push((k, r));
                    progress(g.len().min(cands.len()));
                });
            }
        });
        let mut results = results.into_inner().unwrap_or_else(|e| e.into_inner());
        results.sort_by_key(|r| r.0);
        let mut failed = Vec::new();
        let mut evals: Vec<(usize, Evaluation)> = Vec::new();
        let mut base = Vec::new();
        for (k, r) in results {
            if k >= cands.len() {
                match r {
                    Ok(e) => base.push(e),
                    Err(e) => failed.push((jobs[k].name.clone(), e.to_string())),
                }
                continue;
            }
            match r {
                Ok(e) if e.within_limits => evals.push((k, e)),
                Ok(e) => failed.push((e.name, "outside the limits".into())),
                Err(e) => failed.push((cands[k].name.clone(), e.to_string())),
            }
        }
        // Structural zeros: from every candidate's information together.
        let p = self.names.len();
        let mut total = DMatrix::<f64>::zeros(p, p);
        for (_, e) in &evals {
            total += &e.information;
        }
        let zeros = if evals.is_empty() {
            Vec::new()
        } else {
            structural_zeros(&total, STRUCTURAL_CUT)
        };
        if let Some(&z) = zeros.iter().find(|z| self.selected.contains(z)) {
            return Err(AppError::Invalid(format!(
                "design: {} is structurally unidentifiable: no admissible profile of the {} candidates gives it information independent of the others' ({}); fix it at its nominal value or widen the limits",
                self.names[z],
                evals.len(),
                zeros.iter().map(|&i| self.names[i].as_str()).collect::<Vec<_>>().join(", ")
            )));
        }
        let best = evals
            .iter()
            .enumerate()
            .filter(|(_, (_, e))| e.score.is_finite())
            .fold(None::<usize>, |acc, (j, (_, e))| match acc {
                Some(b) if !self.better(e, &evals[b].1) => Some(b),
                _ => Some(j),
            })
            .ok_or_else(|| {
                AppError::Invalid(format!(
                    "design: none of the {} candidates resolves {} ({} failed: {})",
                    self.candidates,
                    self.selected
                        .iter()
                        .map(|&i| self.names[i].as_str())
                        .collect::<Vec<_>>()
                        .join(", "),
                    failed.len(),
                    failed
                        .first()
                        .map_or(String::new(), |f| format!("{}: {}", f.0, f.1))
                ))
            })?;
        let (k, chosen) = evals[best].clone();
        let mut scenario = cands[k].clone();
        // The predicted standard errors where the test ends.
        let mut at_end = chosen.std_err.clone();
        if self.criterion == Criterion::Time {
            if let Some(t) = chosen.time_to_target_s {
                // The test ends once the target is reached and held: at the next half second.
                scenario.duration = ((t * 2.0).ceil() / 2.0).clamp(0.5, self.duration);
                let c = &chosen.curve;
                let first = c.t.first().copied().unwrap_or(0.0);
                if let Some(j) = c.t.iter().rposition(|&x| x - first <= scenario.duration) {
                    at_end = c.std_err.iter().map(|s| s[j]).collect();
                }
            }
        }
        let mut ranking: Vec<(String, Family, f64)> = evals
            .iter()
            .map(|(_, e)| {
                (
                    e.name.clone(),
                    e.family.unwrap_or(Family::Constant),
                    e.score,
                )
            })
            .collect();
        ranking.sort_by(|a, b| a.2.total_cmp(&b.2));
        let collinear = chosen
            .covariance
            .as_ref()
            .map(|c| {
                collinear_pairs(c, COLLINEAR)
                    .into_iter()
                    .map(|(i, j, rho)| Collinear {
                        params: [self.names[i].clone(), self.names[j].clone()],
                        correlation: rho,
                    })
                    .collect()
            })
            .unwrap_or_default();
        let predicted_std_err = self
            .selected
            .iter()
            .zip(&at_end)
            .map(|(&i, &s)| (self.names[i].clone(), s))
            .collect();
        Ok(Designed {
            params: self
                .selected
                .iter()
                .map(|&i| self.names[i].clone())
                .collect(),
            criterion: self.criterion,
            scenario,
            predicted_std_err,
            chosen,
            baselines: base,
            ranking,
            failed,
            unidentifiable: zeros.iter().map(|&i| self.names[i].clone()).collect(),
            collinear,
            evaluated: evals.len(),
            elapsed_s: clock.elapsed().as_secs_f64(),
        })
    }
}
