//! Named parameters with nominal values, and free/fixed views of them.

use serde::{Deserialize, Serialize};

/// Errors from building or using a parameter set.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ParamError {
    /// A parameter name was given twice.
    #[error("parameter '{0}' is given twice")]
    Duplicate(String),
    /// A name that is not one of the set's parameters.
    #[error("unknown parameter '{name}'; the parameters are: {known}")]
    Unknown {
        /// The name asked for.
        name: String,
        /// The set's names, comma separated.
        known: String,
    },
    /// The number of names and values differ.
    #[error("{names} parameter names but {values} values")]
    LengthMismatch {
        /// Number of names.
        names: usize,
        /// Number of values.
        values: usize,
    },
    /// A nominal value is NaN or infinite.
    #[error("nominal value of '{name}' is not finite ({value})")]
    NonFinite {
        /// Parameter name.
        name: String,
        /// The offending value.
        value: f64,
    },
    /// A free set must contain at least one parameter.
    #[error("no parameter is free: at least one must be estimated")]
    NoneFree,
}

/// A vector of named parameters `ϑ` with nominal values `ϑ0`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParamSet {
    names: Vec<String>,
    nominal: Vec<f64>,
}

impl ParamSet {
    /// A parameter set from names and nominal values (same length, unique names, finite values).
    pub fn new<S: Into<String>>(
        names: impl IntoIterator<Item = S>,
        nominal: Vec<f64>,
    ) -> Result<Self, ParamError> {
        let names: Vec<String> = names.into_iter().map(Into::into).collect();
        if names.len() != nominal.len() {
            return Err(ParamError::LengthMismatch {
                names: names.len(),
                values: nominal.len(),
            });
        }
        // A set, not a scan of the names before: 10⁶ names took hours.
        let mut seen = std::collections::HashSet::with_capacity(names.len());
        for (i, n) in names.iter().enumerate() {
            if !seen.insert(n.as_str()) {
                return Err(ParamError::Duplicate(n.clone()));
            }
            if !nominal[i].is_finite() {
                return Err(ParamError::NonFinite {
                    name: n.clone(),
                    value: nominal[i],
                });
            }
        }
        Ok(Self { names, nominal })
    }

    /// A parameter set whose nominal values are all zero (the thesis's `ϑ0 = 0`).
    pub fn zeros<S: Into<String>>(names: impl IntoIterator<Item = S>) -> Result<Self, ParamError> {
        let names: Vec<String> = names.into_iter().map(Into::into).collect();
        let n = names.len();
        Self::new(names, vec![0.0; n])
    }

    /// Number of parameters.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// True when the set has no parameters.
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// Parameter names in order.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Nominal values `ϑ0` in order.
    pub fn nominal(&self) -> &[f64] {
        &self.nominal
    }

    /// Index of a parameter by name.
    pub fn index_of(&self, name: &str) -> Result<usize, ParamError> {
        self.names
            .iter()
            .position(|n| n == name)
            .ok_or_else(|| ParamError::Unknown {
                name: name.to_string(),
                known: self.names.join(", "),
            })
    }

    /// Names of the parameters a view sets free, in order.
    pub fn free_names(&self, free: &FreeSet) -> Vec<&str> {
        free.free()
            .iter()
            .map(|&i| self.names[i].as_str())
            .collect()
    }

    /// The view in which every parameter is free.
    pub fn all_free(&self) -> FreeSet {
        FreeSet {
            free: (0..self.len()).collect(),
            fixed: Vec::new(),
        }
    }

    /// The view in which the named parameters are free and the rest fixed at nominal values.
    /// The free parameters keep the set's order, whatever order the names are given in.
    pub fn free<S: AsRef<str>>(&self, names: &[S]) -> Result<FreeSet, ParamError> {
        let mut mask = vec![false; self.len()];
        for n in names {
            let i = self.index_of(n.as_ref())?;
            if mask[i] {
                return Err(ParamError::Duplicate(n.as_ref().to_string()));
            }
            mask[i] = true;
        }
        FreeSet::from_mask(&mask)
    }
}

