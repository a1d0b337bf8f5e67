//! The input plan of a recording read on a crank-angle basis: how a file's engine angle is
//! found and in how many passes it is read — what `cycles`, `compression fit`, `convert
//! --crank-angle`, the friction and torque fits and Python's `physid.read(..., wheel=…)` share.
//!
//! * a crank-angle file: a chunk at a time, only the channels asked for (and `t`, `cycle`,
//!   `crank_deg`);
//! * a time-basis file with `theta_en`: a chunk at a time, resampled as it comes
//!   ([`crank_angle_chunks`]) — memory flat in the recording's length;
//! * a time-basis file with an encoder's counts: read three times over, a chunk at a time — the
//!   counts and the marker (the spacing check, the TDC's angle), then the channels with the
//!   counts read ahead of them ([`counts_crank_angle_chunks`]) — memory flat in the recording's
//!   length;
//! * a time-basis file whose angle is a raw sensor's signal (a trigger wheel, a quadrature
//!   encoder): read over in passes, a chunk at a time — what must be known before any angle (a
//!   wheel's gap; an encoder's index level, then its angle 0 and span); the sensor and the
//!   samples' times (what the decoding found, where the firing TDC is); then the channels with
//!   the sensor read ahead of them ([`crate::acquisition::sensor`]) — memory flat in the
//!   recording's length; with [`AngleInput::tdc_from`], the TDC placed from the motored
//!   pressure first by the same reads in passes.
//!
//! What a front end shows while it reads (progress, what decoding found, provenance) it gets
//! through an [`InputObserver`]; the plan itself writes nothing.

use crate::acquisition::sensor::{
    sensor_calibration, sensor_crank_angle_chunks, sensor_decoded, SensorFound,
};
use crate::acquisition::{
    counts_crank_angle_chunks, crank_angle_chunks, raw_sensor, to_crank_angle_decoded,
    AcquisitionOptions, AngleSpec, CountsAngle, CountsScan, DecodedAngle,
};
use crate::compression::{
    tdc_from_pressure, tdc_from_pressure_in, CompressionConfig, CrankBuilder, TdcFromPressure,
};
use crate::error::AppError;
use physid_core::{Basis, Recording, Recordings, Reopen};
use physid_io::{ChunkReader, IoError, ReadOptions};
use std::cell::{Cell, RefCell};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A reader's chunks as a front end watches them go by.
pub type Watched<'a> = Box<dyn Iterator<Item = Result<Recording, IoError>> + 'a>;

/// What a front end is told while a file is read (every method does nothing by default).
pub trait InputObserver {
    /// `path` is opened (the command line records it for the result's provenance).
    fn opened(&self, _path: &Path) {}
    /// The chunks of a reader of `path` (the command line shows a progress bar over them).
    fn watch<'a>(&self, reader: &'a mut ChunkReader, _path: &Path) -> Watched<'a> {
        Box::new(reader)
    }
    /// What the reader noticed but read all the same (a cut-short last line), once the file
    /// has been read to its end.
    fn read_warning(&self, _path: &Path, _warning: &str) {}
    /// What decoding a raw angle sensor found.
    fn decoded(&self, _path: &Path, _decoded: &DecodedAngle) {}
    /// What decoding a raw angle sensor found wrong with the data, when nothing else of it is
    /// to be said ([`AngleInput::quiet`]).
    fn findings(&self, _path: &Path, _findings: &[physid_signal::integrity::Finding]) {}
    /// Where the TDC was placed from the motored pressure `channel`.
    fn tdc_placed(&self, _path: &Path, _channel: &str, _found: &TdcFromPressure) {}
}

/// An observer that is told nothing.
pub struct Unobserved;

impl InputObserver for Unobserved {}

/// Why a reading on a crank-angle basis that gives no sample gives none: what a verb says
/// instead of writing or returning an empty recording.
pub const NO_CRANK_SAMPLE: &str =
    "the recording ends before its first firing TDC, or its engine angle does not turn";

