//! The crank angle decoded from a trigger wheel's raw signal ([`physid_signal::wheel`]), read as
//! it comes — one code path for a whole recording (one chunk) and a file read a chunk at a
//! time. Three passes over `t` and the wheel's channel, each holding a few numbers (per
//! revolution at most), never the samples:
//!
//! 1. [`wheel_gap`]: the edges ([`EdgeDetector`]) through the first pass of the indexing
//!    ([`GapSurvey`]) — where the gap lies, modulo N pitches;
//! 2. [`wheel_decoded`]: the edges again through the second ([`ToothIndex`]) with the gap fixed,
//!    the angle at every sample by the monotone cubic through the edges ([`Pchip`]): what the
//!    decoding found (findings, speed range), the angle at the first sample and — with
//!    `--phase-from` — the channel's mean over the revolution around each TDC
//!    ([`PhaseWindows`]): where the firing TDC lies;
//! 3. [`wheel_crank_angle_chunks`]: the channels resampled to the crank angle, the angle at
//!    their samples from a second reader of the wheel's signal running ahead of them
//!    ([`WheelAhead`]): a standstill holds nothing.

use crate::acquisition::{
    AcquisitionError, AcquisitionOptions, AngleSensor, AngleSpec, CrankAngleStream, DecodedAngle,
};
use crate::error::AppError;
use physid_core::Recording;
use physid_signal::wheel::{
    EdgeDetector, EdgeOptions, Gap, GapSurvey, Pchip, ToothIndex, ToothReport, Wheel,
};
use std::borrow::Borrow;
use std::f64::consts::{PI, TAU};

/// The wheel of an angle spec: channel, wheel, edge options — or the error for another sensor.
fn wheel_of(spec: &AngleSpec) -> Result<(&str, Wheel, &EdgeOptions), AppError> {
    match &spec.sensor {
        AngleSensor::Wheel {
            channel,
            wheel,
            edges,
        } => Ok((channel.as_str(), *wheel, edges)),
        AngleSensor::Quadrature { .. } => Err(AppError::Invalid(
            "the angle sensor is a quadrature encoder, not a trigger wheel".into(),
        )),
    }
}

fn invalid(e: String) -> AppError {
    AppError::Acquisition(AcquisitionError::Invalid(e))
}

/// Pass 1: where the gap of the wheel `spec` names lies, from chunks of `t` and its channel
/// (the edge detector's errors — a sample not finite, time not increasing — named with the
/// channel and the sample).
pub fn wheel_gap<I, R, E>(spec: &AngleSpec, chunks: I) -> Result<Gap, AppError>
where
    I: IntoIterator<Item = Result<R, E>>,
    R: Borrow<Recording>,
    AppError: From<E>,
{
    let (channel, wheel, edges) = wheel_of(spec)?;
    let mut detector = EdgeDetector::new(edges);
    let mut survey = GapSurvey::new(wheel, channel);
    for chunk in chunks {
        let chunk = chunk?;
        let c = chunk.borrow();
        detector.push(c.values("t")?, c.values(channel)?);
        detector.drain(|t, i| survey.push(t, i));
    }
    let rest = detector
        .finish()
        .map_err(|e| invalid(format!("'{channel}': {e}")))?;
    for (&t, &i) in rest.t.iter().zip(&rest.index) {
        survey.push(t, i);
    }
    survey.finish().map_err(|e| invalid(e.to_string()))
}

/// The wheel's angle at any time, from a reader of `t` and its channel running ahead as far as
/// the times asked for: the edges ([`EdgeDetector`]), their angles ([`ToothIndex`], the gap of
/// pass 1), the monotone cubic through them ([`Pchip`]). Holds a chunk and a few edges.
pub struct WheelAhead<A> {
    chunks: A,
    channel: String,
    /// `None` once the signal has ended.
    detector: Option<EdgeDetector>,
    index: ToothIndex,
    pchip: Pchip,
    report: Option<ToothReport>,
}

