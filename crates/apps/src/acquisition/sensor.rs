//! The crank angle decoded from a raw angle sensor — a trigger wheel ([`physid_signal::wheel`])
//! or a quadrature encoder ([`physid_signal::quadrature`]) — read as it comes: one code path
//! for a whole recording (one chunk) and a file read a chunk at a time. Passes over `t` and the
//! sensor's channels, each holding a few numbers (per revolution at most), never the samples:
//!
//! 1. [`sensor_calibration`]: what must be known before any angle is given — a wheel's gap, from
//!    the edges ([`EdgeDetector`]) through the first pass of the indexing ([`GapSurvey`]); an
//!    encoder's index level (its smallest and largest sample, [`IndexRange`]), then the
//!    decoding ([`QuadratureDecoder`]) for the angle 0 at the first index pulse ([`IndexZero`]),
//!    the span after the last time the shaft turned back, and what was found;
//! 2. [`sensor_decoded`]: the angle at every sample by the monotone cubic through the edges
//!    ([`Pchip`]), the sensor read ahead of the samples ([`SensorAhead`]): what a wheel's
//!    decoding found ([`ToothIndex`]), the angle at the first sample and — with
//!    `--phase-from` — the channel's mean over the revolution around each TDC
//!    ([`PhaseWindows`]): where the firing TDC lies;
//! 3. [`sensor_crank_angle_chunks`]: the channels resampled to the crank angle, the sensor read
//!    ahead of them: a standstill holds nothing.

use super::phase::{firing_tdc, no_phase, told_or_first, PhaseWindows};
use super::pulse_edges::{PulseEdges, PulsePoint};
use super::{
    invalid, resampled, AcquisitionOptions, AngleSensor, AngleSpec, CrankAngleStream, DecodedAngle,
    EncoderSummary,
};
use crate::error::AppError;
use physid_core::{Recording, Recordings, Reopen};
use physid_signal::integrity::Finding;
use physid_signal::quadrature::{IndexRange, IndexZero, QuadratureDecoder};
use physid_signal::wheel::{
    EdgeDetector, Gap, GapSurvey, IndexSurvey, Pchip, ToothIndex, ToothReport,
};
use std::borrow::Borrow;
use std::f64::consts::TAU;

/// What must be known of a raw sensor before any angle is given ([`sensor_calibration`]).
#[derive(Debug, Clone)]
pub enum Calibration {
    /// A trigger wheel: where its gap is.
    Wheel(Gap),
    /// A pulse encoder: where its index puts the reference, and the index channel's smallest
    /// and largest sample (its level midway).
    Pulses(Gap, (f64, f64)),
    /// A quadrature encoder.
    Quadrature(EncoderCalibration),
}

/// A quadrature encoder's calibration: its index level, its angle 0, the span of the samples
/// whose angle is given, and what the decoding found.
#[derive(Debug, Clone)]
pub struct EncoderCalibration {
    /// The index channel's smallest and largest sample.
    pub z_range: (f64, f64),
    /// The angle at the first index pulse turning forward, on the counts' scale [rad].
    pub zero: f64,
    /// From the transition after the last time the shaft turned back to the last transition
    /// [s].
    pub span: (f64, f64),
    /// Whether it turned back (the span starts after the first transition).
    pub turned_back: bool,
    /// Transitions, index pulses turning forward.
    pub transitions: usize,
    /// What was decoded (lines, pulses, steps back).
    pub encoder: EncoderSummary,
    /// Unresolved transitions and index pulses out of place, at their samples.
    pub findings: Vec<Finding>,
}

/// The channels of a quadrature encoder spec — A, B, Z — and its lines; the error without Z.
fn encoder_of(spec: &AngleSpec) -> Result<([&str; 3], u32), AppError> {
    match &spec.sensor {
        AngleSensor::Quadrature { a, b, z, lines } => match z {
            Some(z) => Ok(([a.as_str(), b.as_str(), z.as_str()], *lines)),
            None => Err(invalid(format!(
                "--quadrature {a},{b}: without an index channel (Z) the angle has no reference to place the TDC from; give --quadrature {a},{b},Z=LINES"
            ))),
        },
        AngleSensor::Wheel { .. } | AngleSensor::Pulses { .. } => Err(AppError::Invalid(
            "the angle sensor is a trigger wheel or a pulse encoder, not a quadrature encoder"
                .into(),
        )),
    }
}

