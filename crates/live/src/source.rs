//! Where the live service's chunks come from, and how fast.

use crate::control::Control;
use crate::service::LiveError;
use physid_apps::acquisition::{
    file_time_basis_chunks, from_first_marker_phased, mean_rate, on_time_basis, time_basis_chunks,
    uniform_step, AcquisitionOptions, PhaseFrom, StepCheck,
};
use physid_apps::angle_input::AngleInput;
use physid_apps::error::AppError;
use physid_core::{Basis, Channel, Recording};
use physid_io::{ChunkReader, ReadOptions, CHUNK_ROWS};
use physid_sim::run::{OutputBasis, Run, RunOptions};
use physid_sim::scenario::Scenario;
use std::path::Path;
use std::time::{Duration, Instant};

/// A source of chunks of samples on a uniform time basis.
pub trait Source {
    /// The sample rate [Hz].
    fn rate_hz(&self) -> f64;
    /// The next chunk (possibly empty), or `None` at the end. A
    /// [`LiveError::BadFrame`] refuses one chunk only: the stream goes on.
    fn next_chunk(&mut self) -> Result<Option<Recording>, LiveError>;
    /// Something about the last chunk worth telling (a gap), once.
    fn notice(&mut self) -> Option<String> {
        None
    }
    /// Apply a control message, or say why not.
    fn control(&mut self, c: &Control) -> Result<(), String> {
        Err(format!(
            "'{}': only the virtual test cell takes controls",
            c.name()
        ))
    }
}

/// The virtual test cell run as a stream ([`Run`] with [`RunOptions::stream`]): chunks of
/// `chunk_s` seconds of recording; memory flat however long it runs. Its inputs can change
/// between chunks ([`Source::control`]).
pub struct ScenarioSource {
    run: Option<Run>,
    rate_hz: f64,
    chunk_s: f64,
    t: f64,
    stop: bool,
}

impl ScenarioSource {
    /// `scenario` with `opts` (its basis must be a time basis), in chunks of `chunk_s` [s].
    pub fn new(scenario: &Scenario, opts: &RunOptions, chunk_s: f64) -> Result<Self, LiveError> {
        let OutputBasis::Time(rate_hz) = opts.basis else {
            return Err(LiveError::Invalid(
                "the live cell runs on a time basis".into(),
            ));
        };
        // At least a sample a chunk (a shorter one hands on empty chunks, a trillion of them a
        // second at 1e-12 s).
        if !(chunk_s.is_finite() && chunk_s * rate_hz >= 1.0) {
            return Err(LiveError::Invalid(format!(
                "chunk of {} s: expected at least one sample's time at {} Hz ({} s)",
                physid_core::Num(chunk_s),
                physid_core::Num(rate_hz),
                physid_core::Num(1.0 / rate_hz)
            )));
        }
        let opts = RunOptions {
            stream: true,
            ..opts.clone()
        };
        let run = Run::new(scenario, &opts)?;
        // A chunk is held whole (and a copy of it goes through the stages): it must fit.
        let chunk_bytes = 2.0 * chunk_s * run.size_bytes() / run.duration();
        physid_core::memory::check_fits(
            chunk_bytes,
            &format!("a chunk of {chunk_s:?} s at {rate_hz:?} Hz"),
        )
        .map_err(|e| {
            LiveError::Invalid(format!("{e}: a lower --sample-rate or a shorter --chunk"))
        })?;
        Ok(Self {
            run: Some(run),
            rate_hz,
            chunk_s,
            t: 0.0,
            stop: false,
        })
    }
}

impl Source for ScenarioSource {
    fn rate_hz(&self) -> f64 {
        self.rate_hz
    }

    fn control(&mut self, c: &Control) -> Result<(), String> {
        match (c, self.run.as_mut()) {
            (Control::Stop, _) => self.stop = true,
            (_, Some(run)) => c.apply(run)?,
            (_, None) => return Err("the run has ended".into()),
        }
        Ok(())
    }

    fn next_chunk(&mut self) -> Result<Option<Recording>, LiveError> {
        let Some(run) = self.run.as_mut() else {
            return Ok(None);
        };
        self.t += self.chunk_s;
        run.step_until(self.t)?;
        if run.is_done() || self.stop {
            let run = self
                .run
                .take()
                .ok_or_else(|| LiveError::Invalid("no run".into()))?;
            return Ok(Some(run.finish()?));
        }
        Ok(Some(run.drain()?))
    }
}

/// Chunks of a recording as they are read.
type Chunks = Box<dyn Iterator<Item = Result<Recording, AppError>> + Send>;

