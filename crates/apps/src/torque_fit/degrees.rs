//! The 1° samples made again on every pass ([`Degrees`]): a crank-angle file's rows, or a
//! time-basis file resampled from its first TDC marker ([`DegreeCurves`], as the live stage).

use super::*;

/// A time-basis stream resampled to one sample per crank degree, cycles from a TDC angle on
/// `theta_en` (linear between samples, [`CycleStream`]'s crank-angle curves): what the live
/// stage and every pass of the file verb over a time-basis recording run.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(super) struct DegreeCurves {
    pub(super) theta_tdc: f64,
    pub(super) curves: Option<CycleStream>,
    done: Vec<CycleSummary>,
}

impl DegreeCurves {
    pub(super) fn new(theta_tdc: f64) -> Self {
        Self {
            theta_tdc,
            curves: None,
            done: Vec::new(),
        }
    }

    /// A chunk of time-basis samples with `t`, `theta_en` and [`CURVE_CHANNELS`]: every cycle
    /// it completes resampled, `each(u, y, t)` for each degree — the inputs in [`CyclicTorque`]'s
    /// order (θ [rad from the first TDC], ω, α, p_cyl, p_crank, T_oil [°C]), the measured torque
    /// [N·m], the time [s]. A dropout (a channel or the angle not a number) is left out with
    /// the cycle it cuts ([`CycleStream::push_past_dropouts`]; the chunk's: [`dropouts`](Self::dropouts)).
    pub(super) fn push<E: From<AppError>>(
        &mut self,
        chunk: &Recording,
        each: &mut EachDegree<'_, E>,
    ) -> Result<(), E> {
        if chunk.is_empty() {
            return Ok(());
        }
        let invalid = |e: String| E::from(AppError::Invalid(e));
        if self.curves.is_none() {
            for (name, _) in CURVE_CHANNELS {
                chunk.channel(name).map_err(AppError::from)?;
            }
            chunk.channel("theta_en").map_err(AppError::from)?;
            self.curves = Some(
                CycleStream::new(CURVE_CHANNELS.len(), self.theta_tdc, Some(1.0))
                    .map_err(|e| invalid(e.to_string()))?,
            );
        }
        let cols = CURVE_CHANNELS
            .iter()
            .map(|(name, unit)| chunk.values_in(name, unit))
            .collect::<Result<Vec<_>, _>>()
            .map_err(AppError::from)?;
        let views: Vec<&[f64]> = cols.iter().map(|c| c.as_slice()).collect();
        let theta = chunk.values_in("theta_en", "rad").map_err(AppError::from)?;
        let t = chunk.values("t").map_err(AppError::from)?;
        self.done.clear();
        if let Some(c) = self.curves.as_mut() {
            c.push_past_dropouts(t, &theta, &views, &mut self.done)
                .map_err(|e| invalid(e.to_string()))?;
        }
        let step = (1.0f64).to_radians();
        let mut u = [0.0; 6];
        for c in &self.done {
            let Some(curve) = &c.curve else { continue };
            for (k, (&y, &t)) in curve[5].iter().zip(&curve[6]).enumerate() {
                // θ from the first TDC in the stream, as the crank-angle conversion writes it.
                u[0] = c.cycle as f64 * 4.0 * PI + k as f64 * step;
                for (uj, col) in u[1..5].iter_mut().zip(curve) {
                    *uj = col[k];
                }
                u[5] = curve[4][k] - 273.15;
                each(&u, y, t)?;
            }
        }
        Ok(())
    }
}

impl DegreeCurves {
    /// The dropouts the last chunk began.
    pub(super) fn dropouts(&self) -> impl Iterator<Item = Dropout> + '_ {
        let names = CURVE_CHANNELS.map(|(name, _)| name);
        self.curves
            .iter()
            .flat_map(|c| c.dropouts())
            .map(move |d| Dropout::of_cycles(d, &names, 0))
    }
}

/// How a [`Degrees`] makes its 1° samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Angle {
    /// The recording is on a crank-angle basis: its rows are the samples.
    Crank,
    /// A time basis with `theta_en`: resampled on every pass ([`DegreeCurves`]) from the
    /// first TDC marker (found by a first pass).
    Time,
}

