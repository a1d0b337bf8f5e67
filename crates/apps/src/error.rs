//! The one error type of the applications: what went wrong, with where (channel, sample,
//! cycle) in the message.

use crate::acquisition::AcquisitionError;
use physid_core::RecordingError;
use physid_estim::EstimError;
use physid_ident::IdentError;
use physid_io::IoError;
use physid_sim::run::SimError;
use thiserror::Error;

/// Errors of the applications.
#[derive(Debug, Error)]
pub enum AppError {
    /// A missing channel or a channel in a unit that cannot be converted.
    #[error(transparent)]
    Recording(#[from] RecordingError),
    /// Converting to a crank-angle basis.
    #[error(transparent)]
    Acquisition(#[from] AcquisitionError),
    /// The identifiability analysis.
    #[error(transparent)]
    Ident(#[from] IdentError),
    /// The estimator or detector, at a place in the data (`sample 120`, `cycle 7`) or in its
    /// configuration.
    #[error("{at}: {source}")]
    Estim {
        /// Where.
        at: String,
        /// The estimator's error.
        source: EstimError,
    },
    /// Reading a recording.
    #[error(transparent)]
    Io(#[from] IoError),
    /// The virtual test cell: a parameter, fault or scenario, or a run.
    #[error(transparent)]
    Sim(#[from] SimError),
    /// Anything else, explained.
    #[error("{0}")]
    Invalid(String),
}

impl From<String> for AppError {
    fn from(message: String) -> Self {
        AppError::Invalid(message)
    }
}

impl AppError {
    /// An estimator error at `at`, for `map_err`.
    pub fn estim(at: impl std::fmt::Display) -> impl FnOnce(EstimError) -> Self {
        let at = at.to_string();
        move |source| Self::Estim { at, source }
    }
}