/// A file read on a crank-angle basis: where its engine angle comes from and how finely it is
/// sampled.
#[derive(Clone)]
pub struct AngleInput {
    /// The file.
    pub path: PathBuf,
    /// How to read it (map, scale, columns; its `channels` are chosen here).
    pub read: ReadOptions,
    /// The engine angle on a time basis: encoders and marker, or a raw sensor.
    pub angle: AcquisitionOptions,
    /// Place the TDC of the raw sensor from this motored cylinder-pressure channel (the
    /// motored model's TDC, [`tdc_from_pressure`]).
    pub tdc_from: Option<String>,
    /// The slider crank's stroke and rod [m], which [`Self::tdc_from`] needs.
    pub crank: Option<(f64, f64)>,
    /// The compression ratio, when known: held (not fitted) by [`Self::tdc_from`]'s model.
    pub compression_ratio: Option<f64>,
    /// One sample every this many crank degrees (a time-basis file).
    pub step_deg: f64,
    /// How much of the windows `tdc_from` holds between its passes [bytes].
    pub hold_bytes: usize,
    /// Nothing said about the decoded angle or the TDC placed but what the decoding found
    /// wrong with the data (its findings: a dropout, a tooth lost — told all the same).
    pub quiet: bool,
    observer: Arc<dyn InputObserver + Send + Sync>,
}

/// What the first passes over a file found about its engine angle, before any resampling.
#[derive(Clone)]
pub enum Scanned {
    /// An encoder's counts: the encoder and the TDC's angle.
    Counts(CountsAngle),
    /// A raw angle sensor: its calibration, what decoding found, where the TDC is.
    Sensor(Box<SensorFound>),
}

/// One read of the file: a first, or one after it (when what the reader noticed was said
/// already and what the first passes found may be kept).
#[derive(Clone, Copy)]
struct Pass<'s> {
    again: bool,
    scanned: Option<&'s RefCell<Option<Scanned>>>,
}

impl Pass<'_> {
    /// A first read.
    const FIRST: Pass<'static> = Pass {
        again: false,
        scanned: None,
    };
    /// A read after one made elsewhere, nothing kept from it.
    const AGAIN: Pass<'static> = Pass {
        again: true,
        scanned: None,
    };
}

impl AngleInput {
    /// The file `path` read with `read`, its angle found as `angle` says, one sample per crank
    /// degree; `observer` is told what is found.
    pub fn new(
        path: &Path,
        read: ReadOptions,
        angle: AcquisitionOptions,
        observer: Arc<dyn InputObserver + Send + Sync>,
    ) -> Self {
        Self {
            path: path.to_path_buf(),
            read,
            angle,
            tdc_from: None,
            crank: None,
            compression_ratio: None,
            step_deg: 1.0,
            hold_bytes: crate::recording_rows::DEFAULT_HOLD_BYTES,
            quiet: false,
            observer,
        }
    }

    /// A reader of `channels` (all if `None`).
    fn open(&self, channels: Option<Vec<String>>) -> Result<ChunkReader, AppError> {
        self.observer.opened(&self.path);
        let opts = ReadOptions {
            channels,
            ..self.read.clone()
        };
        Ok(ChunkReader::open(&self.path, &opts)?)
    }

    fn open_names(&self, names: &[&str]) -> Result<ChunkReader, AppError> {
        self.open(Some(names.iter().map(|s| s.to_string()).collect()))
    }

    /// What `reader` noticed, said once (not on a pass after the first).
    fn warn(&self, reader: &ChunkReader, pass: Pass) {
        if let (Some(w), false) = (reader.header().meta.get("warning"), pass.again) {
            self.observer.read_warning(&self.path, w);
        }
    }

    /// The file's channels (no samples), as stored.
    pub fn header(&self) -> Result<Recording, AppError> {
        Ok(self.open(None)?.header().clone())
    }

    /// Check before reading that a time-basis file has an engine angle and the channels
    /// `needed` (besides those the resampling makes): an error names every channel of the file.
    pub fn require(&self, needed: &[&str]) -> Result<(), AppError> {
        let header = self.header()?;
        if header.basis == Basis::Time
            && raw_sensor(&header, &self.angle)?.is_none()
            && header.channel("theta_en").is_err()
        {
            CountsScan::new(&header, &self.angle)?;
        }
        for name in needed {
            header.channel(name)?;
        }
        Ok(())
    }

    /// The whole file on a crank-angle basis, with what decoding a raw angle sensor found:
    /// [`Self::read`] into one recording.
    pub fn read_all(
        &self,
        channels: Option<&[&str]>,
    ) -> Result<(Recording, Option<DecodedAngle>), AppError> {
        self.read(
            channels,
            |h| Ok(h.clone()),
            |all, chunk| Ok(all.append(chunk)?),
        )
    }

    /// Read the file on a crank-angle basis: `start` gets the recording's channels (no
    /// samples), then `push` every chunk in order. `channels`: the ones the caller takes
    /// (besides `t`, `cycle`, `crank_deg` and the angle's), or `None` for every channel. What
    /// decoding a raw angle sensor found comes back with the caller's state.
    pub fn read<S>(
        &self,
        channels: Option<&[&str]>,
        start: impl FnOnce(&Recording) -> Result<S, AppError>,
        push: impl FnMut(&mut S, &Recording) -> Result<(), AppError>,
    ) -> Result<(S, Option<DecodedAngle>), AppError> {
        self.read_pass(Pass::FIRST, channels, start, push)
    }

