//! The fit's result ([`TorqueFit`]), its parameter tracks and the JSON summary.

use super::*;

/// One estimated parameter's track.
#[derive(Debug, Clone, Serialize, serde::Deserialize)]
pub struct Track {
    /// Parameter name.
    pub param: String,
    /// Estimates at [`TorqueFit::t`].
    pub value: Vec<f64>,
    /// Standard errors at [`TorqueFit::t`].
    pub std_err: Vec<f64>,
}

/// The test cell's parameter path of each cyclic-torque parameter that has one (the truth of
/// simulated data; the friction cubic's c1 … c10 have none).
pub const TRUTH_PATHS: [(&str, &str); 5] = [
    ("M_rec", "engine.m_rec"),
    ("b", "engine.bore"),
    ("L", "engine.rod"),
    ("r", "engine.crank_radius"),
    ("delta", "engine.pin_offset"),
];

/// The fit's result.
#[derive(Debug, Clone, Serialize)]
pub struct TorqueFit {
    /// Filter name.
    pub method: &'static str,
    /// The ranking of the analysed parameters.
    pub ranking: Vec<RankedParam>,
    /// The estimable parameters, in rank order.
    pub estimable: Vec<String>,
    /// Nominal values of all 15 parameters.
    pub nominal: Vec<f64>,
    /// Final values of all 15 (the fixed ones at nominal).
    pub params: Vec<f64>,
    /// Final standard errors (`None` for fixed parameters).
    pub std_err: Vec<Option<f64>>,
    /// R2 used [N²·m²].
    pub r2: f64,
    /// Covariance repairs by the filter.
    pub repairs: u64,
    /// Times of the tracks [s] (decimated to at most ~4000 points).
    pub t: Vec<f64>,
    /// Tracks of the estimated parameters.
    pub tracks: Vec<Track>,
    /// Measured torque at the track times [N·m].
    pub measured: Vec<f64>,
    /// One-step-ahead prediction at the track times [N·m].
    pub predicted: Vec<f64>,
    /// NMSE (Eq. 6.4) of the nominal model over the recording.
    pub nmse_before: f64,
    /// NMSE of the final estimates over the recording.
    pub nmse_after: f64,
    /// NRMSE of the nominal model.
    pub nrmse_before: f64,
    /// NRMSE of the final estimates.
    pub nrmse_after: f64,
    /// The last two cycles at full resolution: time [s], measured, nominal-model and
    /// final-estimate torque [N·m] (prediction against measurement, readable).
    pub last_cycles: [Vec<f64>; 4],
    /// Samples processed.
    pub samples: usize,
    /// Every cycle's worth (720 samples) through the filter, in order: the estimates' track
    /// (the file verb's `--tracks`).
    pub cycles: Vec<TorqueCycle>,
    /// The samples that were not a number (a sensor's dropout), each left out with the cycle
    /// it cuts.
    pub dropouts: Vec<Dropout>,
}

/// What `physid torque fit --json` prints (and the demo's summary holds).
#[derive(Debug, Clone, Serialize)]
pub struct TorqueSummary<'a> {
    /// The filter.
    pub method: &'static str,
    /// The estimated parameters, in rank order.
    pub estimable: &'a [String],
    /// The identifiability ranking.
    pub ranking: &'a [RankedParam],
    /// Every parameter's final value, by name.
    pub params: BTreeMap<&'static str, f64>,
    /// The standard errors of the estimated ones, by name.
    pub std_err: BTreeMap<&'static str, f64>,
    /// NMSE (Eq. 6.4) of the prediction with the nominal and the final values.
    pub nmse_before: f64,
    /// See `nmse_before`.
    pub nmse_after: f64,
    /// NRMSE of the same.
    pub nrmse_before: f64,
    /// See `nrmse_before`.
    pub nrmse_after: f64,
    /// R² of the batch fit.
    pub r2: f64,
    /// Covariance repairs.
    pub repairs: u64,
    /// Samples.
    pub samples: usize,
    /// The dropouts left out, each with the cycle it cuts.
    pub dropouts: &'a [Dropout],
}

impl TorqueFit {
    /// The result without its tracks.
    pub fn summary(&self) -> TorqueSummary<'_> {
        TorqueSummary {
            method: self.method,
            estimable: &self.estimable,
            ranking: &self.ranking,
            params: PARAMS
                .iter()
                .copied()
                .zip(self.params.iter().copied())
                .collect(),
            std_err: PARAMS
                .iter()
                .zip(&self.std_err)
                .filter_map(|(&n, s)| s.map(|s| (n, s)))
                .collect(),
            nmse_before: self.nmse_before,
            nmse_after: self.nmse_after,
            nrmse_before: self.nrmse_before,
            nrmse_after: self.nrmse_after,
            r2: self.r2,
            repairs: self.repairs,
            samples: self.samples,
            dropouts: &self.dropouts,
        }
    }

    /// The true value of each track over its times, where the recording is simulated and the
    /// parameter is one of the cell's ([`TRUTH_PATHS`]); `None` elsewhere.
    pub fn truths(&self, rec: &Recording) -> Vec<Option<Vec<f64>>> {
        self.tracks
            .iter()
            .map(|tr| {
                let path = TRUTH_PATHS.iter().find(|p| p.0 == tr.param)?.1;
                crate::cell::truth(rec, path, &self.t)
            })
            .collect()
    }
}
