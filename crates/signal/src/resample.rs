//! Resampling on a stream (thesis §4, SPEC §2.7): a time-basis recording to one sample per
//! crank step ([`CrankResampler`]) and a crank-angle recording to a uniform time basis
//! ([`TimeResampler`]), a chunk at a time, equal bit for bit to the whole-record
//! [`crank_grid`](crate::crank::crank_grid) + [`interp`](crate::crank::interp) however the
//! recording is chunked. What they hold: the last two samples and the grid points not yet
//! bracketed (fewer than a chunk's) — no allocation per sample once the buffers have grown.

use crate::crank::{cycle_position, CrankError};
use std::collections::VecDeque;

/// Where a refused grid comes from an angle that jumps more than two revolutions
/// ([`MAX_ADVANCE`](crate::cycles::MAX_ADVANCE)) between two samples — a channel in degrees or
/// counts read as radians, or scaled by mistake — the largest such jump, named by its samples
/// (`seen` is the index of `theta[0]`, `before` the angle of the sample before it): when the
/// grid would fit with no sample advancing more than that (`fits` of its points), the jumps
/// are what asks for it.
fn largest_advance(
    before: Option<f64>,
    theta: &[f64],
    seen: usize,
    step: f64,
    fits: impl FnOnce(f64) -> bool,
) -> Option<String> {
    use crate::cycles::MAX_ADVANCE;
    // Pair `i` ends at `theta[i]` after the sample before, at `theta[i + 1]` without it.
    let prev = before.into_iter().chain(theta.iter().copied());
    let advances = prev
        .zip(theta.iter().copied().skip(usize::from(before.is_none())))
        .map(|(a, b)| b - a);
    let capped: f64 = advances.clone().map(|d| d.min(MAX_ADVANCE)).sum();
    let (i, d) =
        advances.enumerate().fold(
            (0, f64::NEG_INFINITY),
            |m, (i, d)| if d > m.1 { (i, d) } else { m },
        );
    let index = seen + i + usize::from(before.is_none());
    (d > MAX_ADVANCE && fits(capped / step + 1.0)).then(|| {
        format!(
            "the crank angle advances {} rad ({} revolutions) from sample {} to sample {}: is it \
             in radians, and of the right scale?",
            physid_core::Num(d),
            physid_core::Num((d / std::f64::consts::TAU).round()),
            index - 1,
            index
        )
    })
}

/// Linear interpolation of `y(x)` at increasing points, the data coming a chunk at a time:
/// what [`interp`](crate::crank::interp) gives on the whole data — `y[0]` at or before the
/// first `x`, `y[n−1]` at or after the last, between them `y[j] + f·(y[j+1] − y[j])` on the
/// first pair with `x[j] < a ≤ x[j+1]`. A point at or beyond the chunk's last `x` waits for
/// the next chunk (or [`finish`](Self::finish)): only then is it known whether that sample is
/// the last.
#[derive(Debug, Clone)]
pub struct StreamInterp {
    /// The data's name in errors ("the crank angle", "time").
    what: &'static str,
    /// The last two samples seen (x, then the ys), older first.
    tail: [(f64, Vec<f64>); 2],
    /// How many of `tail` hold samples (0, 1, 2).
    held: usize,
    /// Samples seen so far (for errors).
    seen: usize,
    /// Points not answered yet, increasing.
    pending: VecDeque<f64>,
}

impl StreamInterp {
    /// An interpolator of `width` channels over the abscissa `what` (must increase strictly).
    pub fn new(what: &'static str, width: usize) -> Self {
        Self {
            what,
            tail: [(0.0, vec![0.0; width]), (0.0, vec![0.0; width])],
            held: 0,
            seen: 0,
            pending: VecDeque::new(),
        }
    }

    /// Ask for `y` at `a` (not before the last point asked for).
    pub fn ask(&mut self, a: f64) {
        self.pending.push_back(a);
    }