    /// [`Self::read`] once more after a first read: nothing said about the reading or the
    /// angle again.
    pub fn read_again<S>(
        &self,
        channels: Option<&[&str]>,
        start: impl FnOnce(&Recording) -> Result<S, AppError>,
        push: impl FnMut(&mut S, &Recording) -> Result<(), AppError>,
    ) -> Result<(S, Option<DecodedAngle>), AppError> {
        let quiet = AngleInput {
            quiet: true,
            ..self.clone()
        };
        quiet.read_pass(Pass::AGAIN, channels, start, push)
    }

    /// What decoding the raw sensor found, told once (on the first read): all of it, or only
    /// its findings when [`quiet`](Self::quiet).
    fn tell_decoded(&self, again: bool, d: &DecodedAngle) {
        if again {
        } else if self.quiet {
            self.observer.findings(&self.path, &d.findings);
        } else {
            self.observer.decoded(&self.path, d);
        }
    }

    fn read_pass<S>(
        &self,
        pass: Pass,
        channels: Option<&[&str]>,
        start: impl FnOnce(&Recording) -> Result<S, AppError>,
        push: impl FnMut(&mut S, &Recording) -> Result<(), AppError>,
    ) -> Result<(S, Option<DecodedAngle>), AppError> {
        let header = self.header()?;
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
        let opts = &self.angle;
        let sensor = match header.basis {
            Basis::Time => raw_sensor(&header, opts)?,
            Basis::CrankAngle => None,
        };
        let streams = header.basis == Basis::CrankAngle
            || (header.channel("theta_en").is_ok() && sensor.is_none() && self.tdc_from.is_none());
        if streams {
            let names = match header.basis {
                Basis::CrankAngle => wanted(&["t", "cycle", "crank_deg"]),
                Basis::Time => {
                    let mut basis = vec!["t", "theta_en", opts.marker.as_str()];
                    basis.extend(opts.phase_from.reads());
                    wanted(&basis)
                }
            };
            let mut reader = self.open(names)?;
            let file_header = reader.header().clone();
            let chunks = self.observer.watch(&mut reader, &self.path);
            let state = match file_header.basis {
                Basis::CrankAngle => feed(
                    &file_header,
                    chunks.map(|c| c.map_err(AppError::from)),
                    start,
                    push,
                )?,
                Basis::Time => {
                    let (h, chunks) =
                        crank_angle_chunks(&file_header, chunks, opts, self.step_deg)?;
                    feed(&h, chunks, start, push)?
                }
            };
            self.warn(&reader, pass);
            return Ok((state, None));
        }
        // An encoder's counts: read three times over — the counts and the marker first, then
        // the channels with the counts read ahead of them.
        if let (Basis::Time, None, None) = (header.basis, sensor, self.tdc_from.as_ref()) {
            // No encoder either: the error names every channel of the file.
            let scan = CountsScan::new(&header, opts)?;
            // The first pass, unless an earlier pass over the file made it.
            let known = pass.scanned.and_then(|s| s.borrow().clone());
            let counts = match known {
                Some(Scanned::Counts(c)) => c,
                _ => {
                    let mut names = vec!["t", scan.encoder().0];
                    if header.channel(&opts.marker).is_ok() {
                        names.push(opts.marker.as_str());
                    }
                    names.extend(scan.phase_channel());
                    let mut reader = self.open_names(&names)?;
                    let c = scan.scan(self.observer.watch(&mut reader, &self.path))?;
                    if let Some(s) = pass.scanned {
                        *s.borrow_mut() = Some(Scanned::Counts(c.clone()));
                    }
                    c
                }
            };
            let mut angle = self.open_names(&["t", &counts.encoder])?;
            let mut reader = self.open(wanted(&["t"]))?;
            let file_header = reader.header().clone();
            let (h, chunks) = counts_crank_angle_chunks(
                &counts,
                &file_header,
                angle.by_ref(),
                self.observer.watch(&mut reader, &self.path),
                opts,
                self.step_deg,
            )?;
            let s = feed(&h, chunks, start, push)?;
            self.warn(&reader, pass);
            return Ok((s, None));
        }
        // A raw angle sensor's signal, a trigger wheel's or a quadrature encoder's: read over
        // in passes — what must be known before any angle (a wheel's gap; an encoder's index
        // level, then its angle 0 and span), then with the samples' times (what the decoding
        // found, where the TDC is), then ahead of the channels; with `tdc_from`, the TDC
        // placed from the pressure first (the same reads, in passes).
        if let Some(spec) = sensor {
            let mut sensor = vec!["t"];
            sensor.extend(spec.sensor.channels());
            let known = pass.scanned.and_then(|s| s.borrow().clone());
            let found = match known {
                Some(Scanned::Sensor(found)) => *found,
                _ => {
                    let placed = match &self.tdc_from {
                        Some(from) => self.tdc_from_sensor(from)?,
                        None => spec.clone(),
                    };
                    let found = self.sensor_found(&placed, &sensor)?;
                    if let Some(s) = pass.scanned {
                        *s.borrow_mut() = Some(Scanned::Sensor(Box::new(found.clone())));
                    }
                    found
                }
            };
            self.tell_decoded(pass.again, &found.decoded);
            let mut angle = self.open_names(&sensor)?;
            let mut reader = self.open(wanted(&["t"]))?;
            let file_header = reader.header().clone();
            let (h, chunks) = sensor_crank_angle_chunks(
                spec,
                &found,
                &file_header,
                angle.by_ref(),
                self.observer.watch(&mut reader, &self.path),
                opts,
                self.step_deg,
            )?;
            let s = feed(&h, chunks, start, push)?;
            self.warn(&reader, pass);
            return Ok((s, Some(found.decoded)));
        }
        // Decoded whole: only the channels the angle and the caller take.
        let mut angle_channels: Vec<&str> = vec!["t", "theta_en", opts.marker.as_str()];
        angle_channels.extend(opts.encoders.iter().map(|e| e.0.as_str()));
        if let Some(spec) = &opts.sensor {
            angle_channels.extend(spec.sensor.channels());
            angle_channels.extend(spec.phase_from.reads());
        }
        if let Some(c) = &self.tdc_from {
            angle_channels.push(c);
        }
        self.observer.opened(&self.path);
        let opts = ReadOptions {
            channels: wanted(&angle_channels),
            ..self.read.clone()
        };
        let rec = physid_io::read(&self.path, &opts)?;
        if let Some(w) = rec.meta.get("warning") {
            self.observer.read_warning(&self.path, w);
        }
        let (deg, decoded) = self.to_crank_angle(&rec)?;
        drop(rec);
        if let Some(d) = &decoded {
            self.tell_decoded(pass.again, d);
        }
        let mut push = push;
        let header = deg.slice(0..0);
        let mut s = start(&header)?;
        push(&mut s, &deg)?;
        Ok((s, decoded))
    }

