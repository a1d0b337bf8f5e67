//! # physid-ident — which parameters can the data resolve?
//!
//! Identifiability analysis for any [`ParamModel`](physid_core::ParamModel) (thesis §5.2,
//! SPEC §4), knowing nothing of engines:
//!
//! * [`rows`] — the data: columns in memory, or rows gone over in passes (a file read again);
//! * [`sensitivity`] — exact sensitivity rows through the model seam, scaled (Eq. 5.11);
//! * [`triangular`] — the row-streaming triangular factor (Givens; forgetting; downdating);
//! * [`ranking`] — the orthogonal ranking of Alg. 5.1 from that factor, and its cut-offs;
//! * [`wu`] — the MSE criterion of Wu et al. (2011) for how many parameters to estimate;
//! * [`fisher`] — Fisher information, standard errors, confidence intervals, collinearity
//!   index, D/A/E/modified-E criteria (Eq. 5.12–5.13);
//! * [`analysis`] — the batch analysis of a model over a recording, and least-squares fits of
//!   subsets;
//! * [`online`] — the recursive (on-line) ranking with forgetting or a sliding window;
//! * [`workload`] — reproducible benchmark workloads.

pub mod analysis;
pub mod fisher;
pub mod online;
pub mod ranking;
pub mod report;
pub mod rows;
pub mod sensitivity;
pub mod triangular;
pub mod workload;
pub mod wu;

pub use analysis::{
    analyse, fit_subset, wu_along_ranking, Analysis, Fit, IdentConfig, RankedParam, Selection,
    SelectionData, WuDecision,
};
pub use fisher::{collinearity_index, design_criteria, quantify, DesignCriteria, Quantitative};
pub use online::{Memory, OnlineIdent};
pub use ranking::{rank, Cutoff, RankStep, RankWorkspace, Ranking};
pub use report::{identify, IdentReport, Identification, Num, SigmaSource};
pub use rows::{for_each_row, Data, DataRows, Rows};
pub use sensitivity::{sensitivity_matrix, RowScaler, Scaling};
pub use triangular::TriangularFactor;
pub use wu::{wu_criterion, WuCriterion};

use thiserror::Error;

/// What can go wrong in an analysis.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum IdentError {
    /// A configuration or shape problem, explained.
    #[error("{0}")]
    Invalid(String),
    /// A non-finite value in the data or the model's output.
    #[error("row {row}, {column}: {value} (expected a finite number)")]
    BadValue {
        /// Data row (0-based).
        row: usize,
        /// Column or quantity.
        column: String,
        /// The value.
        value: f64,
    },
    /// The rows could not be read (a [`Rows`] source's own error, which names its file).
    #[error("{0}")]
    Read(String),
    /// A matrix that must be invertible is not.
    #[error("{what} is singular: the parameters are not jointly identifiable")]
    Singular {
        /// Which matrix.
        what: &'static str,
    },
}
