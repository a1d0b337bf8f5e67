//! The engine angle from what was recorded: an encoder's counts with its marker (Eq. 4.2),
//! the first TDC, the decoded angle of a raw sensor.

use super::*;

/// The engine angle of a time-basis recording as strictly increasing `(t, θ)` pairs: from
/// `theta_en` if present, else from the engine encoder's counts at the samples where the count
/// moves on (event-based, as the thesis samples). Also the angle at the first TDC marker
/// (or, without a marker, the first multiple of 720° — the simulator's convention).
pub(super) fn engine_angle(
    rec: &Recording,
    opts: &AcquisitionOptions,
) -> Result<EngineAngle, AcquisitionError> {
    let t = rec.values("t")?;
    if let Ok(theta) = rec.values("theta_en") {
        // Its value at the marker (as `from_first_marker` takes it on a stream).
        let marker = rec.values(&opts.marker).ok().and_then(first_marker);
        let mut tdc = match marker {
            Some(i) => theta[i],
            None => first_tdc(theta.first().copied().unwrap_or(0.0)),
        };
        let mut told = None;
        if let Some((from, implied)) = opts.phase_from.resolve(|n| rec.channel(n).is_ok()) {
            // Which revolution fires (as `from_first_marker_phased` tells it on a stream).
            let mut phase = MarkerPhase::new(from);
            let p = rec.values(phase.channel())?;
            phase.marker_at(tdc);
            for (&th, &p) in theta.iter().zip(p) {
                phase.push(th, p);
                if phase.done() {
                    break;
                }
            }
            let first = (tdc, first_guess(marker.is_some()));
            let (at, how) = told_or_first(phase.finish(), implied, || first)?;
            (tdc, told) = (at, Some(how));
        }
        return Ok(EngineAngle {
            t: t.to_vec(),
            theta: theta.to_vec(),
            tdc,
            phase: phase_note(marker.is_some(), told),
        });
    }
    // An encoder's counts: the same scan as on a stream, in one chunk.
    let mut scan = CountsScan::new(rec, opts)?;
    let (t, theta) = scan.push(rec)?;
    let (t, theta) = (t.to_vec(), theta.to_vec());
    let (tdc, phase) = scan.finish_phased()?;
    Ok(EngineAngle {
        tdc,
        t,
        theta,
        phase,
    })
}

/// The first pass over a time-basis recording whose engine angle is an encoder's counts
/// (thesis Eq. 4.2), a chunk at a time: the check that the counts are equally spaced in angle
/// ([`SpacingCheck`]) and the firing TDC's angle — at the first TDC marker, interpolated
/// between the count steps around it by the rule of
/// [`interp`](physid_signal::crank::interp), without a marker the first multiple of 4π
/// ([`first_tdc`]). The angle itself is the count steps ([`CountSteps`]), which
/// [`push`](Self::push) gives too. With `--phase-from`, which revolution of two fires
/// ([`MarkerPhase`], over the first revolutions after the marker, the channel read at the
/// count steps); without, a marker once per revolution is taken as firing and said to be a
/// guess. What it holds: a few numbers, the spacing check's, and the steps of the last chunk.
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
    /// Which revolution fires, with `--phase-from` (and whether it was only implied).
    phase: Option<(MarkerPhase, bool)>,
}