/// Pass 1: what must be known of the sensor `spec` names before any angle is given — passes
/// over `source`, `t` and the sensor's channels (one for a wheel, two for an encoder: the
/// index's level, then the decoding). The decoders' errors — time not increasing, a channel
/// with no finite sample, the wrong wheel — name the channel and the sample; a dropout is a
/// finding, not an error.
pub fn sensor_calibration(
    spec: &AngleSpec,
    source: &dyn Reopen<Recordings, AppError>,
) -> Result<Calibration, AppError> {
    match &spec.sensor {
        AngleSensor::Wheel {
            channel,
            wheel,
            edges,
        } => {
            let mut detector = EdgeDetector::new(edges);
            let mut survey = GapSurvey::new(*wheel, channel);
            source.pass(&mut |c| {
                detector.push(c.values("t")?, c.values(channel)?);
                detector.drain(|t, i| survey.push(t, i));
                Ok(())
            })?;
            let rest = detector
                .finish()
                .map_err(|e| invalid(format!("'{channel}': {e}")))?;
            for (&t, &i) in rest.t.iter().zip(&rest.index) {
                survey.push(t, i);
            }
            Ok(Calibration::Wheel(
                survey.finish().map_err(|e| invalid(e.to_string()))?,
            ))
        }
        AngleSensor::Pulses {
            channel,
            pulses,
            index,
            edges,
        } => {
            let mut range = IndexRange::default();
            source.pass(&mut |c| {
                range.push(c.values(index)?);
                Ok(())
            })?;
            let mut found = PulseEdges::new(channel, index, edges, range.range)?;
            let mut survey = IndexSurvey::new(*pulses, channel, index);
            let mut take = |p: PulsePoint| match p {
                PulsePoint::Edge(t, i) => survey.push(t, i),
                PulsePoint::Index(t) => survey.pulse(t),
            };
            source.pass(&mut |c| found.push(c, &mut take))?;
            found.finish(&mut take)?;
            Ok(Calibration::Pulses(
                survey.finish().map_err(|e| invalid(e.to_string()))?,
                range.range,
            ))
        }
        AngleSensor::Quadrature { .. } => {
            let (names, lines) = encoder_of(spec)?;
            if lines == 0 {
                return Err(invalid("an encoder needs 1 line or more".into()));
            }
            let mut range = IndexRange::default();
            source.pass(&mut |c| {
                range.push(c.values(names[2])?);
                Ok(())
            })?;
            let mut decoder = QuadratureDecoder::new(names, Some(range.range), lines);
            let mut zero = IndexZero::new(lines, names[2]);
            let (mut transitions, mut last, mut from) = (0usize, None, (0usize, f64::NAN));
            let mut last_t = f64::NAN;
            let mut take = |d: &mut QuadratureDecoder, zero: &mut IndexZero| {
                while let Some(tr) = d.pop() {
                    // After the last time it turned back (the crank angle must increase).
                    if transitions == 0 || last.is_some_and(|e| tr.edge <= e) {
                        from = (transitions, tr.t);
                    }
                    transitions += 1;
                    last = Some(tr.edge);
                    last_t = tr.t;
                    zero.transition(tr);
                }
                while let Some(p) = d.pop_pulse() {
                    zero.pulse(p);
                }
            };
            source.pass(&mut |c| {
                let [a, b, z] = names.map(|n| c.values(n));
                decoder.push(c.values("t")?, a?, b?, z?);
                take(&mut decoder, &mut zero);
                Ok(())
            })?;
            decoder.finish().map_err(|e| invalid(e.to_string()))?;
            take(&mut decoder, &mut zero);
            let (zero, pulses, mut out_of_place) = zero.finish();
            let mut findings = decoder.take_findings();
            findings.append(&mut out_of_place);
            findings.sort_by_key(|f| f.index);
            Ok(Calibration::Quadrature(EncoderCalibration {
                z_range: range.range,
                zero,
                span: (from.1, last_t),
                turned_back: from.0 > 0,
                transitions,
                encoder: EncoderSummary {
                    lines,
                    index_pulses: pulses,
                    backward_steps: decoder.backward(),
                },
                findings,
            }))
        }
    }
}

