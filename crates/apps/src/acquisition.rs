//! The thesis's acquisition chain on a [`Recording`] (ch. 4, SPEC §2.7): inspection with the
//! post-run integrity check, conversion between a time basis and one sample per crank
//! degree, zero-phase filtering of chosen channels. The `physid inspect`, `convert` and
//! `filter` verbs are thin wrappers over these.

use crate::error::AppError;
use crate::sensor_angle::{
    sensor_calibration, sensor_crank_angle_chunks, sensor_decoded, SensorAhead, SensorFound,
};
use physid_core::{Basis, Channel, Recording, RecordingError};
use physid_signal::encoder::{first_marker, CountSteps, Encoder, SpacingCheck};
use physid_signal::filter::{butter, Band, FilterError};
use physid_signal::integrity::{
    median_step, Finding, FindingKind, Integrity, IntegrityCheck, IntegrityOptions, NOMINAL_SAMPLES,
};
use physid_signal::wheel::{recognise, EdgeDetector, EdgeOptions, ToothReport, Wheel};
use serde::Serialize;
use std::f64::consts::PI;
use thiserror::Error;

/// Errors of the acquisition functions.
#[derive(Debug, Error)]
pub enum AcquisitionError {
    /// A channel problem.
    #[error(transparent)]
    Recording(#[from] RecordingError),
    /// A filter problem, with the channel.
    #[error("channel '{channel}': {source}")]
    Filter {
        /// The channel.
        channel: String,
        /// What went wrong.
        source: FilterError,
    },
    /// Anything else, explained.
    #[error("{0}")]
    Invalid(String),
}

/// Where the encoders and the TDC marker are.
#[derive(Debug, Clone)]
pub struct AcquisitionOptions {
    /// Encoder counter channels with their pulses per revolution; the TDC marker belongs to the
    /// first (the engine's).
    pub encoders: Vec<(String, u32)>,
    /// The TDC marker channel.
    pub marker: String,
    /// A raw angle sensor (a trigger wheel or a quadrature encoder), decoded into the engine
    /// angle when the recording has no `theta_en` (`--wheel CHANNEL=N-M`,
    /// `--quadrature A,B[,Z]=LINES`).
    pub sensor: Option<AngleSpec>,
}

/// A raw angle sensor on the crankshaft.
#[derive(Debug, Clone, PartialEq)]
pub enum AngleSensor {
    /// A toothed wheel's sensor (analog or digital).
    Wheel {
        /// The sensor's channel.
        channel: String,
        /// The wheel (N−M).
        wheel: Wheel,
        /// Which edges, which level.
        edges: EdgeOptions,
    },
    /// A quadrature encoder's channels A, B and optionally the index Z.
    Quadrature {
        /// Channel A.
        a: String,
        /// Channel B (a quarter line behind A turning forward).
        b: String,
        /// The index, once per revolution.
        z: Option<String>,
        /// Lines per revolution.
        lines: u32,
    },
}

impl AngleSensor {
    /// The raw channels it reads.
    pub fn channels(&self) -> Vec<&str> {
        match self {
            Self::Wheel { channel, .. } => vec![channel.as_str()],
            Self::Quadrature { a, b, z, .. } => [Some(a), Some(b), z.as_ref()]
                .into_iter()
                .flatten()
                .map(String::as_str)
                .collect(),
        }
    }
}

/// A raw angle sensor and where the firing TDC lies on it.
#[derive(Debug, Clone, PartialEq)]
pub struct AngleSpec {
    /// The sensor.
    pub sensor: AngleSensor,
    /// The crank angle from the sensor's reference — a wheel's first tooth edge after the gap,
    /// an encoder's index pulse turning forward — to the next TDC [deg], in [0, 360).
    pub tdc_offset_deg: f64,
    /// Which revolution of two fires: the one whose TDC has the higher mean of this channel
    /// over the revolution centred on it — the cylinder pressure (compression and expansion
    /// against exhaust and intake), a cam sensor high or pulsing in that revolution; with the
    /// suffix `:low` the lower (a cam that marks the other revolution). `None`: the TDC
    /// `tdc_offset_deg` after the first reference edge is taken as the firing one.
    pub phase_from: Option<String>,
}

/// The TDC marker channel of the thesis's test cell (and physid's simulator).
pub const TDC_MARKER: &str = "tdc";

impl Default for AcquisitionOptions {
    /// The thesis's test cell: `count_en` (360 pulses/rev), `count_dy` (1024), marker `tdc`.
    fn default() -> Self {
        Self {
            encoders: vec![("count_en".into(), 360), ("count_dy".into(), 1024)],
            marker: TDC_MARKER.into(),
            sensor: None,
        }
    }
}

impl AcquisitionOptions {
    /// The integrity checks of these encoders and marker on a recording with `header`'s
    /// channels (those it lacks are not checked); the marker is the first encoder's (the
    /// engine's, by default).
    pub fn integrity_options(
        &self,
        header: &Recording,
        samples_per_cycle: Option<usize>,
    ) -> IntegrityOptions {
        IntegrityOptions {
            encoders: self
                .encoders
                .iter()
                .filter(|(n, _)| header.channel(n).is_ok())
                .cloned()
                .collect(),
            marker: header
                .channel(&self.marker)
                .ok()
                .map(|_| self.marker.clone()),
            marker_encoder: self.encoders.first().map(|e| e.0.clone()),
            samples_per_cycle,
        }
    }
}

/// One channel in the summary.
#[derive(Debug, Clone, Serialize)]
pub struct ChannelSummary {
    /// Name.
    pub name: String,
    /// Unit.
    pub unit: String,
    /// Samples.
    pub samples: usize,
}

/// What `physid inspect` reports.
#[derive(Debug, Clone, Serialize)]
pub struct Inspection {
    /// `time` or `crank_angle`.
    pub basis: &'static str,
    /// The channels.
    pub channels: Vec<ChannelSummary>,
    /// Duration [s] (from `t`), if known.
    pub duration_s: Option<f64>,
    /// Sample rate [Hz] (1 / median interval of `t`) on a time basis.
    pub sample_rate_hz: Option<f64>,
    /// Complete engine cycles (720°): counted from `cycle` on a crank-angle basis, from TDC
    /// markers (two per cycle) on a time basis.
    pub cycles: Option<usize>,
    /// The integrity check (with the trigger wheel's findings when one is decoded).
    pub integrity: Integrity,
    /// What decoding the trigger wheel found (`--wheel`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wheel: Option<WheelSummary>,
    /// Without an engine angle: the channels whose signal is a trigger wheel's, and which.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub recognised: Vec<RecognisedWheel>,
}

/// A channel recognised as a trigger wheel's signal.
#[derive(Debug, Clone, Serialize)]
pub struct RecognisedWheel {
    /// The channel.
    pub channel: String,
    /// The wheel, `N-M` (what `--wheel CHANNEL=N-M` takes).
    pub wheel: String,
    /// Teeth per revolution (N − M).
    pub teeth: u32,
    /// Missing teeth in the gap (M).
    pub missing: u32,
    /// Gaps seen.
    pub gaps: usize,
}

/// A trigger wheel as decoded by `physid inspect --wheel`.
#[derive(Debug, Clone, Serialize)]
pub struct WheelSummary {
    /// The sensor's channel.
    pub channel: String,
    /// The wheel given (`N-M`).
    pub wheel: String,
    /// Teeth per revolution (N − M) and missing teeth (M).
    pub teeth: u32,
    /// Missing teeth in the gap.
    pub missing: u32,
    /// Tooth edges decoded (extra edges dropped).
    pub edges: usize,
    /// Whole revolutions between the first and last gap.
    pub revolutions: usize,
    /// The slowest and fastest speed over a tooth [rpm].
    pub rpm_min: f64,
    /// See `rpm_min`.
    pub rpm_max: f64,
    /// Glitch pulses rejected.
    pub glitches: usize,
    /// Why the signal could not be decoded as the wheel given (then the rest is empty).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// Summarise a recording and check its integrity: an [`Inspector`] over it, in one chunk (and
/// a trigger wheel named decoded, [`inspect_wheel`]).
pub fn inspect(rec: &Recording, opts: &AcquisitionOptions) -> Inspection {
    let mut i = Inspector::new(rec, opts);
    i.push(rec);
    let mut i = i.finish();
    inspect_wheel(&mut i, rec, opts, || {
        Ok(std::iter::once(Ok::<&Recording, AppError>(rec)))
    });
    i
}

/// [`inspect`] on a recording read a chunk at a time (`physid inspect` on a file, whatever
/// its length): the channels' sample counts, the duration, the sample rate (1 / the median
/// step of the first [`NOMINAL_SAMPLES`]), the complete cycles and the integrity check
/// ([`IntegrityCheck`]), all taken as the chunks pass. Memory does not grow with the
/// recording: the first chunks are held only until the samples per cycle and the nominal step
/// are known from them.
#[derive(Debug, Clone)]
pub struct Inspector {
    opts: AcquisitionOptions,
    header: Recording,
    /// Held until the samples per cycle are known (crank-angle basis) — at most
    /// [`NOMINAL_SAMPLES`] samples.
    pending: Vec<Recording>,
    pending_rows: usize,
    check: Option<IntegrityCheck>,
    per_cycle: Option<usize>,
    t_head: Vec<f64>,
    t_span: Option<(f64, f64)>,
    rows: usize,
    /// Cycle runs: the current (value, length) and the complete ones so far.
    run: Option<(f64, usize)>,
    complete: usize,
    /// Marker rising edges so far, and the marker's last value.
    edges: usize,
    prev_marker: Option<f64>,
    prev_deg: Option<f64>,
    /// Without an engine angle: the edges of the channels that may be a wheel's signal, over
    /// their first [`RECOGNISE_SAMPLES`], to recognise one ([`physid_signal::wheel::recognise`]).
    candidates: Vec<(String, EdgeDetector)>,
}

/// The samples of a channel [`Inspector`] looks at to recognise a trigger wheel.
pub const RECOGNISE_SAMPLES: usize = 1 << 21;

/// Channels [`Inspector`] tries as a trigger wheel's signal: on a time basis with no engine
/// angle given or present, those without a standard name whose unit is none, a voltage or a
/// count (at most 8).
fn wheel_candidates(header: &Recording, opts: &AcquisitionOptions) -> Vec<(String, EdgeDetector)> {
    let has_angle = header.channel("theta_en").is_ok()
        || opts.encoders.iter().any(|(n, _)| header.channel(n).is_ok());
    if opts.sensor.is_some() || has_angle || header.basis != Basis::Time {
        return Vec::new();
    }
    header
        .channels()
        .iter()
        .filter(|c| {
            c.name != "t"
                && physid_core::standard_unit(&c.name).is_none()
                && (c.unit.is_empty()
                    || physid_core::units::lookup(&c.unit)
                        .is_some_and(|u| ["voltage", "dimensionless"].contains(&u.dimension)))
        })
        .take(8)
        .map(|c| (c.name.clone(), EdgeDetector::new(&EdgeOptions::default())))
        .collect()
}

impl Inspector {
    /// An inspection of a recording with `header`'s channels, units and basis.
    pub fn new(header: &Recording, opts: &AcquisitionOptions) -> Self {
        Self {
            opts: opts.clone(),
            header: header.slice(0..0),
            pending: Vec::new(),
            pending_rows: 0,
            check: None,
            per_cycle: None,
            t_head: Vec::new(),
            t_span: None,
            rows: 0,
            run: None,
            complete: 0,
            edges: 0,
            prev_marker: None,
            prev_deg: None,
            candidates: wheel_candidates(header, opts),
        }
    }

