//! A recording read on a crank-angle basis, as it comes where it can — what `cycles`,
//! `compression fit` and `convert --crank-angle` read:
//!
//! * a crank-angle file: a chunk at a time, only the channels asked for (and `t`, `cycle`,
//!   `crank_deg`);
//! * a time-basis file with `theta_en`: a chunk at a time, resampled as it comes
//!   ([`physid_apps::acquisition::crank_angle_chunks`]) — memory flat in the recording's length;
//! * a time-basis file with an encoder's counts: read three times over, a chunk at a time — the
//!   counts and the marker (the spacing check, the TDC's angle), then the channels with the
//!   counts read ahead of them ([`physid_apps::acquisition::counts_crank_angle_chunks`]) —
//!   memory flat in the recording's length;
//! * a time-basis file whose angle is a raw sensor's signal (`--wheel`, `--quadrature`): read
//!   over in passes, a chunk at a time — what must be known before any angle (a wheel's gap; an
//!   encoder's index level, then its angle 0 and span); the sensor and the samples' times (what
//!   the decoding found, where the firing TDC is); then the channels with the sensor read ahead
//!   of them ([`physid_apps::acquisition::sensor`]) — memory flat in the recording's length; with
//!   `--tdc-from`, the TDC placed from the pressure first by the same reads in passes.

use super::{CrankArgs, InputArgs};
use crate::cmd::convert::tell_wheel;
use crate::cmd::inspect::tell_tdc_from;
use crate::cmd::inspect::AngleArgs;
use crate::progress::Reading;
use miette::Result;
use physid_apps::acquisition::sensor::{
    sensor_calibration, sensor_crank_angle_chunks, sensor_decoded, SensorFound,
};
use physid_apps::acquisition::{
    counts_crank_angle_chunks, crank_angle_chunks, raw_sensor, AcquisitionOptions, AngleSensor,
    AngleSpec, CountsAngle, CountsScan, DecodedAngle,
};
use physid_apps::compression::{tdc_from_pressure_in, CompressionConfig, CrankPasses};
use physid_apps::error::AppError;
use physid_core::{Basis, Recording};
use std::cell::{Cell, RefCell};
use std::path::Path;

/// Where the crank angle comes from and how finely it is sampled.
#[derive(Clone, Copy)]
pub struct CrankInput<'a> {
    /// How to read the file.
    pub input: &'a InputArgs,
    /// The engine angle on a time basis.
    pub angle: &'a AngleArgs,
    /// The slider crank (for `--tdc-from`).
    pub crank: &'a CrankArgs,
    /// The file.
    pub path: &'a Path,
    /// One sample every this many crank degrees (a time-basis file).
    pub step_deg: f64,
    /// No word on stderr about the decoded angle.
    pub quiet: bool,
    /// A pass after the first: what the reader noticed (a cut-short last line) was said on
    /// the first and is not said again.
    pub again: bool,
    /// What the first passes over an encoder's counts or a wheel's signal found, kept from one
    /// pass over the file to the next (`None`: made on every read).
    pub scanned: Option<&'a RefCell<Option<Scanned>>>,
}

/// What the first passes over a file found about its engine angle, before any resampling.
#[derive(Clone)]
pub enum Scanned {
    /// An encoder's counts: the encoder and the TDC's angle.
    Counts(CountsAngle),
    /// A raw angle sensor: its calibration, what decoding found, where the TDC is.
    Sensor(Box<SensorFound>),
}

impl<'a> CrankInput<'a> {
    /// The file `path` at one sample per crank degree, its angle found as `angle` says (the
    /// defaults: the thesis's encoders and marker), a first read.
    pub fn degrees(
        input: &'a InputArgs,
        path: &'a Path,
        angle: &'a AngleArgs,
        crank: &'a CrankArgs,
    ) -> Self {
        Self {
            input,
            angle,
            crank,
            path,
            step_deg: 1.0,
            quiet: false,
            again: false,
            scanned: None,
        }
    }

    /// Check before reading that a time-basis file has an engine angle and the channels
    /// `needed` (besides those the resampling makes): an error names every channel of the file.
    pub fn require(&self, needed: &[&str]) -> Result<()> {
        let at = super::app_error(self.path);
        let header = self.input.open_all(self.path)?.header().clone();
        let opts = self.angle.options()?;
        if header.basis == Basis::Time
            && header.channel("theta_en").is_err()
            && !sensor_present(&opts, &header)
        {
            CountsScan::new(&header, &opts)
                .map_err(AppError::from)
                .map_err(&at)?;
        }
        for name in needed {
            header.channel(name).map_err(AppError::from).map_err(&at)?;
        }
        Ok(())
    }

