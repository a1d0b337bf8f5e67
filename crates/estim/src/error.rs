//! Errors of the estimators. Every error leaves the estimator's state as it was.

/// What went wrong in building or updating an estimator.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EstimError {
    /// Configuration that no estimator can run with (λ outside (0, 1], a negative variance, …).
    #[error("invalid configuration: {0}")]
    InvalidConfig(String),
    /// A matrix or vector of the wrong size.
    #[error("{what}: expected {expected}, got {got}")]
    DimensionMismatch {
        /// What had the wrong size.
        what: &'static str,
        /// The size expected.
        expected: usize,
        /// The size given.
        got: usize,
    },
    /// A covariance given at construction that is not positive definite.
    #[error("{what} is not positive definite")]
    NotPositiveDefinite {
        /// Which matrix.
        what: &'static str,
    },
    /// A sample containing NaN or ±inf; the sample was refused and the state is unchanged.
    #[error("sample {sample}: {what} is not finite ({value})")]
    NonFinite {
        /// Index of the sample (0-based count of samples offered so far).
        sample: u64,
        /// Which entry: `"y"` or `"phi[3]"` style.
        what: String,
        /// The value.
        value: f64,
    },
    /// The update would have made the covariance lose positive definiteness (or overflow); the
    /// sample was refused and the state is unchanged.
    #[error("sample {sample}: covariance lost positive definiteness ({detail}); sample refused, state unchanged (reset the covariance, add a wind-up guard, or use a square-root method: dsfc for linear models, srukf for non-linear ones)")]
    LostPositiveDefiniteness {
        /// Index of the sample.
        sample: u64,
        /// What was seen.
        detail: String,
    },
    /// A statistic that needs more samples than have been seen.
    #[error("not enough samples: {needed} needed, {seen} seen")]
    NotEnoughData {
        /// Samples needed.
        needed: usize,
        /// Samples seen (effective count under forgetting).
        seen: usize,
    },
}

/// Check one sample before it touches any state: `xs` must have `expected` entries, all finite
/// (entry `i` is named `label(i)` in the error), and the scalar `y` (named `y_name`) finite.
pub(crate) fn check_sample(
    sample: u64,
    what: &'static str,
    xs: &[f64],
    expected: usize,
    y_name: &'static str,
    y: f64,
    label: impl Fn(usize) -> String,
) -> Result<(), EstimError> {
    if xs.len() != expected {
        return Err(EstimError::DimensionMismatch {
            what,
            expected,
            got: xs.len(),
        });
    }
    if !y.is_finite() {
        return Err(EstimError::NonFinite {
            sample,
            what: y_name.into(),
            value: y,
        });
    }
    if let Some(i) = xs.iter().position(|v| !v.is_finite()) {
        return Err(EstimError::NonFinite {
            sample,
            what: label(i),
            value: xs[i],
        });
    }
    Ok(())
}

/// A free/fixed view must cover exactly the parameter set it is used with.
/// Check one sample of a model's inputs (named after the model's inputs in the error) and
/// its measured output, as [`check_sample`] does.
pub(crate) fn check_model_sample<M: physid_core::ParamModel>(
    model: &M,
    sample: u64,
    inputs: &[f64],
    y: f64,
) -> Result<(), EstimError> {
    let names = model.input_names();
    check_sample(
        sample,
        "model inputs φ",
        inputs,
        names.len(),
        "y",
        y,
        |i| format!("input '{}'", names[i]),
    )
}

/// A parameter set for `model` must name the model's parameters, in its order.
pub(crate) fn check_model_params<M: physid_core::ParamModel>(
    params: &physid_core::ParamSet,
    model: &M,
) -> Result<(), EstimError> {
    if params.names() != model.param_names() {
        return Err(EstimError::InvalidConfig(format!(
            "parameter set ({}) does not match the model's parameters ({})",
            params.names().join(", "),
            model.param_names().join(", ")
        )));
    }
    Ok(())
}

pub(crate) fn check_view(
    params: &physid_core::ParamSet,
    free: &physid_core::FreeSet,
) -> Result<(), EstimError> {
    if free.full_len() != params.len() {
        return Err(EstimError::DimensionMismatch {
            what: "free/fixed view",
            expected: params.len(),
            got: free.full_len(),
        });
    }
    // Nothing to estimate: an empty covariance has no decomposition (nalgebra panics on one).
    let p = free.free().len();
    if p == 0 {
        return Err(EstimError::InvalidConfig(
            "no free parameter: nothing to estimate".into(),
        ));
    }
    // The covariance and the copies its updates work on (P, its factor, P0, a work matrix):
    // 10⁵ parameters asked for 80 GB at once and the allocator aborted the process (Python's
    // with it). Below 64 MB the machine is not asked.
    let bytes = 4.0 * (p as f64).powi(2) * std::mem::size_of::<f64>() as f64;
    if bytes > 64e6 {
        let what = format!("the covariance of {p} free parameters ({p}×{p}, and its copies)");
        physid_core::memory::check_fits(bytes, &what)
            .map_err(|e| EstimError::InvalidConfig(e.to_string()))?;
    }
    Ok(())
}