    /// Take the next chunk.
    pub fn push(&mut self, chunk: &Recording) {
        if self.check.is_some() {
            self.scan(chunk);
            return;
        }
        if self.per_cycle.is_none() {
            // The samples per cycle from the first positive step of `crank_deg`.
            if let Ok(d) = chunk.values("crank_deg") {
                let mut prev = self.prev_deg;
                for &v in d {
                    if let Some(step) = prev.map(|p| v - p).filter(|s| *s > 0.0) {
                        self.per_cycle = Some((720.0 / step).round() as usize);
                        break;
                    }
                    prev = Some(v);
                }
                self.prev_deg = d.last().copied().or(self.prev_deg);
            }
        }
        self.pending_rows += chunk.len();
        self.pending.push(chunk.clone());
        if self.per_cycle.is_some()
            || self.header.channel("crank_deg").is_err()
            || self.pending_rows >= NOMINAL_SAMPLES
        {
            self.start();
        }
    }

    fn start(&mut self) {
        self.check = Some(IntegrityCheck::new(
            &self.opts.integrity_options(&self.header, self.per_cycle),
            &self.header,
        ));
        for c in std::mem::take(&mut self.pending) {
            self.scan(&c);
        }
    }

    fn scan(&mut self, chunk: &Recording) {
        if let Some(c) = self.check.as_mut() {
            c.push(chunk);
        }
        self.rows += chunk.len();
        if let Ok(t) = chunk.values("t") {
            let room = RECOGNISE_SAMPLES.saturating_sub(self.rows - chunk.len());
            let n = t.len().min(room);
            for (name, d) in self.candidates.iter_mut() {
                if let (Ok(v), true) = (chunk.values(name), n > 0) {
                    d.push(&t[..n], &v[..n]);
                }
            }
        }
        if let Ok(t) = chunk.values("t") {
            let room = NOMINAL_SAMPLES.saturating_sub(self.t_head.len());
            self.t_head.extend_from_slice(&t[..t.len().min(room)]);
            if let (Some(&a), Some(&b)) = (t.first(), t.last()) {
                self.t_span = Some((self.t_span.map_or(a, |s| s.0), b));
            }
        }
        match self.header.basis {
            Basis::CrankAngle => {
                if let Ok(cycle) = chunk.values("cycle") {
                    for &v in cycle {
                        match &mut self.run {
                            Some((value, len)) if *value == v => *len += 1,
                            run => {
                                if let Some((_, len)) = run.take() {
                                    self.complete +=
                                        usize::from(self.per_cycle.is_none_or(|p| len == p));
                                }
                                *run = Some((v, 1));
                            }
                        }
                    }
                }
            }
            Basis::Time => {
                if let Ok(m) = chunk.values(&self.opts.marker) {
                    for &v in m {
                        if v != 0.0 && self.prev_marker.is_none_or(|p| p == 0.0) {
                            self.edges += 1;
                        }
                        self.prev_marker = Some(v);
                    }
                }
            }
        }
    }