    /// Refuse asking for `count` more points when they, their answers (every channel) and the
    /// `extra` values kept for each would not fit in the memory available — a grid finer than
    /// the data by a factor of millions (a step of 1e-9°) — instead of growing until the
    /// allocator aborts. `grid` says what the points are, `from` is the chunk's first sample,
    /// `cause` says what in the data asks for so many if it knows, given whether a count of
    /// points would fit (else the error advises a coarser grid); both are called only for the
    /// error.
    pub fn room_for(
        &self,
        count: f64,
        extra: usize,
        grid: impl FnOnce() -> String,
        from: usize,
        cause: impl FnOnce(&dyn Fn(f64) -> bool) -> Option<String>,
    ) -> Result<(), CrankError> {
        let per_point = (self.tail[0].1.len() + 2 + extra) * std::mem::size_of::<f64>();
        let bytes = count * per_point as f64;
        // Below 64 MB a chunk's grid is not worth asking the machine about (every chunk of a
        // stream would read /proc/meminfo).
        if bytes < 64e6 {
            return Ok(());
        }
        let what = format!(
            "{} points of {} in the data from sample {} on",
            physid_core::Num(count.round()),
            grid(),
            from
        );
        physid_core::memory::check_fits(bytes, &what).map_err(|e| {
            let fits =
                |count: f64| physid_core::memory::check_fits(count * per_point as f64, "").is_ok();
            let advice = cause(&fits).unwrap_or_else(|| "make the grid coarser".into());
            CrankError::Invalid(format!("{e}: {advice}"))
        })
    }

    /// The points asked for and not answered yet.
    pub fn waiting(&self) -> usize {
        self.pending.len()
    }

    /// The last `x` seen.
    pub fn last_x(&self) -> Option<f64> {
        (self.held > 0).then(|| self.tail[1].0)
    }

    /// Take the next chunk of data (`x` and one slice per channel, as long as `x`), answering
    /// the points it brackets: each answered point goes to `at`, its values to `out` (one
    /// vector per channel). Errors at a non-finite or non-increasing `x`, naming the sample.
    pub fn push(
        &mut self,
        x: &[f64],
        ys: &[&[f64]],
        at: &mut Vec<f64>,
        out: &mut [Vec<f64>],
    ) -> Result<(), CrankError> {
        for (i, &v) in x.iter().enumerate() {
            let index = self.seen + i;
            if !v.is_finite() {
                return Err(CrankError::Invalid(format!(
                    "{} is {v} at sample {index}",
                    self.what
                )));
            }
            let prev = if i > 0 { Some(x[i - 1]) } else { self.last_x() };
            if let Some(p) = prev.filter(|&p| v <= p) {
                return Err(CrankError::NotIncreasing {
                    what: self.what,
                    index,
                    prev: p,
                    next: v,
                });
            }
        }
        if x.is_empty() {
            return Ok(());
        }
        // The data: the tail, then the chunk.
        let held = self.held;
        let len = held + x.len();
        let xs = |k: usize| {
            if k < held {
                self.tail[2 - held + k].0
            } else {
                x[k - held]
            }
        };
        let y = |k: usize, c: usize| {
            if k < held {
                self.tail[2 - held + k].1[c]
            } else {
                ys[c][k - held]
            }
        };
        let last = xs(len - 1);
        let mut j = 0;
        while let Some(&a) = self.pending.front() {
            if self.seen == 0 && a <= xs(0) {
                at.push(a);
                for (c, o) in out.iter_mut().enumerate() {
                    o.push(y(0, c));
                }
            } else if a < last {
                while xs(j + 1) < a {
                    j += 1;
                }
                let f = (a - xs(j)) / (xs(j + 1) - xs(j));
                at.push(a);
                for (c, o) in out.iter_mut().enumerate() {
                    o.push(y(j, c) + f * (y(j + 1, c) - y(j, c)));
                }
            } else {
                break;
            }
            self.pending.pop_front();
        }
        // Keep the last two samples.
        let n = x.len();
        for k in n.saturating_sub(2)..n {
            self.tail.swap(0, 1);
            let (xk, row) = &mut self.tail[1];
            *xk = x[k];
            for (r, col) in row.iter_mut().zip(ys) {
                *r = col[k];
            }
        }
        self.held = (held + x.len()).min(2);
        self.seen += x.len();
        Ok(())
    }

    /// The end of the data: every point still waiting is at or after the last `x`, so takes the
    /// last sample's values (no data at all: NaN).
    pub fn finish(&mut self, at: &mut Vec<f64>, out: &mut [Vec<f64>]) {
        let held = self.held;
        while let Some(a) = self.pending.pop_front() {
            at.push(a);
            for (c, o) in out.iter_mut().enumerate() {
                o.push(if held > 0 {
                    self.tail[1].1[c]
                } else {
                    f64::NAN
                });
            }
        }
    }
}