/// A recording's 1° samples as [`Rows`] — made again on every pass from the recording's
/// channels ([`RecordingRows`]: a file read again a chunk at a time, or its channels held after
/// the first pass within a limit): a crank-angle recording's rows, or a time-basis one's
/// resampled from its first TDC marker. The cyclic-torque model's analyses, batch fit, filter
/// and prediction each go over them in passes, so the fit keeps memory independent of the
/// recording's length.
pub struct Degrees<'a> {
    rows: DegreeSource<'a>,
    angle: Angle,
    /// The TDC angle on `theta_en` (time basis), once found.
    tdc: Cell<Option<f64>>,
    /// Samples in a pass, once one has been made.
    len: Cell<Option<usize>>,
    /// The dropouts the first pass left out, each with the cycle it cuts.
    dropouts: RefCell<Vec<Dropout>>,
}

impl<'a> Degrees<'a> {
    /// The 1° samples of the file `path` read with `options` (its channel selection replaced by
    /// the fit's channels), the channels held after the first pass within `hold_bytes`. A
    /// time-basis file needs `theta_en` (one whose angle is an encoder's counts: [`Degrees::crank`]
    /// over its crank-angle samples made as it is read).
    pub fn file(path: &Path, options: &ReadOptions, hold_bytes: usize) -> Result<Self, AppError> {
        let header = ChunkReader::open(path, options)?.header().clone();
        let (angle, needed, also) = Self::channels(&header)?;
        let rows = RecordingRows::file(
            path,
            options,
            needed.iter().map(|c| Column::named(c)).collect(),
            None,
            &also,
            hold_bytes,
        )?;
        Ok(Self::over(rows, angle))
    }

    /// The 1° samples of a recording in memory.
    pub fn memory(rec: &'a Recording) -> Result<Self, AppError> {
        let (angle, _, _) = Self::channels(rec)?;
        Ok(Self::over(
            RecordingRows::memory(rec, Vec::new(), None),
            angle,
        ))
    }

    /// The 1° samples of a crank-angle recording made again on every pass (a time-basis file
    /// whose angle is an encoder's counts, resampled as it is read: the CLI's `CrankFile`).
    pub fn crank(source: &'a dyn Reopen<Recordings, AppError>) -> Self {
        Self {
            rows: DegreeSource::Passes(source),
            angle: Angle::Crank,
            tdc: Cell::new(None),
            len: Cell::new(None),
            dropouts: RefCell::default(),
        }
    }

    /// How the samples are made from a recording with `header`'s channels, and the channels
    /// read: needed, and taken when there.
    pub(super) fn channels(header: &Recording) -> Result<(Angle, Vec<&str>, Vec<&str>), AppError> {
        match header.basis {
            Basis::CrankAngle => Ok((Angle::Crank, crank_channels(header), Vec::new())),
            Basis::Time if header.channel("theta_en").is_ok() => {
                let (needed, also) = sample_channels();
                Ok((Angle::Time, needed, also))
            }
            Basis::Time => Err(AppError::Invalid(
                "a time-basis recording without 'theta_en': its crank-angle samples are made from the encoder's counts as it is read (`physid torque fit` does), or convert it with `physid convert --crank-angle` first".into(),
            )),
        }
    }

    pub(super) fn over(rows: RecordingRows<'a>, angle: Angle) -> Self {
        Self {
            rows: DegreeSource::Rows(rows),
            angle,
            tdc: Cell::new(None),
            len: Cell::new(None),
            dropouts: RefCell::default(),
        }
    }

    /// What the reader noticed but read all the same (a cut-short last line), once the file
    /// has been read to its end.
    pub fn warning(&self) -> Option<String> {
        self.rows.warning()
    }

    /// Whether the channels are held (after a first pass, within the limit).
    pub fn held(&self) -> bool {
        self.rows.held()
    }

    /// The number of 1° samples (a pass, the first time).
    pub fn len(&self) -> Result<usize, AppError> {
        if let Some(n) = self.len.get() {
            return Ok(n);
        }
        self.samples::<AppError>(&mut |_| Ok(()))?;
        Ok(self.len.get().unwrap_or(0))
    }

    /// The samples that are not a number (a sensor's dropout), each left out with the cycle it
    /// cuts (a pass, the first time).
    pub fn dropouts(&self) -> Result<Vec<Dropout>, AppError> {
        self.len()?;
        Ok(self.dropouts.borrow().clone())
    }