    /// The end of the recording: the inspection.
    pub fn finish(mut self) -> Inspection {
        if self.check.is_none() {
            self.start();
        }
        let rec = &self.header;
        let has = |n: &str| rec.channel(n).is_ok();
        let cycles = match rec.basis {
            Basis::CrankAngle => has("cycle").then(|| {
                let last = self
                    .run
                    .is_some_and(|(_, len)| self.per_cycle.is_none_or(|p| len == p));
                self.complete + usize::from(last)
            }),
            Basis::Time => has(&self.opts.marker).then(|| self.edges.saturating_sub(1) / 2),
        };
        let integrity = self.check.map(IntegrityCheck::finish).unwrap_or_else(|| {
            IntegrityCheck::new(&IntegrityOptions::default(), &self.header).finish()
        });
        let recognised = self
            .candidates
            .into_iter()
            .filter_map(|(channel, d)| {
                let r = recognise(&d.finish().ok()?)?;
                Some(RecognisedWheel {
                    channel,
                    wheel: r.wheel.to_string(),
                    teeth: r.wheel.present(),
                    missing: r.wheel.missing,
                    gaps: r.gaps,
                })
            })
            .collect();
        Inspection {
            basis: match rec.basis {
                Basis::Time => "time",
                Basis::CrankAngle => "crank_angle",
            },
            channels: rec
                .channels()
                .iter()
                .map(|c| ChannelSummary {
                    name: c.name.clone(),
                    unit: c.unit.clone(),
                    samples: self.rows,
                })
                .collect(),
            duration_s: self.t_span.map(|(a, b)| b - a),
            sample_rate_hz: match rec.basis {
                Basis::Time => median_step(&self.t_head).map(|d| 1.0 / d),
                Basis::CrankAngle => None,
            },
            cycles,
            integrity,
            wheel: None,
            recognised,
        }
    }
}

/// The trigger wheel `opts` names (`--wheel`), decoded as the file is read — `chunks` makes a
/// reader of `t` and its channel each time it is called (twice: where the gap is, then each
/// edge's angle, [`crate::sensor_angle`]) — into the inspection `i`: its summary, and what the
/// decoding found among the integrity findings (why it could not be decoded, when not). Nothing
/// without a wheel in `opts` or on a time basis without its channel.
pub fn inspect_wheel<F, I, R, E>(
    i: &mut Inspection,
    header: &Recording,
    opts: &AcquisitionOptions,
    mut chunks: F,
) where
    F: FnMut() -> Result<I, AppError>,
    I: IntoIterator<Item = Result<R, E>>,
    R: std::borrow::Borrow<Recording>,
    AppError: From<E>,
{
    let Some(spec) = opts.sensor.as_ref() else {
        return;
    };
    let AngleSensor::Wheel { channel, wheel, .. } = &spec.sensor else {
        return;
    };
    if header.channel(channel).is_err() || header.basis != Basis::Time {
        return;
    }
    let mut summary = WheelSummary {
        channel: channel.to_string(),
        wheel: wheel.to_string(),
        teeth: wheel.present(),
        missing: wheel.missing,
        edges: 0,
        revolutions: 0,
        rpm_min: f64::NAN,
        rpm_max: f64::NAN,
        glitches: 0,
        error: None,
    };
    let integrity = &mut i.integrity;
    let decoded = sensor_calibration(spec, &mut chunks)
        .and_then(|cal| SensorAhead::new(spec, &cal, chunks()?.into_iter())?.finish());
    match decoded {
        Ok(Some(a)) => {
            summary.edges = a.edges;
            summary.revolutions = a.revolutions;
            summary.glitches = a.glitches;
            (summary.rpm_min, summary.rpm_max) = a.rpm;
            for f in a.findings {
                if f.kind == FindingKind::Note {
                    integrity.notes.push(f);
                } else {
                    integrity.ok = false;
                    integrity.findings.push(f);
                }
            }
            integrity.findings.sort_by_key(|f| f.index);
        }
        Ok(None) => {}
        Err(e) => {
            let e = e.to_string();
            integrity.ok = false;
            integrity.findings.push(Finding {
                kind: FindingKind::UnevenPulses,
                index: 0,
                detail: e.clone(),
            });
            summary.error = Some(e);
        }
    }
    i.wheel = Some(summary);
}

/// The engine angle of a time-basis recording as strictly increasing `(t, θ)` pairs: from
/// `theta_en` if present, else from the engine encoder's counts at the samples where the count
/// moves on (event-based, as the thesis samples). Also the angle at the first TDC marker
/// (or, without a marker, the first multiple of 720° — the simulator's convention).
fn engine_angle(
    rec: &Recording,
    opts: &AcquisitionOptions,
) -> Result<EngineAngle, AcquisitionError> {
    let t = rec.values("t")?;
    if let Ok(theta) = rec.values("theta_en") {
        // Its value at the marker (as `from_first_marker` takes it on a stream).
        let tdc = match rec.values(&opts.marker).ok().and_then(first_marker) {
            Some(i) => theta[i],
            None => first_tdc(theta.first().copied().unwrap_or(0.0)),
        };
        return Ok(EngineAngle {
            t: t.to_vec(),
            theta: theta.to_vec(),
            tdc,
        });
    }
    // An encoder's counts: the same scan as on a stream, in one chunk.
    let mut scan = CountsScan::new(rec, opts)?;
    let (t, theta) = scan.push(rec)?;
    let (t, theta) = (t.to_vec(), theta.to_vec());
    Ok(EngineAngle {
        tdc: scan.finish()?,
        t,
        theta,
    })
}

/// The first pass over a time-basis recording whose engine angle is an encoder's counts
/// (thesis Eq. 4.2), a chunk at a time: the check that the counts are equally spaced in angle
/// ([`SpacingCheck`]) and the firing TDC's angle — at the first TDC marker, interpolated
/// between the count steps around it by the rule of
/// [`interp`](physid_signal::crank::interp), without a marker the first multiple of 4π
/// ([`first_tdc`]). The angle itself is the count steps ([`CountSteps`]), which
/// [`push`](Self::push) gives too. What it holds: a few numbers, the spacing check's, and the
/// steps of the last chunk.
#[derive(Debug, Clone)]
pub struct CountsScan {
    /// The encoder: its count channel and pulses per revolution.
    name: String,
    ppr: u32,
    marker: String,
    steps: CountSteps,
    spacing: SpacingCheck,
    edge: FirstMarker,
    /// The angle at the marker's time.
    at: MarkerAngle,
    /// Samples seen.
    samples: usize,
    /// Count steps seen.
    stepped: usize,
    /// The last chunk's count steps: times [s] and angles [rad].
    t: Vec<f64>,
    theta: Vec<f64>,
}

impl CountsScan {
    /// The scan of the first of `opts.encoders` that `header` has — or the error that the
    /// recording has no engine angle at all.
    pub fn new(header: &Recording, opts: &AcquisitionOptions) -> Result<Self, AcquisitionError> {
        let (name, ppr) = opts
            .encoders
            .iter()
            .find(|(n, _)| header.channel(n).is_ok())
            .ok_or_else(|| {
                AcquisitionError::Invalid(format!(
                    "no engine angle: the recording needs 'theta_en' [rad], an encoder count channel ({}), a trigger wheel's signal (--wheel CHANNEL=N-M) or a quadrature encoder's (--quadrature A,B,Z=LINES) — `physid inspect` names a channel that is a trigger wheel's; the channels are {}",
                    opts.encoders.iter().map(|e| e.0.as_str()).collect::<Vec<_>>().join(", "),
                    header.names().join(", ")
                ))
            })?;
        let encoder = Encoder { ppr: *ppr };
        Ok(Self {
            name: name.clone(),
            ppr: *ppr,
            marker: opts.marker.clone(),
            steps: CountSteps::new(encoder),
            spacing: SpacingCheck::new(*ppr),
            edge: FirstMarker::default(),
            at: MarkerAngle::default(),
            samples: 0,
            stepped: 0,
            t: Vec::new(),
            theta: Vec::new(),
        })
    }

    /// The count channel and its pulses per revolution.
    pub fn encoder(&self) -> (&str, u32) {
        (&self.name, self.ppr)
    }

    /// The next chunk (with `t`, the counts and, when the recording has one, the marker): the
    /// count steps in it — their times [s] and angles [rad].
    pub fn push(&mut self, chunk: &Recording) -> Result<(&[f64], &[f64]), AcquisitionError> {
        let t = chunk.values("t")?;
        let counts = chunk.values(&self.name)?;
        self.spacing.push(t, counts);
        if self.at.a.is_none() {
            if let Some(i) = chunk
                .values(&self.marker)
                .ok()
                .and_then(|m| self.edge.edge(m))
            {
                self.at.a = Some((t[i], self.samples + i));
            }
        }
        self.steps.push(t, counts, &mut self.t, &mut self.theta);
        for (&x, &y) in self.t.iter().zip(&self.theta) {
            self.at.point(x, y);
        }
        self.samples += t.len();
        self.stepped += self.t.len();
        Ok((&self.t, &self.theta))
    }

