//! Per-cycle statistics on a stream (thesis §4.3, its Fig. 4.8; SPEC §2.7): the samples of a
//! time-basis recording arrive in chunks; each four-stroke cycle (720° = 4π rad of the
//! continuous crank angle, starting at a firing TDC) is summed up when its last degree has
//! arrived — the crank-angle mean of each channel, its minimum and maximum with the crank
//! angle of the maximum, and optionally the channel on a crank-angle grid (the cyclic view).
//!
//! The means are crank-angle means, `x̄ = (1/4π) ∫ x dθ` over the cycle (trapezoidal rule, the
//! cycle's ends interpolated linearly between the samples around them) — what a crank-angle
//! resampled recording's per-cycle mean ([`crate::crank::cycle_stats`]) approximates. The
//! result depends only on the sequence of samples, never on how it was chunked.
//!
//! A sample whose angle does not advance (an engine at rest) adds nothing; the partial cycle
//! before the first boundary is not reported, and the first cycle that starts in the stream is
//! cycle 0. A sample whose angle lies more than a cycle past the previous one's
//! ([`MAX_ADVANCE`]) ends a gap in the data when the time has advanced with it at a crank's
//! speed (at most [`MAX_CRANK_SPEED`]: a DAQ's dropout, frames lost): the cycle in progress is
//! left out, the sample taken as a stream's first again, and the cycles after the gap keep their
//! numbers (the cycles lost are missing from the count). Otherwise it is an error naming the
//! sample: no cycle can be summed up across it, and an angle of 10⁹ rad written by a bad sensor
//! or a bad frame one sample after another would otherwise close 10⁸ empty cycles.

use crate::crank::CrankError;
use std::f64::consts::PI;

/// One complete cycle.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CycleSummary {
    /// Cycle index: 0 for the first cycle that starts in the stream (as the recordings'
    /// `cycle` channel counts from the first TDC marker).
    pub cycle: i64,
    /// Time at its start and end [s] (interpolated at the boundary angles).
    pub t_start_s: f64,
    /// Time at its end [s].
    pub t_end_s: f64,
    /// Crank-angle mean of each channel.
    pub mean: Vec<f64>,
    /// Each channel at the cycle's start and end (interpolated at the boundary angles): what
    /// changed over the cycle, e.g. its speed.
    pub start: Vec<f64>,
    /// See [`start`](Self::start).
    pub end: Vec<f64>,
    /// Smallest sample of each channel in the cycle.
    pub min: Vec<f64>,
    /// Largest sample of each channel in the cycle.
    pub max: Vec<f64>,
    /// Crank angle in the cycle [deg] of each channel's largest sample.
    pub max_deg: Vec<f64>,
    /// Each channel at 0, step, 2·step, … < 720° (interpolated), when curves were asked for.
    pub curve: Option<Vec<Vec<f64>>>,
    /// The time at each grid point asked for ([`CycleStream::with_times_at`]) [s], interpolated
    /// as a channel's curve is — what a caller that needs the time at a few angles has,
    /// without the time's whole curve.
    #[serde(default)]
    pub times: Vec<f64>,
}

/// Where a dropout starts ([`CycleStream::push_past_dropouts`]): a run of samples whose angle
/// or one of whose channels is not a number.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dropout {
    /// Its first sample's index in the stream.
    pub sample: usize,
    /// Its first sample's time [s].
    pub t: f64,
    /// What is not a number there: `None` the angle, `Some(j)` channel `j`.
    pub channel: Option<usize>,
    /// The value it has there.
    pub value: f64,
}

