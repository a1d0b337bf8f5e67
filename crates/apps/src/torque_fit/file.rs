//! The file verb: a recording in memory or a file read in passes ([`torque_fit`],
//! [`torque_fit_degrees`]).

use super::*;

/// Samples per cycle at one per crank degree.
pub(super) const PER_CYCLE: usize = 720;

/// The channels resampled to one per crank degree from time-basis samples, in the model's
/// input order after θ, then the measured torque and the time, with their units.
pub(super) const CURVE_CHANNELS: [(&str, &str); 7] = [
    ("omega_en", "rad/s"),
    ("alpha_en", "rad/s^2"),
    ("p_cyl", "Pa"),
    ("p_crank", "Pa"),
    ("T_oil", "K"),
    ("torque_engine", "N*m"),
    ("t", "s"),
];

/// Samples per chunk of 1° samples handed to the analyses and the filter.
pub(super) const FILE_CHUNK: usize = 4096;

/// Points the tracks keep at least; beyond twice this, every other one is dropped (the tracks'
/// step doubles), so they take bounded memory however long the recording.
pub const TRACK_POINTS: usize = 4000;

/// Run Application 3 on a recording in memory: one sample per crank degree (a crank-angle
/// recording, or a time-basis one with `theta_en` resampled as it is gone over, cycles from its
/// first TDC marker; one with only the encoder count is converted first), the parameters chosen
/// on all of it ([`torque_fit_degrees`]).
pub fn torque_fit(rec: &Recording, cfg: &TorqueFitConfig) -> Result<TorqueFit, AppError> {
    if rec.basis == Basis::Time && rec.channel("theta_en").is_err() {
        let converted = to_crank_angle(rec, &AcquisitionOptions::default(), 1.0)?;
        return torque_fit_degrees(&Degrees::memory(&converted)?, cfg);
    }
    torque_fit_degrees(&Degrees::memory(rec)?, cfg)
}

/// Application 3 over a recording's 1° samples, gone over in passes: the parameters chosen on
/// all of them (the analyses and the batch fit fold them a chunk at a time), the filter run
/// through them once, the prediction of the nominal and the final model summed over them once.
/// Memory is that of the source ([`Degrees`]) and the bounded tracks, whatever the length.
pub fn torque_fit_degrees(src: &Degrees, cfg: &TorqueFitConfig) -> Result<TorqueFit, AppError> {
    let n = src.len()?;
    at_least_a_cycle(n)?;
    let mut filter = TorqueFilter::choose(cfg, src, true)?;
    let mut out = Vec::new();
    let mut u = [0.0; 6];
    src.samples::<AppError>(&mut |d| {
        for i in 0..d.y.len() {
            d.row(i, &mut u);
            filter.step(&u, d.y[i], d.t[i], &mut out)?;
        }
        Ok(())
    })?;
    let mut fit = filter.result(cfg, src, n)?;
    fit.dropouts = src.dropouts()?;
    fit.cycles = out
        .into_iter()
        .filter_map(|o| match o {
            TorqueOutput::Cycle(c) => Some(c),
            TorqueOutput::Selected { .. } | TorqueOutput::Dropout(_) => None,
        })
        .collect();
    Ok(fit)
}

pub(super) fn at_least_a_cycle(n: usize) -> Result<(), AppError> {
    if n < PER_CYCLE {
        return Err(AppError::Invalid(format!(
            "{n} samples: the fit needs at least one cycle (720 samples at one per crank degree)"
        )));
    }
    Ok(())
}

/// The channels the fit reads from a crank-angle recording with `header`'s channels (physid
/// names): the crank angle — `theta`, else `theta_en` — and the curves'.
pub fn crank_channels(header: &Recording) -> Vec<&'static str> {
    let theta = if header.channel("theta").is_ok() {
        "theta"
    } else {
        "theta_en"
    };
    let mut names = vec![theta];
    names.extend(CURVE_CHANNELS.iter().map(|c| c.0));
    names
}

/// The channels the fit reads from a time-basis recording (physid names): those it needs, then
/// those it takes when they are there (the TDC marker).
pub fn sample_channels() -> (Vec<&'static str>, Vec<&'static str>) {
    let mut needed = vec!["theta_en"];
    needed.extend(CURVE_CHANNELS.iter().map(|c| c.0));
    (needed, vec![TDC_MARKER])
}

/// What takes each 1° sample: the model's inputs, the measured torque [N·m], the time [s].
pub(super) type EachDegree<'f, E> = dyn FnMut(&[f64; 6], f64, f64) -> Result<(), E> + 'f;