/// The decoder of a raw sensor that gives its angle's points — a wheel's edges or an encoder's
/// transitions, with their angle [rad].
enum PointDecoder {
    Wheel {
        channel: String,
        /// `None` once the signal has ended.
        detector: Option<Box<EdgeDetector>>,
        index: Box<ToothIndex>,
        report: Option<ToothReport>,
    },
    Quadrature {
        names: [String; 3],
        decoder: Box<QuadratureDecoder>,
        q: f64,
        zero: f64,
        ended: bool,
    },
    Pulses {
        /// `None` once the signal has ended.
        found: Option<Box<PulseEdges>>,
        index: Box<ToothIndex>,
        report: Option<ToothReport>,
    },
}

/// A raw sensor's angle at any time, from a reader of `t` and its channels running ahead as far
/// as the times asked for: its points ([`sensor_calibration`]'s calibration fixed), the
/// monotone cubic through them ([`Pchip`]). Holds a chunk and a few points.
pub struct SensorAhead<A> {
    chunks: A,
    decoder: PointDecoder,
    pchip: Pchip,
}

impl<A, R, E> SensorAhead<A>
where
    A: Iterator<Item = Result<R, E>>,
    R: Borrow<Recording>,
    AppError: From<E>,
{
    /// The sensor `spec` names, calibrated by `cal`, read from `chunks`.
    pub fn new(spec: &AngleSpec, cal: &Calibration, chunks: A) -> Result<Self, AppError> {
        Ok(Self {
            chunks,
            decoder: PointDecoder::new(spec, cal)?,
            pchip: Pchip::default(),
        })
    }

    /// The angle [rad] at the time `a` [s] (the times asked for increasing): NaN before the
    /// first point and after the last.
    pub fn at(&mut self, a: f64) -> Result<f64, AppError> {
        loop {
            if let Some(v) = self.pchip.at(a) {
                return Ok(v);
            }
            if !self.next_point() {
                self.read()?;
            }
        }
    }

    /// A point decoded into the cubic: whether there was one (or the points ended).
    fn next_point(&mut self) -> bool {
        match &mut self.decoder {
            PointDecoder::Wheel { index, report, .. }
            | PointDecoder::Pulses { index, report, .. } => match index.pop() {
                Some((t, angle, _)) => self.pchip.push(t, angle),
                None if report.is_some() => self.pchip.end(),
                None => return false,
            },
            PointDecoder::Quadrature {
                decoder,
                q,
                zero,
                ended,
                ..
            } => match decoder.pop() {
                Some(tr) => self.pchip.push(tr.t, tr.edge as f64 * *q - *zero),
                None if *ended => self.pchip.end(),
                None => return false,
            },
        }
        true
    }

    /// The next chunk of the signal, or its end.
    fn read(&mut self) -> Result<(), AppError> {
        let chunk = match self.chunks.next() {
            Some(c) => Some(c?),
            None => None,
        };
        self.decoder.take(chunk.as_ref().map(Borrow::borrow))
    }

    /// Read the signal to its end (its points no longer needed): what a wheel's decoding
    /// found.
    pub fn finish(mut self) -> Result<Option<ToothReport>, AppError> {
        while !self.decoder.drain() {
            self.read()?;
        }
        Ok(self.decoder.report())
    }
}