/// The stream's state between chunks (see the module docs).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct CycleStream {
    theta_tdc: f64,
    step: f64,
    points: usize,
    curves: bool,
    /// The statistics (means, extremes) kept too; `false`: the curves alone
    /// ([`curves_only`](Self::curves_only)).
    stats: bool,
    /// The previous sample's angle and time (its values are `prev_x`).
    prev: Option<(f64, f64)>,
    prev_x: Vec<f64>,
    /// The cycle in progress: index, whether it began at its boundary, start time.
    cycle: i64,
    /// `floor((θ − θ_TDC) / 4π)` of the first cycle that starts in the stream.
    first: i64,
    complete: bool,
    t_start: f64,
    /// The next grid point's index in the cycle.
    next_grid: usize,
    integral: Vec<f64>,
    /// The channels at the start of the cycle in progress.
    start_x: Vec<f64>,
    min: Vec<f64>,
    max: Vec<f64>,
    max_deg: Vec<f64>,
    curve: Vec<Vec<f64>>,
    seen: usize,
    /// Scratch of [`push_curves`](Self::push_curves): each grid point's sample and fraction.
    #[serde(skip)]
    grid_scratch: GridScratch,
    /// Curves handed back ([`recycle`](Self::recycle)) for the next cycle to fill.
    #[serde(skip)]
    spare: Option<Vec<Vec<f64>>>,
    /// The grid points whose times are asked for, and their times in the cycle in progress.
    #[serde(default)]
    marks: Vec<usize>,
    #[serde(default)]
    mark_times: Vec<f64>,
    /// The next sample comes after a gap in the data ([`resume_after_gap`](Self::resume_after_gap)).
    #[serde(default)]
    resumed: bool,
    /// Gaps resumed after so far.
    #[serde(default)]
    gaps: u64,
    /// The last sample taken was in a dropout ([`push_past_dropouts`](Self::push_past_dropouts)).
    #[serde(default)]
    in_dropout: bool,
    /// The dropouts the last chunk began (scratch, [`dropouts`](Self::dropouts)).
    #[serde(skip)]
    dropouts: Vec<Dropout>,
}

/// The grid points a run of samples passes: for each, the first sample at or past it (`to[q]`,
/// counted in the run; the one before it is `to[q] − 1`, or the previous sample for 0) and the
/// fraction of the way from the sample before (`f[q]`). Sized once to a cycle's points.
#[derive(Debug, Clone, Default)]
struct GridScratch {
    to: Vec<usize>,
    f: Vec<f64>,
}

impl CycleStream {
    /// `channels` channels; cycles start at `theta_tdc` + k·4π [rad]; with `curve_step_deg`,
    /// each cycle's curve on that crank-angle grid [deg] (720 must be a multiple of it).
    pub fn new(
        channels: usize,
        theta_tdc: f64,
        curve_step_deg: Option<f64>,
    ) -> Result<Self, CrankError> {
        if !theta_tdc.is_finite() {
            return Err(CrankError::Invalid(format!(
                "TDC angle {theta_tdc} rad: expected a finite number"
            )));
        }
        let step_deg = curve_step_deg.unwrap_or(1.0);
        let points = 720.0 / step_deg;
        if !(step_deg >= MIN_CURVE_STEP_DEG
            && points >= 2.0
            && (points - points.round()).abs() < 1e-9)
        {
            return Err(CrankError::Invalid(format!(
                "curve step {step_deg:?}°: expected a divisor of 720° giving at least 2 points, \
                 at least {MIN_CURVE_STEP_DEG}° (a cycle's curves are held while it is in \
                 progress: 72 000 points per channel at the finest)"
            )));
        }
        let points = points.round() as usize;
        let curves = curve_step_deg.is_some();
        Ok(Self {
            theta_tdc,
            step: 4.0 * PI / points as f64,
            points,
            curves,
            stats: true,
            prev: None,
            prev_x: vec![0.0; channels],
            cycle: 0,
            first: 0,
            complete: false,
            t_start: f64::NAN,
            next_grid: 0,
            integral: vec![0.0; channels],
            start_x: vec![f64::NAN; channels],
            min: vec![f64::INFINITY; channels],
            max: vec![f64::NEG_INFINITY; channels],
            max_deg: vec![f64::NAN; channels],
            curve: (0..if curves { channels } else { 0 })
                .map(|_| Vec::with_capacity(points))
                .collect(),
            seen: 0,
            grid_scratch: GridScratch::default(),
            spare: None,
            marks: Vec::new(),
            mark_times: Vec::new(),
            resumed: false,
            gaps: 0,
            in_dropout: false,
            dropouts: Vec::new(),
        })
    }

