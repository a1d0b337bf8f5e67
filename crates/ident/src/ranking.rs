//! The orthogonal estimability ranking (thesis Alg. 5.1; Yao et al. 2003), from the triangular
//! factor of the scaled sensitivity matrix.
//!
//! Alg. 5.1 selects the column of `Z` with the largest sum of squares, then repeatedly the
//! column whose residual after regression on the columns selected so far is largest. Those
//! residual sums of squares depend on `Z` only through `ZᵀZ = RᵀR`, so the selection runs on
//! the p columns of `R` — a column-pivoted modified Gram–Schmidt with re-orthogonalisation,
//! O(p³) whatever the number of rows, and never `(XᵀX)⁻¹` as the thesis's code forms it.

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

/// Residuals within this relative distance of the largest count as tied; ties go to the lowest
/// parameter index, so that rounding never decides the order.
const TIE: f64 = 1e-12;

/// One step of the ranking.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct RankStep {
    /// Index of the selected parameter (into the analysed parameter list).
    pub param: usize,
    /// Its residual sum of squares after regression on the parameters selected before it
    /// (step 1: its column sum of squares).
    pub residual_ss: f64,
    /// `residual_ss` relative to step 1's.
    pub relative: f64,
}

/// The full ranking: every parameter, in selection order.
#[derive(Debug, Clone, PartialEq, Serialize, serde::Deserialize)]
pub struct Ranking {
    /// The steps, most estimable first.
    pub steps: Vec<RankStep>,
    /// Column sums of squares `SS_j = Σ_i Z_ij²` in parameter order (step 1 of Alg. 5.1).
    pub column_ss: Vec<f64>,
}

/// Where the estimable set ends.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case", tag = "kind", content = "value")]
pub enum Cutoff {
    /// The thesis's code: stop when the next column would repeat one already chosen — its
    /// residual is zero to rounding (residual norm ≤ 1e3·ε of the largest column's norm).
    #[default]
    Repeat,
    /// Stop when the residual sum of squares falls below this value.
    Absolute(f64),
    /// Stop when the residual relative to the first falls below this fraction.
    Relative(f64),
}

/// Rank the columns of the factor `r` (p × p, `RᵀR = ZᵀZ`).
pub fn rank(r: &DMatrix<f64>) -> Ranking {
    let mut ws = RankWorkspace::new(r.ncols());
    ws.w.copy_from(r);
    ws.rank();
    ws.ranking
}

/// The ranking's working memory for a fixed p, so that ranking again and again (on-line
/// identifiability) allocates nothing: copy the factor into [`factor_mut`](Self::factor_mut),
/// then [`rank`](Self::rank).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct RankWorkspace {
    w: DMatrix<f64>,
    q: nalgebra::DVector<f64>,
    selected: Vec<bool>,
    ranking: Ranking,
}

impl RankWorkspace {
    /// For `p` parameters.
    pub fn new(p: usize) -> Self {
        Self {
            w: DMatrix::zeros(p, p),
            q: nalgebra::DVector::zeros(p),
            selected: vec![false; p],
            ranking: Ranking {
                steps: Vec::with_capacity(p),
                column_ss: vec![0.0; p],
            },
        }
    }

    /// The factor to rank (p × p), written in place (the ranking overwrites it).
    pub fn factor_mut(&mut self) -> &mut DMatrix<f64> {
        &mut self.w
    }

    /// Rank the factor written into [`factor_mut`](Self::factor_mut) (Alg. 5.1, module
    /// documentation).
    pub fn rank(&mut self) -> &Ranking {
        let p = self.w.ncols();
        let Self {
            w,
            q,
            selected,
            ranking,
        } = self;
        for (j, ss) in ranking.column_ss.iter_mut().enumerate() {
            *ss = w.column(j).norm_squared();
        }
        let max_ss = ranking.column_ss.iter().cloned().fold(0.0, f64::max);
        // Below this a residual is rounding noise: no direction left to orthogonalise against.
        let zero = max_ss * (p.max(1) as f64 * f64::EPSILON).powi(2);
        selected.fill(false);
        ranking.steps.clear();
        let mut first = 0.0;
        for _ in 0..p {
            let best = (0..p)
                .filter(|&j| !selected[j])
                .map(|j| w.column(j).norm_squared())
                .fold(f64::MIN, f64::max);
            let (j, res) = (0..p)
                .filter(|&j| !selected[j])
                .map(|j| (j, w.column(j).norm_squared()))
                .find(|&(_, v)| v >= best * (1.0 - TIE))
                .unwrap_or((0, 0.0));
            selected[j] = true;
            if ranking.steps.is_empty() {
                first = res;
            }
            ranking.steps.push(RankStep {
                param: j,
                residual_ss: res,
                relative: if first > 0.0 { res / first } else { 0.0 },
            });
            if res <= zero {
                continue;
            }
            q.copy_from(&w.column(j));
            *q /= res.sqrt();
            for k in (0..p).filter(|&k| !selected[k]) {
                // Modified Gram–Schmidt, twice ("twice is enough", Kahan–Parlett).
                for _ in 0..2 {
                    let c = q.dot(&w.column(k));
                    let mut col = w.column_mut(k);
                    col.axpy(-c, &*q, 1.0);
                }
            }
        }
        &self.ranking
    }
}

impl Ranking {
    /// How many parameters (the first K steps) the cut-off declares estimable.
    pub fn estimable(&self, cutoff: Cutoff) -> usize {
        let first = self.steps.first().map_or(0.0, |s| s.residual_ss);
        self.steps
            .iter()
            .take_while(|s| match cutoff {
                Cutoff::Repeat => s.residual_ss > first * (1e3 * f64::EPSILON).powi(2),
                Cutoff::Absolute(x) => s.residual_ss > x,
                Cutoff::Relative(x) => s.relative > x,
            })
            .count()
    }

    /// Parameter indices in selection order.
    pub fn order(&self) -> Vec<usize> {
        self.steps.iter().map(|s| s.param).collect()
    }
}