impl PointDecoder {
    /// The decoder of the sensor `spec` names, calibrated by `cal`.
    fn new(spec: &AngleSpec, cal: &Calibration) -> Result<Self, AppError> {
        Ok(match (&spec.sensor, cal) {
            (AngleSensor::Wheel { channel, edges, .. }, Calibration::Wheel(gap)) => {
                PointDecoder::Wheel {
                    channel: channel.clone(),
                    detector: Some(Box::new(EdgeDetector::new(edges))),
                    index: Box::new(ToothIndex::new(gap, channel)),
                    report: None,
                }
            }
            (
                AngleSensor::Pulses {
                    channel,
                    index,
                    edges,
                    ..
                },
                Calibration::Pulses(gap, range),
            ) => PointDecoder::Pulses {
                found: Some(Box::new(PulseEdges::new(channel, index, edges, *range)?)),
                index: Box::new(ToothIndex::new(gap, channel)),
                report: None,
            },
            (AngleSensor::Quadrature { .. }, Calibration::Quadrature(c)) => {
                let (names, lines) = encoder_of(spec)?;
                PointDecoder::Quadrature {
                    names: names.map(str::to_string),
                    decoder: Box::new(QuadratureDecoder::new(names, Some(c.z_range), lines)),
                    q: TAU / (4.0 * lines as f64),
                    zero: c.zero,
                    ended: false,
                }
            }
            _ => {
                return Err(AppError::Invalid(
                    "the calibration is of another sensor".into(),
                ))
            }
        })
    }

    /// Take the signal's next chunk `c`, or its end (`None`).
    fn take(&mut self, c: Option<&Recording>) -> Result<(), AppError> {
        match self {
            PointDecoder::Wheel {
                channel,
                detector,
                index,
                report,
            } => {
                let Some(d) = detector.as_mut() else {
                    return Ok(());
                };
                if let Some(c) = c {
                    d.push(c.values("t")?, c.values(channel)?);
                    d.drain(|t, i| index.push(t, i));
                    return Ok(());
                }
                let rest = detector
                    .take()
                    .map(|d| d.finish())
                    .transpose()
                    .map_err(|e| invalid(format!("'{channel}': {e}")))?;
                if let Some(rest) = rest {
                    for (&t, &i) in rest.t.iter().zip(&rest.index) {
                        index.push(t, i);
                    }
                    index.glitches(
                        rest.glitches.len(),
                        rest.glitches.first().copied().unwrap_or(0),
                    );
                    index.dropouts(channel, &rest.dropouts);
                }
                *report = Some(index.finish().map_err(|e| invalid(e.to_string()))?);
            }
            PointDecoder::Pulses {
                found,
                index,
                report,
            } => {
                let mut take = |p: PulsePoint| match p {
                    PulsePoint::Edge(t, i) => index.push(t, i),
                    PulsePoint::Index(t) => index.index_pulse(t),
                };
                match (c, found.take()) {
                    (_, None) => {}
                    (Some(c), Some(mut f)) => {
                        f.push(c, &mut take)?;
                        *found = Some(f);
                    }
                    (None, Some(f)) => {
                        let end = f.finish(&mut take)?;
                        index.glitches(end.glitches, end.first_glitch);
                        for (channel, d) in &end.dropouts {
                            index.dropouts(channel, d);
                        }
                        *report = Some(index.finish().map_err(|e| invalid(e.to_string()))?);
                    }
                }
            }
            PointDecoder::Quadrature {
                names,
                decoder,
                ended,
                ..
            } => match c {
                Some(c) => {
                    let [a, b, z] = [0, 1, 2].map(|k| c.values(&names[k]));
                    decoder.push(c.values("t")?, a?, b?, z?);
                    // The pulses placed the angle 0 in the calibration.
                    while decoder.pop_pulse().is_some() {}
                }
                None => {
                    decoder.finish().map_err(|e| invalid(e.to_string()))?;
                    *ended = true;
                }
            },
        }
        Ok(())
    }

    /// What a wheel's decoding found, once the signal has ended.
    fn report(self) -> Option<ToothReport> {
        match self {
            PointDecoder::Wheel { report, .. } | PointDecoder::Pulses { report, .. } => report,
            PointDecoder::Quadrature { .. } => None,
        }
    }