    /// The time at each of these grid points too (a cycle's
    /// [`times`](CycleSummary::times), in this order; NaN where the cycle did not reach one —
    /// never in a complete cycle). An error for a point past the grid's last.
    pub fn with_times_at(mut self, points: &[usize]) -> Result<Self, CrankError> {
        if let Some(&k) = points.iter().find(|&&k| k >= self.points) {
            return Err(CrankError::Invalid(format!(
                "grid point {k}: the grid has {} points",
                self.points
            )));
        }
        self.marks = points.to_vec();
        self.mark_times = vec![f64::NAN; points.len()];
        Ok(self)
    }

    /// Note `time`, the time at grid point `k`, when it is asked for.
    #[inline]
    fn mark(&mut self, k: usize, time: f64) {
        for (m, at) in self.marks.iter().zip(&mut self.mark_times) {
            if *m == k {
                *at = time;
            }
        }
    }

    /// The curves alone (a stream made with a curve step): a cycle's `mean`, `min`, `max` and
    /// `max_deg` are left empty and not computed — what a caller that analyses the curves itself
    /// needs, at less cost per sample.
    pub fn curves_only(mut self) -> Self {
        self.stats = !self.curves;
        self
    }

    /// The index of the first cycle that starts in the stream, counted in 4π from the TDC angle
    /// (`floor((θ − θ_TDC)/4π)` of its start; known after the first sample): a summary's
    /// `cycle` plus this is the cycle's absolute index.
    pub fn first_index(&self) -> i64 {
        self.first
    }

    /// Hand back a cycle's curves once read: the next cycle fills them instead of new ones
    /// (no allocation per cycle). Curves of another channel count are dropped.
    pub fn recycle(&mut self, mut curve: Vec<Vec<f64>>) {
        if curve.len() == self.curve.len() {
            curve.iter_mut().for_each(Vec::clear);
            self.spare = Some(curve);
        }
    }

    /// The angle where cycle `c` starts [rad].
    fn start(&self, c: i64) -> f64 {
        self.theta_tdc + c as f64 * 4.0 * PI
    }

    /// The angle of the next grid point of the cycle in progress [rad] (its end when the grid
    /// is done).
    fn next_grid_angle(&self) -> f64 {
        self.grid_angle(self.next_grid)
    }

    /// The angle of grid point `k` of the cycle in progress [rad]; `k` = `points` is its end,
    /// where [`sample`](Self::sample) closes it.
    fn grid_angle(&self, k: usize) -> f64 {
        self.start(self.cycle) + k as f64 * self.step
    }