/// Which parameters of a [`ParamSet`] are estimated (free) and which are held at their nominal
/// values (fixed): a view by indices into the full parameter vector.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct FreeSet {
    free: Vec<usize>,
    fixed: Vec<usize>,
}

impl FreeSet {
    /// From a mask over the full parameter vector (`true` = free).
    pub fn from_mask(mask: &[bool]) -> Result<Self, ParamError> {
        let free: Vec<usize> = (0..mask.len()).filter(|&i| mask[i]).collect();
        if free.is_empty() {
            return Err(ParamError::NoneFree);
        }
        let fixed = (0..mask.len()).filter(|&i| !mask[i]).collect();
        Ok(Self { free, fixed })
    }

    /// Indices of the free parameters, ascending.
    pub fn free(&self) -> &[usize] {
        &self.free
    }

    /// Indices of the fixed parameters, ascending.
    pub fn fixed(&self) -> &[usize] {
        &self.fixed
    }

    /// Number of parameters in the full vector.
    pub fn full_len(&self) -> usize {
        self.free.len() + self.fixed.len()
    }

    /// True when no parameter is fixed.
    pub fn is_all_free(&self) -> bool {
        self.fixed.is_empty()
    }

    /// Gather the free entries of a full-length vector into `out` (length = number free).
    pub fn gather(&self, full: &[f64], out: &mut [f64]) {
        for (o, &i) in out.iter_mut().zip(&self.free) {
            *o = full[i];
        }
    }

    /// Write the free entries `reduced` into their places of a full-length vector.
    pub fn scatter(&self, reduced: &[f64], full: &mut [f64]) {
        for (&r, &i) in reduced.iter().zip(&self.free) {
            full[i] = r;
        }
    }

    /// For a model linear in the parameters, `y = φᵀϑ`: the contribution of the fixed
    /// parameters, `Σ_fixed φ_j·ϑ0_j`, which is subtracted from `y` so that the free parameters
    /// see `y − Σ_fixed φ_j ϑ0_j = φ_freeᵀ ϑ_free`.
    pub fn fixed_contribution(&self, phi_full: &[f64], nominal: &[f64]) -> f64 {
        self.fixed.iter().map(|&j| phi_full[j] * nominal[j]).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn free_view_keeps_set_order_and_splits_regression() {
        let p = ParamSet::new(["K", "B", "off"], vec![1250.0, 0.95, 0.0]).unwrap();
        let v = p.free(&["off", "K"]).unwrap();
        assert_eq!(v.free(), &[0, 2]);
        assert_eq!(v.fixed(), &[1]);
        assert_eq!(p.free_names(&v), vec!["K", "off"]);
        let phi = [2.0, 3.0, 1.0];
        let mut red = [0.0; 2];
        v.gather(&phi, &mut red);
        assert_eq!(red, [2.0, 1.0]);
        // y = 2·1250 + 3·0.95 + 1·0 ; fixed part is 3·0.95
        assert_eq!(v.fixed_contribution(&phi, p.nominal()), 3.0 * 0.95);
        let mut full = p.nominal().to_vec();
        v.scatter(&[1300.0, 0.5], &mut full);
        assert_eq!(full, vec![1300.0, 0.95, 0.5]);
    }

    #[test]
    fn errors_name_the_problem() {
        let p = ParamSet::zeros(["A", "B"]).unwrap();
        let e = p.free(&["C"]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "unknown parameter 'C'; the parameters are: A, B"
        );
        assert_eq!(p.free::<&str>(&[]).unwrap_err(), ParamError::NoneFree);
        assert!(matches!(
            ParamSet::zeros(["A", "A"]),
            Err(ParamError::Duplicate(_))
        ));
        assert!(matches!(
            ParamSet::new(["A"], vec![f64::NAN]),
            Err(ParamError::NonFinite { .. })
        ));
    }
}
