//! The monitor's result as the verb's JSON prints it ([`ShaftSummary`]).

use super::*;

/// What `physid monitor shaft --json` prints (and the demo's summary holds per method).
#[derive(Debug, Clone, Serialize)]
pub struct ShaftSummary<'a> {
    /// The method.
    pub method: &'static str,
    /// Final K, B, τ0.
    #[serde(rename = "final")]
    pub final_estimate: ShaftParams,
    /// Their standard errors (null before they can be estimated, and for those unresolved).
    pub std_err: ShaftParams,
    /// The parameters the data did not resolve (absent when all were).
    #[serde(skip_serializing_if = "<[_]>::is_empty")]
    pub unresolved: &'a [&'static str],
    /// What makes the estimates suspect (absent when nothing does).
    #[serde(skip_serializing_if = "<[_]>::is_empty")]
    pub warnings: &'a [String],
    /// The alarms.
    pub alarms: &'a [ShaftAlarm],
    /// NMSE (Eq. 6.4) of the tracks against the truth (simulated data).
    pub nmse: Option<PerParam>,
    /// With the excitation supervisor: how long K and B were frozen [s].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frozen_s: Option<PerParam>,
}

impl ShaftMonitor {
    /// The result without its tracks.
    pub fn summary(&self) -> ShaftSummary<'_> {
        ShaftSummary {
            method: self.method,
            final_estimate: self.final_estimate,
            std_err: self.final_std_err,
            unresolved: &self.unresolved,
            warnings: &self.warnings,
            alarms: &self.alarms,
            nmse: self.nmse,
            frozen_s: self.frozen_s,
        }
    }
}