/// A recording replayed in chunks of `chunk_s` seconds: a file read as it comes (memory
/// does not grow with its length), or one in memory. A crank-angle recording is put on a time
/// basis at its mean rate first, as the file verbs do (a file: as it is read). The sample rate is the mean step
/// of the first chunk read (its first [`CHUNK_ROWS`] samples, whatever the source); every later
/// step is held to it.
pub struct ReplaySource {
    chunks: Chunks,
    /// Samples read and not yet handed out: `held[at..]`.
    held: Recording,
    at: usize,
    rate_hz: f64,
    chunk: usize,
    theta_tdc: f64,
    /// The step of the samples handed out, held to the first chunk's.
    steps: StepCheck,
    /// The reading failed (a damaged file): the error, returned once the samples read before
    /// it are handed out.
    failed: Option<LiveError>,
}

impl ReplaySource {
    /// `rec` in chunks of `chunk_s` seconds.
    pub fn new(rec: Recording, chunk_s: f64) -> Result<Self, LiveError> {
        let rec = match on_time_basis(&rec)? {
            Some(r) => r,
            None => rec,
        };
        let n = rec.len();
        let chunks = (0..n.max(1))
            .step_by(CHUNK_ROWS)
            .map(move |start| Ok(rec.slice(start..start + CHUNK_ROWS)));
        Self::from_chunks(Box::new(chunks), chunk_s, &AcquisitionOptions::default())
    }

    /// The file `path`, read as it comes with `opts`, in chunks of `chunk_s` seconds.
    pub fn open(path: &Path, opts: &ReadOptions, chunk_s: f64) -> Result<Self, LiveError> {
        Self::open_phased(path, opts, chunk_s, PhaseFrom::Pressure)
    }

    /// [`open`](Self::open), the firing revolution told from `phase_from` (by default `p_cyl`
    /// when the file has it, [`MarkerPhase`](physid_apps::acquisition::MarkerPhase)) when the
    /// TDC comes from a marker once per revolution.
    pub fn open_phased(
        path: &Path,
        opts: &ReadOptions,
        chunk_s: f64,
        phase_from: PhaseFrom,
    ) -> Result<Self, LiveError> {
        let acq = AcquisitionOptions {
            phase_from,
            ..AcquisitionOptions::default()
        };
        let reader = ChunkReader::open(path, opts)?;
        if reader.header().basis == Basis::CrankAngle {
            // At the mean rate of the whole recording, resampled as it is read, in the chunks
            // the recording put on a time basis whole would give.
            let header = reader.header().clone();
            let chunks = file_time_basis_chunks(path, opts, &header, reader)?;
            return Self::from_chunks(Box::new(chunks), chunk_s, &acq);
        }
        Self::from_chunks(
            Box::new(reader.map(|c| c.map_err(AppError::from))),
            chunk_s,
            &acq,
        )
    }

    /// A time-basis file whose engine angle `plan` decodes (an encoder's counts and marker, a
    /// raw trigger wheel or quadrature encoder), in chunks of `chunk_s` seconds: on a
    /// crank-angle basis as it is read (its `theta`, from the firing TDC, taken as `theta_en`;
    /// `cycle` and `crank_deg` left out), then back on a uniform time basis at its mean rate —
    /// a first decoding pass gives the rate ([`mean_rate`]), a second, in a thread a few chunks
    /// ahead, the samples. Memory does not grow with the file's length.
    pub fn open_angle(plan: AngleInput, chunk_s: f64) -> Result<Self, LiveError> {
        // The first pass: the crank-angle samples' count and time span (no other channel).
        let ((n, first, last), _) = plan.read(
            Some(&[]),
            |_| Ok((0usize, f64::NAN, f64::NAN)),
            |(n, first, last), c| {
                let t = c.values("t")?;
                if *n == 0 {
                    *first = t.first().copied().unwrap_or(f64::NAN);
                }
                *last = t.last().copied().unwrap_or(*last);
                *n += t.len();
                Ok(())
            },
        )?;
        let rate = mean_rate(n, first, last)?;
        let (tx, rx) = std::sync::mpsc::sync_channel::<Result<Recording, AppError>>(4);
        std::thread::Builder::new()
            .name("physid-angle".into())
            .spawn(move || {
                let send = |r: Result<Recording, AppError>| {
                    tx.send(r)
                        .map_err(|_| AppError::Invalid("the replay stopped reading".into()))
                };
                let read = plan.read_again(
                    None,
                    |h| send(on_engine_angle(h)),
                    |_, c| send(on_engine_angle(c)),
                );
                if let Err(e) = read {
                    // Nobody to tell if the replay has gone.
                    let _ = tx.send(Err(e));
                }
            })
            .map_err(|e| LiveError::Invalid(format!("starting the angle's decoding: {e}")))?;
        let header = rx
            .recv()
            .map_err(|_| LiveError::Invalid("the angle's decoding stopped".into()))??;
        let chunks = time_basis_chunks(&header, rx, rate, CHUNK_ROWS)?;
        Self::from_chunks(Box::new(chunks), chunk_s, &AcquisitionOptions::default())
    }