    /// A time-basis recording `rec` (of this file) taken to one sample every `step_deg` crank
    /// degrees, with what decoding a raw angle sensor found; with `tdc_from`, the TDC placed
    /// from the motored pressure first.
    pub fn to_crank_angle(
        &self,
        rec: &Recording,
    ) -> Result<(Recording, Option<DecodedAngle>), AppError> {
        let mut opts = self.angle.clone();
        if let Some(channel) = &self.tdc_from {
            let found = tdc_from_pressure(rec, &opts, &self.config(channel)?, self.step_deg)?;
            if !self.quiet {
                self.observer.tdc_placed(&self.path, channel, &found);
            }
            if let Some(spec) = opts.sensor.as_mut() {
                spec.tdc_offset_deg = found.tdc_offset_deg;
                spec.phase_from = spec.phase_from.or_channel(channel);
            }
        }
        Ok(to_crank_angle_decoded(rec, &opts, self.step_deg)?)
    }

    /// The motored model's configuration for `tdc_from`'s `channel` (the compression ratio
    /// held when known).
    fn config(&self, channel: &str) -> Result<CompressionConfig, AppError> {
        let (stroke, rod) = self.crank.ok_or_else(|| {
            AppError::Invalid(format!(
                "placing the TDC from '{channel}' needs the crank's lengths: the stroke and the connecting rod [m]"
            ))
        })?;
        let mut cfg = CompressionConfig::new(channel, stroke, rod);
        if let Some(r) = self.compression_ratio {
            cfg.held.push(("eps".into(), r));
        }
        Ok(cfg)
    }

    /// A raw sensor `spec`'s calibration (the file read for each of its passes: an encoder's
    /// two)
    /// and what decoding its channels `sensor` with the samples' times finds.
    fn sensor_found(&self, spec: &AngleSpec, sensor: &[&str]) -> Result<SensorFound, AppError> {
        let cal = sensor_calibration(
            spec,
            &Channels {
                input: self,
                names: sensor,
            },
        )?;
        let mut angle = self.open_names(sensor)?;
        // The phase's channel when the file has it (the default's pressure may be absent).
        let header = self.header()?;
        let mut names = vec!["t"];
        names.extend(
            spec.phase_from
                .reads()
                .filter(|p| header.channel(p).is_ok()),
        );
        let mut samples = self.open_names(&names)?;
        let decoded = sensor_decoded(
            spec,
            &cal,
            angle.by_ref(),
            self.observer.watch(&mut samples, &self.path),
        )?;
        Ok(SensorFound { cal, decoded })
    }

