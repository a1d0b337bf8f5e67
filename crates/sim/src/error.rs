//! Errors of the virtual test cell: a bad parameter, fault, scenario or option (explained), or a
//! run whose solution left the physical domain.

use thiserror::Error;

/// Errors of the virtual test cell.
#[derive(Debug, Error, PartialEq)]
pub enum SimError {
    /// A bad parameter, scenario or fault, explained.
    #[error("{0}")]
    Invalid(String),
    /// The solution left the physical domain (a volume emptied, a temperature went
    /// negative): the step, time and what.
    #[error(
        "the simulation diverged at t = {t:.6} s{}: {what}; try a smaller solver.step_deg",
        if *.t < 0.0 { " (in the settling, before the recording starts)" } else { "" }
    )]
    Diverged {
        /// Time [s] on the recording's clock (negative: in the settling before it).
        t: f64,
        /// What went wrong.
        what: String,
    },
}

impl From<String> for SimError {
    fn from(message: String) -> Self {
        SimError::Invalid(message)
    }
}
