//! Batch identifiability of a [`ParamModel`] over a recording: one streaming pass folds the
//! scaled sensitivity rows into the triangular factor that the ranking needs, and the unscaled
//! rows (with the output residual when the output is measured) into a second one for the
//! quantitative results — O(p²) memory for any number of rows. Every function here goes over
//! its [`Rows`] in passes (the output's level, the factors, each Gauss–Newton iteration), so a
//! source that reads its file again on each pass keeps nothing of the recording.

use crate::fisher::{collinearity_index, design_criteria, quantify, DesignCriteria, Quantitative};
use crate::ranking::{rank, Cutoff, Ranking};
use crate::rows::{for_each_row, Rows};
use crate::sensitivity::{output_levels, OutputLevels, RowScaler, Scaling};
use crate::triangular::TriangularFactor;
use crate::wu::{wu_criterion, WuCriterion};
use crate::IdentError;
use nalgebra::DMatrix;
use physid_core::{GradientEngine, ParamModel};
use serde::{Deserialize, Serialize};

/// How to analyse.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
pub struct IdentConfig {
    /// Sensitivity scaling.
    pub scaling: Scaling,
    /// Thesis-scaling guard `g`: rows with `|y| < g·rms(y)` are divided by `±g·rms(y)`.
    pub guard: f64,
    /// Subtract each column's mean first (Eq. 5.9 as printed; the thesis's code and Yao et al.
    /// do not).
    pub centre: bool,
}

impl Default for IdentConfig {
    fn default() -> Self {
        Self {
            scaling: Scaling::Thesis,
            guard: 1e-3,
            centre: false,
        }
    }
}

/// The batch analysis: the ranking, and what the quantitative results are computed from.
#[derive(Debug, Clone, Serialize, serde::Deserialize)]
pub struct Analysis {
    /// Names of the analysed parameters (the free subset), in their order.
    pub names: Vec<String>,
    /// Their indices in the model's parameter list.
    pub free: Vec<usize>,
    /// The nominal values of all the model's parameters.
    pub theta0: Vec<f64>,
    /// Data rows.
    pub rows: usize,
    /// The scaling used.
    pub config: IdentConfig,
    /// Rows where the thesis scaling's guard replaced `y_i`.
    pub guarded_rows: usize,
    /// Analysed parameters (indices into [`names`](Self::names)) whose nominal value is 0, so
    /// that their column was scaled by 1 instead of `ϑ0` (thesis and sigma scalings).
    pub unit_scaled: Vec<usize>,
    /// Output level statistics.
    pub levels: OutputLevels,
    /// The orthogonal ranking (every analysed parameter, selection order).
    pub ranking: Ranking,
    z: TriangularFactor,
    /// `[J | r]`: unscaled sensitivities and, with a measured output, `r = y − h(ϑ0)`.
    j: TriangularFactor,
    has_y: bool,
}