    /// Take a chunk: `t` [s], the continuous crank angle `theta` [rad], and the channels
    /// (`x[j]` as long as `t`); each cycle completed is pushed onto `out`. A value that is not
    /// finite, or an angle more than [`MAX_ADVANCE`] past the previous sample's, is an error
    /// naming its sample (counted from the stream's start); the samples before it are taken.
    pub fn push(
        &mut self,
        t: &[f64],
        theta: &[f64],
        x: &[&[f64]],
        out: &mut Vec<CycleSummary>,
    ) -> Result<(), CrankError> {
        let n = t.len();
        if theta.len() != n || x.len() != self.prev_x.len() || x.iter().any(|c| c.len() != n) {
            return Err(CrankError::Invalid(format!(
                "a chunk of {n} samples with {} angles and {} channels of lengths {:?}: expected {} channels, all as long",
                theta.len(),
                x.len(),
                x.iter().map(|c| c.len()).collect::<Vec<_>>(),
                self.prev_x.len()
            )));
        }
        // With the curves alone, block by block while the samples are finite and their angles
        // increase (each block checked while it is in the cache, then taken); the rest, from a
        // block that is not, sample by sample — the same arithmetic either way.
        let mut from = 0;
        if !self.stats {
            while let Some((th0, _)) = self.prev.filter(|_| from < n) {
                let block = from..(from + CHECK_BLOCK).min(n);
                if !(advancing(th0, &theta[block.clone()])
                    && finite(&t[block.clone()])
                    && finite(&theta[block.clone()])
                    && x.iter().all(|c| finite(&c[block.clone()])))
                {
                    break;
                }
                from = block.end;
                self.push_curves(t, theta, x, block, out);
            }
        }
        for i in from..n {
            let index = self.seen + i;
            let bad = |what: &str, v: f64| {
                CrankError::Invalid(format!(
                    "{what} is {v} at sample {index}: expected a finite number"
                ))
            };
            if !t[i].is_finite() {
                return Err(bad("the time", t[i]));
            }
            if !theta[i].is_finite() {
                return Err(bad("the crank angle", theta[i]));
            }
            if let Some(j) = x.iter().position(|c| !c[i].is_finite()) {
                return Err(bad(&format!("channel {j}"), x[j][i]));
            }
            if let Some((th0, t0)) = self.prev.filter(|&(th0, _)| theta[i] - th0 > MAX_ADVANCE) {
                let advance = theta[i] - th0;
                if !(t[i] > t0 && advance / (t[i] - t0) <= MAX_CRANK_SPEED) {
                    return Err(CrankError::Invalid(format!(
                        "the crank angle advances by {advance:.4e} rad ({:.4e} cycles) at sample \
                         {index}, from {th0:.6e} to {:.6e} rad in {:.4e} s: expected at most a \
                         cycle (4π rad) between two samples, or across a gap in time at most \
                         {MAX_CRANK_SPEED:.0} rad/s (25 000 rpm) — an angle that is not the crank's",
                        advance / (4.0 * PI),
                        theta[i],
                        t[i] - t0
                    )));
                }
                self.resume_after_gap();
            }
            self.sample(t[i], theta[i], |j| x[j][i], out);
        }
        self.seen += n;
        Ok(())
    }

    /// The samples `block` of a chunk, all finite and their angles increasing from the previous
    /// sample's, with the curves alone (no statistics): what [`sample`](Self::sample) does, the
    /// same arithmetic, run by run — the samples before a cycle's end through
    /// [`grid_run`](Self::grid_run), the one at or past it through `sample`, which closes the
    /// cycle.
    fn push_curves(
        &mut self,
        t: &[f64],
        theta: &[f64],
        x: &[&[f64]],
        block: std::ops::Range<usize>,
        out: &mut Vec<CycleSummary>,
    ) {
        let mut from = block.start;
        while from < block.end {
            let end = self.grid_angle(self.points);
            // The angles increase: the run before the end found by bisection.
            let stop = from + theta[from..block.end].partition_point(|&th| th < end);
            if stop > from {
                self.grid_run(&t[from..stop], &theta[from..stop], x, from);
            }
            if stop == block.end {
                break;
            }
            let th = theta[stop];
            self.sample(t[stop], th, |j| x[j][stop], out);
            from = stop + 1;
        }
    }