    /// `tdc_from`'s `channel` on a raw sensor's file, read as it goes: the sensor's angle spec
    /// with the TDC where the motored model puts it ([`tdc_from_pressure_in`]: a read for the
    /// pressure's peak, then the fit's passes — each a [`CrankFile`] pass with the TDC given).
    fn tdc_from_sensor(&self, channel: &str) -> Result<AngleSpec, AppError> {
        let cfg = self.config(channel)?;
        let read = Reread {
            input: self,
            channel,
        };
        let found = tdc_from_pressure_in(&read, &self.angle, &cfg, self.step_deg, self.hold_bytes)?;
        if !self.quiet {
            self.observer.tdc_placed(&self.path, channel, &found);
        }
        let mut spec = self.angle.sensor.clone().ok_or_else(|| {
            AppError::Invalid(format!(
                "placing the TDC from '{channel}': no raw angle sensor (a wheel or a quadrature encoder)"
            ))
        })?;
        spec.tdc_offset_deg = found.tdc_offset_deg;
        spec.phase_from = spec.phase_from.or_channel(channel);
        Ok(spec)
    }
}

/// An [`AngleInput`]'s file's channels `names` (as stored: mapped, in SI), read again on
/// every pass.
struct Channels<'a> {
    input: &'a AngleInput,
    names: &'a [&'a str],
}

impl Reopen<Recordings, AppError> for Channels<'_> {
    fn pass(
        &self,
        visit: &mut dyn for<'c> FnMut(&'c Recording) -> Result<(), AppError>,
    ) -> Result<(), AppError> {
        for chunk in self.input.open_names(self.names)? {
            visit(&chunk?)?;
        }
        Ok(())
    }
}

/// An [`AngleInput`]'s file read with other acquisition options: [`CrankFile`]s of `channel`,
/// each pass after one made elsewhere (nothing said about the reading again).
struct Reread<'a> {
    input: &'a AngleInput,
    channel: &'a str,
}

impl CrankBuilder for Reread<'_> {
    fn with<'s>(&'s self, opts: &AcquisitionOptions) -> Box<dyn Reopen<Recordings, AppError> + 's> {
        let input = AngleInput {
            angle: opts.clone(),
            tdc_from: None,
            quiet: true,
            ..self.input.clone()
        };
        Box::new(CrankFile::new(input, vec![self.channel]).again())
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

/// An [`AngleInput`] gone over in passes (`compression fit`'s windows, when they are not held;
/// the torque fit's degrees): read again on each, the channels `channels` (and the angle's);
/// what the first pass said is not said again, and what its first passes over an encoder's
/// counts or a wheel found is kept for the next.
pub struct CrankFile<'a> {
    input: AngleInput,
    channels: Vec<&'a str>,
    passes: Cell<usize>,
    scanned: RefCell<Option<Scanned>>,
}

impl<'a> CrankFile<'a> {
    /// `input`'s channels `channels`, gone over in passes.
    pub fn new(input: AngleInput, channels: Vec<&'a str>) -> Self {
        Self {
            input,
            channels,
            passes: Cell::new(0),
            scanned: RefCell::new(None),
        }
    }

    /// A pass after this one made elsewhere: nothing is said about the reading, the first
    /// pass's included (what [`Reread`] makes).
    fn again(self) -> Self {
        self.passes.set(1);
        self
    }
}

impl Reopen<Recordings, AppError> for CrankFile<'_> {
    /// One pass: after the first, nothing is said about the reading again.
    fn pass(
        &self,
        visit: &mut dyn for<'c> FnMut(&'c Recording) -> Result<(), AppError>,
    ) -> Result<(), AppError> {
        let again = self.passes.get() > 0;
        self.passes.set(self.passes.get() + 1);
        let input = AngleInput {
            quiet: self.input.quiet || again,
            ..self.input.clone()
        };
        let pass = Pass {
            again,
            scanned: Some(&self.scanned),
        };
        let visit = RefCell::new(visit);
        input.read_pass(
            pass,
            Some(&self.channels),
            |h| (visit.borrow_mut())(h),
            |_, chunk| (visit.borrow_mut())(chunk),
        )?;
        Ok(())
    }
}
