//! Calibrating the virtual cell from a recording (issue 44; thesis §9.2's self-calibrated
//! model): which of the cell's physical parameters the recording resolves, their values and
//! 95 % intervals.
//!
//! The cell is driven by the recording's inputs ([`Replay`]) and its noiseless outputs are
//! compared with the measured channels degree by degree, each channel weighted by its noise
//! (`r_c = (y_c − ŷ_c(ϑ))/σ_c`, `σ_c` the channel's residual RMS at the fit). In scaled
//! coordinates `u_j = ϑ_j/ϑ_j,nominal`:
//!
//! 1. the sensitivities `S = ∂ŷ/∂u` of the whole run, by central differences of replays
//!    (step [`REL_STEP`]; the tests check they converge with the step);
//! 2. the estimability ranking of `Z = W·S` (thesis Alg. 5.1, [`physid_ident::ranking`]) at
//!    the nominal cell; along it a parameter is estimable when, with those taken before it,
//!    every relative standard error stays ≤ `max_rel_se` — the others are held at nominal,
//!    and said so;
//! 3. a bounded Gauss–Newton (Levenberg–Marquardt) fit of the estimable ones, `u` within
//!    [`BOUNDS`] of nominal, until every step is below 1 % of its standard error;
//! 4. their covariance `(ZᵀZ)⁻¹` at the fit (the Fisher information of white sensor noise),
//!    95 % intervals `±1.96·σ`, and the pairs correlated beyond 0.9.

use super::replay::Replay;
use crate::error::AppError;
use nalgebra::{DMatrix, DVector};
use physid_sim::params::CellParams;
use serde::Serialize;

/// The cell's parameters a twin calibrates by default (their `--list-params` paths).
pub const DEFAULT_PARAMS: &[&str] = &[
    "shaft.k",
    "shaft.b",
    "engine.inertia",
    "dyno.inertia",
    "engine.friction_scale",
    "engine.kappa",
    "engine.v_int",
    "engine.m_rec",
];

/// Relative step of the central differences.
pub const REL_STEP: f64 = 2.5e-4;
/// How far from nominal a calibrated value may go: `[BOUNDS.0, BOUNDS.1]·nominal`.
pub const BOUNDS: (f64, f64) = (0.25, 4.0);
/// Correlations beyond this are reported as nearly collinear pairs.
pub const COLLINEAR: f64 = 0.9;

/// What to calibrate.
#[derive(Debug, Clone)]
pub struct CalibrateConfig {
    /// The nominal cell (the start values, and the values of whatever is held).
    pub cell: CellParams,
    /// The parameters tried (paths).
    pub params: Vec<String>,
    /// A parameter is estimable while its relative standard error stays at or below this.
    pub max_rel_se: f64,
    /// Gauss–Newton iterations at most.
    pub max_iter: usize,
    /// Threads for the replays (0: all cores).
    pub threads: usize,
}

impl Default for CalibrateConfig {
    fn default() -> Self {
        Self {
            cell: CellParams::default(),
            params: DEFAULT_PARAMS.iter().map(|s| s.to_string()).collect(),
            max_rel_se: 0.05,
            max_iter: 12,
            threads: 0,
        }
    }
}

/// One parameter's result.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ParamFit {
    /// Path (`--list-params`).
    pub path: String,
    /// Nominal value (the start, and the value kept when not estimable).
    pub nominal: f64,
    /// Calibrated value (nominal when not estimable).
    pub value: f64,
    /// Standard error (estimable), or the one it would have alongside the estimable ones.
    pub std_err: f64,
    /// 95 % interval (estimable only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ci95: Option<[f64; 2]>,
    /// Whether the recording resolves it.
    pub estimable: bool,
    /// Its place in the estimability ranking at the nominal cell (1 = most estimable).
    pub rank: usize,
    /// Why it is held (not estimable).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub held: Option<String>,
}

/// One channel's match.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ChannelFit {
    /// Name.
    pub name: String,
    /// The noise σ the fit weighted it by (its residual RMS at the fit).
    pub sigma: f64,
    /// Residual RMS of the nominal cell.
    pub rms_nominal: f64,
    /// Residual RMS of the calibrated cell.
    pub rms_calibrated: f64,
}

