//! The fit's result ([`FrictionFit`]), the friction presets and the JSON summary.

use super::*;

/// The characterisation's result.
#[derive(Debug, Clone, Serialize)]
pub struct FrictionFit {
    /// The cycle means the fit used.
    pub data: CycleMeans,
    /// The ranking of all 20 coefficients (selection order).
    pub ranking: Vec<RankedParam>,
    /// The estimable coefficients, in rank order.
    pub estimable: Vec<String>,
    /// Nominal coefficients c1 … c20.
    pub nominal: Vec<f64>,
    /// Final coefficients c1 … c20 (the non-estimable ones at nominal).
    pub params: Vec<f64>,
    /// Standard errors of the estimated coefficients (`None` for the fixed ones).
    pub std_err: Vec<Option<f64>>,
    /// The nominal model's prediction per cycle [N·m].
    pub predicted_nominal: Vec<f64>,
    /// One-step-ahead prediction per cycle [N·m].
    pub predicted: Vec<f64>,
    /// The final coefficients' prediction per cycle [N·m].
    pub predicted_final: Vec<f64>,
    /// `100·(predicted − measured)/measured` per cycle.
    pub error_pct: Vec<f64>,
    /// `100·(predicted − truth)/truth` per cycle, when the recording carries the truth.
    pub truth_error_pct: Option<Vec<f64>>,
    /// The last cycle's prediction error [%].
    pub final_error_pct: f64,
    /// The largest |prediction error| after the start-up transient [%].
    pub max_error_after_transient_pct: f64,
    /// The same against the truth, when known [%].
    pub max_truth_error_after_transient_pct: Option<f64>,
    /// NMSE (Eq. 6.4) of the nominal model and of the final coefficients against the measured
    /// cycle means.
    pub nmse_nominal: f64,
    /// See [`nmse_nominal`](Self::nmse_nominal).
    pub nmse_final: f64,
    /// Every steady cycle through the estimator, in order: the coefficients' track (the file
    /// verb's `--tracks`).
    #[serde(skip)]
    pub cycles: Vec<FrictionSample>,
    /// The samples that were not a number (a sensor's dropout), each left out with the cycle
    /// it cuts.
    pub dropouts: Vec<Dropout>,
}

/// The model presets by name: the thesis's and the original model's
/// ([`physid_models::friction::PRESETS`]) and `cell`, the built-in virtual test cell's engine (its
/// geometry with the thesis's oil and valvetrain).
pub const FRICTION_PRESETS: [&str; 3] = ["thesis", "sandoval2002", "cell"];

/// A friction model preset by name ([`FRICTION_PRESETS`]); `None` for an unknown name.
pub fn friction_preset(name: &str) -> Option<(Design<f64>, Settings)> {
    match name {
        "cell" => Some(crate::cell::cell_friction_model()),
        other => physid_models::friction::preset(other),
    }
}

/// The characterisation's objective (thesis §7.3): the prediction within ±5 % after the
/// start-up transient.
pub const OBJECTIVE_PCT: f64 = 5.0;

/// What `physid friction fit --json` prints (and the demo's summary holds).
#[derive(Debug, Clone, Serialize)]
pub struct FrictionSummary<'a> {
    /// The estimated coefficients, in rank order.
    pub estimable: &'a [String],
    /// The identifiability ranking.
    pub ranking: &'a [RankedParam],
    /// Every coefficient's final value, by name.
    pub params: BTreeMap<&'static str, f64>,
    /// Their nominal values.
    pub nominal: BTreeMap<&'static str, f64>,
    /// The standard errors of the estimated ones (null where the estimator has none yet).
    pub std_err: BTreeMap<&'a str, Option<f64>>,
    /// The prediction errors [%].
    pub prediction_error_pct: PredictionErrors,
    /// NMSE (Eq. 6.4) against the cycle means.
    pub nmse: NmseBeforeAfter,
    /// The cycles.
    pub cycles: CycleCount,
    /// The dropouts left out, each with the cycle it cuts.
    pub dropouts: &'a [Dropout],
}

/// Prediction errors of a friction fit [%].
#[derive(Debug, Clone, Copy, Serialize)]
pub struct PredictionErrors {
    /// Of the last cycle.
    #[serde(rename = "final")]
    pub final_pct: f64,
    /// The largest after the start-up transient, against the cycle means.
    pub max_after_transient: f64,
    /// The same against the simulated truth.
    pub max_after_transient_vs_truth: Option<f64>,
}

/// NMSE of the nominal and of the fitted model.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct NmseBeforeAfter {
    /// The nominal coefficients.
    pub nominal: f64,
    /// The fitted ones.
    pub fitted: f64,
}

/// The cycles a friction fit used and skipped.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct CycleCount {
    /// Used.
    pub used: usize,
    /// Skipped as not steady.
    pub skipped_unsteady: usize,
}

impl FrictionFit {
    /// The result without its tracks.
    pub fn summary(&self) -> FrictionSummary<'_> {
        let by_name = |v: &[f64]| {
            REGRESSION_PARAMS
                .iter()
                .copied()
                .zip(v.iter().copied())
                .collect()
        };
        FrictionSummary {
            estimable: &self.estimable,
            ranking: &self.ranking,
            params: by_name(&self.params),
            nominal: by_name(&self.nominal),
            std_err: self
                .estimable
                .iter()
                .map(|n| {
                    let j = REGRESSION_PARAMS.iter().position(|p| p == n);
                    (n.as_str(), j.and_then(|j| self.std_err[j]))
                })
                .collect(),
            prediction_error_pct: PredictionErrors {
                final_pct: self.final_error_pct,
                max_after_transient: self.max_error_after_transient_pct,
                max_after_transient_vs_truth: self.max_truth_error_after_transient_pct,
            },
            nmse: NmseBeforeAfter {
                nominal: self.nmse_nominal,
                fitted: self.nmse_final,
            },
            cycles: CycleCount {
                used: self.data.len(),
                skipped_unsteady: self.data.skipped_unsteady,
            },
            dropouts: &self.dropouts,
        }
    }

    /// The largest prediction error after the start-up transient [%], against the simulated
    /// truth when the recording carries it, else against the measured cycle means.
    pub fn error_after_transient_pct(&self) -> f64 {
        self.max_truth_error_after_transient_pct
            .unwrap_or(self.max_error_after_transient_pct)
    }

    /// Whether that error is within [`OBJECTIVE_PCT`].
    pub fn objective_met(&self) -> bool {
        self.error_after_transient_pct() <= OBJECTIVE_PCT
    }
}