    /// Whether there are no 1° samples.
    pub fn is_empty(&self) -> Result<bool, AppError> {
        Ok(self.len()? == 0)
    }

    /// The firing TDC's angle on `theta_en` at the first marker (0 without one) — or a
    /// revolution on, as the cylinder pressure tells when the recording has `p_cyl`
    /// ([`PhaseFrom::Pressure`], what a stream and `convert --crank-angle` do by default) —
    /// found by a pass the first time: the rule of
    /// [`from_first_marker_phased`](crate::acquisition::from_first_marker_phased).
    pub(super) fn tdc(&self) -> Result<f64, AppError> {
        if let Some(t) = self.tdc.get() {
            return Ok(t);
        }
        let mut scan = FirstMarker::default();
        let mut found = None;
        // Which revolution fires, resolved on the first chunk's channels.
        let mut phase: Option<Option<(MarkerPhase, bool)>> = None;
        self.rows.chunks::<AppError>(&mut |chunk| {
            if found.is_none() {
                found = scan.scan(chunk, TDC_MARKER);
            }
            let told = phase.get_or_insert_with(|| {
                PhaseFrom::Pressure
                    .resolve(|n| chunk.channel(n).is_ok())
                    .map(|(from, implied)| (MarkerPhase::new(from), implied))
            });
            if let Some((p, _)) = told.as_mut().filter(|(p, _)| !p.done()) {
                let channel = chunk.values(p.channel())?;
                for (&th, &v) in chunk.values("theta_en")?.iter().zip(channel) {
                    p.push(th, v);
                }
                // Without a marker, from 0 (as below): nothing is held for one to come.
                if let Some(a) = found {
                    p.marker_at(a.unwrap_or(0.0));
                }
            }
            Ok(())
        })?;
        let first = found.flatten().unwrap_or(0.0);
        let t = match phase.flatten() {
            Some((mut p, implied)) => {
                p.marker_at(first);
                let guess = (first, first_guess(found.flatten().is_some()));
                told_or_first(p.finish(), implied, || guess)?.0
            }
            None => first,
        };
        self.tdc.set(Some(t));
        Ok(t)
    }

    /// Go over every 1° sample once, in chunks of columns ([`TorqueData`], at most
    /// [`FILE_CHUNK`] samples from a time basis, [`CHUNK_ROWS`] from a crank-angle basis); an
    /// error of `visit` ends the pass and is returned. A pass that makes a different number of
    /// samples than the first is an error (the file changed).
    pub fn samples<E>(&self, visit: &mut dyn FnMut(&TorqueData) -> Result<(), E>) -> Result<(), E>
    where
        E: From<AppError> + From<IdentError>,
    {
        let mut n = 0;
        let mut log = DropoutLog::default();
        match self.angle {
            Angle::Crank => {
                // Whole cycles (720 rows from the first, as the filter counts them) go to
                // `visit`: one with a sample that is not a number is left out.
                let mut buf = TorqueData::with_capacity(FILE_CHUNK + PER_CYCLE);
                let (mut start, mut whole) = (0, true);
                self.rows.chunks::<E>(&mut |chunk| {
                    in_pieces(chunk, &mut |piece| {
                        let data = TorqueData::columns(piece)?;
                        log.see(&data.named(), &data.t);
                        // The piece in runs that end where a cycle does, or at its end.
                        let mut i = 0;
                        while i < data.y.len() {
                            let j = (i + PER_CYCLE - (buf.y.len() - start)).min(data.y.len());
                            whole &= data.finite(i..j);
                            buf.extend_from(&data, i..j);
                            i = j;
                            if buf.y.len() - start < PER_CYCLE {
                                continue;
                            }
                            if !whole {
                                buf.truncate(start);
                            }
                            (start, whole) = (buf.y.len(), true);
                            if start >= FILE_CHUNK {
                                n += start;
                                visit(&buf)?;
                                buf.clear();
                                start = 0;
                            }
                        }
                        Ok(())
                    })
                })?;
                // The last cycle, cut short by the recording's end.
                if !whole {
                    buf.truncate(start);
                }
                if !buf.y.is_empty() {
                    n += buf.y.len();
                    visit(&buf)?;
                }
            }
            Angle::Time => {
                let mut curves = DegreeCurves::new(self.tdc()?);
                let mut buf = TorqueData::with_capacity(FILE_CHUNK);
                self.rows.chunks::<E>(&mut |chunk| {
                    in_pieces(chunk, &mut |piece| {
                        curves.push::<E>(piece, &mut |u, y, t| {
                            buf.push(u, y, t);
                            if buf.y.len() == FILE_CHUNK {
                                n += buf.y.len();
                                visit(&buf)?;
                                buf.clear();
                            }
                            Ok(())
                        })?;
                        log.found.extend(curves.dropouts());
                        Ok(())
                    })
                })?;
                if !buf.y.is_empty() {
                    n += buf.y.len();
                    visit(&buf)?;
                }
            }
        }
        match self.len.get() {
            None => {
                self.len.set(Some(n));
                self.dropouts.replace(log.found);
            }
            Some(m) if m != n => {
                return Err(E::from(AppError::Invalid(format!(
                    "the recording gave {n} samples at one per crank degree on a later pass, {m} on the first: was the file changed while it was read?"
                ))))
            }
            Some(_) => {}
        }
        Ok(())
    }
}