    /// Read the file on a crank-angle basis: `start` gets the recording's channels (no
    /// samples), then `push` every chunk in order. `channels`: the ones the caller takes
    /// (besides `t`, `cycle`, `crank_deg` and the angle's), or `None` for every channel. What
    /// decoding a raw angle sensor found comes back with the caller's state.
    pub fn read<S>(
        &self,
        channels: Option<&[&str]>,
        start: impl FnOnce(&Recording) -> Result<S, AppError>,
        mut push: impl FnMut(&mut S, &Recording) -> Result<(), AppError>,
    ) -> Result<(S, Option<DecodedAngle>)> {
        let at = super::app_error(self.path);
        let header = self.input.open_all(self.path)?.header().clone();
        let present = |names: &mut Vec<String>, extra: &[&str]| {
            for n in extra {
                if header.channel(n).is_ok() && !names.iter().any(|m| m == n) {
                    names.push(n.to_string());
                }
            }
        };
        let wanted = |basis: &[&str]| -> Option<Vec<String>> {
            channels.map(|c| {
                let mut names = Vec::new();
                present(&mut names, basis);
                present(&mut names, c);
                names
            })
        };
        // A reader of these channels, or of every one.
        let open = |names: Option<Vec<String>>| match names {
            Some(n) => {
                let n: Vec<&str> = n.iter().map(String::as_str).collect();
                self.input.open(self.path, &n, &[])
            }
            None => self.input.open_all(self.path),
        };
        let opts = self.angle.options()?;
        let streams = header.basis == Basis::CrankAngle
            || (header.channel("theta_en").is_ok() && self.angle.wheel.tdc_from.is_none());
        if streams {
            let names = match header.basis {
                Basis::CrankAngle => wanted(&["t", "cycle", "crank_deg"]),
                Basis::Time => wanted(&["t", "theta_en", opts.marker.as_str()]),
            };
            let mut reader = open(names)?;
            let file_header = reader.header().clone();
            let chunks = Reading::new(&mut reader, self.path);
            let state = match file_header.basis {
                Basis::CrankAngle => {
                    let mut s = start(&file_header).map_err(&at)?;
                    for chunk in chunks {
                        let chunk = chunk.map_err(AppError::from).map_err(&at)?;
                        push(&mut s, &chunk).map_err(&at)?;
                    }
                    s
                }
                Basis::Time => {
                    let (h, chunks) =
                        crank_angle_chunks(&file_header, chunks, &opts, self.step_deg)
                            .map_err(&at)?;
                    feed(&h, chunks, start, push).map_err(&at)?
                }
            };
            if !self.again {
                super::warn_read(&reader, self.path);
            }
            return Ok((state, None));
        }
        // An encoder's counts: read three times over — the counts and the marker first, then
        // the channels with the counts read ahead of them.
        if let (Basis::Time, false, None) = (
            header.basis,
            sensor_present(&opts, &header),
            self.angle.wheel.tdc_from.as_ref(),
        ) {
            // No encoder either: the error names every channel of the file.
            let scan = CountsScan::new(&header, &opts)
                .map_err(AppError::from)
                .map_err(&at)?;
            // The first pass, unless an earlier pass over the file made it.
            let known = self.scanned.and_then(|s| s.borrow().clone());
            let counts = match known {
                Some(Scanned::Counts(c)) => c,
                _ => {
                    let mut names = vec!["t", scan.encoder().0];
                    if header.channel(&opts.marker).is_ok() {
                        names.push(opts.marker.as_str());
                    }
                    let mut reader = self.input.open(self.path, &names, &[])?;
                    let c = scan
                        .scan(Reading::new(&mut reader, self.path))
                        .map_err(&at)?;
                    if let Some(s) = self.scanned {
                        *s.borrow_mut() = Some(Scanned::Counts(c.clone()));
                    }
                    c
                }
            };
            let mut angle = self.input.open(self.path, &["t", &counts.encoder], &[])?;
            let mut reader = open(wanted(&["t"]))?;
            let file_header = reader.header().clone();
            let (h, chunks) = counts_crank_angle_chunks(
                &counts,
                &file_header,
                angle.by_ref(),
                Reading::new(&mut reader, self.path),
                &opts,
                self.step_deg,
            )
            .map_err(&at)?;
            let s = feed(&h, chunks, start, push).map_err(&at)?;
            if !self.again {
                super::warn_read(&reader, self.path);
            }
            return Ok((s, None));
        }
        // A raw angle sensor's signal, a trigger wheel's or a quadrature encoder's: read over
        // in passes — what must be known before any angle (a wheel's gap; an encoder's index
        // level, then its angle 0 and span), then with the samples' times (what the decoding
        // found, where the TDC is), then ahead of the channels; with --tdc-from, the TDC
        // placed from the pressure first (the same reads, in passes).
        if let Some(spec) = raw_sensor(&header, &opts) {
            let mut sensor = vec!["t"];
            sensor.extend(spec.sensor.channels());
            let known = self.scanned.and_then(|s| s.borrow().clone());
            let found = match known {
                Some(Scanned::Sensor(found)) => *found,
                _ => {
                    let placed = match &self.angle.wheel.tdc_from {
                        Some(from) => self.tdc_from_sensor(&opts, from)?,
                        None => spec.clone(),
                    };
                    let spec = &placed;
                    // A reader for each of the calibration's passes (an encoder's two).
                    let passes = match spec.sensor {
                        AngleSensor::Wheel { .. } => 1,
                        AngleSensor::Quadrature { .. } => 2,
                    };
                    let mut readers = (0..passes)
                        .map(|_| self.input.open(self.path, &sensor, &[]))
                        .collect::<Result<Vec<_>>>()?;
                    readers.reverse();
                    let cal = sensor_calibration(spec, || {
                        readers
                            .pop()
                            .ok_or_else(|| AppError::Invalid("a pass too many".into()))
                    })
                    .map_err(&at)?;
                    let mut angle = self.input.open(self.path, &sensor, &[])?;
                    let mut names = vec!["t"];
                    if let Some(p) = &spec.phase_from {
                        names.push(p.strip_suffix(":low").unwrap_or(p));
                    }
                    let mut samples = self.input.open(self.path, &names, &[])?;
                    let decoded = sensor_decoded(
                        spec,
                        &cal,
                        angle.by_ref(),
                        Reading::new(&mut samples, self.path),
                    )
                    .map_err(&at)?;
                    let found = SensorFound { cal, decoded };
                    if let Some(s) = self.scanned {
                        *s.borrow_mut() = Some(Scanned::Sensor(Box::new(found.clone())));
                    }
                    found
                }
            };
            if !self.quiet {
                tell_wheel(self.path, &found.decoded);
            }
            let mut angle = self.input.open(self.path, &sensor, &[])?;
            let mut reader = open(wanted(&["t"]))?;
            let file_header = reader.header().clone();
            let (h, chunks) = sensor_crank_angle_chunks(
                spec,
                &found,
                &file_header,
                angle.by_ref(),
                Reading::new(&mut reader, self.path),
                &opts,
                self.step_deg,
            )
            .map_err(&at)?;
            let s = feed(&h, chunks, start, push).map_err(&at)?;
            if !self.again {
                super::warn_read(&reader, self.path);
            }
            return Ok((s, Some(found.decoded)));
        }
        // Decoded whole: only the channels the angle and the caller take.
        let mut angle_channels: Vec<&str> = vec!["t", "theta_en", opts.marker.as_str()];
        angle_channels.extend(opts.encoders.iter().map(|e| e.0.as_str()));
        if let Some(spec) = &opts.sensor {
            angle_channels.extend(spec.sensor.channels());
            if let Some(p) = &spec.phase_from {
                angle_channels.push(p.strip_suffix(":low").unwrap_or(p));
            }
        }
        if let Some(c) = &self.angle.wheel.tdc_from {
            angle_channels.push(c);
        }
        let rec = self.input.read(self.path, wanted(&angle_channels))?;
        let (deg, decoded) =
            self.angle
                .to_crank_angle(&rec, self.crank, self.step_deg, self.path, self.quiet)?;
        drop(rec);
        if let (Some(d), false) = (&decoded, self.quiet) {
            tell_wheel(self.path, d);
        }
        let header = deg.slice(0..0);
        let mut s = start(&header).map_err(&at)?;
        push(&mut s, &deg).map_err(&at)?;
        Ok((s, decoded))
    }
}