impl<A, R, E> WheelAhead<A>
where
    A: Iterator<Item = Result<R, E>>,
    R: Borrow<Recording>,
    AppError: From<E>,
{
    /// The wheel `spec` names, its gap `gap`, read from `chunks`.
    pub fn new(spec: &AngleSpec, gap: &Gap, chunks: A) -> Result<Self, AppError> {
        let (channel, _, edges) = wheel_of(spec)?;
        Ok(Self {
            chunks,
            channel: channel.to_string(),
            detector: Some(EdgeDetector::new(edges)),
            index: ToothIndex::new(gap, channel),
            pchip: Pchip::default(),
            report: None,
        })
    }

    /// The angle [rad] at the time `a` [s] (the times asked for increasing): NaN before the
    /// first edge and after the last.
    pub fn at(&mut self, a: f64) -> Result<f64, AppError> {
        loop {
            if let Some(v) = self.pchip.at(a) {
                return Ok(v);
            }
            if let Some((t, angle, _)) = self.index.pop() {
                self.pchip.push(t, angle);
            } else if self.report.is_some() {
                self.pchip.end();
            } else {
                self.read()?;
            }
        }
    }

    /// The next chunk of the signal, or its end (the report then).
    fn read(&mut self) -> Result<(), AppError> {
        let index = &mut self.index;
        let Some(detector) = self.detector.as_mut() else {
            return Ok(());
        };
        match self.chunks.next() {
            Some(chunk) => {
                let chunk = chunk?;
                let c = chunk.borrow();
                detector.push(c.values("t")?, c.values(&self.channel)?);
                detector.drain(|t, i| index.push(t, i));
            }
            None => {
                let channel = &self.channel;
                let rest = self
                    .detector
                    .take()
                    .map(EdgeDetector::finish)
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
                }
                self.report = Some(index.finish().map_err(|e| invalid(e.to_string()))?);
            }
        }
        Ok(())
    }

    /// Read the signal to its end: what the decoding found.
    pub fn finish(mut self) -> Result<ToothReport, AppError> {
        while self.report.is_none() {
            self.read()?;
        }
        Ok(self.report.take().unwrap_or_else(|| unreachable!()))
    }
}

/// Which of two revolutions fires, a sample at a time: the mean of a channel over the
/// revolution centred on each TDC a revolution apart (`offset + 2πk`: the samples whose angle
/// is in `[offset + 2πk − π, offset + 2πk + π)`, from the first whole one), the median over the
/// TDCs of each parity; the higher (lower with `:low`) fires. Holds two means per revolution.
#[derive(Debug, Clone)]
pub struct PhaseWindows {
    offset: f64,
    /// The first revolution not yet closed (from the first sample's angle), and the sum and
    /// count of the samples in it and in the next (they may share a sample at the border).
    k: Option<i64>,
    open: [(f64, usize); 2],
    /// The means of the closed revolutions, by the parity of `k`.
    means: [Vec<f64>; 2],
}

impl PhaseWindows {
    /// The TDCs `offset` [rad] after the sensor's reference, a revolution apart.
    pub fn new(offset: f64) -> Self {
        Self {
            offset,
            k: None,
            open: [(-0.0, 0); 2],
            means: [Vec::new(), Vec::new()],
        }
    }

    fn centre(&self, k: i64) -> f64 {
        self.offset + TAU * k as f64
    }

    /// The next sample: its angle `theta` [rad] (not decreasing) and the channel's value `p`.
    pub fn push(&mut self, theta: f64, p: f64) {
        let offset = self.offset;
        let mut k = *self
            .k
            .get_or_insert_with(|| ((theta + PI - offset) / TAU).ceil() as i64);
        // The revolutions this sample is past: their means (the samples in them, not NaN).
        while self.centre(k) + PI <= theta {
            let (sum, n) = self.open[0];
            if n > 0 {
                let mean = sum / n as f64;
                if mean.is_finite() {
                    self.means[k.rem_euclid(2) as usize].push(mean);
                }
            }
            self.open = [self.open[1], (-0.0, 0)];
            k += 1;
        }
        self.k = Some(k);
        for j in 0..2 {
            let angle = self.centre(k + j);
            if angle - PI <= theta && theta < angle + PI {
                let o = &mut self.open[j as usize];
                *o = (o.0 + p, o.1 + 1);
            }
        }
    }

