//! From a crank basis back to a uniform time basis, and the uniform-step check.

use super::*;

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
