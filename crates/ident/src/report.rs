//! The whole identifiability question for one recording, as `physid identify` and the Python
//! package ask it: rank the parameters (Alg. 5.1), decide how many the data can estimate (a
//! cut-off or the Wu criterion), and quantify the selected subset — its values (fitted when
//! the measured output is given, else the nominal ones), the Fisher information with the noise
//! variance, standard errors, t-values and 95 % intervals, correlations, the collinearity index
//! and the design criteria (§5.2.2). [`Identification::report`] is the result as plain data
//! (Serialize): the JSON the command prints.

use crate::analysis::{fit_subset, Analysis, IdentConfig, Selection, WuDecision};
use crate::fisher::{design_criteria, quantify, DesignCriteria, Quantitative};
use crate::ranking::{Cutoff, RankStep};
use crate::rows::Rows;
use crate::sensitivity::Scaling;
use crate::{analyse, IdentError};
use nalgebra::DMatrix;
use physid_core::ParamModel;
use serde::{Serialize, Serializer};
use std::collections::BTreeMap;

/// Where the noise variance σ² of the Fisher information came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SigmaSource {
    /// Given by the user.
    Given,
    /// The residual variance of the subset's least-squares fit.
    Fit,
    /// Neither: σ² = 1 (relative precision only).
    Unit,
}

/// Why an identification has no σ² and no precision: the fit's residuals square outside
/// double precision.
pub const SIGMA2_OUTSIDE: &str = "the fit's squared residuals are outside double precision (they underflow to 0 or overflow): the noise variance and the precision cannot be given; the ranking stands. Rescale the output (e.g. to SI units, or with --scale) for them";

/// One recording's identification (see the module docs).
#[derive(Debug, Clone)]
pub struct Identification {
    /// The ranking analysis.
    pub analysis: Analysis,
    /// How many of the ranked parameters the data can estimate.
    pub k: usize,
    /// The cut-off that decided `k`.
    pub selection: Selection,
    /// The Wu criterion's details, when it decided.
    pub wu: Option<WuDecision>,
    /// Values of the selected parameters (fitted, or nominal).
    pub values: Vec<f64>,
    /// Noise variance σ² and its source (NaN when the fit's residuals square outside double
    /// precision: [`SIGMA2_OUTSIDE`]).
    pub sigma2: f64,
    /// See `sigma2`.
    pub sigma_source: SigmaSource,
    /// The selected subset's precision (none selected: `None`).
    pub quant: Option<Quantitative>,
    /// Collinearity index of the selected subset (1 for fewer than two).
    pub collinearity: f64,
    /// Design criteria of the Fisher information (none selected: `None`).
    pub design: Option<DesignCriteria>,
}

/// Identify the `free` parameters of `model` on `data` (nominal values `nominal`): rank, select
/// by `selection`, quantify with the noise standard deviation `sigma` if given.
pub fn identify<M: ParamModel, R: Rows + ?Sized>(
    model: &M,
    data: &R,
    nominal: &[f64],
    free: &[usize],
    config: IdentConfig,
    selection: Selection,
    sigma: Option<f64>,
) -> Result<Identification, IdentError> {
    let a = analyse(model, data, nominal, free, config)?;
    let (k, wu) = selection.resolve(model, data, &a)?;
    let selected = a.top(k);
    let subset: Vec<usize> = selected.iter().map(|&i| a.free[i]).collect();
    let mut values: Vec<f64> = subset.iter().map(|&j| nominal[j]).collect();
    let (gram, sigma2, sigma_source) = if data.has_y() && k > 0 {
        let fit = fit_subset(model, data, nominal, &subset, 30)?;
        values = subset.iter().map(|&j| fit.theta[j]).collect();
        let dof = a.rows.saturating_sub(k).max(1) as f64;
        match sigma {
            Some(s) => (fit.gram, s * s, SigmaSource::Given),
            None => (fit.gram, fit.rss / dof, SigmaSource::Fit),
        }
    } else {
        let (s2, src) = match sigma {
            Some(s) => (s * s, SigmaSource::Given),
            None => (1.0, SigmaSource::Unit),
        };
        (a.gram(&selected), s2, src)
    };
    // The fit's residuals of data scaled by 1e-300 square to 0 (or of 1e200 to ∞): σ² is
    // then unknown, not 0, and no precision is given from it (issue 41, item 5).
    let sigma2_outside =
        sigma_source == SigmaSource::Fit && !(sigma2.is_finite() && sigma2 >= f64::MIN_POSITIVE);
    let sigma2 = if sigma2_outside { f64::NAN } else { sigma2 };
    let quant = if k > 0 && !sigma2_outside {
        quantify(&gram, sigma2, &values, a.rows).ok()
    } else {
        None
    };
    let collinearity = if k > 1 {
        a.collinearity(&selected)
    } else {
        1.0
    };
    let design = (k > 0 && !sigma2_outside).then(|| design_criteria(&(gram / sigma2)));
    Ok(Identification {
        analysis: a,
        k,
        selection,
        wu,
        values,
        sigma2,
        sigma_source,
        quant,
        collinearity,
        design,
    })
}

