//! From a crank basis back to a uniform time basis, and the uniform-step check.

use super::*;

/// The sample period [s] of a time channel that must be uniform: the mean step, or an error at
/// the first step that goes back or repeats a time, else at the first step further than
/// [`step_tolerance`] (0.1 %, or stamps rounded to the microsecond) from the median step (what
/// to do about it included). The median, not the mean, is the
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
        .position(|w| ((w[1] - w[0]) - median).abs() > step_tolerance(median))
    {
        Some(i) => Err(AcquisitionError::Invalid(format!(
            "the time step is not uniform at sample {} ({} s, {median} s elsewhere): {fix}",
            i + 1,
            t[i + 1] - t[i]
        ))),
        None => Ok(dt),
    }
}

/// Time stamps rounded to this [s] (a DAQ's export to the microsecond) are a uniform clock's.
pub const STAMP_QUANTUM_S: f64 = 1e-6;

/// How far a step may be from the period `dt` and the clock still count as uniform: 0.1 % of
/// it, or — for stamps rounded to [`STAMP_QUANTUM_S`] (steps of 13 and 14 µs at 72 kHz) — the
/// quantum, as long as that is under a quarter of the period (so a dropped sample, a whole
/// period, is never taken for rounding).
pub fn step_tolerance(dt: f64) -> f64 {
    (1e-3 * dt).max((STAMP_QUANTUM_S * 1.001).min(0.25 * dt))
}

/// The uniform-step check of a stream ([`uniform_step`]'s, a chunk at a time): every step of
/// `t`, across chunk boundaries too, within [`step_tolerance`] of the period `dt` taken from
/// the first samples (their mean step) — an error at the first that is not, with its sample
/// index from the stream's start.
#[derive(Debug, Clone)]
pub struct StepCheck {
    dt: f64,
    t_prev: Option<f64>,
    seen: usize,
}

impl StepCheck {
    /// Steps of `dt` [s].
    pub fn new(dt: f64) -> Self {
        Self {
            dt,
            t_prev: None,
            seen: 0,
        }
    }

    /// The sample period [s] the steps are held to.
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// The next chunk's times.
    pub fn check(&mut self, t: &[f64]) -> Result<(), AcquisitionError> {
        for (i, &now) in t.iter().enumerate() {
            if let Some(before) = self.t_prev.replace(now) {
                if ((now - before) - self.dt).abs() > step_tolerance(self.dt) {
                    return Err(AcquisitionError::Invalid(format!(
                        "the time step is not uniform at sample {} ({} s, mean {} s): check with physid inspect, resample with physid convert --time-basis HZ",
                        self.seen + i,
                        now - before,
                        self.dt
                    )));
                }
            }
        }
        self.seen += t.len();
        Ok(())
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

/// A crank-angle recording (one sample per crank step, so its time step follows the speed) on
/// a uniform time basis at its mean sample rate ([`mean_rate`]), as the monitor takes it;
/// `None` for a recording already on a time basis.
pub fn on_time_basis(rec: &Recording) -> Result<Option<Recording>, AppError> {
    if rec.basis != Basis::CrankAngle {
        return Ok(None);
    }
    let t = rec.values("t")?;
    let rate = mean_rate(
        t.len(),
        t.first().copied().unwrap_or(f64::NAN),
        t.last().copied().unwrap_or(f64::NAN),
    )?;
    Ok(Some(to_time_basis(rec, rate)?))
}

/// The mean sample rate [Hz] of a crank-angle recording's `n` samples of `t`, from `first` to
/// `last`: `(n − 1)/(last − first)` — what [`on_time_basis`] puts it on, and what a stream
/// takes from a first pass over `t` alone.
pub fn mean_rate(n: usize, first: f64, last: f64) -> Result<f64, AppError> {
    let span = last - first;
    if n < 2 || span.is_nan() || span <= 0.0 {
        return Err(AppError::Invalid(
            "a crank-angle recording whose time 't' does not advance cannot be put on a time basis"
                .into(),
        ));
    }
    Ok((n - 1) as f64 / span)
}

/// The mean sample rate ([`mean_rate`]) of the crank-angle file `path`, read with `opts`: a
/// pass over its `t` alone (and `anchor`, another of its channels — an MDF4 file finds `t`'s
/// channel group by it).
pub fn file_mean_rate(
    path: &std::path::Path,
    opts: &physid_io::ReadOptions,
    anchor: &str,
) -> Result<f64, AppError> {
    let opts = physid_io::ReadOptions {
        channels: Some(vec!["t".into(), anchor.into()]),
        ..opts.clone()
    };
    let (mut n, mut first, mut last) = (0, f64::NAN, f64::NAN);
    for chunk in physid_io::ChunkReader::open(path, &opts)? {
        let chunk = chunk?;
        let t = chunk.values("t")?;
        if n == 0 {
            first = t.first().copied().unwrap_or(f64::NAN);
        }
        last = t.last().copied().unwrap_or(last);
        n += t.len();
    }
    mean_rate(n, first, last)
}

/// A crank-angle file `path` (read with `opts`; `header` its reader's channels, `chunks` its
/// chunks as they are read) on a uniform time basis at its mean sample rate, in chunks of
/// [`physid_io::CHUNK_ROWS`]: the rate from a first pass over `t` alone ([`file_mean_rate`],
/// anchored on the header's first other channel), then [`time_basis_chunks`] as it is read —
/// the chunks [`on_time_basis`] on the whole recording would give.
pub fn file_time_basis_chunks<'a, I, E>(
    path: &std::path::Path,
    opts: &physid_io::ReadOptions,
    header: &Recording,
    chunks: I,
) -> Result<impl Iterator<Item = Result<Recording, AppError>> + 'a, AppError>
where
    I: IntoIterator<Item = Result<Recording, E>> + 'a,
    I::IntoIter: 'a,
    E: 'a,
    AppError: From<E>,
{
    let anchor = header
        .names()
        .into_iter()
        .find(|n| *n != "t")
        .unwrap_or("t")
        .to_string();
    let rate = file_mean_rate(path, opts, &anchor)?;
    time_basis_chunks(header, chunks, rate, physid_io::CHUNK_ROWS)
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
pub(super) fn assemble<'a>(
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