impl CrankInput<'_> {
    /// `--tdc-from CHANNEL` on a raw sensor's file, read as it goes: the sensor's angle spec
    /// with the TDC where the motored model puts it ([`tdc_from_pressure_in`]: a read for the
    /// pressure's peak, then the fit's passes — each a [`CrankFile`] pass with the TDC given).
    fn tdc_from_sensor(&self, opts: &AcquisitionOptions, channel: &str) -> Result<AngleSpec> {
        let (stroke, rod) = self.crank.lengths(&format!("--tdc-from {channel}"))?;
        let cfg = CompressionConfig::new(channel, stroke, rod);
        let read = |o: &AcquisitionOptions,
                    visit: &mut dyn FnMut(&Recording) -> Result<(), AppError>|
         -> Result<(), AppError> {
            let mut angle = self.angle.clone();
            if let Some(spec) = &o.sensor {
                angle.wheel.tdc_offset = spec.tdc_offset_deg;
                angle.wheel.phase_from.clone_from(&spec.phase_from);
            }
            angle.wheel.tdc_from = None;
            let input = CrankInput {
                angle: &angle,
                quiet: true,
                again: true,
                scanned: None,
                ..*self
            };
            CrankFile::new(input, vec![channel]).chunks(visit)
        };
        let found = tdc_from_pressure_in(&read, opts, &cfg, self.step_deg, super::hold_bytes()?)
            .map_err(super::app_error(self.path))?;
        if !self.quiet {
            tell_tdc_from(self.path, channel, &found);
        }
        let mut spec = opts
            .sensor
            .clone()
            .ok_or_else(|| miette::miette!("--tdc-from {channel}: no --wheel or --quadrature"))?;
        spec.tdc_offset_deg = found.tdc_offset_deg;
        spec.phase_from.get_or_insert_with(|| channel.to_string());
        Ok(spec)
    }
}

