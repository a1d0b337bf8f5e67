//! Where the live service's chunks come from, and how fast.

use crate::control::Control;
use crate::service::LiveError;
use physid_apps::acquisition::uniform_step;
use physid_apps::shaft_monitor::on_time_basis;
use physid_core::Recording;
use physid_sim::run::{OutputBasis, Run, RunOptions};
use physid_sim::scenario::Scenario;
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
        if !(chunk_s.is_finite() && chunk_s > 0.0) {
            return Err(LiveError::Invalid(format!(
                "chunk of {chunk_s} s: expected > 0"
            )));
        }
        let opts = RunOptions {
            stream: true,
            ..opts.clone()
        };
        Ok(Self {
            run: Some(Run::new(scenario, &opts)?),
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
            (_, Some(run)) => c.apply(run),
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

/// A recording replayed in chunks of `chunk` samples (a crank-angle recording put on a time
/// basis first, as the file verbs do).
pub struct ReplaySource {
    rec: Recording,
    rate_hz: f64,
    chunk: usize,
    next: usize,
}

impl ReplaySource {
    /// `rec` in chunks of `chunk_s` seconds.
    pub fn new(rec: Recording, chunk_s: f64) -> Result<Self, LiveError> {
        let rec = match on_time_basis(&rec)? {
            Some(r) => r,
            None => rec,
        };
        let rate_hz =
            1.0 / uniform_step(rec.values("t")?).map_err(physid_apps::error::AppError::from)?;
        if !(chunk_s.is_finite() && chunk_s > 0.0) {
            return Err(LiveError::Invalid(format!(
                "chunk of {chunk_s} s: expected > 0"
            )));
        }
        Ok(Self {
            chunk: ((chunk_s * rate_hz).round() as usize).max(1),
            rec,
            rate_hz,
            next: 0,
        })
    }
}

impl Source for ReplaySource {
    fn rate_hz(&self) -> f64 {
        self.rate_hz
    }

    fn next_chunk(&mut self) -> Result<Option<Recording>, LiveError> {
        let n = self.rec.len();
        if self.next >= n {
            return Ok(None);
        }
        let end = (self.next + self.chunk).min(n);
        let c = self.rec.slice(self.next..end);
        self.next = end;
        Ok(Some(c))
    }
}

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
            Ok(f) if f.is_finite() && f > 0.0 => Ok(Pace::Factor(f)),
            _ => Err(format!(
                "'{s}': expected max or a factor > 0 (1 = real time)"
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
        let Pace::Factor(f) = self.pace else { return };
        let (wall0, t0) = *self.start.get_or_insert((Instant::now(), t_s));
        let due = Duration::from_secs_f64(((t_s - t0) / f).max(0.0));
        if let Some(left) = due.checked_sub(wall0.elapsed()) {
            std::thread::sleep(left);
        }
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
    }
}
