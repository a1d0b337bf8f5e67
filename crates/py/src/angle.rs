//! A file read on a crank-angle basis from Python: the engine angle from `theta_en`, an
//! encoder's counts and marker, or a raw trigger wheel or quadrature encoder — the library's
//! input plan ([`physid_apps::angle_input`]), the same as `physid convert --crank-angle`.

use crate::err;
use physid_apps::acquisition::{
    parse_threshold, AcquisitionOptions, AngleSensor, AngleSpec, DecodedAngle, PhaseFrom,
};
use physid_apps::angle_input::{AngleInput, InputObserver};
use physid_apps::compression::TdcFromPressure;
use physid_core::Recording;
use physid_io::ReadOptions;
use physid_signal::wheel::{Edge, EdgeOptions};
use pyo3::PyResult;
use std::path::Path;
use std::sync::{Arc, Mutex};

/// How the engine angle is found, as `physid.read` takes it.
pub(crate) struct AngleArgs {
    pub wheel: Option<String>,
    pub quadrature: Option<String>,
    pub encoder_raw: Option<String>,
    pub index_raw: Option<String>,
    pub encoders: Option<Vec<String>>,
    pub marker: Option<String>,
    pub tdc_offset: f64,
    pub phase_from: Option<String>,
    pub tdc_from: Option<String>,
    pub stroke: Option<f64>,
    pub rod: Option<f64>,
    pub edge: String,
    pub threshold: Option<String>,
    pub step_deg: f64,
}

impl AngleArgs {
    /// Whether any of them asks for a crank-angle basis.
    pub fn any(&self) -> bool {
        self.wheel.is_some()
            || self.quadrature.is_some()
            || self.encoder_raw.is_some()
            || self.encoders.is_some()
            || self.tdc_from.is_some()
    }

    /// The acquisition options they give (errors name the argument).
    fn options(&self) -> PyResult<AcquisitionOptions> {
        let mut o = AcquisitionOptions::default();
        if let Some(m) = &self.marker {
            o.marker.clone_from(m);
        }
        if let Some(e) = &self.encoders {
            o.encoders = e
                .iter()
                .map(|e| AcquisitionOptions::parse_encoder(e).map_err(err))
                .collect::<PyResult<_>>()?;
        }
        let edges = || -> PyResult<EdgeOptions> {
            let edge: Edge = self.edge.parse().map_err(err)?;
            let threshold = self
                .threshold
                .as_deref()
                .map(parse_threshold)
                .transpose()
                .map_err(err)?;
            Ok(EdgeOptions { edge, threshold })
        };
        let given = [&self.wheel, &self.quadrature, &self.encoder_raw];
        if given.iter().filter(|s| s.is_some()).count() > 1 {
            return Err(err("give one of wheel, quadrature and encoder_raw"));
        }
        if self.index_raw.is_some() != self.encoder_raw.is_some() {
            return Err(err(
                "encoder_raw and index_raw go together: the pulses and their index",
            ));
        }
        let sensor = match given {
            [Some(w), ..] => Some(AngleSensor::parse_wheel(w, edges()?).map_err(err)?),
            [_, Some(q), _] => Some(AngleSensor::parse_quadrature(q).map_err(err)?),
            [.., Some(e)] => Some(
                AngleSensor::parse_pulses(
                    e,
                    self.index_raw.as_deref().unwrap_or_default(),
                    edges()?,
                )
                .map_err(err)?,
            ),
            _ => None,
        };
        o.sensor = match sensor {
            Some(s) => Some(
                AngleSpec::new(s, self.tdc_offset, PhaseFrom::parse(self.phase_from.as_deref()))
                    .map_err(|e| err(format!("tdc_offset {e}")))?,
            ),
            None if self.tdc_from.is_some() => {
                return Err(err(
                    "tdc_from places the TDC on a raw angle sensor: give wheel, quadrature or encoder_raw",
                ))
            }
            None => {
                // With `theta_en` or an encoder's counts and marker, as `convert --phase-from`.
                o.phase_from = PhaseFrom::parse(self.phase_from.as_deref());
                None
            }
        };
        Ok(o)
    }
}

/// What the plan tells, kept for the recording's `meta`.
#[derive(Default)]
struct Kept {
    notes: Mutex<Vec<(String, String)>>,
}

impl Kept {
    fn keep(&self, key: &str, text: String) {
        // A poisoned lock only loses a note.
        if let Ok(mut n) = self.notes.lock() {
            n.push((key.to_string(), text));
        }
    }
}

impl InputObserver for Kept {
    fn read_warning(&self, _path: &Path, warning: &str) {
        self.keep("warning", warning.to_string());
    }

    fn decoded(&self, _path: &Path, d: &DecodedAngle) {
        let mut text = format!("{}; {}", d.summary, d.phase);
        for f in &d.findings {
            text.push_str(&format!("; sample {}: {}", f.index, f.detail));
        }
        self.keep("angle", text);
    }

    fn tdc_placed(&self, _path: &Path, channel: &str, found: &TdcFromPressure) {
        self.keep(
            "tdc_from",
            format!(
                "TDC from '{channel}' (the motored model over {} TDCs): {:.3}° after the sensor's reference (95 %: {:.3} … {:.3}°)",
                found.fit.events.len(),
                found.tdc_offset_deg,
                found.ci95.0,
                found.ci95.1
            ),
        );
    }
}

/// `path` read with `read` on a crank-angle basis as `args` say; what decoding found is in the
/// recording's `meta` (`angle`, `tdc_from`, `warning`).
pub(crate) fn read_crank_angle(
    path: &Path,
    read: ReadOptions,
    args: &AngleArgs,
) -> PyResult<Recording> {
    if !(args.step_deg.is_finite() && args.step_deg > 0.0) {
        return Err(err(format!(
            "step_deg {}: expected a crank-angle step > 0 degrees",
            physid_core::Num(args.step_deg)
        )));
    }
    let channels = read.channels.clone();
    let kept = Arc::new(Kept::default());
    let mut plan = AngleInput::new(path, read, args.options()?, kept.clone());
    plan.step_deg = args.step_deg;
    match (&args.tdc_from, args.stroke, args.rod) {
        (Some(c), Some(stroke), Some(rod)) => {
            plan.tdc_from = Some(c.clone());
            plan.crank = Some((stroke, rod));
        }
        (Some(c), ..) => {
            return Err(err(format!(
                "tdc_from '{c}' needs the crank's lengths: stroke and rod [m]"
            )))
        }
        (None, None, None) => {}
        (None, ..) => {
            return Err(err(
                "stroke and rod are for placing the TDC from a motored pressure (tdc_from=CHANNEL): without it, they would be ignored",
            ))
        }
    }
    let names: Option<Vec<&str>> = channels
        .as_ref()
        .map(|c| c.iter().map(String::as_str).collect());
    let (mut rec, _) = plan
        .read_all(names.as_deref())
        .map_err(|e| err(format!("{}: {e}", path.display())))?;
    if rec.is_empty() {
        return Err(err(format!(
            "{}: no sample on a crank-angle basis: {}",
            path.display(),
            physid_apps::angle_input::NO_CRANK_SAMPLE
        )));
    }
    let notes = kept.notes.lock().map(|n| n.clone()).unwrap_or_default();
    for (k, v) in notes {
        rec.meta.insert(k, v);
    }
    Ok(rec)
}