    /// The first pass over a recording's chunks (`t`, the counts and the marker): the encoder
    /// and the firing TDC's angle — or why no crank angle can be taken from the counts.
    pub fn scan<S, E>(mut self, chunks: S) -> Result<CountsAngle, AppError>
    where
        S: IntoIterator<Item = Result<Recording, E>>,
        AppError: From<E>,
    {
        for chunk in chunks {
            self.push(&chunk?)?;
        }
        let (encoder, ppr) = (self.name.clone(), self.ppr);
        Ok(CountsAngle {
            encoder,
            ppr,
            tdc: self.finish()?,
        })
    }

    /// The firing TDC's angle [rad] — or why no crank angle can be taken from the counts.
    pub fn finish(self) -> Result<f64, AcquisitionError> {
        let (name, ppr) = (&self.name, self.ppr);
        if let Some(why) = self.spacing.finish() {
            return Err(AcquisitionError::Invalid(format!(
                "'{name}' as an encoder of {ppr} pulses per revolution: {why} — give the wheel's raw signal with --wheel CHANNEL=N-M (e.g. enc=60-2) instead"
            )));
        }
        if self.stepped < 2 {
            return Err(AcquisitionError::Invalid(format!(
                "time ({0}) and angle ({0}) need the same length, at least 2",
                self.stepped
            )));
        }
        match self.at.value() {
            Some(Ok(tdc)) => Ok(tdc),
            Some(Err((a, i))) => Err(AcquisitionError::Invalid(format!(
                "the time at the first TDC marker ('{}', sample {i}) is {a}: the crank angle there cannot be interpolated",
                self.marker
            ))),
            None => Ok(first_tdc(self.at.first.map_or(0.0, |p| p.1))),
        }
    }
}

/// What the first pass over an encoder's counts found ([`CountsScan::scan`]): what the
/// second, the resampling, needs.
#[derive(Debug, Clone, PartialEq)]
pub struct CountsAngle {
    /// The count channel.
    pub encoder: String,
    /// Its pulses per revolution.
    pub ppr: u32,
    /// The firing TDC's angle on the counts' angle [rad].
    pub tdc: f64,
}

/// `interp(x, y, &[a])` over points `(x, y)` that come one at a time, `a` told before the
/// points after it: the first point's `y` when `a` is at or before it, the last point's when
/// at or after it, between them `y[j] + f·(y[j+1] − y[j])` on the first pair with
/// `x[j] < a ≤ x[j+1]`.
#[derive(Debug, Clone, Default)]
struct MarkerAngle {
    /// The abscissa asked for, and the sample it is at.
    a: Option<(f64, usize)>,
    /// The first point.
    first: Option<(f64, f64)>,
    /// The last point.
    last: Option<(f64, f64)>,
    /// The first point at or after `a` (not the first), with the one before it.
    bracket: Option<((f64, f64), (f64, f64))>,
}

impl MarkerAngle {
    fn point(&mut self, x: f64, y: f64) {
        if self.first.is_none() {
            self.first = Some((x, y));
        }
        if let (Some((a, _)), None, Some(prev)) = (self.a, self.bracket, self.last) {
            if x >= a {
                self.bracket = Some((prev, (x, y)));
            }
        }
        self.last = Some((x, y));
    }

    /// `y` at `a` (`None` when nothing was asked; `Err` with it and its sample when it is not
    /// a number).
    fn value(&self) -> Option<Result<f64, (f64, usize)>> {
        let (a, i) = self.a?;
        if !a.is_finite() {
            return Some(Err((a, i)));
        }
        let ((x0, y0), (xn, yn)) = (self.first?, self.last?);
        Some(Ok(if a <= x0 {
            y0
        } else if a >= xn {
            yn
        } else {
            match self.bracket {
                Some(((xj, yj), (xk, yk))) => {
                    let f = (a - xj) / (xk - xj);
                    yj + f * (yk - yj)
                }
                // Times that do not increase: no pair brackets it (the resampling then says
                // where they stop increasing).
                None => f64::NAN,
            }
        }))
    }
}

/// The firing TDC's angle without a marker: the first multiple of 4π at or after the engine
/// angle's first value `theta0` [rad] (cycles start there).
pub fn first_tdc(theta0: f64) -> f64 {
    (theta0 / (4.0 * PI)).ceil() * 4.0 * PI
}

/// The engine angle of a time-basis recording ([`engine_angle`]).
struct EngineAngle {
    /// Strictly increasing times [s] …
    t: Vec<f64>,
    /// … and angles [rad].
    theta: Vec<f64>,
    /// The first firing TDC's angle [rad].
    tdc: f64,
}

/// What decoding a raw angle sensor found, and where the firing TDC lies on its angle.
#[derive(Debug, Clone)]
pub struct DecodedAngle {
    /// The firing TDC's angle [rad]: the first at or after the first sample.
    pub tdc: f64,
    /// What decoding a wheel found (teeth, gaps, speed range).
    pub wheel: Option<ToothReport>,
    /// What decoding a quadrature encoder found.
    pub encoder: Option<EncoderSummary>,
    /// Missing, extra and unresolved edges, references out of place, at their samples.
    pub findings: Vec<Finding>,
    /// What was decoded, for a person.
    pub summary: String,
    /// How the firing revolution was chosen, for a person.
    pub phase: String,
}

/// A quadrature encoder as decoded.
#[derive(Debug, Clone, Serialize)]
pub struct EncoderSummary {
    /// Lines per revolution.
    pub lines: u32,
    /// Index pulses turning forward.
    pub index_pulses: usize,
    /// Quarter-line steps turning back.
    pub backward_steps: usize,
}

/// The raw angle sensor (a trigger wheel, a quadrature encoder) whose signal is the engine
/// angle of a time-basis recording without `theta_en`, when the options name one whose
/// channels the recording has (any of them: a missing one is named when it is read).
pub fn raw_sensor<'a>(header: &Recording, opts: &'a AcquisitionOptions) -> Option<&'a AngleSpec> {
    opts.sensor.as_ref().filter(|s| {
        header.channel("theta_en").is_err()
            && s.sensor
                .channels()
                .iter()
                .any(|c| header.channel(c).is_ok())
    })
}

/// An application error as one of the acquisition chain's (the wheel's passes on a recording
/// held whole).
fn acquisition(e: AppError) -> AcquisitionError {
    match e {
        AppError::Acquisition(e) => e,
        AppError::Recording(e) => AcquisitionError::Recording(e),
        e => AcquisitionError::Invalid(e.to_string()),
    }
}

/// The angle of a firing TDC on the recording's `theta_en` [rad]: its value at the first TDC
/// marker; `None` without `theta_en` or a marker (cycles then start at multiples of 4π, as
/// [`to_crank_angle`] starts them).
pub fn marker_tdc_angle(rec: &Recording, opts: &AcquisitionOptions) -> Option<f64> {
    let theta = rec.values("theta_en").ok()?;
    let i = first_marker(rec.values(&opts.marker).ok()?)?;
    theta.get(i).copied().filter(|v| v.is_finite())
}