    /// A run of samples (`x[j][offset..]` as long as `theta`) inside the cycle in progress,
    /// their angles increasing from the previous sample's: the grid points they pass onto the
    /// curves, in two passes — for each grid point the first sample at or past it and the
    /// fraction of the way (the angles alone), then each channel there — and the run's last
    /// sample made the previous one.
    fn grid_run(&mut self, t: &[f64], theta: &[f64], x: &[&[f64]], offset: usize) {
        let Some((th_prev, t_prev)) = self.prev else {
            return;
        };
        let (c0, step, n) = (self.start(self.cycle), self.step, theta.len());
        let scratch = &mut self.grid_scratch;
        if scratch.to.len() < self.points {
            scratch.to.resize(self.points, 0);
            scratch.f.resize(self.points, 0.0);
        }
        let last = theta[n - 1];
        let k0 = self.next_grid;
        let (mut q, mut i, mut k) = (0, 0, k0);
        loop {
            // As grid_angle: the same arithmetic. Every point before the cycle's end is in the
            // scratch: the run lies before it.
            let g = c0 + k as f64 * step;
            if g > last {
                break;
            }
            while theta[i] < g {
                i += 1;
            }
            let th0 = if i == 0 { th_prev } else { theta[i - 1] };
            scratch.to[q] = i;
            scratch.f[q] = fraction(g, th0, theta[i]);
            q += 1;
            k += 1;
        }
        self.next_grid = k;
        let (to, f) = (&scratch.to[..q], &scratch.f[..q]);
        // The times asked for, as a channel's curve (`t` the channel).
        for (m, at) in self.marks.iter().zip(&mut self.mark_times) {
            if (k0..k).contains(m) {
                let (i, f) = (to[m - k0], f[m - k0]);
                let a = if i == 0 { t_prev } else { t[i - 1] };
                *at = a + f * (t[i] - a);
            }
        }
        for (j, curve) in self.curve.iter_mut().enumerate() {
            let xj = &x[j][offset..offset + n];
            let before = self.prev_x[j];
            curve.extend(to.iter().zip(f).map(|(&i, &f)| {
                let a = if i == 0 { before } else { xj[i - 1] };
                a + f * (xj[i] - a)
            }));
            self.prev_x[j] = xj[n - 1];
        }
        self.prev = Some((last, t[n - 1]));
    }

    /// One sample.
    fn sample(&mut self, t: f64, th: f64, x: impl Fn(usize) -> f64, out: &mut Vec<CycleSummary>) {
        let Some((th0, t0)) = self.prev else {
            // The first sample: its cycle began before the stream unless it sits on the start.
            self.cycle = ((th - self.theta_tdc) / (4.0 * PI)).floor() as i64;
            let into = th - self.start(self.cycle);
            self.complete = into == 0.0;
            // After a gap the numbering goes on from the stream's first cycle.
            if !std::mem::take(&mut self.resumed) {
                self.first = self.cycle + i64::from(!self.complete);
            }
            self.t_start = t;
            self.next_grid = (into / self.step).ceil() as usize;
            self.accept(t, th, &x, true);
            return;
        };
        if th <= th0 {
            return;
        }
        // Grid points and cycle boundaries between the previous sample and this one.
        loop {
            let g = self.next_grid_angle();
            if g > th {
                break;
            }
            let f = fraction(g, th0, th);
            if self.next_grid == self.points {
                // The boundary: close the cycle with the piece up to it …
                for j in 0..self.prev_x.len() {
                    let at = self.prev_x[j] + f * (x(j) - self.prev_x[j]);
                    if self.stats {
                        self.integral[j] += 0.5 * (self.prev_x[j] + at) * (g - th0);
                    }
                    self.prev_x[j] = at;
                }
                let t_end = t0 + f * (t - t0);
                self.close(t_end, out);
                // … and start the next one there, from the interpolated values.
                self.cycle += 1;
                self.complete = true;
                self.t_start = t_end;
                self.next_grid = 0;
                self.start_x.copy_from_slice(&self.prev_x);
                self.prev = Some((g, t_end));
                return self.sample(t, th, x, out);
            }
            for (j, c) in self.curve.iter_mut().enumerate() {
                c.push(self.prev_x[j] + f * (x(j) - self.prev_x[j]));
            }
            if !self.marks.is_empty() {
                self.mark(self.next_grid, t0 + f * (t - t0));
            }
            self.next_grid += 1;
        }
        if self.stats {
            for j in 0..self.integral.len() {
                self.integral[j] += 0.5 * (self.prev_x[j] + x(j)) * (th - th0);
            }
        }
        self.accept(t, th, &x, false);
    }

    /// A gap in the data: the cycle in progress left out (it cannot be summed up across the
    /// gap), and the next sample taken as a stream's first — the cycle numbers go on from the
    /// stream's first cycle, so the cycles lost in the gap are missing from the count.
    fn resume_after_gap(&mut self) {
        self.complete = false;
        self.close(f64::NAN, &mut Vec::new());
        self.prev = None;
        self.resumed = true;
        self.gaps += 1;
    }

