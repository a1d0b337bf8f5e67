//! The TDC from the pressure itself ([`tdc_from_pressure`]): each cycle's peak angle
//! ([`PeakAngles`]), then the motored fit's TDC offset and loss angle.

use super::*;

/// The TDC found on a motored pressure trace ([`tdc_from_pressure`]).
#[derive(Debug, Clone, Serialize)]
pub struct TdcFromPressure {
    /// The crank angle from the sensor's reference to the firing TDC [deg], in [0, 360).
    pub tdc_offset_deg: f64,
    /// Its 95 % interval [deg] (from the fit over all the TDCs).
    pub ci95: (f64, f64),
    /// Where the pressure peaks [deg ATDC] on the fitted trace: before TDC by the loss angle.
    pub peak_deg: Option<f64>,
    /// The fit it came from (on the recording with the TDC where the pressure peaks).
    pub fit: CompressionFit,
    /// Complete cycles left out as fired ([`fired`]): the TDC is placed on the motored ones.
    pub fired_left_out: usize,
}

/// Place the firing TDC from a motored cylinder-pressure trace: decode the raw angle sensor
/// of `opts` with its reference as TDC, move the TDC to where `channel` peaks (the median over
/// the cycles), then fit the motored model there ([`compression_fit`]) — whose `tdc_shift`, fitted
/// with the loss rate, is where the true TDC lies: `offset = peak + tdc_shift`, not the peak (the
/// peak comes early by the thermodynamic loss angle). Which revolution fires comes from
/// `opts`' `phase_from`, or from `channel` when none is given. [`tdc_from_pressure_in`] on the
/// recording held whole.
pub fn tdc_from_pressure(
    rec: &Recording,
    opts: &crate::acquisition::AcquisitionOptions,
    cfg: &CompressionConfig,
    step_deg: f64,
) -> Result<TdcFromPressure, AppError> {
    tdc_from_pressure_in(&InMemory { rec, step_deg }, opts, cfg, step_deg, usize::MAX)
}

/// A raw angle sensor's recording put on a crank-angle basis with the options given, gone over
/// in passes — the builder of the passes [`tdc_from_pressure_in`] makes (as arrow-rs's reader
/// builders): a recording in memory, or a file read again
/// ([`CrankFile`](crate::angle_input::CrankFile)).
pub trait CrankBuilder {
    /// The recording on a crank-angle basis with `opts`, gone over in passes.
    fn with<'s>(
        &'s self,
        opts: &crate::acquisition::AcquisitionOptions,
    ) -> Box<dyn Reopen<Recordings, AppError> + 's>;
}

/// A time-basis recording in memory put on a crank-angle basis every `step_deg`.
struct InMemory<'r> {
    rec: &'r Recording,
    step_deg: f64,
}

impl CrankBuilder for InMemory<'_> {
    fn with<'s>(
        &'s self,
        opts: &crate::acquisition::AcquisitionOptions,
    ) -> Box<dyn Reopen<Recordings, AppError> + 's> {
        Box::new(Decoded {
            rec: self.rec,
            opts: opts.clone(),
            step_deg: self.step_deg,
        })
    }
}

/// One [`InMemory`] recording with its options: each pass decodes it whole.
struct Decoded<'r> {
    rec: &'r Recording,
    opts: crate::acquisition::AcquisitionOptions,
    step_deg: f64,
}

impl Reopen<Recordings, AppError> for Decoded<'_> {
    fn pass(
        &self,
        visit: &mut dyn for<'c> FnMut(&'c Recording) -> Result<(), AppError>,
    ) -> Result<(), AppError> {
        let decoded =
            crate::acquisition::to_crank_angle_decoded(self.rec, &self.opts, self.step_deg)?;
        visit(&decoded.0)
    }
}

/// [`tdc_from_pressure`] on a recording read in passes — `source` puts it on a crank-angle
/// basis (every `step_deg`) with the options given, a chunk at a time: a pass for the
/// pressure's peak in every cycle ([`PeakAngles`]), then the motored fit's passes over the
/// TDCs' windows, held when they take at most `hold_bytes` ([`TdcEvents`]).
pub fn tdc_from_pressure_in(
    source: &dyn CrankBuilder,
    opts: &crate::acquisition::AcquisitionOptions,
    cfg: &CompressionConfig,
    step_deg: f64,
    hold_bytes: usize,
) -> Result<TdcFromPressure, AppError> {
    cfg.validate()?;
    let Some(spec) = &opts.sensor else {
        return Err(AppError::Invalid(format!(
            "--tdc-from {}: the TDC is placed on a raw angle sensor's reference: give --wheel or --quadrature",
            cfg.channel
        )));
    };
    let mut opts = opts.clone();
    let mut spec = spec.clone();
    spec.tdc_offset_deg = 0.0;
    spec.phase_from = spec.phase_from.or_channel(&cfg.channel);
    opts.sensor = Some(spec.clone());
    // 1. The peak's angle after the reference, the median over the complete cycles.
    let mut peaks = PeakAngles::new(&cfg.channel, step_deg);
    source.with(&opts).pass(&mut |chunk| peaks.push(chunk))?;
    let fired_left_out = peaks.fired();
    let peak = peaks.finish()?;
    // 2. The model fitted with the TDC at the peak.
    spec.tdc_offset_deg = peak;
    opts.sensor = Some(spec);
    let passes = source.with(&opts);
    let events = TdcEvents::new(passes.as_ref(), &cfg.channel, cfg.window_deg, hold_bytes);
    let fit = compression_fit_events(&events, cfg)?;
    if let Some(why) = fit.implausible.first() {
        return Err(AppError::Invalid(format!(
            "--tdc-from {}: the motored fit that places the TDC is not physical — {why}",
            cfg.channel
        )));
    }
    let tdc = fit
        .get("tdc_shift")
        .filter(|e| e.status == "fitted")
        .cloned()
        .ok_or_else(|| {
            AppError::Invalid(format!(
                "--tdc-from {}: the pressure trace does not resolve the TDC (the identifiability analysis left it out: ranking {})",
                cfg.channel,
                fit.ranking
                    .iter()
                    .map(|r| r.param.as_str())
                    .collect::<Vec<_>>()
                    .join(" > ")
            ))
        })?;
    let (lo, hi) = tdc.ci95.unwrap_or((tdc.value, tdc.value));
    let offset = peak + tdc.value;
    let wrap = offset.rem_euclid(360.0) - offset;
    Ok(TdcFromPressure {
        tdc_offset_deg: offset + wrap,
        ci95: (peak + lo + wrap, peak + hi + wrap),
        peak_deg: fit.peak_deg,
        fit,
        fired_left_out,
    })
}

