//! Zero-phase Butterworth filtering of chosen channels, whole and on the stream.

use super::*;

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
    steps: StepCheck,
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
            steps: StepCheck::new(dt),
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
        s.steps.check(chunk.values("t")?)?;
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
