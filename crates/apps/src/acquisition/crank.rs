//! From a time basis to one sample per crank step (SPEC §2.7), whole and a chunk at a time.

use super::*;

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
    if let Some(spec) = raw_sensor(rec, opts)? {
        // The sensor's passes, over the recording as one chunk.
        let one = || std::iter::once(Ok::<&Recording, AppError>(rec));
        let run = || -> Result<_, AppError> {
            let cal = sensor_calibration(spec, rec)?;
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
    stream.note_phase(angle.phase);
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
    let (tdc, phase, chunks) = from_first_marker_phased(chunks, opts)?;
    let mut chunks = chunks.peekable();
    let tdc = match (tdc, chunks.peek()) {
        (Some(tdc), _) => tdc,
        (None, Some(Ok(first))) => {
            first_tdc(first.values("theta_en")?.first().copied().unwrap_or(0.0))
        }
        (None, _) => 0.0,
    };
    let mut stream = CrankAngleStream::new(header, opts, tdc, step_deg)?;
    stream.note_phase(phase);
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
    stream.note_phase(counts.phase.clone());
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

    /// How the firing revolution was told, in the output's `phase` metadata.
    pub fn note_phase(&mut self, phase: Option<String>) {
        if let Some(p) = phase {
            self.meta.insert("phase".into(), p);
        }
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