impl Identification {
    /// Names of the selected (estimable) parameters, in rank order.
    pub fn estimable(&self) -> Vec<&str> {
        let a = &self.analysis;
        a.top(self.k).iter().map(|&i| a.names[i].as_str()).collect()
    }

    /// Names of the others, in rank order.
    pub fn unidentifiable(&self) -> Vec<&str> {
        let a = &self.analysis;
        a.ranking.steps[self.k..]
            .iter()
            .map(|s| a.names[s.param].as_str())
            .collect()
    }

    /// The result as plain data.
    pub fn report(&self) -> IdentReport<'_> {
        let a = &self.analysis;
        let step = |s: &RankStep| Step {
            param: &a.names[s.param],
            residual_ss: s.residual_ss,
            relative: s.relative,
        };
        let sel = self.estimable();
        let by_name = |v: &[f64]| -> BTreeMap<&str, Num> {
            sel.iter().copied().zip(v.iter().map(|&x| Num(x))).collect()
        };
        let rows = |m: &DMatrix<f64>| -> Vec<Vec<f64>> {
            (0..m.nrows())
                .map(|i| (0..m.ncols()).map(|j| m[(i, j)]).collect())
                .collect()
        };
        IdentReport {
            rows: a.rows,
            ranking: a.ranking.steps[..self.k].iter().map(step).collect(),
            unidentifiable: self.unidentifiable(),
            remainder: a.ranking.steps[self.k..].iter().map(step).collect(),
            scaling: a.config.scaling,
            guarded_rows: a.guarded_rows,
            unit_scaled: a.unit_scaled.iter().map(|&i| a.names[i].as_str()).collect(),
            cutoff: match (&self.selection, &self.wu) {
                (Selection::Rule(c), _) => CutoffReport::Rule(*c),
                (_, Some((wu, j))) => CutoffReport::Wu {
                    kind: "wu",
                    k_star: Some(wu.k_star),
                    j: Some(j),
                    r_c: Some(&wu.r_c),
                    r_ckub: Some(&wu.r_ckub),
                    r_cc: Some(&wu.r_cc),
                },
                (_, None) => CutoffReport::Wu {
                    kind: "wu",
                    k_star: None,
                    j: None,
                    r_c: None,
                    r_ckub: None,
                    r_cc: None,
                },
            },
            sigma2: Num(self.sigma2),
            sigma2_source: self.sigma_source,
            sigma2_note: self.sigma2.is_nan().then_some(SIGMA2_OUTSIDE),
            collinearity: Num(self.collinearity),
            d_criterion: Num(self.design.map_or(f64::NAN, |c| c.d)),
            design: self.design.map(|c| DesignReport {
                d: Num(c.d),
                a: Num(c.a),
                e: Num(c.e),
                modified_e: Num(c.modified_e),
            }),
            precision: self.quant.as_ref().map(|q| Precision {
                params: by_name(&self.values),
                fim: rows(&q.fim),
                std_err: by_name(&q.std_err),
                t_values: by_name(&q.t_values),
                ci95: sel
                    .iter()
                    .copied()
                    .zip(q.ci95.iter().map(|&(l, h)| [l, h]))
                    .collect(),
                correlation: rows(&q.correlation),
            }),
        }
    }
}