/// Where a [`Degrees`] reads its recording on each pass.
pub(super) enum DegreeSource<'a> {
    /// The channels of a file or a recording in memory ([`RecordingRows`]).
    Rows(RecordingRows<'a>),
    /// A crank-angle recording made again on every pass.
    Passes(&'a dyn Reopen<Recordings, AppError>),
}

impl DegreeSource<'_> {
    /// `visit` every chunk in order; an error of `visit` ends the pass and is returned.
    pub(super) fn chunks<E: From<IdentError> + From<AppError>>(
        &self,
        visit: &mut dyn FnMut(&Recording) -> Result<(), E>,
    ) -> Result<(), E> {
        match self {
            Self::Rows(rows) => rows.chunks(visit),
            Self::Passes(source) => {
                // `visit`'s error comes back as it is; the source's as an application error.
                let mut failed = None;
                let read = source.pass(&mut |chunk| {
                    visit(chunk).map_err(|e| {
                        failed = Some(e);
                        AppError::Invalid(String::new())
                    })
                });
                match (read, failed) {
                    (Ok(()), _) => Ok(()),
                    (Err(_), Some(e)) => Err(e),
                    (Err(e), None) => Err(E::from(e)),
                }
            }
        }
    }

    pub(super) fn warning(&self) -> Option<String> {
        match self {
            Self::Rows(rows) => rows.warning(),
            Self::Passes(_) => None,
        }
    }

    pub(super) fn held(&self) -> bool {
        match self {
            Self::Rows(rows) => rows.held(),
            Self::Passes(_) => false,
        }
    }
}

/// `each` piece of at most [`CHUNK_ROWS`] rows of `chunk` in order: the channels held whole
/// are converted a reader chunk's worth at a time, not copied whole.
pub(super) fn in_pieces<E>(
    chunk: &Recording,
    each: &mut dyn FnMut(&Recording) -> Result<(), E>,
) -> Result<(), E> {
    if chunk.len() <= CHUNK_ROWS {
        return each(chunk);
    }
    for start in (0..chunk.len()).step_by(CHUNK_ROWS) {
        each(&chunk.slice(start..start + CHUNK_ROWS))?;
    }
    Ok(())
}

impl Rows for Degrees<'_> {}

impl Reopen<DataRows, IdentError> for Degrees<'_> {
    fn pass(
        &self,
        visit: &mut dyn for<'c> FnMut(&'c Data<'c>) -> Result<(), IdentError>,
    ) -> Result<(), IdentError> {
        self.samples::<IdentError>(&mut |d| visit(&d.view()))
    }
}

/// An application's error met while a [`Rows`] source makes its rows: a reading error as
/// [`IdentError::Read`] (it names its file), an analysis' as itself, another explained.
impl From<AppError> for IdentError {
    fn from(e: AppError) -> Self {
        match e {
            AppError::Ident(e) => e,
            AppError::Io(e) => IdentError::Read(e.to_string()),
            e => IdentError::Invalid(e.to_string()),
        }
    }
}