/// `start` on the crank-angle recording's header `h`, then `push` every chunk in order.
fn feed<S>(
    h: &Recording,
    chunks: impl Iterator<Item = Result<Recording, AppError>>,
    start: impl FnOnce(&Recording) -> Result<S, AppError>,
    mut push: impl FnMut(&mut S, &Recording) -> Result<(), AppError>,
) -> Result<S, AppError> {
    let mut s = start(h)?;
    for chunk in chunks {
        push(&mut s, &chunk?)?;
    }
    Ok(s)
}

/// Whether the engine angle is a raw sensor's (`--wheel`, `--quadrature`) whose channels the
/// file has.
fn sensor_present(opts: &AcquisitionOptions, header: &Recording) -> bool {
    opts.sensor.as_ref().is_some_and(|s| {
        s.sensor
            .channels()
            .iter()
            .any(|c| header.channel(c).is_ok())
    })
}

/// A [`CrankInput`] gone over in passes (`compression fit`'s windows, when they are not held):
/// read again on each, the channels `channels` (and the angle's); what the first pass said on
/// stderr is not said again.
pub struct CrankFile<'a> {
    input: CrankInput<'a>,
    channels: Vec<&'a str>,
    passes: Cell<usize>,
    /// An encoder's counts or a wheel: the first passes' findings, kept for the next.
    scanned: RefCell<Option<Scanned>>,
}

impl<'a> CrankFile<'a> {
    /// `input`'s channels `channels`, gone over in passes.
    pub fn new(input: CrankInput<'a>, channels: Vec<&'a str>) -> Self {
        Self {
            input,
            channels,
            passes: Cell::new(0),
            scanned: RefCell::new(None),
        }
    }
}

impl CrankPasses for CrankFile<'_> {
    fn chunks(
        &self,
        visit: &mut dyn FnMut(&Recording) -> Result<(), AppError>,
    ) -> Result<(), AppError> {
        let again = self.passes.get() > 0;
        self.passes.set(self.passes.get() + 1);
        let input = CrankInput {
            quiet: self.input.quiet || again,
            again,
            scanned: Some(&self.scanned),
            ..self.input
        };
        // An error of `visit` comes back as it is; the reader's names the file.
        let failed = RefCell::new(None);
        let keep = |e: AppError| {
            *failed.borrow_mut() = Some(e);
            AppError::Invalid(String::new())
        };
        let visit = RefCell::new(visit);
        let read = input.read(
            Some(&self.channels),
            |h| (visit.borrow_mut())(h).map_err(keep),
            |_, chunk| (visit.borrow_mut())(chunk).map_err(keep),
        );
        match (read, failed.into_inner()) {
            (Ok(_), _) => Ok(()),
            (Err(_), Some(e)) => Err(e),
            (Err(e), None) => Err(AppError::Ident(physid_ident::IdentError::Read(
                e.to_string(),
            ))),
        }
    }
}