/// A number for JSON, which has no infinity: ±∞ as the strings `"inf"`/`"-inf"`, NaN as null.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Num(pub f64);

impl Serialize for Num {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self.0 {
            x if x == f64::INFINITY => s.serialize_str("inf"),
            x if x == f64::NEG_INFINITY => s.serialize_str("-inf"),
            x if x.is_nan() => s.serialize_none(),
            x => s.serialize_f64(x),
        }
    }
}

/// One step of the ranking, by name.
#[derive(Debug, Clone, Serialize)]
pub struct Step<'a> {
    /// The parameter.
    pub param: &'a str,
    /// Residual sum of squares after it.
    pub residual_ss: f64,
    /// The same relative to the first.
    pub relative: f64,
}

/// The cut-off that decided.
#[derive(Debug, Clone, Serialize)]
#[serde(untagged)]
pub enum CutoffReport<'a> {
    /// A residual rule (`{"kind": "repeat"}`, `{"kind": "relative", "value": …}`, …).
    Rule(Cutoff),
    /// The Wu criterion with its details.
    Wu {
        /// `"wu"`.
        kind: &'static str,
        /// The K it chose.
        #[serde(skip_serializing_if = "Option::is_none")]
        k_star: Option<usize>,
        /// `J_K` per K.
        #[serde(skip_serializing_if = "Option::is_none")]
        j: Option<&'a [f64]>,
        /// `r_C,K`.
        #[serde(skip_serializing_if = "Option::is_none")]
        r_c: Option<&'a [f64]>,
        /// `r_CKUB,K`.
        #[serde(skip_serializing_if = "Option::is_none")]
        r_ckub: Option<&'a [f64]>,
        /// `r_CC,K`.
        #[serde(skip_serializing_if = "Option::is_none")]
        r_cc: Option<&'a [f64]>,
    },
}

/// Design criteria, JSON-safe.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct DesignReport {
    /// D: det(F).
    pub d: Num,
    /// A: trace(F⁻¹).
    pub a: Num,
    /// E: the smallest eigenvalue.
    pub e: Num,
    /// Modified E: the condition number.
    pub modified_e: Num,
}

/// The selected subset's precision.
#[derive(Debug, Clone, Serialize)]
pub struct Precision<'a> {
    /// Values, by name.
    pub params: BTreeMap<&'a str, Num>,
    /// Fisher information.
    pub fim: Vec<Vec<f64>>,
    /// Standard errors.
    pub std_err: BTreeMap<&'a str, Num>,
    /// t-values.
    pub t_values: BTreeMap<&'a str, Num>,
    /// 95 % confidence intervals.
    pub ci95: BTreeMap<&'a str, [f64; 2]>,
    /// Correlation matrix.
    pub correlation: Vec<Vec<f64>>,
}

/// An identification as plain data (see the module docs).
#[derive(Debug, Clone, Serialize)]
pub struct IdentReport<'a> {
    /// Rows of data.
    pub rows: usize,
    /// The estimable parameters' ranking steps.
    pub ranking: Vec<Step<'a>>,
    /// The parameters the data cannot estimate.
    pub unidentifiable: Vec<&'a str>,
    /// Their ranking steps.
    pub remainder: Vec<Step<'a>>,
    /// The sensitivity scaling.
    pub scaling: Scaling,
    /// Rows whose output was below the thesis scaling's guard.
    pub guarded_rows: usize,
    /// Parameters with a zero nominal value, scaled by 1.
    pub unit_scaled: Vec<&'a str>,
    /// The cut-off.
    pub cutoff: CutoffReport<'a>,
    /// Noise variance σ² (null: see `sigma2_note`).
    pub sigma2: Num,
    /// Its source.
    pub sigma2_source: SigmaSource,
    /// Why σ² is null.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma2_note: Option<&'static str>,
    /// Collinearity index of the estimable subset.
    pub collinearity: Num,
    /// det of the Fisher information.
    pub d_criterion: Num,
    /// Design criteria.
    pub design: Option<DesignReport>,
    /// The estimable subset's values and precision (at its top level in the JSON).
    #[serde(flatten)]
    pub precision: Option<Precision<'a>>,
}