    /// The gaps in the data the stream has resumed after (see the module docs).
    pub fn gaps(&self) -> u64 {
        self.gaps
    }

    /// `n` samples left out of the stream (a dropout: values that are not numbers), as a gap
    /// in the data: the cycle in progress left out, the next sample taken as a stream's first,
    /// the cycles after it numbered on; the samples counted in the stream's sample index.
    pub fn leave_out(&mut self, n: usize) {
        if self.prev.is_some() {
            self.resume_after_gap();
        }
        self.seen += n;
    }

    /// [`push`](Self::push) for a stream with dropouts — a sensor's values that are not numbers:
    /// a sample whose angle or one of whose channels is not a number is left out with the
    /// samples after it up to the next whole one ([`leave_out`](Self::leave_out), a gap in the
    /// data: the cycle it cuts is not reported, the cycles after it keep their numbers). The
    /// dropouts the chunk began are [`dropouts`](Self::dropouts) until the next chunk (one
    /// that goes on from the chunk before is not begun again). A time that is not finite is
    /// still an error naming its sample. Without a dropout, exactly [`push`](Self::push).
    pub fn push_past_dropouts(
        &mut self,
        t: &[f64],
        theta: &[f64],
        x: &[&[f64]],
        out: &mut Vec<CycleSummary>,
    ) -> Result<(), CrankError> {
        self.dropouts.clear();
        let n = t.len();
        let whole = |i: usize| theta[i].is_finite() && x.iter().all(|c| c[i].is_finite());
        if theta.len() != n || x.iter().any(|c| c.len() != n) || (0..n).all(whole) {
            if n > 0 && theta.len() == n {
                self.in_dropout = false;
            }
            return self.push(t, theta, x, out);
        }
        let mut from = 0;
        while from < n {
            // The whole samples from `from`, then the dropout after them.
            let end = (from..n).find(|&i| !whole(i)).unwrap_or(n);
            if end > from {
                self.in_dropout = false;
                let part: Vec<&[f64]> = x.iter().map(|c| &c[from..end]).collect();
                self.push(&t[from..end], &theta[from..end], &part, out)?;
            }
            if end == n {
                break;
            }
            let resume = (end..n).find(|&i| whole(i)).unwrap_or(n);
            if let Some(i) = (end..resume).find(|&i| !t[i].is_finite()) {
                return Err(CrankError::Invalid(format!(
                    "the time is {} at sample {}: expected a finite number",
                    t[i],
                    self.seen + i - end
                )));
            }
            if !self.in_dropout {
                self.in_dropout = true;
                let (channel, value) = std::iter::once((None, theta[end]))
                    .chain(x.iter().enumerate().map(|(j, c)| (Some(j), c[end])))
                    .find(|(_, v)| !v.is_finite())
                    .unwrap_or((None, theta[end]));
                self.dropouts.push(Dropout {
                    sample: self.seen,
                    t: t[end],
                    channel,
                    value,
                });
            }
            self.leave_out(resume - end);
            from = resume;
        }
        Ok(())
    }

    /// The dropouts the last chunk given to [`push_past_dropouts`](Self::push_past_dropouts)
    /// began, in order.
    pub fn dropouts(&self) -> &[Dropout] {
        &self.dropouts
    }

    /// The samples taken or left out so far: the next sample's index in the stream.
    pub fn seen(&self) -> usize {
        self.seen
    }

    /// Make `(t, th, x)` the previous sample and count it in the extremes.
    fn accept(&mut self, t: f64, th: f64, x: &impl Fn(usize) -> f64, first: bool) {
        if self.stats {
            let deg = (th - self.start(self.cycle)).to_degrees();
            for j in 0..self.prev_x.len() {
                let v = x(j);
                self.prev_x[j] = v;
                self.min[j] = self.min[j].min(v);
                if v > self.max[j] {
                    self.max[j] = v;
                    self.max_deg[j] = deg;
                }
            }
        } else {
            for j in 0..self.prev_x.len() {
                self.prev_x[j] = x(j);
            }
        }
        if first && self.complete {
            self.start_x.copy_from_slice(&self.prev_x);
        }
        if first && self.curves && self.next_grid == 0 {
            for j in 0..self.curve.len() {
                self.curve[j].push(self.prev_x[j]);
            }
            self.mark(0, t);
            self.next_grid = 1;
        }
        self.prev = Some((th, t));
    }

