//! The model's data: a motored recording's 1° samples as the rows of Eq. 8.2 ([`TorqueData`])
//! and the identifiability of its parameters on them ([`torque_identifiability`]).

use super::*;

/// The model's data from a crank-angle recording: input columns θ (`theta_en`, rad from TDC),
/// ω, α, p_cyl, p_crank [Pa], T_oil [°C], the measured engine torque, and time.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct TorqueData {
    /// Input columns in [`CyclicTorque`]'s order.
    pub inputs: Vec<Vec<f64>>,
    /// Measured engine torque `torque_engine` [N·m].
    pub y: Vec<f64>,
    /// Time [s].
    pub t: Vec<f64>,
    /// The crank angle's channel (`theta`, `theta_en`), for what a sample that is not a
    /// number is named by.
    #[serde(skip, default = "theta_en")]
    theta: &'static str,
}

fn theta_en() -> &'static str {
    "theta_en"
}

impl TorqueData {
    /// Read and check the channels (units converted to the model's). The crank angle is
    /// `theta` (rad from TDC, as the acquisition chain's crank-angle conversion writes it) or
    /// else `theta_en`; a time-basis recording is first resampled to one sample per crank
    /// degree from its engine encoder and TDC marker.
    pub fn from_recording(rec: &Recording) -> Result<Self, AppError> {
        let converted;
        let rec = if rec.basis == Basis::Time {
            converted = to_crank_angle(rec, &AcquisitionOptions::default(), 1.0)?;
            &converted
        } else {
            rec
        };
        Self::from_crank_angle(rec, 0)
    }

    /// The columns of a crank-angle recording, or of a chunk of one whose first sample is the
    /// recording's `offset`-th (an error names the sample in the recording).
    pub fn from_crank_angle(rec: &Recording, offset: usize) -> Result<Self, AppError> {
        let data = Self::columns(rec)?;
        for (name, col) in data.named() {
            if let Some(i) = col.iter().position(|v| !v.is_finite()) {
                return Err(AppError::Invalid(format!(
                    "channel '{name}' sample {} is {}: the model needs finite data",
                    offset + i,
                    col[i]
                )));
            }
        }
        Ok(data)
    }

    /// The columns of a crank-angle recording as they are, a sample that is not a number
    /// included ([`Degrees`] leaves out the cycle it cuts).
    pub(super) fn columns(rec: &Recording) -> Result<Self, AppError> {
        let theta = if rec.values("theta").is_ok() {
            "theta"
        } else {
            "theta_en"
        };
        let t_oil_c: Vec<f64> = rec
            .values_in("T_oil", "K")?
            .iter()
            .map(|k| k - 273.15)
            .collect();
        let inputs = vec![
            rec.values_in(theta, "rad")?,
            rec.values_in("omega_en", "rad/s")?,
            rec.values_in("alpha_en", "rad/s^2")?,
            rec.values_in("p_cyl", "Pa")?,
            rec.values_in("p_crank", "Pa")?,
            t_oil_c,
        ];
        let y = rec.values_in("torque_engine", "N*m")?;
        let t = rec.values("t")?.to_vec();
        Ok(Self {
            inputs,
            y,
            t,
            theta,
        })
    }

    /// The model's channels (the inputs, then the measured torque) by name.
    pub(super) fn named(&self) -> [(&'static str, &[f64]); 7] {
        let c = |k: usize| self.inputs[k].as_slice();
        [
            (self.theta, c(0)),
            ("omega_en", c(1)),
            ("alpha_en", c(2)),
            ("p_cyl", c(3)),
            ("p_crank", c(4)),
            ("T_oil", c(5)),
            ("torque_engine", &self.y),
        ]
    }

    /// Whether the samples `r` are all numbers, inputs and torque.
    pub(super) fn finite(&self, r: std::ops::Range<usize>) -> bool {
        let all = |c: &[f64]| c.iter().all(|v| v.is_finite());
        all(&self.y[r.clone()]) && self.inputs.iter().all(|c| all(&c[r.clone()]))
    }

    /// The samples from `n` on dropped.
    pub(super) fn truncate(&mut self, n: usize) {
        for col in &mut self.inputs {
            col.truncate(n);
        }
        self.y.truncate(n);
        self.t.truncate(n);
    }

    /// The samples `r` of `other` appended.
    pub(super) fn extend_from(&mut self, other: &TorqueData, r: std::ops::Range<usize>) {
        for (col, from) in self.inputs.iter_mut().zip(&other.inputs) {
            col.extend_from_slice(&from[r.clone()]);
        }
        self.y.extend_from_slice(&other.y[r.clone()]);
        self.t.extend_from_slice(&other.t[r]);
    }

    /// The identifiability data view.
    pub fn view(&self) -> Data<'_> {
        Data {
            inputs: self.inputs.iter().map(|c| c.as_slice()).collect(),
            y: Some(&self.y),
        }
    }

    pub(super) fn row(&self, i: usize, u: &mut [f64; 6]) {
        for (k, col) in self.inputs.iter().enumerate() {
            u[k] = col[i];
        }
    }

    /// No samples, room for `n`.
    pub(super) fn with_capacity(n: usize) -> Self {
        Self {
            inputs: (0..6).map(|_| Vec::with_capacity(n)).collect(),
            y: Vec::with_capacity(n),
            t: Vec::with_capacity(n),
            theta: "theta_en",
        }
    }

    /// One sample: the inputs, the measured torque, the time.
    pub(super) fn push(&mut self, u: &[f64; 6], y: f64, t: f64) {
        for (col, v) in self.inputs.iter_mut().zip(u) {
            col.push(*v);
        }
        self.y.push(y);
        self.t.push(t);
    }

    /// Every sample dropped, the room kept.
    pub(super) fn clear(&mut self) {
        for col in &mut self.inputs {
            col.clear();
        }
        self.y.clear();
        self.t.clear();
    }
}

impl Rows for TorqueData {}

impl Reopen<DataRows, IdentError> for TorqueData {
    fn pass(
        &self,
        visit: &mut dyn for<'c> FnMut(&'c Data<'c>) -> Result<(), IdentError>,
    ) -> Result<(), IdentError> {
        visit(&self.view())
    }
}

/// Identifiability of the cyclic-torque parameters on a recording's 1° samples (in memory,
/// [`TorqueData`], or gone over in passes, [`Degrees`]): the analysis over every parameter not
/// in `fixed`, and the indices (into [`PARAMS`]) of the estimable ones in rank order.
pub fn torque_identifiability<R: Rows + ?Sized>(
    data: &R,
    nominal: &[f64; 15],
    fixed: &[String],
    selection: &Selection,
) -> Result<(Analysis, Vec<usize>), AppError> {
    for f in fixed {
        if !PARAMS.contains(&f.as_str()) {
            return Err(AppError::Invalid(format!(
                "fixed parameter '{f}': the parameters are {}",
                PARAMS.join(", ")
            )));
        }
    }
    let free: Vec<usize> = (0..15)
        .filter(|&j| !fixed.iter().any(|f| f == PARAMS[j]))
        .collect();
    if free.is_empty() {
        return Err(AppError::Invalid(
            "every parameter is fixed: nothing to analyse".into(),
        ));
    }
    let model = CyclicTorque::default();
    let a = analyse(&model, data, nominal, &free, IdentConfig::default())?;
    let (k, _) = selection.resolve(&model, data, &a)?;
    let estimable = a.top(k).iter().map(|&i| free[i]).collect();
    Ok((a, estimable))
}