/// Analyse `model` at `theta0` over `data`, for the parameters `free` (indices; all if empty):
/// two passes.
pub fn analyse<M: ParamModel, R: Rows + ?Sized>(
    model: &M,
    data: &R,
    theta0: &[f64],
    free: &[usize],
    config: IdentConfig,
) -> Result<Analysis, IdentError> {
    let names_all = model.param_names();
    if theta0.len() != names_all.len() {
        return Err(IdentError::Invalid(format!(
            "{} nominal values for {} parameters ({})",
            theta0.len(),
            names_all.len(),
            names_all.join(", ")
        )));
    }
    if let Some((j, v)) = theta0.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(IdentError::Invalid(format!(
            "nominal value of {} is {v}",
            names_all[j]
        )));
    }
    let free: Vec<usize> = if free.is_empty() {
        (0..names_all.len()).collect()
    } else {
        free.to_vec()
    };
    if let Some(&j) = free.iter().find(|&&j| j >= names_all.len()) {
        return Err(IdentError::Invalid(format!(
            "parameter index {j} out of range"
        )));
    }
    if !(config.guard.is_finite() && config.guard > 0.0) {
        return Err(IdentError::Invalid(format!(
            "guard {}: expected a finite value > 0",
            physid_core::Num(config.guard)
        )));
    }
    let p = free.len();
    let levels = output_levels(model, data, theta0)?;
    let theta_free: Vec<f64> = free.iter().map(|&j| theta0[j]).collect();
    let scaler = RowScaler::new(
        config.scaling,
        &theta_free,
        levels.level(config.scaling, config.guard),
    )?;
    let has_y = data.has_y();
    let mut fz = TriangularFactor::new(p);
    let mut fj = TriangularFactor::new(p + usize::from(has_y));
    let mut engine = GradientEngine::new(theta0.len());
    let mut g = vec![0.0; p];
    let mut z = vec![0.0; p];
    let mut jr = vec![0.0; p + usize::from(has_y)];
    let mut mean = vec![0.0; p];
    let mut guarded = 0;
    // The largest scaled sensitivity: whether a factor that is not finite overflowed.
    let mut z_max = 0.0f64;
    // The largest unscaled sensitivity and residual: whether their squares overflowed.
    let (mut g_max, mut r_max) = (0.0f64, 0.0f64);
    let n = for_each_row(model, data, |i, u, y| {
        let h = engine.value_and_gradient(model, u, theta0, &free, &mut g);
        if let Some(k) = g.iter().position(|v| !v.is_finite()) {
            return Err(IdentError::BadValue {
                row: i,
                column: format!("∂h/∂{}", names_all[free[k]]),
                value: g[k],
            });
        }
        guarded += usize::from(scaler.scale(&g, y.unwrap_or(h), &mut z));
        z_max = z.iter().fold(z_max, |m, v| m.max(v.abs()));
        if config.centre {
            // Centred scatter without cancellation (Welford's update as a rank-one row):
            // S_k = S_{k−1} + (k−1)/k·(z − m_{k−1})(z − m_{k−1})ᵀ.
            let k = (i + 1) as f64;
            let w = ((k - 1.0) / k).sqrt();
            for (zj, mj) in z.iter_mut().zip(mean.iter_mut()) {
                let d = *zj - *mj;
                *mj += d / k;
                *zj = w * d;
            }
        }
        fz.add_row(&z);
        jr[..p].copy_from_slice(&g);
        g_max = g.iter().fold(g_max, |m, v| m.max(v.abs()));
        if let Some(y) = y {
            jr[p] = y - h;
            r_max = r_max.max(jr[p].abs());
        }
        fj.add_row(&jr);
        Ok(())
    })?;
    if n != levels.rows {
        return Err(IdentError::Read(format!(
            "the data gave {n} rows on a second pass, {} on the first",
            levels.rows
        )));
    }
    if fz.is_finite() && !fj.is_finite() && g_max.max(r_max).powi(2) * (n.max(1) as f64) > 1e300 {
        return Err(IdentError::Invalid(format!(
            "the data overflow 64-bit floating point in their squares (|∂h/∂θ| up to {g_max:.3e}, |y − h| up to {r_max:.3e}: sums of squares beyond 1.8e308): rescale the data (e.g. to SI units or by a power of ten)"
        )));
    }
    if !(fz.is_finite() && fj.is_finite()) {
        // Sums of squares beyond 1e308 need a sensitivity beyond √(1e308/n); below that, the
        // factor lost finiteness on sensitivities that are exactly collinear.
        let overflow = z_max * z_max * (n.max(1) as f64) > 1e300;
        return Err(IdentError::Invalid(
            if overflow && config.scaling == Scaling::None {
                format!(
                "the sensitivities overflow (a scaled sensitivity of {z_max:.3e}: sums of squares beyond 1e308): rescale the parameters or use --scaling thesis/sigma"
            )
            } else if overflow {
                // Scaled by the output's level already: the output and the model at ϑ0 are far
                // apart in size (y × 1e-300 against nominal values for y).
                format!(
                "the scaled sensitivities overflow (up to {z_max:.3e}: sums of squares beyond 1e308) with {} scaling: the output's level (rms {:.3e}) is out of all proportion to the model's sensitivities at the nominal values — check the output's units and the nominal values (--params)",
                config.scaling.name(),
                levels.rms
            )
            } else {
                format!(
                "the parameters' sensitivities are exactly collinear (the largest is {z_max:.3e}, \
                 no overflow): parameters that enter the model the same way cannot be told apart \
                 — keep one of each such group (--free) or write the model with one"
            )
            },
        ));
    }
    let ranking = rank(&fz.r());
    Ok(Analysis {
        names: free.iter().map(|&j| names_all[j].clone()).collect(),
        free,
        theta0: theta0.to_vec(),
        rows: n,
        config,
        guarded_rows: guarded,
        unit_scaled: if config.scaling == Scaling::None {
            Vec::new()
        } else {
            (0..p).filter(|&i| theta_free[i] == 0.0).collect()
        },
        levels,
        ranking,
        z: fz,
        j: fj,
        has_y,
    })
}

fn sub_gram(f: &TriangularFactor, subset: &[usize]) -> DMatrix<f64> {
    let r = f.r();
    let cols = r.select_columns(subset);
    cols.transpose() * cols
}