/// A time-basis stream of chunks with the firing TDC's angle on `theta_en`: what
/// [`marker_tdc_angle`] gives on the whole recording (`None` without a marker or `theta_en`), known
/// before the stages that index cycles from it take the first sample. The chunks up to the one
/// with the first marker are held until it comes (an engine turning a few times in the first
/// chunk: nothing more is held), then handed on with the rest.
pub fn from_first_marker<I, E>(
    chunks: I,
    opts: &AcquisitionOptions,
) -> Result<(Option<f64>, impl Iterator<Item = Result<Recording, E>>), E>
where
    I: IntoIterator<Item = Result<Recording, E>>,
{
    let mut chunks = chunks.into_iter();
    let mut held = Vec::new();
    let mut scan = FirstMarker::default();
    let mut tdc = None;
    for chunk in chunks.by_ref() {
        let chunk = chunk?;
        let found = scan.scan(&chunk, &opts.marker);
        held.push(chunk);
        if let Some(found) = found {
            tdc = found;
            break;
        }
    }
    Ok((tdc, held.into_iter().map(Ok).chain(chunks)))
}

/// The firing TDC's angle on `theta_en` at a stream's first TDC marker, a chunk at a time: the
/// rule of [`marker_tdc_angle`] on the whole recording.
#[derive(Debug, Clone, Default)]
pub struct FirstMarker {
    /// The marker's last sample in the chunks so far.
    prev: Option<f64>,
}

impl FirstMarker {
    /// Look in the next chunk for the first rising edge of the marker channel `marker` (the
    /// sample before the chunk included): `Some(angle)` once found — `Some(None)` when the
    /// chunk has no `marker` or `theta_en` channel, or `theta_en` is not finite there (no angle
    /// will come) — `None` while it has not come.
    pub fn scan(&mut self, chunk: &Recording, marker: &str) -> Option<Option<f64>> {
        let (Ok(m), Ok(theta)) = (chunk.values(marker), chunk.values("theta_en")) else {
            return Some(None);
        };
        let found = self.edge(m);
        found.map(|i| theta.get(i).copied().filter(|v| v.is_finite()))
    }

    /// The first rising edge in the next samples `m` of the marker (the sample before them
    /// included), [`first_marker`]'s rule: its index in `m`.
    pub fn edge(&mut self, m: &[f64]) -> Option<usize> {
        let found = m.iter().enumerate().find_map(|(i, &v)| {
            let before = if i == 0 { self.prev } else { Some(m[i - 1]) };
            (v != 0.0 && before.is_none_or(|p| p == 0.0)).then_some(i)
        });
        self.prev = m.last().copied().or(self.prev);
        found
    }
}

/// Resample a time-basis recording to one sample every `step_deg` crank degrees from the
/// first TDC marker: channels `t`, `theta` [rad from TDC], `cycle`, `crank_deg`, then every
/// other channel interpolated (the encoder counts and the marker are left out).
pub fn to_crank_angle(
    rec: &Recording,
    opts: &AcquisitionOptions,
    step_deg: f64,
) -> Result<Recording, AcquisitionError> {
    to_crank_angle_decoded(rec, opts, step_deg).map(|r| r.0)
}

/// [`to_crank_angle`], with what decoding a raw angle sensor found when the angle came from one.
/// The same resampling as [`CrankAngleStream`], on the whole recording as one chunk.
pub fn to_crank_angle_decoded(
    rec: &Recording,
    opts: &AcquisitionOptions,
    step_deg: f64,
) -> Result<(Recording, Option<DecodedAngle>), AcquisitionError> {
    if rec.basis != Basis::Time {
        return Err(AcquisitionError::Invalid(
            "the recording is already on a crank-angle basis".into(),
        ));
    }
    if let Some(spec) = raw_sensor(rec, opts) {
        // The sensor's passes, over the recording as one chunk.
        let one = || std::iter::once(Ok::<&Recording, AppError>(rec));
        let run = || -> Result<_, AppError> {
            let cal = sensor_calibration(spec, || Ok(one()))?;
            let decoded = sensor_decoded(spec, &cal, one(), one())?;
            let found = SensorFound { cal, decoded };
            let (mut out, chunks) =
                sensor_crank_angle_chunks(spec, &found, rec, one(), one(), opts, step_deg)?;
            for chunk in chunks {
                out.append(&chunk?)?;
            }
            Ok((out, Some(found.decoded)))
        };
        return run().map_err(acquisition);
    }
    let angle = engine_angle(rec, opts)?;
    if angle.t.len() < 2 {
        return Err(AcquisitionError::Invalid(format!(
            "time ({}) and angle ({}) need the same length, at least 2",
            angle.t.len(),
            angle.theta.len()
        )));
    }
    let mut stream = CrankAngleStream::new(rec, opts, angle.tdc, step_deg)?;
    stream.push_angle(&angle.t, &angle.theta)?;
    stream.resampler.finish_angle();
    let mut out = stream.push_channels(rec)?;
    out.append(&stream.finish()?)?;
    Ok((out, None))
}

/// A time-basis stream with `theta_en` (`header` its channels) on one sample every `step_deg`
/// crank degrees, resampled as it comes ([`CrankAngleStream`]): the firing TDC at the first
/// marker ([`from_first_marker`]), without one at the first multiple of 4π ([`first_tdc`]) —
/// what [`to_crank_angle`] gives on the whole recording. Returns the crank-angle recording's
/// header (its channels, no samples) and its chunks.
pub fn crank_angle_chunks<'a, I, E>(
    header: &Recording,
    chunks: I,
    opts: &AcquisitionOptions,
    step_deg: f64,
) -> Result<
    (
        Recording,
        impl Iterator<Item = Result<Recording, AppError>> + 'a,
    ),
    AppError,
>
where
    I: IntoIterator<Item = Result<Recording, E>> + 'a,
    I::IntoIter: 'a,
    E: 'a,
    AppError: From<E>,
{
    header.channel("theta_en")?;
    let (tdc, chunks) = from_first_marker(chunks, opts)?;
    let mut chunks = chunks.peekable();
    let tdc = match (tdc, chunks.peek()) {
        (Some(tdc), _) => tdc,
        (None, Some(Ok(first))) => {
            first_tdc(first.values("theta_en")?.first().copied().unwrap_or(0.0))
        }
        (None, _) => 0.0,
    };
    let mut stream = CrankAngleStream::new(header, opts, tdc, step_deg)?;
    let out_header = stream.header()?;
    let (mut done, mut samples) = (false, 0);
    let iter = std::iter::from_fn(move || {
        if done {
            return None;
        }
        match chunks.next() {
            Some(Ok(c)) => {
                samples += c.len();
                Some(stream.push(&c).map_err(AppError::Acquisition))
            }
            Some(Err(e)) => {
                done = true;
                Some(Err(e.into()))
            }
            None => {
                done = true;
                Some(if samples < 2 {
                    Err(AppError::Invalid(format!(
                        "{samples} sample(s): the crank angle needs at least 2"
                    )))
                } else {
                    stream.finish().map_err(AppError::Acquisition)
                })
            }
        }
    });
    Ok((out_header, iter))
}

/// A time-basis stream whose engine angle is an encoder's counts on one sample every `step_deg`
/// crank degrees, resampled as it comes — what [`to_crank_angle`] gives on the whole
/// recording — in two passes over the file:
///
/// 1. `t`, the counts and the marker through a [`CountsScan`] ([`CountsScan::scan`]): the
///    spacing check and the firing TDC's angle, `counts`, before anything is resampled (once:
///    a verb that goes over the file in passes keeps it);
/// 2. `chunks`, the channels (`header` their channels, with `t`), with `angle`, the counts
///    again (`t` and the count channel), read ahead of them: a chunk of channels is resampled
///    once the angle has come past its last time ([`CrankAngleStream`]).
///
/// What it holds: a chunk of each, and the grid points of an angle chunk ahead; the angle is
/// read ahead, not held, however long the engine stands still. Returns the crank-angle
/// recording's header (its channels, no samples) and its chunks.
pub fn counts_crank_angle_chunks<'a, A, C, E>(
    counts: &CountsAngle,
    header: &Recording,
    angle: A,
    chunks: C,
    opts: &AcquisitionOptions,
    step_deg: f64,
) -> Result<
    (
        Recording,
        impl Iterator<Item = Result<Recording, AppError>> + 'a,
    ),
    AppError,