    /// The firing parity (0: the TDCs `offset + 4πk`; 1: a revolution on) and how it was
    /// told, for a person; `from` is the channel as given (`NAME` or `NAME:low`).
    pub fn finish(mut self, from: &str, tdc_offset_deg: f64) -> Result<(i64, String), AppError> {
        let (name, low) = match from.strip_suffix(":low") {
            Some(n) => (n, true),
            None => (from, false),
        };
        if self.means[0].is_empty() || self.means[1].is_empty() {
            return Err(invalid(format!(
                "--phase-from {from}: the recording spans fewer than two whole revolutions around TDCs (with finite '{name}'), so which one fires cannot be told"
            )));
        }
        let level = |v: &mut Vec<f64>| {
            v.sort_unstable_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let (l0, l1) = (level(&mut self.means[0]), level(&mut self.means[1]));
        let parity = usize::from((l1 > l0) != low);
        let (fire, other) = if parity == 1 { (l1, l0) } else { (l0, l1) };
        Ok((
            parity as i64,
            format!(
                "the firing TDC {tdc_offset_deg:.3}° after the reference of {} revolutions ('{name}' {} there: mean {fire:.4e} over the revolution around it against {other:.4e} a revolution away, medians over the TDCs)",
                if parity == 1 { "odd" } else { "even" },
                if low { "lower" } else { "higher" }
            ),
        ))
    }
}

/// How the firing revolution is told without `--phase-from`, for a person.
pub fn no_phase(tdc_offset_deg: f64) -> String {
    format!("the TDC {tdc_offset_deg}° after the first reference taken as firing (no --phase-from)")
}

/// The firing TDC's angle [rad]: the first of parity `parity` (see [`PhaseWindows::finish`])
/// at or after the first sample's angle `theta0`.
pub fn firing_tdc(offset: f64, parity: i64, theta0: f64) -> f64 {
    let mut tdc = offset + TAU * parity as f64;
    tdc += 4.0 * PI * ((theta0 - tdc) / (4.0 * PI)).ceil();
    tdc
}

/// Pass 2: what decoding the wheel found and where the firing TDC lies — `angle` the chunks of
/// `t` and the wheel's channel, `samples` those of `t` (and the `--phase-from` channel): the
/// angle at every sample between the first and last edge.
pub fn wheel_decoded<A, S, R1, R2, E1, E2>(
    spec: &AngleSpec,
    gap: &Gap,
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
    let mut ahead = WheelAhead::new(spec, gap, angle.into_iter())?;
    let offset = spec.tdc_offset_deg.to_radians();
    let phase_name = spec
        .phase_from
        .as_deref()
        .map(|p| p.strip_suffix(":low").unwrap_or(p));
    let mut windows = PhaseWindows::new(offset);
    let (mut theta0, mut inside) = (None, 0usize);
    for chunk in samples {
        let chunk = chunk?;
        let c = chunk.borrow();
        let t = c.values("t")?;
        let p = match phase_name {
            Some(name) => Some(c.values(name)?),
            None => None,
        };
        for (i, &x) in t.iter().enumerate() {
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
    let (parity, phase) = match &spec.phase_from {
        None => (0, no_phase(spec.tdc_offset_deg)),
        Some(from) => windows.finish(from, spec.tdc_offset_deg)?,
    };
    let summary = format!(
        "wheel {} decoded: {} edges over {} revolutions, {:.0}–{:.0} rpm",
        report.wheel, report.edges, report.revolutions, report.rpm.0, report.rpm.1
    );
    Ok(DecodedAngle {
        tdc: firing_tdc(offset, parity, theta0),
        findings: report.findings.clone(),
        wheel: Some(report),
        encoder: None,
        summary,
        phase,
    })
}

/// What passes 1 and 2 found: where the gap is; what the decoding found, and where the firing
/// TDC lies.
#[derive(Debug, Clone)]
pub struct WheelFound {
    /// Where the gap is ([`wheel_gap`]).
    pub gap: Gap,
    /// What the decoding found, the firing TDC ([`wheel_decoded`]).
    pub decoded: DecodedAngle,
}

/// Pass 3: a time-basis stream (`header` its channels, `chunks` them) on one sample every
/// `step_deg` crank degrees ([`CrankAngleStream`]), the firing TDC where pass 2 placed it
/// (`found`), the angle at each chunk's samples from `angle` — a second reader of `t` and
/// the wheel's channel — read ahead of it ([`WheelAhead`]). Returns the crank-angle recording's
/// header (its channels, no samples) and its chunks.
pub fn wheel_crank_angle_chunks<'a, A, C, R1, R2, E1, E2>(
    spec: &AngleSpec,
    found: &WheelFound,
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
    let mut ahead = WheelAhead::new(spec, &found.gap, angle.into_iter())?;
    let mut chunks = chunks.into_iter();
    let (mut t_in, mut theta) = (Vec::new(), Vec::new());
    let mut done = false;
    let iter = std::iter::from_fn(move || {
        if done {
            return None;
        }
        let mut resample = |c: R2| -> Result<Recording, AppError> {
            let c = c.borrow();
            let t = c.values("t")?;
            t_in.clear();
            theta.clear();
            for &x in t {
                let a = ahead.at(x)?;
                if !a.is_nan() {
                    t_in.push(x);
                    theta.push(a);
                }
            }
            stream.push_angle(&t_in, &theta)?;
            Ok(stream.push_channels(c)?)
        };
        let next = match chunks.next() {
            Some(Ok(c)) => resample(c),
            Some(Err(e)) => Err(e.into()),
            None => {
                done = true;
                stream.finish().map_err(AppError::Acquisition)
            }
        };
        done |= next.is_err();
        Some(next)
    });
    Ok((out_header, iter))
}