    /// Report the cycle in progress (when it began at its boundary) and reset the sums.
    fn close(&mut self, t_end: f64, out: &mut Vec<CycleSummary>) {
        if self.complete {
            out.push(CycleSummary {
                cycle: self.cycle - self.first,
                t_start_s: self.t_start,
                t_end_s: t_end,
                mean: if self.stats {
                    self.integral.iter().map(|s| s / (4.0 * PI)).collect()
                } else {
                    Vec::new()
                },
                start: self.start_x.clone(),
                end: self.prev_x.clone(),
                min: if self.stats {
                    self.min.clone()
                } else {
                    Vec::new()
                },
                max: if self.stats {
                    self.max.clone()
                } else {
                    Vec::new()
                },
                max_deg: if self.stats {
                    self.max_deg.clone()
                } else {
                    Vec::new()
                },
                times: self.mark_times.clone(),
                curve: self.curves.then(|| {
                    let fresh = self.spare.take().unwrap_or_else(|| {
                        (0..self.curve.len())
                            .map(|_| Vec::with_capacity(self.points))
                            .collect()
                    });
                    std::mem::replace(&mut self.curve, fresh)
                }),
            });
        }
        self.integral.fill(0.0);
        self.min.fill(f64::INFINITY);
        self.max.fill(f64::NEG_INFINITY);
        self.max_deg.fill(f64::NAN);
        self.mark_times.fill(f64::NAN);
        for c in &mut self.curve {
            c.clear();
        }
    }
}

/// The samples checked at a time on the curves-only path before they are taken: the check's
/// reads bring them into the cache for the work that follows (3 × 16 KB for the time, the angle
/// and a channel, in the second-level cache; the live combustion stage with knock went from
/// 98–99× to 101–103× real time against checking a whole chunk of 3600 samples first).
const CHECK_BLOCK: usize = 2048;

/// The fraction of the way from angle `th0` to `th1` at which angle `g` lies (linear
/// interpolation; the one formula of every path, so their curves agree bit for bit).
#[inline]
fn fraction(g: f64, th0: f64, th1: f64) -> f64 {
    (g - th0) / (th1 - th0)
}

/// The finest curve step [deg]: a hundredth of a degree, finer than any indicating system
/// resolves (0.1° is usual). A step of 10⁻⁹° asked for 5.8 TB for one cycle's curve.
pub const MIN_CURVE_STEP_DEG: f64 = 0.01;

/// The largest advance of the crank angle between two samples [rad]: a cycle.
pub const MAX_ADVANCE: f64 = 4.0 * PI;

/// The fastest a crank can have turned across a gap in the data [rad/s]: 25 000 rpm (racing
/// engines turn to 20 000). An angle that advances more than a cycle faster than this is not
/// the crank's.
pub const MAX_CRANK_SPEED: f64 = 25_000.0 * 2.0 * PI / 60.0;

/// Whether the angles increase from `th0`, each by at most [`MAX_ADVANCE`] (one pass, no
/// early exit).
fn advancing(th0: f64, theta: &[f64]) -> bool {
    let Some((&first, rest)) = theta.split_first() else {
        return true;
    };
    let pairs = theta[..rest.len()].iter().zip(rest);
    let step = |a: f64, b: f64| (b > a) & (b - a <= MAX_ADVANCE);
    step(th0, first) & pairs.fold(true, |ok, (&a, &b)| ok & step(a, b))
}

/// Whether every value is finite (one pass, which the compiler vectorises: no early exit).
fn finite(v: &[f64]) -> bool {
    v.iter().fold(true, |ok, v| ok & v.is_finite())
}