/// A calibration.
#[derive(Debug, Clone, Serialize)]
pub struct Calibration {
    /// Every parameter tried, in the order given.
    pub params: Vec<ParamFit>,
    /// The channels matched.
    pub channels: Vec<ChannelFit>,
    /// Pairs of estimable parameters correlated beyond [`COLLINEAR`]: `(a, b, ρ)`.
    pub collinear: Vec<(String, String, f64)>,
    /// Gauss–Newton iterations taken.
    pub iterations: usize,
    /// Samples per channel compared.
    pub samples: usize,
    /// Replays of the cell run.
    pub replays: usize,
    /// The estimable parameters' covariance (what `check` propagates into each channel's
    /// residual band).
    pub covariance: Covariance,
}

/// The covariance of the estimable parameters, `(ZᵀZ)⁻¹` at the fit in their own units.
#[derive(Debug, Clone, Default, Serialize, serde::Deserialize, PartialEq)]
pub struct Covariance {
    /// The parameters (paths), in the matrix's order.
    pub params: Vec<String>,
    /// Row by row [unit_i·unit_j].
    pub matrix: Vec<Vec<f64>>,
}

impl Calibration {
    /// The calibrated cell: `cell` with the estimable parameters' values.
    pub fn cell(&self, cell: &CellParams) -> Result<CellParams, AppError> {
        let mut c = cell.clone();
        for p in self.params.iter().filter(|p| p.estimable) {
            c.set(&p.path, p.value)?;
        }
        Ok(c)
    }
}

/// The cell with parameters `paths` at `u·nominal`.
fn cell_at(base: &CellParams, paths: &[String], nominal: &[f64], u: &[f64]) -> CellParams {
    let mut c = base.clone();
    for ((p, n), u) in paths.iter().zip(nominal).zip(u) {
        // Paths were checked when the nominal values were read.
        let _ = c.set(p, n * u);
    }
    c
}

/// `f` of every item, on `threads` threads, in order.
fn par_map<T: Sync, R: Send>(items: &[T], threads: usize, f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::Mutex;
    let threads = if threads == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        threads
    }
    .clamp(1, items.len().max(1));
    let next = AtomicUsize::new(0);
    let out: Mutex<Vec<(usize, R)>> = Mutex::new(Vec::with_capacity(items.len()));
    std::thread::scope(|s| {
        for _ in 0..threads {
            s.spawn(|| loop {
                let k = next.fetch_add(1, Ordering::Relaxed);
                let Some(item) = items.get(k) else { break };
                let r = f(item);
                out.lock().unwrap_or_else(|e| e.into_inner()).push((k, r));
            });
        }
    });
    let mut out = out.into_inner().unwrap_or_else(|e| e.into_inner());
    out.sort_by_key(|r| r.0);
    out.into_iter().map(|r| r.1).collect()
}

/// The fit's working state: the replay, the parameters and the weights.
struct Problem<'a> {
    replay: &'a Replay,
    base: &'a CellParams,
    paths: Vec<String>,
    nominal: Vec<f64>,
    threads: usize,
    rel_step: f64,
    replays: std::sync::atomic::AtomicUsize,
}

impl Problem<'_> {
    /// The replayed outputs at `u` (the paths `active`, the others at nominal).
    fn outputs(&self, active: &[usize], u: &[f64]) -> Result<Vec<Vec<f64>>, AppError> {
        let mut full = vec![1.0; self.paths.len()];
        for (&j, &uj) in active.iter().zip(u) {
            full[j] = uj;
        }
        self.replays
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        self.replay
            .simulate(&cell_at(self.base, &self.paths, &self.nominal, &full))
    }

    /// Each channel's residual `y − ŷ`.
    fn residuals(&self, y: &[Vec<f64>]) -> Vec<Vec<f64>> {
        self.replay
            .measured
            .iter()
            .zip(y)
            .map(|(m, s)| m.iter().zip(s).map(|(a, b)| a - b).collect())
            .collect()
    }

    /// The outputs at `u` and their sensitivities to each of `active` (central differences),
    /// the replays run on all threads: `(ŷ, S)` with `S[j][c][k] = ∂ŷ_c,k/∂u_j`.
    #[allow(clippy::type_complexity)]
    fn sensitivities(
        &self,
        active: &[usize],
        u: &[f64],
    ) -> Result<(Vec<Vec<f64>>, Vec<Vec<Vec<f64>>>), AppError> {
        let mut jobs: Vec<Vec<f64>> = vec![u.to_vec()];
        for j in 0..active.len() {
            for sign in [1.0, -1.0] {
                let mut v = u.to_vec();
                v[j] += sign * self.rel_step;
                jobs.push(v);
            }
        }
        let mut runs = par_map(&jobs, self.threads, |v| self.outputs(active, v)).into_iter();
        let y = runs
            .next()
            .ok_or_else(|| AppError::Invalid("no replay".into()))??;
        let mut s = Vec::with_capacity(active.len());
        for _ in active {
            let plus = runs
                .next()
                .ok_or_else(|| AppError::Invalid("no replay".into()))??;
            let minus = runs
                .next()
                .ok_or_else(|| AppError::Invalid("no replay".into()))??;
            s.push(
                plus.iter()
                    .zip(&minus)
                    .map(|(p, m)| {
                        p.iter()
                            .zip(m)
                            .map(|(a, b)| (a - b) / (2.0 * self.rel_step))
                            .collect()
                    })
                    .collect(),
            );
        }
        Ok((y, s))
    }
}