/// The crank-angle recording's basis channels for a chunk of grid points.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CrankChunk {
    /// Continuous crank angle [rad] from the first TDC marker.
    pub theta: Vec<f64>,
    /// Time [s] (interpolated).
    pub t: Vec<f64>,
    /// Cycle index (cycle 0 starts at the first TDC marker).
    pub cycle: Vec<f64>,
    /// Crank angle within the cycle [deg], 0 … 720.
    pub crank_deg: Vec<f64>,
    /// The other channels at the grid's times, in the order given.
    pub channels: Vec<Vec<f64>>,
}

impl CrankChunk {
    fn clear(&mut self, width: usize) {
        self.theta.clear();
        self.t.clear();
        self.cycle.clear();
        self.crank_deg.clear();
        self.channels.resize_with(width, Vec::new);
        for c in &mut self.channels {
            c.clear();
        }
    }
}

/// A time-basis recording to one sample every `step_deg` from the first TDC marker, a chunk at
/// a time — [`crank_grid`](crate::crank::crank_grid) (the grid angles `θ_tdc + k·step`, `k`
/// from the first at or after the data's first angle to the last at or before its last; their
/// times interpolated on the angle) and then every channel interpolated at those times, equal
/// to the whole record's [`interp`](crate::crank::interp) bit for bit.
///
/// The angle may come at its own times (an encoder's counts, a decoded wheel): it is given by
/// [`push_angle`](Self::push_angle) and [`finish_angle`](Self::finish_angle), the channels by
/// [`push_channels`](Self::push_channels) and [`finish`](Self::finish). The angle leads: a
/// chunk of channels is pushed once the angle has come past its last time (or is finished) —
/// on one time basis, the angle and the channels of each chunk, in that order.
#[derive(Debug, Clone)]
pub struct CrankResampler {
    theta_tdc: f64,
    step: f64,
    /// The next grid index to ask for (`None` before the first angle).
    next: Option<i64>,
    /// Time on the angle.
    angle: StreamInterp,
    /// The channels on time.
    channels: StreamInterp,
    /// Scratch: the grid angles answered and their times.
    grid: Vec<f64>,
    times: [Vec<f64>; 1],
    /// The grid angles whose times are asked of `channels`, in order.
    queued: VecDeque<f64>,
}

impl CrankResampler {
    /// Resample `width` channels every `step_deg` (> 0) from the angle `theta_tdc` [rad].
    pub fn new(theta_tdc: f64, step_deg: f64, width: usize) -> Result<Self, CrankError> {
        if !(step_deg.is_finite() && step_deg > 0.0) {
            return Err(CrankError::Invalid(format!(
                "crank-angle step {step_deg}°: expected > 0",
                step_deg = physid_core::Num(step_deg)
            )));
        }
        Ok(Self {
            theta_tdc,
            step: step_deg.to_radians(),
            next: None,
            angle: StreamInterp::new("the crank angle", 1),
            channels: StreamInterp::new("time", width),
            grid: Vec::new(),
            times: [Vec::new()],
            queued: VecDeque::new(),
        })
    }

    /// The next angles and their times [s] (strictly increasing both).
    pub fn push_angle(&mut self, t: &[f64], theta: &[f64]) -> Result<(), CrankError> {
        if t.len() != theta.len() {
            return Err(CrankError::Invalid(format!(
                "time ({}) and angle ({}) need the same length",
                t.len(),
                theta.len()
            )));
        }
        if let (None, Some(&first)) = (self.next, theta.first()) {
            let first = self.theta_tdc.max(first);
            self.next = Some(((first - self.theta_tdc) / self.step).ceil() as i64);
        }
        // Ask for the grid angles at or before the chunk's last (they are in the whole grid).
        if let (Some(k), Some(&last)) = (self.next.as_mut(), theta.last()) {
            if last.is_finite() {
                let n = ((last - self.theta_tdc) / self.step).floor().max(-1.0);
                // The angle's interpolator holds the points and their times, the channels'
                // their times and values; the chunk out their θ, cycle and crank angle.
                let (step, step_deg) = (self.step, self.step.to_degrees());
                let before = self.angle.last_x();
                let seen = self.angle.seen;
                self.channels.room_for(
                    n + 1.0 - *k as f64,
                    4,
                    || format!("the {}° crank-angle grid", physid_core::Num(step_deg)),
                    seen,
                    |fits| largest_advance(before, theta, seen, step, fits),
                )?;
                let n = n as i64 + 1;
                while *k < n {
                    self.angle.ask(self.theta_tdc + *k as f64 * self.step);
                    *k += 1;
                }
            }
        }
        self.grid.clear();
        self.times[0].clear();
        self.angle
            .push(theta, &[t], &mut self.grid, &mut self.times)?;
        self.forward();
        Ok(())
    }