    /// Drop the points decoded so far (not needed); whether the points have ended.
    fn drain(&mut self) -> bool {
        match self {
            PointDecoder::Wheel { index, report, .. }
            | PointDecoder::Pulses { index, report, .. } => {
                while index.pop().is_some() {}
                report.is_some()
            }
            PointDecoder::Quadrature { decoder, ended, .. } => {
                while decoder.pop().is_some() {}
                *ended
            }
        }
    }
}

/// The sensor `spec` names, calibrated by `cal`, decoded over one whole pass of `source` (its
/// points not needed): what a wheel's decoding found ([`ToothReport`]), what an encoder's
/// decoding refused.
pub fn sensor_pass(
    spec: &AngleSpec,
    cal: &Calibration,
    source: &dyn Reopen<Recordings, AppError>,
) -> Result<Option<ToothReport>, AppError> {
    let mut d = PointDecoder::new(spec, cal)?;
    source.pass(&mut |c| {
        d.drain();
        d.take(Some(c))
    })?;
    while !d.drain() {
        d.take(None)?;
    }
    Ok(d.report())
}

impl Calibration {
    /// The span of the samples whose angle is given [s]: an encoder's after the last time it
    /// turned back; a wheel's every sample between its first and last edge (where its angle is
    /// a number).
    fn span(&self) -> (f64, f64) {
        match self {
            Self::Wheel(_) | Self::Pulses(..) => (f64::NEG_INFINITY, f64::INFINITY),
            Self::Quadrature(c) => c.span,
        }
    }
}

/// Pass 2: what decoding the sensor found and where the firing TDC lies — `angle` the chunks of
/// `t` and the sensor's channels, `samples` those of `t` (and the `--phase-from` channel): the
/// angle at every sample in the sensor's span.
pub fn sensor_decoded<A, S, R1, R2, E1, E2>(
    spec: &AngleSpec,
    cal: &Calibration,
    angle: A,
    samples: S,
) -> Result<DecodedAngle, AppError>
where
    A: IntoIterator<Item = Result<R1, E1>>,
    S: IntoIterator<Item = Result<R2, E2>>,
    R1: Borrow<Recording>,
    R2: Borrow<Recording>,
    AppError: From<E1> + From<E2>,
{
    let mut ahead = SensorAhead::new(spec, cal, angle.into_iter())?;
    let (first, last) = cal.span();
    let offset = spec.tdc_offset_deg.to_radians();
    // The channel the phase is told from, and whether only implied: from the first chunk's
    // channels.
    let mut phase_from: Option<Option<(&str, bool)>> = None;
    let mut windows = PhaseWindows::new(offset);
    let (mut theta0, mut inside) = (None, 0usize);
    for chunk in samples {
        let chunk = chunk?;
        let c = chunk.borrow();
        let t = c.values("t")?;
        let from =
            *phase_from.get_or_insert_with(|| spec.phase_from.resolve(|n| c.channel(n).is_ok()));
        let p = match from {
            Some((from, _)) => Some(c.values(from.strip_suffix(":low").unwrap_or(from))?),
            None => None,
        };
        for (i, &x) in t.iter().enumerate() {
            if !(first..=last).contains(&x) {
                continue;
            }
            let theta = ahead.at(x)?;
            if theta.is_nan() {
                continue;
            }
            inside += 1;
            theta0.get_or_insert(theta);
            if let Some(p) = p {
                windows.push(theta, p[i]);
            }
        }
    }
    let report = ahead.finish()?;
    let theta0 = match theta0 {
        Some(t) if inside >= 2 => t,
        _ => {
            return Err(invalid(format!(
                "{}: fewer than 2 samples between the sensor's first and last edge",
                spec.sensor.channels().join(", ")
            )))
        }
    };
    let first = || (0, no_phase(spec.tdc_offset_deg));
    let (parity, phase) = match phase_from.flatten() {
        None => first(),
        Some((from, implied)) => {
            told_or_first(windows.finish(from, spec.tdc_offset_deg), implied, first)?
        }
    };
    let tdc = firing_tdc(offset, parity, theta0);
    Ok(match (report, cal) {
        (Some(report), _) => DecodedAngle {
            tdc,
            summary: match &spec.sensor {
                AngleSensor::Pulses { pulses, index, .. } => format!(
                    "encoder of {pulses} pulses with the index '{index}' decoded: {} edges over {} revolutions, {:.0}–{:.0} rpm",
                    report.edges, report.revolutions, report.rpm.0, report.rpm.1
                ),
                _ => format!(
                    "wheel {} decoded: {} edges over {} revolutions, {:.0}–{:.0} rpm",
                    report.wheel, report.edges, report.revolutions, report.rpm.0, report.rpm.1
                ),
            },
            findings: report.findings.clone(),
            wheel: Some(report),
            encoder: None,
            phase,
        },
        (None, Calibration::Quadrature(c)) => DecodedAngle {
            tdc,
            summary: format!(
                "quadrature encoder of {} lines decoded: {} transitions, {} index pulse(s) turning forward, {} steps back{}",
                c.encoder.lines,
                c.transitions,
                c.encoder.index_pulses,
                c.encoder.backward_steps,
                if c.turned_back {
                    format!(" (the crank angle from {:.6} s, after it last turned back)", c.span.0)
                } else {
                    String::new()
                }
            ),
            findings: c.findings.clone(),
            wheel: None,
            encoder: Some(c.encoder.clone()),
            phase,
        },
        (None, Calibration::Wheel(_) | Calibration::Pulses(..)) => {
            return Err(AppError::Invalid("the wheel's decoding has no report".into()))
        }
    })
}