/// Each channel's RMS.
fn rms(r: &[Vec<f64>]) -> Vec<f64> {
    r.iter()
        .map(|c| (c.iter().map(|x| x * x).sum::<f64>() / c.len().max(1) as f64).sqrt())
        .collect()
}

/// The weights `1/σ_c`, σ_c a channel's residual RMS, floored at 1e-9 of its largest
/// measured magnitude (a channel matched to rounding).
fn weights(r: &[Vec<f64>], measured: &[Vec<f64>]) -> Vec<f64> {
    rms(r)
        .iter()
        .zip(measured)
        .map(|(s, m)| {
            let big = m.iter().fold(0.0f64, |a, x| a.max(x.abs()));
            1.0 / s.max(1e-9 * big).max(f64::MIN_POSITIVE)
        })
        .collect()
}

/// `Z = W·S` (rows: every channel's samples) for the columns `cols` of `s`, and `W·r`.
fn weighted(
    s: &[Vec<Vec<f64>>],
    cols: &[usize],
    r: &[Vec<f64>],
    w: &[f64],
) -> (DMatrix<f64>, DVector<f64>) {
    let rows: usize = r.iter().map(Vec::len).sum();
    let mut z = DMatrix::zeros(rows, cols.len());
    let mut rw = DVector::zeros(rows);
    let mut i0 = 0;
    for (c, (rc, wc)) in r.iter().zip(w).enumerate() {
        for (k, x) in rc.iter().enumerate() {
            rw[i0 + k] = wc * x;
            for (jj, &j) in cols.iter().enumerate() {
                z[(i0 + k, jj)] = wc * s[j][c][k];
            }
        }
        i0 += rc.len();
    }
    (z, rw)
}

/// `(ZᵀZ)⁻¹`, or `None` when singular.
fn covariance(z: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    (z.transpose() * z).cholesky().map(|c| c.inverse())
}

/// A Levenberg–Marquardt fit's state: the scaled values of the active parameters, the
/// outputs there, their sensitivities, the residuals and the weights.
struct Fit {
    u: Vec<f64>,
    y: Vec<Vec<f64>>,
    s: Vec<Vec<Vec<f64>>>,
    r: Vec<Vec<f64>>,
    w: Vec<f64>,
    iterations: usize,
}

impl Fit {
    /// `Σ_c Σ_k (w_c·r_c,k)²`.
    fn cost(r: &[Vec<f64>], w: &[f64]) -> f64 {
        r.iter()
            .zip(w)
            .map(|(c, wc)| c.iter().map(|x| (wc * x).powi(2)).sum::<f64>())
            .sum()
    }

    /// Bounded Levenberg–Marquardt steps on `active` (`u` within [`BOUNDS`]) until each step
    /// is below 1 % of its standard error, or `max_iter`; the weights follow the residuals.
    fn levenberg_marquardt(
        &mut self,
        pb: &Problem<'_>,
        active: &[usize],
        max_iter: usize,
    ) -> Result<(), AppError> {
        let cols: Vec<usize> = (0..active.len()).collect();
        let mut mu = 1e-3;
        self.iterations = 0;
        if self.s.len() != active.len() {
            let (y, s) = pb.sensitivities(active, &self.u)?;
            self.r = pb.residuals(&y);
            (self.y, self.s) = (y, s);
        }
        while self.iterations < max_iter {
            self.iterations += 1;
            let (z, rw) = weighted(&self.s, &cols, &self.r, &self.w);
            let jtj = z.transpose() * &z;
            let g = z.transpose() * rw;
            let c0 = Self::cost(&self.r, &self.w);
            let mut accepted = None;
            for _ in 0..10 {
                let mut a = jtj.clone();
                for i in 0..a.nrows() {
                    a[(i, i)] *= 1.0 + mu;
                }
                let Some(step) = a.cholesky().map(|c| c.solve(&g)) else {
                    mu *= 10.0;
                    continue;
                };
                let un: Vec<f64> = self
                    .u
                    .iter()
                    .zip(step.iter())
                    .map(|(a, d)| (a + d).clamp(BOUNDS.0, BOUNDS.1))
                    .collect();
                if let Ok(yn) = pb.outputs(active, &un) {
                    if Self::cost(&pb.residuals(&yn), &self.w) < c0 {
                        accepted = Some((un, step));
                        mu = (mu / 10.0).max(1e-9);
                        break;
                    }
                }
                mu *= 10.0;
            }
            let Some((un, step)) = accepted else { break };
            self.u = un;
            let (y, s) = pb.sensitivities(active, &self.u)?;
            self.r = pb.residuals(&y);
            (self.y, self.s) = (y, s);
            self.w = weights(&self.r, &pb.replay.measured);
            let (z, _) = weighted(&self.s, &cols, &self.r, &self.w);
            if let Some(cov) = covariance(&z) {
                if step
                    .iter()
                    .enumerate()
                    .all(|(i, d)| d.abs() < 0.01 * cov[(i, i)].sqrt())
                {
                    break;
                }
            }
        }
        Ok(())
    }
}