impl CountsScan {
    /// The scan of the first of `opts.encoders` that `header` has — or the error that the
    /// recording has no engine angle at all.
    pub fn new(header: &Recording, opts: &AcquisitionOptions) -> Result<Self, AcquisitionError> {
        let phase = opts
            .phase_from
            .resolve(|n| header.channel(n).is_ok())
            .map(|(from, implied)| (MarkerPhase::new(from), implied));
        if let Some((p, _)) = &phase {
            header.channel(p.channel())?;
        }
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
            phase,
        })
    }

    /// The channel `--phase-from` reads, when given (the first pass reads it too).
    pub fn phase_channel(&self) -> Option<&str> {
        self.phase.as_ref().map(|(p, _)| p.channel())
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
        if let Some((phase, _)) = self.phase.as_mut().filter(|(p, _)| !p.done()) {
            // The channel at each count step (a step is at a sample's time).
            let p = chunk.values(phase.channel())?;
            let mut j = 0;
            for (&x, &y) in self.t.iter().zip(&self.theta) {
                while j < t.len() && t[j] < x {
                    j += 1;
                }
                if j < t.len() && t[j] == x {
                    phase.push(y, p[j]);
                }
            }
            if let Some(a) = self.at.settled() {
                phase.marker_at(a);
            }
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
        let (tdc, phase) = self.finish_phased()?;
        Ok(CountsAngle {
            encoder,
            ppr,
            tdc,
            phase,
        })
    }

    /// [`finish`](Self::finish), with the phase told (`--phase-from`) or — a marker once per
    /// revolution taken as firing — said to be a guess.
    pub fn finish_phased(mut self) -> Result<(f64, Option<String>), AcquisitionError> {
        let marker = self.at.a.is_some();
        let phase = self.phase.take();
        let tdc = self.finish()?;
        match phase {
            Some((mut p, implied)) => {
                p.marker_at(tdc);
                let first = (tdc, first_guess(marker));
                let (at, told) = told_or_first(p.finish(), implied, || first)?;
                Ok((at, Some(told)))
            }
            None => Ok((tdc, phase_note(marker, None))),
        }
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
    /// How the firing revolution was told, or that it is a guess.
    pub phase: Option<String>,
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

    /// `y` at `a` once no later point can change it (bracketed, or `a` at or before the first
    /// point).
    fn settled(&self) -> Option<f64> {
        let (a, _) = self.a?;
        let at_first = self.first.is_some_and(|(x0, _)| a <= x0);
        if !(at_first || self.bracket.is_some()) {
            return None;
        }
        self.value()?.ok().filter(|v| v.is_finite())
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
pub(super) struct EngineAngle {
    /// Strictly increasing times [s] …
    pub(super) t: Vec<f64>,
    /// … and angles [rad].
    pub(super) theta: Vec<f64>,
    /// The first firing TDC's angle [rad].
    pub(super) tdc: f64,
    /// How the firing revolution was told ([`phase_note`]).
    pub(super) phase: Option<String>,
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
/// angle of a time-basis recording, when the options name one — also where the recording has a
/// `theta_en`: the sensor was asked for. A channel of it the recording lacks is an error naming
/// it and the recording's channels (the angle used to come from `theta_en` or the encoder's
/// counts instead, without a word).
pub fn raw_sensor<'a>(
    header: &Recording,
    opts: &'a AcquisitionOptions,
) -> Result<Option<&'a AngleSpec>, AcquisitionError> {
    let Some(spec) = &opts.sensor else {
        return Ok(None);
    };
    match spec.sensor.channels().into_iter().find(|c| header.channel(c).is_err()) {
        Some(c) => Err(AcquisitionError::Invalid(format!(
            "the engine angle is to be decoded from '{c}' ({}'s), which the recording does not have; its channels are {}",
            spec.sensor.kind(),
            header.names().join(", ")
        ))),
        None => Ok(Some(spec)),
    }
}

/// An application error as one of the acquisition chain's (the wheel's passes on a recording
/// held whole).
pub(super) fn acquisition(e: AppError) -> AcquisitionError {
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

/// [`from_first_marker`], with the phase told from `opts.phase_from` when given
/// ([`MarkerPhase`]: the chunks of its first revolutions after the marker held too; without a
/// marker, from the first multiple of 4π on `theta_en`): the firing TDC's angle, how the phase
/// was told ([`phase_note`]), the chunks.
#[allow(clippy::type_complexity)]
pub fn from_first_marker_phased<I, E>(
    chunks: I,
    opts: &AcquisitionOptions,
) -> Result<
    (
        Option<f64>,
        Option<String>,
        impl Iterator<Item = Result<Recording, E>>,
    ),
    AppError,
>
where
    I: IntoIterator<Item = Result<Recording, E>>,
    AppError: From<E>,
{
    let (tdc, chunks) = from_first_marker(chunks, opts)?;
    let mut chunks = chunks.peekable();
    // The channels are the first chunk's (an error there is the stream's to give).
    let resolved = match chunks.peek() {
        Some(Ok(first)) => opts.phase_from.resolve(|n| first.channel(n).is_ok()),
        _ => None,
    };
    let Some((from, implied)) = resolved else {
        let note = phase_note(tdc.is_some(), None);
        return Ok((tdc, note, Vec::new().into_iter().chain(chunks)));
    };
    let mut phase = MarkerPhase::new(from);
    let mut held = Vec::new();
    while !phase.done() {
        let Some(chunk) = chunks.next() else { break };
        let chunk = chunk?;
        let theta = chunk.values("theta_en")?;
        if !phase.has_marker() {
            phase
                .marker_at(tdc.unwrap_or_else(|| first_tdc(theta.first().copied().unwrap_or(0.0))));
        }
        for (&th, &p) in theta.iter().zip(chunk.values(phase.channel())?) {
            phase.push(th, p);
        }
        held.push(Ok(chunk));
    }
    let first = (phase.first_marker().or(tdc), first_guess(tdc.is_some()));
    let told = phase.finish().map(|(at, how)| (Some(at), how));
    let (at, told) = told_or_first(told, implied, || first)?;
    Ok((at, Some(told), held.into_iter().chain(chunks)))
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