>
where
    A: IntoIterator<Item = Result<Recording, E>> + 'a,
    A::IntoIter: 'a,
    C: IntoIterator<Item = Result<Recording, E>> + 'a,
    C::IntoIter: 'a,
    E: 'a,
    AppError: From<E>,
{
    let mut stream = CrankAngleStream::new(header, opts, counts.tdc, step_deg)?;
    let out_header = stream.header()?;
    let mut ahead = CountsAhead {
        angle: angle.into_iter(),
        steps: CountSteps::new(Encoder { ppr: counts.ppr }),
        name: counts.encoder.clone(),
        until: f64::NEG_INFINITY,
        done: false,
        t: Vec::new(),
        theta: Vec::new(),
    };
    let iter = resampled(stream, chunks, move |c, stream| match c {
        Some(c) => ahead.past(c.values("t")?.last().copied(), stream),
        None => ahead.past(Some(f64::INFINITY), stream),
    });
    Ok((out_header, iter))
}

/// The chunks of a time-basis stream's channels through `stream` as they come: `angle` gives
/// the stream the engine angle up to (at least) each chunk's last time before its channels
/// are resampled, and at the end (`None`) the rest; then the last crank-angle samples.
pub(crate) fn resampled<'a, C, R, E>(
    mut stream: CrankAngleStream,
    chunks: C,
    mut angle: impl FnMut(Option<&Recording>, &mut CrankAngleStream) -> Result<(), AppError> + 'a,
) -> impl Iterator<Item = Result<Recording, AppError>> + 'a
where
    C: IntoIterator<Item = Result<R, E>> + 'a,
    C::IntoIter: 'a,
    R: std::borrow::Borrow<Recording>,
    E: 'a,
    AppError: From<E>,
{
    let mut chunks = chunks.into_iter();
    let mut done = false;
    std::iter::from_fn(move || {
        if done {
            return None;
        }
        let next = match chunks.next() {
            Some(Ok(c)) => {
                let c = c.borrow();
                angle(Some(c), &mut stream)
                    .and_then(|()| stream.push_channels(c).map_err(AppError::Acquisition))
            }
            Some(Err(e)) => Err(e.into()),
            None => {
                done = true;
                angle(None, &mut stream)
                    .and_then(|()| stream.finish().map_err(AppError::Acquisition))
            }
        };
        done |= next.is_err();
        Some(next)
    })
}

/// The angle of [`counts_crank_angle_chunks`]: the counts read ahead of the channels.
struct CountsAhead<A> {
    angle: A,
    steps: CountSteps,
    /// The count channel.
    name: String,
    /// The last count step's time pushed [s].
    until: f64,
    /// The angle is finished.
    done: bool,
    /// Scratch: an angle chunk's count steps.
    t: Vec<f64>,
    theta: Vec<f64>,
}

impl<A, E> CountsAhead<A>
where
    A: Iterator<Item = Result<Recording, E>>,
    AppError: From<E>,
{
    /// Push the angle until it has come past `last` [s] (a chunk's last time; not a number:
    /// nothing, the channels say what is wrong), or to its end.
    fn past(&mut self, last: Option<f64>, stream: &mut CrankAngleStream) -> Result<(), AppError> {
        let Some(last) = last.filter(|l| !l.is_nan()) else {
            return Ok(());
        };
        while !self.done && self.until < last {
            match self.angle.next() {
                Some(chunk) => {
                    let chunk = chunk?;
                    self.steps.push(
                        chunk.values("t")?,
                        chunk.values(&self.name)?,
                        &mut self.t,
                        &mut self.theta,
                    );
                    stream.push_angle(&self.t, &self.theta)?;
                    if let Some(&x) = self.t.last() {
                        self.until = x;
                    }
                }
                None => {
                    self.done = true;
                    stream.resampler.finish_angle();
                }
            }
        }
        Ok(())
    }
}

/// A time-basis recording to one sample every `step_deg` crank degrees from the firing TDC, a
/// chunk at a time ([`physid_signal::resample::CrankResampler`]): channels `t`, `theta` [rad
/// from TDC], `cycle`, `crank_deg`, then every other channel interpolated at the grid's times
/// (the engine angle's channels — `theta_en`, encoder counts, a raw sensor's — and the marker
/// are left out). On a stream the angle is `theta_en` ([`push`](Self::push)), the TDC's angle
/// from [`from_first_marker`]; [`to_crank_angle_decoded`] gives it a decoded angle whole. What
/// it holds: the last two samples and the grid points of less than a chunk.
#[derive(Debug)]
pub struct CrankAngleStream {
    resampler: physid_signal::resample::CrankResampler,
    /// The channels carried over (name, unit).
    carried: Vec<(String, String)>,
    meta: std::collections::BTreeMap<String, String>,
    out: physid_signal::resample::CrankChunk,
}

impl CrankAngleStream {
    /// The stage for recordings with `header`'s channels, the firing TDC at `theta_tdc` [rad]
    /// on the engine angle.
    pub fn new(
        header: &Recording,
        opts: &AcquisitionOptions,
        theta_tdc: f64,
        step_deg: f64,
    ) -> Result<Self, AcquisitionError> {
        if header.basis != Basis::Time {
            return Err(AcquisitionError::Invalid(
                "the recording is already on a crank-angle basis".into(),
            ));
        }
        let skip: Vec<&str> = opts
            .encoders
            .iter()
            .map(|e| e.0.as_str())
            .chain([opts.marker.as_str(), "t", "theta_en"])
            .chain(opts.sensor.iter().flat_map(|s| s.sensor.channels()))
            .collect();
        let carried: Vec<(String, String)> = header
            .channels()
            .iter()
            .filter(|c| !skip.contains(&c.name.as_str()))
            .map(|c| (c.name.clone(), c.unit.clone()))
            .collect();
        let resampler =
            physid_signal::resample::CrankResampler::new(theta_tdc, step_deg, carried.len())
                .map_err(|e| AcquisitionError::Invalid(e.to_string()))?;
        let mut meta = header.meta.clone();
        meta.insert("crank_step_deg".into(), format!("{step_deg}"));
        let out = physid_signal::resample::CrankChunk {
            channels: vec![Vec::new(); carried.len()],
            ..Default::default()
        };
        Ok(Self {
            resampler,
            carried,
            meta,
            out,
        })
    }

    /// The next chunk, its angle from `theta_en`: the crank-angle samples it completes.
    pub fn push(&mut self, chunk: &Recording) -> Result<Recording, AcquisitionError> {
        self.push_angle(chunk.values("t")?, chunk.values("theta_en")?)?;
        self.push_channels(chunk)
    }

    pub(crate) fn push_angle(&mut self, t: &[f64], theta: &[f64]) -> Result<(), AcquisitionError> {
        self.resampler
            .push_angle(t, theta)
            .map_err(|e| AcquisitionError::Invalid(e.to_string()))
    }

    pub(crate) fn push_channels(
        &mut self,
        chunk: &Recording,
    ) -> Result<Recording, AcquisitionError> {
        let ys = self
            .carried
            .iter()
            .map(|(n, _)| chunk.values(n))
            .collect::<Result<Vec<_>, _>>()?;
        self.resampler
            .push_channels(chunk.values("t")?, &ys, &mut self.out)
            .map_err(|e| AcquisitionError::Invalid(e.to_string()))?;
        self.emit()
    }

    /// The end of the recording: the last crank-angle samples.
    pub fn finish(&mut self) -> Result<Recording, AcquisitionError> {
        self.resampler.finish(&mut self.out);
        self.emit()
    }