/// The nominal values of `params` in `cell`, each checked to be a positive number.
fn nominal_values(cell: &CellParams, params: &[String]) -> Result<Vec<f64>, AppError> {
    if params.is_empty() {
        return Err(AppError::Invalid("no parameters to calibrate".into()));
    }
    let mut nominal = Vec::with_capacity(params.len());
    for p in params {
        let v = cell.get(p).ok_or_else(|| {
            AppError::Invalid(format!(
                "--params {p}: no such cell parameter (physid simulate --list-params)"
            ))
        })?;
        if !(v.is_finite() && v > 0.0) {
            return Err(AppError::Invalid(format!(
                "--params {p}: its nominal value {v} is not > 0 (the twin calibrates positive physical parameters relative to nominal)"
            )));
        }
        nominal.push(v);
    }
    Ok(nominal)
}

/// The sensitivities `∂ŷ_c,k/∂u_j` of the replayed outputs to each of `params` in scaled
/// coordinates (`u_j = ϑ_j/ϑ_j,nominal`) at the cell `cell`, by central differences of step
/// `rel_step`: `[j][c][k]`.
pub fn sensitivities(
    replay: &Replay,
    cell: &CellParams,
    params: &[String],
    rel_step: f64,
) -> Result<Vec<Vec<Vec<f64>>>, AppError> {
    let pb = Problem {
        replay,
        base: cell,
        paths: params.to_vec(),
        nominal: nominal_values(cell, params)?,
        threads: 0,
        rel_step,
        replays: Default::default(),
    };
    let all: Vec<usize> = (0..params.len()).collect();
    Ok(pb.sensitivities(&all, &vec![1.0; all.len()])?.1)
}