    fn from_chunks(
        chunks: Chunks,
        chunk_s: f64,
        acq: &AcquisitionOptions,
    ) -> Result<Self, LiveError> {
        if !(chunk_s.is_finite() && chunk_s > 0.0) {
            return Err(LiveError::Invalid(format!(
                "chunk of {chunk_s:?} s: expected > 0"
            )));
        }
        let (theta_tdc, _, chunks) = from_first_marker_phased(chunks, acq)?;
        let theta_tdc = theta_tdc.unwrap_or(0.0);
        let mut chunks: Chunks = Box::new(chunks);
        let first = chunks
            .next()
            .transpose()?
            .unwrap_or_else(|| Recording::new(Basis::Time));
        let rate_hz = 1.0 / uniform_step(first.values("t")?).map_err(AppError::from)?;
        Ok(Self {
            chunks,
            held: first,
            at: 0,
            chunk: ((chunk_s * rate_hz).round() as usize).max(1),
            rate_hz,
            theta_tdc,
            steps: StepCheck::new(1.0 / rate_hz),
            failed: None,
        })
    }

    /// The angle of a firing TDC on `theta_en` [rad]: its value at the recording's first TDC
    /// marker (`0` without one), where the stages start their cycles.
    pub fn theta_tdc(&self) -> f64 {
        self.theta_tdc
    }
}

impl Source for ReplaySource {
    fn rate_hz(&self) -> f64 {
        self.rate_hz
    }

    fn next_chunk(&mut self) -> Result<Option<Recording>, LiveError> {
        // Enough samples held for a chunk, or the end of the recording (or of what reads).
        while self.held.len() - self.at < self.chunk && self.failed.is_none() {
            let next = match self.chunks.next().transpose() {
                Ok(Some(next)) => next,
                Ok(None) => break,
                Err(e) => {
                    self.failed = Some(e.into());
                    break;
                }
            };
            let mut joined = Recording::new(self.held.basis);
            for ch in self.held.channels() {
                let mut values = ch.values[self.at..].to_vec();
                values.extend_from_slice(next.values(&ch.name)?);
                joined.push(Channel {
                    name: ch.name.clone(),
                    unit: ch.unit.clone(),
                    values,
                })?;
            }
            self.held = joined;
            self.at = 0;
        }
        let n = self.held.len();
        if self.at >= n {
            return self.failed.take().map_or(Ok(None), Err);
        }
        let end = (self.at + self.chunk).min(n);
        let c = self.held.slice(self.at..end);
        self.at = end;
        self.steps.check(c.values("t")?).map_err(AppError::from)?;
        Ok(Some(c))
    }
}

/// A crank-angle chunk's channels as the live stages take them: `theta` (the crank angle from
/// the firing TDC) as `theta_en` (unless the chunk has one), without `cycle` and `crank_deg`
/// (which do not interpolate on a time basis: they jump at every cycle).
fn on_engine_angle(c: &Recording) -> Result<Recording, AppError> {
    let has_theta_en = c.channel("theta_en").is_ok();
    let mut out = Recording::new(c.basis);
    out.meta = c.meta.clone();
    for ch in c.channels() {
        if ch.name == "cycle" || ch.name == "crank_deg" {
            continue;
        }
        let mut ch = ch.clone();
        if ch.name == "theta" && !has_theta_en {
            ch.name = "theta_en".into();
        }
        out.push(ch)?;
    }
    Ok(out)
}

/// The slowest pace: a thousandth of real time (a second of the cell in 17 minutes).
pub const MIN_PACE: f64 = 1e-3;
/// The fastest pace as a factor (beyond it, `max`).
pub const MAX_PACE: f64 = 1e6;

/// How fast a source runs against the wall clock.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Pace {
    /// As fast as it can.
    Max,
    /// This many seconds of recording per second of wall clock (1 = real time).
    Factor(f64),
}

impl std::str::FromStr for Pace {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        if s == "max" {
            return Ok(Pace::Max);
        }
        match s.parse::<f64>() {
            Ok(f) if (MIN_PACE..=MAX_PACE).contains(&f) => Ok(Pace::Factor(f)),
            _ => Err(format!(
                "'{s}': expected max or a factor from {MIN_PACE} to {MAX_PACE:e} (1 = real time)"
            )),
        }
    }
}