    /// The crank-angle recording's channels, without samples.
    pub fn header(&mut self) -> Result<Recording, AcquisitionError> {
        Ok(self.emit()?.slice(0..0))
    }

    fn emit(&mut self) -> Result<Recording, AcquisitionError> {
        let o = &self.out;
        let basis = [
            ("t", "s", &o.t),
            ("theta", "rad", &o.theta),
            ("cycle", "-", &o.cycle),
            ("crank_deg", "deg", &o.crank_deg),
        ];
        let carried = self
            .carried
            .iter()
            .zip(&o.channels)
            .map(|((n, u), v)| (n.as_str(), u.as_str(), v));
        assemble(
            Basis::CrankAngle,
            &self.meta,
            basis.into_iter().chain(carried),
        )
    }
}

/// The sample period [s] of a time channel that must be uniform: the mean step, or an error at
/// the first step that goes back or repeats a time, else at the first step more than 0.1 % away
/// from the median step (what to do about it included). The median, not the mean, is the
/// reference: one jump back or forward moves the mean, and every step would then look wrong
/// from the first.
pub fn uniform_step(t: &[f64]) -> Result<f64, AcquisitionError> {
    if t.len() < 2 {
        return Err(AcquisitionError::Invalid("fewer than 2 samples".into()));
    }
    let fix = "check with physid inspect, resample with physid convert --time-basis HZ";
    if let Some(i) = t.iter().position(|v| !v.is_finite()) {
        return Err(AcquisitionError::Invalid(format!(
            "the time is {} at sample {i}: {fix}",
            t[i]
        )));
    }
    if let Some(i) = t.windows(2).position(|w| w[1] <= w[0]) {
        let how = if t[i + 1] == t[i] {
            "repeats"
        } else {
            "goes back"
        };
        return Err(AcquisitionError::Invalid(format!(
            "the time {how} at sample {} ({} s after {} s): {fix}",
            i + 1,
            t[i + 1],
            t[i]
        )));
    }
    let mut steps: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    let mid = steps.len() / 2;
    let median = *steps.select_nth_unstable_by(mid, f64::total_cmp).1;
    let dt = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
    match t
        .windows(2)
        .position(|w| ((w[1] - w[0]) - median).abs() > 1e-3 * median)
    {
        Some(i) => Err(AcquisitionError::Invalid(format!(
            "the time step is not uniform at sample {} ({} s, {median} s elsewhere): {fix}",
            i + 1,
            t[i + 1] - t[i]
        ))),
        None => Ok(dt),
    }
}

/// Resample a crank-angle recording (with its `t` channel) to a uniform time basis at
/// `rate_hz`: [`TimeBasisStream`] on the whole recording as one chunk.
pub fn to_time_basis(rec: &Recording, rate_hz: f64) -> Result<Recording, AcquisitionError> {
    let mut stream = TimeBasisStream::new(rec, rate_hz)?;
    let mut out = stream.push(rec)?;
    out.append(&stream.finish()?)?;
    Ok(out)
}

/// A stream of crank-angle chunks (`header` their channels) on a uniform time basis at
/// `rate_hz` ([`TimeBasisStream`]), handed on in chunks of `rows` samples (the last shorter,
/// one empty chunk for an empty stream) — the chunks [`to_time_basis`] on the whole recording
/// cut in `rows` would give.
pub fn time_basis_chunks<'a, I, E>(
    header: &Recording,
    chunks: I,
    rate_hz: f64,
    rows: usize,
) -> Result<impl Iterator<Item = Result<Recording, AppError>> + 'a, AppError>
where
    I: IntoIterator<Item = Result<Recording, E>> + 'a,
    I::IntoIter: 'a,
    E: 'a,
    AppError: From<E>,
{
    let mut stream = TimeBasisStream::new(header, rate_hz)?;
    let mut pending = stream.header()?;
    let mut chunks = chunks.into_iter();
    let rows = rows.max(1);
    let (mut finished, mut emitted) = (false, false);
    Ok(std::iter::from_fn(move || loop {
        if pending.len() >= rows || (finished && (!pending.is_empty() || !emitted)) {
            let n = pending.len().min(rows);
            let out = pending.slice(0..n);
            pending = pending.slice(n..pending.len());
            emitted = true;
            return Some(Ok(out));
        }
        if finished {
            return None;
        }
        let next = match chunks.next() {
            Some(Ok(c)) => stream.push(&c),
            Some(Err(e)) => {
                (finished, emitted) = (true, true);
                pending = pending.slice(0..0);
                return Some(Err(e.into()));
            }
            None => {
                finished = true;
                stream.finish()
            }
        };
        if let Err(e) = next.and_then(|out| pending.append(&out).map_err(AcquisitionError::from)) {
            (finished, emitted) = (true, true);
            pending = pending.slice(0..0);
            return Some(Err(e.into()));
        }
    }))
}

/// A recording to a uniform time basis at `rate_hz` from its first time, a chunk at a time
/// ([`physid_signal::resample::TimeResampler`]): `t`, then every other channel interpolated.
/// What it holds: the last two samples and the times of less than a chunk.
#[derive(Debug)]
pub struct TimeBasisStream {
    resampler: physid_signal::resample::TimeResampler,
    /// The channels carried over (name, unit).
    carried: Vec<(String, String)>,
    meta: std::collections::BTreeMap<String, String>,
    t: Vec<f64>,
    out: Vec<Vec<f64>>,
}

impl TimeBasisStream {
    /// The stage for recordings with `header`'s channels (a `t` among them).
    pub fn new(header: &Recording, rate_hz: f64) -> Result<Self, AcquisitionError> {
        header.channel("t")?;
        let carried: Vec<(String, String)> = header
            .channels()
            .iter()
            .filter(|c| c.name != "t")
            .map(|c| (c.name.clone(), c.unit.clone()))
            .collect();
        let resampler = physid_signal::resample::TimeResampler::new(rate_hz, carried.len())
            .map_err(|e| AcquisitionError::Invalid(e.to_string()))?;
        Ok(Self {
            resampler,
            out: vec![Vec::new(); carried.len()],
            carried,
            meta: header.meta.clone(),
            t: Vec::new(),
        })
    }

    /// The next chunk: the time-basis samples it completes.
    pub fn push(&mut self, chunk: &Recording) -> Result<Recording, AcquisitionError> {
        let ys = self
            .carried
            .iter()
            .map(|(n, _)| chunk.values(n))
            .collect::<Result<Vec<_>, _>>()?;
        self.resampler
            .push(chunk.values("t")?, &ys, &mut self.t, &mut self.out)
            .map_err(|e| AcquisitionError::Invalid(e.to_string()))?;
        self.emit()
    }

    /// The end of the recording: the last samples.
    pub fn finish(&mut self) -> Result<Recording, AcquisitionError> {
        self.resampler.finish(&mut self.t, &mut self.out);
        self.emit()
    }

    /// The time-basis recording's channels, without samples.
    pub fn header(&self) -> Result<Recording, AcquisitionError> {
        Ok(self.emit()?.slice(0..0))
    }

    fn emit(&self) -> Result<Recording, AcquisitionError> {
        let carried = self
            .carried
            .iter()
            .zip(&self.out)
            .map(|((n, u), v)| (n.as_str(), u.as_str(), v));
        assemble(
            Basis::Time,
            &self.meta,
            std::iter::once(("t", "s", &self.t)).chain(carried),
        )
    }
}

/// A recording on `basis` with `meta` and the columns (name, unit, values) in order.
fn assemble<'a>(
    basis: Basis,
    meta: &std::collections::BTreeMap<String, String>,
    columns: impl IntoIterator<Item = (&'a str, &'a str, &'a Vec<f64>)>,
) -> Result<Recording, AcquisitionError> {
    let mut out = Recording::new(basis);
    out.meta = meta.clone();
    for (name, unit, values) in columns {
        out.push(Channel {
            name: name.into(),
            unit: unit.into(),
            values: values.clone(),
        })?;
    }
    Ok(out)
}