impl Analysis {
    /// The estimable count K for a cut-off.
    pub fn estimable(&self, cutoff: Cutoff) -> usize {
        self.ranking.estimable(cutoff)
    }

    /// The ranking as a table: every analysed parameter in selection order, the first `k`
    /// marked estimable.
    pub fn ranked(&self, k: usize) -> Vec<RankedParam> {
        self.ranking
            .steps
            .iter()
            .enumerate()
            .map(|(i, s)| RankedParam {
                param: self.names[s.param].clone(),
                rank: i + 1,
                relative_residual: s.relative,
                estimable: i < k,
            })
            .collect()
    }

    /// Indices (into [`names`](Self::names)) of the first `k` ranked parameters.
    pub fn top(&self, k: usize) -> Vec<usize> {
        self.ranking.steps.iter().take(k).map(|s| s.param).collect()
    }

    /// The scaled Gram matrix `ZᵀZ` of a subset (indices into [`names`](Self::names)).
    pub fn gram_scaled(&self, subset: &[usize]) -> DMatrix<f64> {
        sub_gram(&self.z, subset)
    }

    /// The unscaled Gram matrix `JᵀJ` of a subset.
    pub fn gram(&self, subset: &[usize]) -> DMatrix<f64> {
        sub_gram(&self.j, subset)
    }

    /// Collinearity index γ_K of a subset, on the scaled sensitivities.
    pub fn collinearity(&self, subset: &[usize]) -> f64 {
        collinearity_index(&self.gram_scaled(subset))
    }

    /// Residual sum of squares of the output after a linearised (one Gauss–Newton step) fit of
    /// the subset from `ϑ0`; `None` without a measured output.
    pub fn linearised_rss(&self, subset: &[usize]) -> Option<f64> {
        if !self.has_y {
            return None;
        }
        let p = self.free.len();
        let mut cols = subset.to_vec();
        cols.push(p);
        let m = self.j.r().select_columns(&cols);
        let r = m.qr().r();
        let k = subset.len();
        Some(r[(k, k)].powi(2))
    }

    /// Precision of a subset at `ϑ0` with noise variance `sigma2` (design-based, Eq. 5.12).
    pub fn quantify(&self, subset: &[usize], sigma2: f64) -> Result<Quantitative, IdentError> {
        let theta: Vec<f64> = subset.iter().map(|&i| self.theta0[self.free[i]]).collect();
        quantify(&self.gram(subset), sigma2, &theta, self.rows)
    }

    /// D-, A-, E-, modified-E criteria of a subset's Fisher information with noise variance
    /// `sigma2`.
    pub fn design_criteria(&self, subset: &[usize], sigma2: f64) -> DesignCriteria {
        design_criteria(&(self.gram(subset) / sigma2))
    }
}

/// A Gauss–Newton least-squares fit of a parameter subset (indices into the model's parameter
/// list), the rest held at `theta0`; needs the measured output.
#[derive(Debug, Clone)]
pub struct Fit {
    /// All parameters, the subset fitted.
    pub theta: Vec<f64>,
    /// Residual sum of squares at `theta`.
    pub rss: f64,
    /// `JᵀJ` of the subset at `theta`.
    pub gram: DMatrix<f64>,
    /// Gauss–Newton iterations taken.
    pub iterations: usize,
}