/// The angle [deg after the reference] where a channel peaks in every complete cycle of a
/// crank-angle recording (`720/step` samples, cycle ≥ 0; the last of equal peaks), a chunk at a
/// time; the median of them, unwrapped around the first so that peaks either side of 0°/720°
/// agree, modulo 360° ([`tdc_from_pressure`]'s first step). Holds a number per cycle.
#[derive(Debug, Clone)]
pub struct PeakAngles {
    channel: String,
    per: usize,
    /// The cycle being gone over, and its samples (angle, pressure).
    run: Option<CycleRun>,
    run_deg: Vec<f64>,
    run_p: Vec<f64>,
    peaks: Vec<f64>,
    /// Complete cycles left out as fired ([`fired`]).
    fired: usize,
}

/// A cycle as [`PeakAngles`] goes over it: its number, samples, and its highest finite sample's
/// value and angle.
#[derive(Debug, Clone, Copy)]
pub(super) struct CycleRun {
    cycle: f64,
    samples: usize,
    best: Option<(f64, f64)>,
}

impl PeakAngles {
    /// The peaks of `channel` on a recording of a sample every `step_deg`.
    pub fn new(channel: &str, step_deg: f64) -> Self {
        Self {
            channel: channel.to_string(),
            per: (720.0 / step_deg).round() as usize,
            run: None,
            run_deg: Vec::new(),
            run_p: Vec::new(),
            peaks: Vec::new(),
            fired: 0,
        }
    }

    /// The next chunk (`cycle`, `crank_deg` and the channel).
    pub fn push(&mut self, chunk: &Recording) -> Result<(), AppError> {
        let (cycle, deg) = (chunk.values("cycle")?, chunk.values("crank_deg")?);
        let p = chunk.values(&self.channel)?;
        for i in 0..cycle.len() {
            if self.run.is_some_and(|r| r.cycle != cycle[i]) {
                self.close();
            }
            if self.run_deg.len() < self.per {
                self.run_deg.push(deg[i]);
                self.run_p.push(p[i]);
            }
            match &mut self.run {
                Some(r) if r.cycle == cycle[i] => {
                    r.samples += 1;
                    if p[i].is_finite() && r.best.is_none_or(|(b, _)| p[i].total_cmp(&b).is_ge()) {
                        r.best = Some((p[i], deg[i]));
                    }
                }
                _ => {
                    self.run = Some(CycleRun {
                        cycle: cycle[i],
                        samples: 1,
                        best: p[i].is_finite().then_some((p[i], deg[i])),
                    });
                }
            }
        }
        Ok(())
    }

    /// The cycle gone over: its peak, when it is complete and motored.
    pub(super) fn close(&mut self) {
        if let Some(CycleRun {
            cycle,
            samples,
            best: Some((_, at)),
        }) = self.run.take()
        {
            if cycle >= 0.0 && samples == self.per {
                if fired(&self.run_deg, &self.run_p, at) == Some(true) {
                    self.fired += 1;
                } else {
                    self.peaks.push(at);
                }
            }
        }
        self.run_deg.clear();
        self.run_p.clear();
    }

    /// Complete cycles left out as fired.
    pub fn fired(&self) -> usize {
        self.fired
    }

    /// The median peak angle [deg], in [0, 360).
    pub fn finish(mut self) -> Result<f64, AppError> {
        self.close();
        let peaks = &mut self.peaks;
        if peaks.is_empty() && self.fired > 0 {
            return Err(AppError::Invalid(format!(
                "--tdc-from {}: all {} complete cycles fired (the pressure 60° … 100° after the peak above that as far before by more than {:.0} %): the TDC is placed on motored cycles — record some (the engine motored, or coasting down)",
                self.channel,
                self.fired,
                (FIRED_RATIO - 1.0) * 100.0
            )));
        }
        if peaks.is_empty() {
            return Err(AppError::Invalid(format!(
                "--tdc-from {}: no complete cycle to find the pressure's peak in",
                self.channel
            )));
        }
        let first = peaks[0];
        for x in peaks.iter_mut() {
            *x = first + (*x - first + 360.0).rem_euclid(720.0) - 360.0;
        }
        peaks.sort_unstable_by(f64::total_cmp);
        Ok(peaks[peaks.len() / 2].rem_euclid(360.0))
    }
}