impl std::fmt::Display for Pace {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Pace::Max => f.write_str("max"),
            Pace::Factor(x) => write!(f, "{x}"),
        }
    }
}

/// Keeps a run at its pace: [`wait_until`](Self::wait_until) sleeps until the wall clock has
/// caught up with a recording time.
#[derive(Debug)]
pub struct Pacer {
    pace: Pace,
    start: Option<(Instant, f64)>,
}

impl Pacer {
    /// A pacer at `pace`.
    pub fn new(pace: Pace) -> Self {
        Self { pace, start: None }
    }

    /// Sleep until recording time `t_s` is due (the first call sets the origin).
    pub fn wait_until(&mut self, t_s: f64) {
        if let Some(left) = self.left_until(t_s) {
            std::thread::sleep(left);
        }
    }

    /// How long until recording time `t_s` is due (the first call sets the origin); `None`:
    /// it is due now (or the pace is `max`). For a caller that waits in its own way (a NATS
    /// publisher waits inside its client's event loop).
    pub fn left_until(&mut self, t_s: f64) -> Option<Duration> {
        let Pace::Factor(f) = self.pace else {
            return None;
        };
        let (wall0, t0) = *self.start.get_or_insert((Instant::now(), t_s));
        // Saturated: a time of 10³⁰⁰ s (a replayed file's bad clock) is never due, not a panic.
        let due = Duration::try_from_secs_f64(((t_s - t0) / f).max(0.0)).unwrap_or(Duration::MAX);
        due.checked_sub(wall0.elapsed())
    }

    /// Move the origin later by `d` (a pause): the run goes on from where it was, not racing to
    /// catch up.
    pub fn shift(&mut self, d: Duration) {
        if let Some((wall0, _)) = self.start.as_mut() {
            *wall0 += d;
        }
    }

    /// How long ago recording time `t_s` was due on the wall clock [s] (negative: still ahead);
    /// `None` at `--pace max` or before the first chunk.
    pub fn since_due(&self, t_s: f64) -> Option<f64> {
        let (Pace::Factor(f), Some((wall0, t0))) = (self.pace, self.start) else {
            return None;
        };
        Some(wall0.elapsed().as_secs_f64() - (t_s - t0) / f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pace_parses() {
        assert_eq!("max".parse::<Pace>(), Ok(Pace::Max));
        assert_eq!("10".parse::<Pace>(), Ok(Pace::Factor(10.0)));
        assert!("0".parse::<Pace>().is_err() && "fast".parse::<Pace>().is_err());
        // 1e-300 panicked converting a chunk's due time into a Duration.
        for bad in ["1e-300", "1e-4", "1e7", "inf", "nan"] {
            let e = bad.parse::<Pace>().unwrap_err();
            assert!(e.contains("a factor from 0.001 to 1e6"), "{bad}: {e}");
        }
        assert_eq!("0.001".parse::<Pace>(), Ok(Pace::Factor(1e-3)));
        // A due time past what a Duration holds is never due (not a panic).
        let mut p = Pacer::new(Pace::Factor(1e-3));
        assert_eq!(p.left_until(0.0), None);
        let far = p.left_until(1e300);
        assert!(
            far.is_some_and(|d| d > Duration::from_secs(1 << 60)),
            "{far:?}"
        );
    }

    /// The virtual cell's chunk holds a sample at least (a chunk of 1e-12 s handed on empty
    /// chunks for ever), and fits in memory (1e12 Hz used to end in the allocator's abort).
    #[test]
    fn a_cell_chunk_shorter_than_a_sample_or_too_large_to_hold_is_refused() {
        use physid_sim::run::{OutputBasis, RunOptions};
        use physid_sim::scenario::named;
        let scenario = named("shaft-steady").unwrap();
        let at = |rate: f64| RunOptions {
            duration: Some(1.0),
            basis: OutputBasis::Time(rate),
            ..Default::default()
        };
        let e = ScenarioSource::new(&scenario, &at(10_000.0), 1e-12)
            .err()
            .unwrap()
            .to_string();
        assert!(
            e.contains("expected at least one sample's time at 10000 Hz (0.0001 s)"),
            "{e}"
        );
        if physid_core::memory::available().is_some() {
            let e = ScenarioSource::new(&scenario, &at(1e12), 0.01)
                .err()
                .unwrap()
                .to_string();
            assert!(
                e.starts_with("a chunk of 0.01 s at 1000000000000.0 Hz would take about")
                    && e.ends_with("a lower --sample-rate or a shorter --chunk"),
                "{e}"
            );
        }
        assert!(ScenarioSource::new(&scenario, &at(10_000.0), 1e-4).is_ok());
    }
}