/// Fit `subset` (model parameter indices) by Gauss–Newton with step halving, streaming the rows
/// (`[J | r]` folded into a triangular factor each iteration), at most `max_iter` iterations.
pub fn fit_subset<M: ParamModel, R: Rows + ?Sized>(
    model: &M,
    data: &R,
    theta0: &[f64],
    subset: &[usize],
    max_iter: usize,
) -> Result<Fit, IdentError> {
    if !data.has_y() {
        return Err(IdentError::Invalid(
            "fitting needs the measured output column".into(),
        ));
    }
    let k = subset.len();
    let mut theta = theta0.to_vec();
    let mut engine = GradientEngine::new(theta0.len());
    let mut g = vec![0.0; k];
    let mut row = vec![0.0; k + 1];
    let mut factor = TriangularFactor::new(k + 1);
    // One pass: the factor of [J | r] at `theta`, and the rss.
    let mut pass =
        |theta: &[f64], factor: &mut TriangularFactor| -> Result<(f64, usize), IdentError> {
            factor.clear();
            let mut rss = 0.0;
            let n = for_each_row(model, data, |_, u, y| {
                let h = engine.value_and_gradient(model, u, theta, subset, &mut g);
                row[..k].copy_from_slice(&g);
                row[k] = y.unwrap_or(h) - h;
                rss += row[k] * row[k];
                factor.add_row(&row);
                Ok(())
            })?;
            Ok((rss, n))
        };
    let rss_at = |theta: &[f64]| -> Result<f64, IdentError> {
        let mut rss = 0.0;
        for_each_row(model, data, |_, u, y| {
            let h = model.eval::<f64>(u, theta);
            let r = y.unwrap_or(h) - h;
            rss += r * r;
            Ok(())
        })?;
        Ok(rss)
    };
    let (mut rss, n) = pass(&theta, &mut factor)?;
    // What counts as a decrease: more than the rounding of sums over n rows (n·ε relative), and
    // at least 1e-12 — below it a step is noise, and taking it would go on iterating.
    let tol = 1e-12_f64.max(n as f64 * f64::EPSILON);
    let mut iterations = 0;
    for _ in 0..max_iter {
        let r = factor.r();
        let rmax = (0..k).map(|i| r[(i, i)].abs()).fold(0.0, f64::max);
        // Back substitution; a negligible pivot (an unidentifiable direction) takes no step.
        let mut delta = vec![0.0; k];
        for i in (0..k).rev() {
            if r[(i, i)].abs() <= rmax * 1e-10 {
                continue;
            }
            let mut s = r[(i, k)];
            for j in i + 1..k {
                s -= r[(i, j)] * delta[j];
            }
            delta[i] = s / r[(i, i)];
        }
        // The decrease the linearised model predicts for the full step, Σ R[i,k]² over the
        // directions taken: when it is within rounding the fit has converged, and no trial pass
        // over the data is made (the line search would halve down to nothing, each halving a
        // pass — over a file read again on every pass, minutes).
        let predicted: f64 = (0..k)
            .filter(|&i| r[(i, i)].abs() > rmax * 1e-10)
            .map(|i| r[(i, k)] * r[(i, k)])
            .sum();
        if predicted.is_nan() || predicted <= tol * rss {
            break;
        }
        let mut alpha = 1.0;
        let mut trial = theta.clone();
        let mut rss_try = f64::INFINITY;
        while alpha > 1e-6 {
            for (idx, &j) in subset.iter().enumerate() {
                trial[j] = theta[j] + alpha * delta[idx];
            }
            rss_try = rss_at(&trial)?;
            if rss_try.is_finite() && rss_try <= rss {
                break;
            }
            alpha *= 0.5;
        }
        // Converged: no decrease beyond rounding (then the step is not taken).
        if !(rss_try.is_finite() && rss - rss_try > tol * rss) {
            break;
        }
        iterations += 1;
        theta = trial;
        rss = pass(&theta, &mut factor)?.0;
    }
    let r = factor.r();
    let jk = r.view((0, 0), (k, k)).into_owned();
    Ok(Fit {
        theta,
        rss,
        gram: jk.transpose() * jk,
        iterations,
    })
}

/// The Wu et al. (2011) criterion along a ranking: fit the top K parameters for K = 1 … p
/// ([`fit_subset`], at most `max_iter` Gauss–Newton iterations each), `J_K = rss_K/σ²` with
/// `σ² = sigma2` if given, else `rss_p/(n − p)`.
pub fn wu_along_ranking<M: ParamModel, R: Rows + ?Sized>(
    model: &M,
    data: &R,
    analysis: &Analysis,
    sigma2: Option<f64>,
    max_iter: usize,
) -> Result<(WuCriterion, Vec<f64>), IdentError> {
    let p = analysis.free.len();
    let mut rss = Vec::with_capacity(p);
    for k in 1..=p {
        let subset: Vec<usize> = analysis.top(k).iter().map(|&i| analysis.free[i]).collect();
        rss.push(fit_subset(model, data, &analysis.theta0, &subset, max_iter)?.rss);
    }
    let n = analysis.rows;
    let s2 = match sigma2 {
        Some(s) => s,
        None if n > p => rss[p - 1] / (n - p) as f64,
        None => {
            return Err(IdentError::Invalid(format!(
                "{n} rows for {p} parameters: give the noise variance"
            )))
        }
    };
    if !(s2.is_finite() && s2 > 0.0) {
        return Err(IdentError::Invalid(format!(
            "noise variance {s2}: the full model fits exactly; give the noise variance"
        )));
    }
    let j: Vec<f64> = rss.iter().map(|r| r / s2).collect();
    let wu = wu_criterion(&j, n).ok_or_else(|| IdentError::Invalid("no parameters".into()))?;
    Ok((wu, j))
}