/// What passes 1 and 2 found: the sensor's calibration; what the decoding found, and where the
/// firing TDC lies.
#[derive(Debug, Clone)]
pub struct SensorFound {
    /// What must be known before any angle is given ([`sensor_calibration`]).
    pub cal: Calibration,
    /// What the decoding found, the firing TDC ([`sensor_decoded`]).
    pub decoded: DecodedAngle,
}

/// Pass 3: a time-basis stream (`header` its channels, `chunks` them) on one sample every
/// `step_deg` crank degrees ([`CrankAngleStream`]), the firing TDC where pass 2 placed it
/// (`found`), the angle at each chunk's samples from `angle` — a second reader of `t` and
/// the sensor's channels — read ahead of it ([`SensorAhead`]). Returns the crank-angle
/// recording's header (its channels, no samples) and its chunks.
pub fn sensor_crank_angle_chunks<'a, A, C, R1, R2, E1, E2>(
    spec: &AngleSpec,
    found: &SensorFound,
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
    A: IntoIterator<Item = Result<R1, E1>> + 'a,
    A::IntoIter: 'a,
    R1: Borrow<Recording>,
    C: IntoIterator<Item = Result<R2, E2>> + 'a,
    C::IntoIter: 'a,
    R2: Borrow<Recording>,
    E1: 'a,
    E2: 'a,
    AppError: From<E1> + From<E2>,
{
    let mut stream = CrankAngleStream::new(header, opts, found.decoded.tdc, step_deg)?;
    let out_header = stream.header()?;
    let mut ahead = SensorAhead::new(spec, &found.cal, angle.into_iter())?;
    let (first, last) = found.cal.span();
    let (mut t_in, mut theta) = (Vec::new(), Vec::new());
    let iter = resampled(stream, chunks, move |c, stream| {
        let Some(c) = c else { return Ok(()) };
        t_in.clear();
        theta.clear();
        for &x in c
            .values("t")?
            .iter()
            .filter(|x| (first..=last).contains(*x))
        {
            let a = ahead.at(x)?;
            if !a.is_nan() {
                t_in.push(x);
                theta.push(a);
            }
        }
        Ok(stream.push_angle(&t_in, &theta)?)
    });
    Ok((out_header, iter))
}