    /// The grid points answered on the angle: their times asked of the channels.
    fn forward(&mut self) {
        for (&g, &tk) in self.grid.iter().zip(&self.times[0]) {
            self.queued.push_back(g);
            self.channels.ask(tk);
        }
    }

    /// The next samples of the channels at their times `t` (strictly increasing), writing the
    /// grid points they bracket to `out` (cleared first).
    pub fn push_channels(
        &mut self,
        t: &[f64],
        ys: &[&[f64]],
        out: &mut CrankChunk,
    ) -> Result<(), CrankError> {
        out.clear(ys.len());
        self.channels.push(t, ys, &mut out.t, &mut out.channels)?;
        self.basis(out);
        Ok(())
    }

    /// The end of the angle: its grid points left take its last time.
    pub fn finish_angle(&mut self) {
        self.grid.clear();
        self.times[0].clear();
        self.angle.finish(&mut self.grid, &mut self.times);
        self.forward();
    }

    /// The end of the data (the angle's too): the grid points left, to `out` (cleared first).
    pub fn finish(&mut self, out: &mut CrankChunk) {
        self.finish_angle();
        out.clear(out.channels.len());
        self.channels.finish(&mut out.t, &mut out.channels);
        self.basis(out);
    }

    /// θ, cycle and crank_deg of the grid points answered (`out.t` is filled).
    fn basis(&mut self, out: &mut CrankChunk) {
        for _ in 0..out.t.len() {
            let g = self.queued.pop_front().unwrap_or(f64::NAN);
            let (c, d) = cycle_position(g - self.theta_tdc);
            out.theta.push(g - self.theta_tdc);
            out.cycle.push(c);
            out.crank_deg.push(d);
        }
    }
}

/// A recording to a uniform time basis at `rate_hz` from its first time, a chunk at a time:
/// the times `t₀ + i/rate` up to the last, every channel interpolated there (equal to the whole
/// record's [`interp`](crate::crank::interp) bit for bit).
#[derive(Debug, Clone)]
pub struct TimeResampler {
    rate: f64,
    t0: Option<f64>,
    next: i64,
    channels: StreamInterp,
}

impl TimeResampler {
    /// Resample `width` channels at `rate_hz` (> 0).
    pub fn new(rate_hz: f64, width: usize) -> Result<Self, CrankError> {
        if !(rate_hz.is_finite() && rate_hz > 0.0) {
            return Err(CrankError::Invalid(format!(
                "sample rate {rate_hz} Hz: expected > 0",
                rate_hz = physid_core::Num(rate_hz)
            )));
        }
        Ok(Self {
            rate: rate_hz,
            t0: None,
            next: 0,
            channels: StreamInterp::new("time", width),
        })
    }

    /// The next samples at their times `t` (strictly increasing): the uniform times they
    /// bracket to `t_out`, the channels there to `out` (both cleared first).
    pub fn push(
        &mut self,
        t: &[f64],
        ys: &[&[f64]],
        t_out: &mut Vec<f64>,
        out: &mut [Vec<f64>],
    ) -> Result<(), CrankError> {
        t_out.clear();
        out.iter_mut().for_each(Vec::clear);
        if let (None, Some(&first)) = (self.t0, t.first()) {
            self.t0 = Some(first);
        }
        if let (Some(t0), Some(&last)) = (self.t0, t.last()) {
            if last.is_finite() && t0.is_finite() {
                let n = ((last - t0) * self.rate).floor();
                self.channels.room_for(
                    n + 1.0 - self.next as f64,
                    0,
                    || format!("the {} Hz time basis", physid_core::Num(self.rate)),
                    self.channels.seen,
                    |_| None,
                )?;
                let n = n as i64 + 1;
                while self.next < n {
                    self.channels.ask(t0 + self.next as f64 / self.rate);
                    self.next += 1;
                }
            }
        }
        self.channels.push(t, ys, t_out, out)
    }

    /// The end of the data: the times left (at the last sample's values).
    pub fn finish(&mut self, t_out: &mut Vec<f64>, out: &mut [Vec<f64>]) {
        t_out.clear();
        out.iter_mut().for_each(Vec::clear);
        self.channels.finish(t_out, out);
    }
}