/// One row of a ranking table (thesis Tables 7.3 and 8.1).
#[derive(Debug, Clone, PartialEq, Serialize, serde::Deserialize)]
pub struct RankedParam {
    /// Parameter name.
    pub param: String,
    /// Rank in the orthogonal selection (1 = most estimable).
    pub rank: usize,
    /// Residual sum of squares at its selection, relative to the first.
    pub relative_residual: f64,
    /// Within the estimable subset.
    pub estimable: bool,
}

/// The Wu criterion's details when it decided the count: the criterion and `J_K` per K.
pub type WuDecision = (WuCriterion, Vec<f64>);

/// How many of the ranked parameters to estimate: a cut-off on the ranking's residuals, or
/// the Wu et al. (2011) criterion (which fits the top-ranked subsets, so it needs the measured
/// output).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Selection {
    /// A residual cut-off (repeat, absolute, relative).
    Rule(Cutoff),
    /// Wu et al.: `argmin r_CC,K`, with the noise variance if known.
    Wu {
        /// Noise variance σ² (`None`: from the full fit).
        sigma2: Option<f64>,
    },
}

/// A number as a user writes it: `1e-6`, not `0.000001`.
fn short(v: f64) -> String {
    if v != 0.0 && !(1e-3..1e6).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

impl std::fmt::Display for Selection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.to_text())
    }
}

impl std::str::FromStr for Selection {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::parse(s)
    }
}

/// Read from its text form (`"repeat"`, `"wu"`, `"rel:1e-6"`, `"0.5"`), so that a pipeline
/// file's cut-off is checked when the file is read.
impl<'de> Deserialize<'de> for Selection {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let text = String::deserialize(d)?;
        Self::parse(&text).map_err(serde::de::Error::custom)
    }
}

/// [`Selection`] as data both ways, lossless (its own `Deserialize` reads the text form a
/// pipeline file gives): for a stage's checkpointed configuration,
/// `#[serde(with = "physid_ident::SelectionData")]`.
#[derive(Serialize, Deserialize)]
#[serde(remote = "Selection", rename_all = "snake_case")]
pub enum SelectionData {
    /// A residual cut-off.
    Rule(Cutoff),
    /// Wu et al., with the noise variance if known.
    Wu {
        /// Noise variance σ².
        sigma2: Option<f64>,
    },
}

impl Selection {
    /// Parse `repeat`, `wu`, `rel:F` (relative cut-off) or a number (absolute cut-off); the
    /// error says what was expected.
    pub fn parse(s: &str) -> Result<Self, String> {
        let bad = || {
            format!("cut-off '{s}': expected repeat, wu, rel:FRACTION or an absolute residual ≥ 0")
        };
        let number = |v: &str| {
            v.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite() && *v >= 0.0)
                .ok_or_else(bad)
        };
        match s.trim() {
            "repeat" => Ok(Self::Rule(Cutoff::Repeat)),
            "wu" => Ok(Self::Wu { sigma2: None }),
            t => match t.strip_prefix("rel:") {
                Some(r) => Ok(Self::Rule(Cutoff::Relative(number(r)?))),
                None => Ok(Self::Rule(Cutoff::Absolute(number(t)?))),
            },
        }
    }

    /// The text [`parse`](Self::parse) reads back (`repeat`, `wu`, `rel:F`, a number).
    pub fn to_text(&self) -> String {
        match self {
            Self::Rule(Cutoff::Repeat) => "repeat".into(),
            Self::Rule(Cutoff::Relative(r)) => format!("rel:{}", short(*r)),
            Self::Rule(Cutoff::Absolute(a)) => short(*a),
            Self::Wu { .. } => "wu".into(),
        }
    }

    /// The number of top-ranked parameters to estimate, with the Wu criterion's details when
    /// it decided.
    pub fn resolve<M: ParamModel, R: Rows + ?Sized>(
        &self,
        model: &M,
        data: &R,
        analysis: &Analysis,
    ) -> Result<(usize, Option<WuDecision>), IdentError> {
        match *self {
            Self::Rule(c) => Ok((analysis.estimable(c), None)),
            Self::Wu { sigma2 } => {
                if !data.has_y() {
                    return Err(IdentError::Invalid(
                        "the Wu criterion fits the top-ranked parameters: it needs the measured output"
                            .into(),
                    ));
                }
                let (wu, j) = wu_along_ranking(model, data, analysis, sigma2, 30)?;
                Ok((wu.k_star, Some((wu, j))))
            }
        }
    }
}