/// A zero-phase Butterworth filter for [`filter_channels`].
#[derive(Debug, Clone)]
pub struct FilterSpec {
    /// Band type.
    pub band: Band,
    /// Cut-off(s) [Hz].
    pub cutoff_hz: Vec<f64>,
    /// Order.
    pub order: usize,
    /// Use the transfer function (scipy's `filtfilt`) instead of second-order sections
    /// (`sosfiltfilt`, better conditioned; the default).
    pub transfer_function: bool,
}

/// Zero-phase filtering of chosen channels on a stream of a time-basis recording's chunks: what
/// `physid filter` runs, a chunk at a time, so that its memory does not grow with the
/// recording. Each filtered channel goes through a [`ZeroPhaseStream`] (the whole-record
/// `sosfiltfilt` to ≈ 1e-13 of the signal's scale in the interior, bit for bit over the last
/// samples); the other channels are held back by the same latency, so every output chunk has
/// all the channels, row-aligned. The sample rate is `1/Δt` of the first chunk's `t`, which must
/// stay uniform (within 0.1 %) across the whole stream.
#[derive(Debug)]
pub struct FilterStream {
    spec: FilterSpec,
    /// Which channels are filtered, by the order of the chunks' channels.
    wanted: Vec<String>,
    /// Started at the first chunk: per channel, its filter (None: passed through) and the
    /// output waiting to be given.
    state: Option<Started>,
}

#[derive(Debug)]
struct Started {
    names: Vec<(String, String)>,
    filters: Vec<Option<physid_signal::stream::ZeroPhaseStream>>,
    pending: Vec<std::collections::VecDeque<f64>>,
    dt: f64,
    t_last: f64,
    taken: usize,
    out: Vec<f64>,
}

impl FilterStream {
    /// A stream filtering `channels` with `spec` (second-order sections: the transfer-function
    /// form is the whole-record [`filter_channels`] only).
    pub fn new(channels: &[String], spec: &FilterSpec) -> Result<Self, AcquisitionError> {
        if spec.transfer_function {
            return Err(AcquisitionError::Invalid(
                "the transfer-function form (--ba) filters whole recordings only".into(),
            ));
        }
        Ok(Self {
            spec: spec.clone(),
            wanted: channels.to_vec(),
            state: None,
        })
    }

    fn start(&mut self, chunk: &Recording) -> Result<(), AcquisitionError> {
        if chunk.basis != Basis::Time {
            return Err(AcquisitionError::Invalid(
                "zero-phase filtering in Hz needs a time basis: convert the recording first".into(),
            ));
        }
        for w in &self.wanted {
            chunk.channel(w)?;
        }
        let dt = uniform_step(chunk.values("t")?)?;
        let zpk = butter(
            self.spec.order,
            &self.spec.cutoff_hz,
            self.spec.band,
            1.0 / dt,
        )
        .map_err(|source| AcquisitionError::Filter {
            channel: self.wanted.join(", "),
            source,
        })?;
        let sos = zpk.to_sos();
        let names: Vec<(String, String)> = chunk
            .channels()
            .iter()
            .map(|c| (c.name.clone(), c.unit.clone()))
            .collect();
        let filters = names
            .iter()
            .map(|(n, _)| {
                self.wanted
                    .contains(n)
                    .then(|| physid_signal::stream::ZeroPhaseStream::new(&sos, None, None))
            })
            .collect();
        self.state = Some(Started {
            pending: vec![Default::default(); names.len()],
            names,
            filters,
            dt,
            t_last: f64::NAN,
            taken: 0,
            out: Vec::new(),
        });
        Ok(())
    }

    /// Take a chunk (the same channels every time); the rows that are ready, if any.
    pub fn push(&mut self, chunk: &Recording) -> Result<Option<Recording>, AcquisitionError> {
        if self.state.is_none() {
            self.start(chunk)?;
        }
        let Some(s) = self.state.as_mut() else {
            unreachable!("started above");
        };
        // The time step, checked across chunk boundaries too.
        let t = chunk.values("t")?;
        let mut prev = s.t_last;
        for (i, &v) in t.iter().enumerate() {
            if prev.is_finite() && ((v - prev) - s.dt).abs() > 1e-3 * s.dt {
                return Err(AcquisitionError::Invalid(format!(
                    "the time step is not uniform at sample {} ({} s, {} s before): check with physid inspect, resample with physid convert --time-basis HZ",
                    s.taken + i,
                    v - prev,
                    s.dt
                )));
            }
            prev = v;
        }
        s.t_last = prev;
        for (j, (name, _)) in s.names.iter().enumerate() {
            let x = chunk.values(name)?;
            match s.filters[j].as_mut() {
                Some(f) => {
                    s.out.clear();
                    f.push(x, &mut s.out)
                        .map_err(|source| AcquisitionError::Filter {
                            channel: name.clone(),
                            source,
                        })?;
                    s.pending[j].extend(s.out.iter().copied());
                }
                None => s.pending[j].extend(x.iter().copied()),
            }
        }
        s.taken += t.len();
        Self::ready(s)
    }

    /// The end of the stream: the last rows.
    pub fn finish(&mut self) -> Result<Option<Recording>, AcquisitionError> {
        let Some(s) = self.state.as_mut() else {
            return Err(AcquisitionError::Invalid("fewer than 2 samples".into()));
        };
        for j in 0..s.names.len() {
            if let Some(f) = s.filters[j].as_mut() {
                s.out.clear();
                f.finish(&mut s.out)
                    .map_err(|source| AcquisitionError::Filter {
                        channel: s.names[j].0.clone(),
                        source,
                    })?;
                s.pending[j].extend(s.out.iter().copied());
            }
        }
        Self::ready(s)
    }

    /// The rows every channel has (after [`finish`](Self::finish): all of them); `None` when
    /// there are none.
    fn ready(s: &mut Started) -> Result<Option<Recording>, AcquisitionError> {
        let n = s.pending.iter().map(|p| p.len()).min().unwrap_or(0);
        if n == 0 {
            return Ok(None);
        }
        let mut out = Recording::new(Basis::Time);
        for ((name, unit), p) in s.names.iter().zip(&mut s.pending) {
            out.push(Channel {
                name: name.clone(),
                unit: unit.clone(),
                values: p.drain(..n).collect(),
            })?;
        }
        Ok(Some(out))
    }
}

/// Filter `channels` of a time-basis recording in place (forward–backward, zero phase); the
/// sample rate is `1/Δt` of its `t` channel, which must be uniform (within 0.1 %).
pub fn filter_channels(
    rec: &mut Recording,
    channels: &[String],
    spec: &FilterSpec,
) -> Result<(), AcquisitionError> {
    if rec.basis != Basis::Time {
        return Err(AcquisitionError::Invalid(
            "zero-phase filtering in Hz needs a time basis: convert the recording first".into(),
        ));
    }
    let dt = uniform_step(rec.values("t")?)?;
    let zpk = butter(spec.order, &spec.cutoff_hz, spec.band, 1.0 / dt).map_err(|source| {
        AcquisitionError::Filter {
            channel: channels.join(", "),
            source,
        }
    })?;
    let (tf, sos) = (zpk.to_ba(), zpk.to_sos());
    let mut filtered = Vec::new();
    for name in channels {
        let x = rec.values(name)?;
        let y = if spec.transfer_function {
            tf.filtfilt(x)
        } else {
            sos.sosfiltfilt(x)
        }
        .map_err(|source| AcquisitionError::Filter {
            channel: name.clone(),
            source,
        })?;
        filtered.push((name.clone(), y));
    }
    for (name, y) in filtered {
        rec.replace_values(&name, y)?;
    }
    Ok(())
}