/// Calibrate the cell `config.cell` on `replay`.
pub fn calibrate(replay: &Replay, config: &CalibrateConfig) -> Result<Calibration, AppError> {
    let pb = Problem {
        replay,
        base: &config.cell,
        paths: config.params.clone(),
        nominal: nominal_values(&config.cell, &config.params)?,
        threads: config.threads,
        rel_step: REL_STEP,
        replays: Default::default(),
    };
    let all: Vec<usize> = (0..pb.paths.len()).collect();
    // 1–2. Sensitivities and the ranking at the nominal cell.
    let ones = vec![1.0; all.len()];
    let (y0, s0) = pb.sensitivities(&all, &ones)?;
    let r0 = pb.residuals(&y0);
    let rms_nominal = rms(&r0);
    let w0 = weights(&r0, &replay.measured);
    let (z0, _) = weighted(&s0, &all, &r0, &w0);
    let qr = z0.clone().qr();
    let ranking = physid_ident::ranking::rank(&qr.r());
    let mut rank_of = vec![0; all.len()];
    for (i, st) in ranking.steps.iter().enumerate() {
        rank_of[st.param] = i + 1;
    }
    // Along the ranking, a first estimable set: each parameter whose information is not
    // repeated by those before it (relative standard error below 1 with the nominal
    // residual's weights — a noise larger than the data's, so nothing resolved is left out).
    let mut active: Vec<usize> = Vec::new();
    let mut held: Vec<(usize, String)> = Vec::new();
    for st in &ranking.steps {
        let mut trial = active.clone();
        trial.push(st.param);
        match covariance(&z0.select_columns(&trial)) {
            Some(cov) if (0..trial.len()).all(|i| cov[(i, i)].sqrt() <= 1.0) => active = trial,
            _ => held.push((
                st.param,
                "no information in this recording beside the parameters ranked before it (its sensitivity is nil or repeats theirs)".into(),
            )),
        }
    }
    // 3. Fit; then, with the fit's noise, drop the least resolved while any relative standard
    // error exceeds the limit, and fit again from there.
    let mut fit = Fit {
        u: vec![1.0; active.len()],
        y: y0.clone(),
        s: active.iter().map(|&j| s0[j].clone()).collect(),
        r: r0.clone(),
        w: w0.clone(),
        iterations: 0,
    };
    let mut iterations = 0;
    let cov = loop {
        if active.is_empty() {
            break DMatrix::zeros(0, 0);
        }
        fit.levenberg_marquardt(&pb, &active, config.max_iter)?;
        iterations += fit.iterations;
        let (z, _) = weighted(
            &fit.s,
            &(0..active.len()).collect::<Vec<_>>(),
            &fit.r,
            &fit.w,
        );
        let cov = covariance(&z).ok_or_else(|| {
            AppError::Invalid("the estimable parameters' information is singular at the fit".into())
        })?;
        let rel: Vec<f64> = (0..active.len()).map(|i| cov[(i, i)].sqrt()).collect();
        let (worst, &se) = rel
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .unwrap_or((0, &0.0));
        if se <= config.max_rel_se {
            break cov;
        }
        let j = active.remove(worst);
        held.push((
            j,
            format!(
                "not resolved: its relative standard error at the fit was {se:.2e} (limit {})",
                config.max_rel_se
            ),
        ));
        // Back to nominal, the others from where they were.
        fit.u.remove(worst);
        fit.s.clear();
    };
    let (u, r, w) = (fit.u.clone(), fit.r.clone(), fit.w.clone());
    // 4. The covariance at the fit (above), the intervals and the collinear pairs.
    let rms_calibrated = rms(&r);
    let sigma: Vec<f64> = w.iter().map(|x| 1.0 / x).collect();
    // The held ones' standard errors beside the estimable set, at the nominal point's weights.
    let mut params: Vec<ParamFit> = Vec::with_capacity(all.len());
    for j in &all {
        let (n, path) = (pb.nominal[*j], &pb.paths[*j]);
        if let Some(i) = active.iter().position(|a| a == j) {
            let se = cov[(i, i)].sqrt() * n;
            let v = u[i] * n;
            params.push(ParamFit {
                path: path.clone(),
                nominal: n,
                value: v,
                std_err: se,
                ci95: Some([v - 1.96 * se, v + 1.96 * se]),
                estimable: true,
                rank: rank_of[*j],
                held: None,
            });
        } else {
            let mut trial = active.clone();
            trial.push(*j);
            let zt = z0.select_columns(&trial);
            let se = covariance(&zt).map_or(f64::INFINITY, |c| {
                c[(trial.len() - 1, trial.len() - 1)].sqrt() * n
            });
            params.push(ParamFit {
                path: path.clone(),
                nominal: n,
                value: n,
                std_err: se,
                ci95: None,
                estimable: false,
                rank: rank_of[*j],
                held: held.iter().find(|h| h.0 == *j).map(|h| h.1.clone()),
            });
        }
    }
    let mut collinear = Vec::new();
    for a in 0..active.len() {
        for b in a + 1..active.len() {
            let rho = cov[(a, b)] / (cov[(a, a)] * cov[(b, b)]).sqrt();
            if rho.abs() > COLLINEAR {
                collinear.push((
                    pb.paths[active[a]].clone(),
                    pb.paths[active[b]].clone(),
                    rho,
                ));
            }
        }
    }
    let covariance = Covariance {
        params: active.iter().map(|&j| pb.paths[j].clone()).collect(),
        matrix: (0..active.len())
            .map(|a| {
                (0..active.len())
                    .map(|b| cov[(a, b)] * pb.nominal[active[a]] * pb.nominal[active[b]])
                    .collect()
            })
            .collect(),
    };
    let channels = replay
        .channels
        .iter()
        .enumerate()
        .map(|(c, name)| ChannelFit {
            name: name.clone(),
            sigma: sigma[c],
            rms_nominal: rms_nominal[c],
            rms_calibrated: rms_calibrated[c],
        })
        .collect();
    Ok(Calibration {
        params,
        channels,
        collinear,
        iterations,
        samples: replay.n,
        replays: pb.replays.into_inner(),
        covariance,
    })
}
