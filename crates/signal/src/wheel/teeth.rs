//! The first step of the indexing, as the edges come ([`Teeth`]): each period's length against
//! its neighbours', the extra edges dropped, the pitches counted across each period between the
//! edges kept.

use super::*;

/// A period's pitch count is rounded from its ratio to the neighbours' median; further than
/// this from a whole number, it is reported as irregular.
pub(super) const PITCH_TOLERANCE: f64 = 0.3;

/// A period shorter than this fraction of a pitch ends on an extra edge.
pub(super) const EXTRA_EDGE: f64 = 0.6;

pub(super) fn median(v: &mut [f64]) -> f64 {
    v.sort_unstable_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Each period's length against the median of up to three periods either side of it.
pub(super) fn relative_periods(t: &[f64]) -> Vec<f64> {
    let mut rel = Relative::default();
    let mut r = Vec::with_capacity(t.len().saturating_sub(1));
    for &x in t {
        rel.push(x);
        while let Some((_, x)) = rel.next(false) {
            r.push(x);
        }
    }
    while let Some((_, x)) = rel.next(true) {
        r.push(x);
    }
    r
}

/// [`relative_periods`] as the edge times come: period `k` (from edge `k` to `k + 1`) is
/// known once three more periods have come, or the edges have ended. Holds seven periods.
#[derive(Debug, Clone, Default)]
struct Relative {
    /// The periods from `from` on [s].
    p: VecDeque<f64>,
    from: usize,
    /// Periods so far, the next to give, the last edge's time.
    periods: usize,
    next: usize,
    last: Option<f64>,
}

impl Relative {
    fn push(&mut self, t: f64) {
        if let Some(last) = self.last {
            self.p.push_back(t - last);
            self.periods += 1;
        }
        self.last = Some(t);
    }

    /// The next period's index and ratio, once known (`end`: no more edges will come).
    fn next(&mut self, end: bool) -> Option<(usize, f64)> {
        let (k, n) = (self.next, self.periods);
        if k >= n || (!end && k + 3 >= n) {
            return None;
        }
        let p = |i: usize| self.p[i - self.from];
        let mut buf = [0.0; 6];
        let mut m = 0;
        for i in (k.saturating_sub(3)..k).chain((k + 1).min(n)..(k + 4).min(n)) {
            buf[m] = p(i);
            m += 1;
        }
        let r = if m == 0 {
            1.0
        } else {
            p(k) / median(&mut buf[..m])
        };
        self.next += 1;
        while self.from + 3 < self.next {
            self.p.pop_front();
            self.from += 1;
        }
        Some((k, r))
    }
}

/// The distance of `x` from the nearest whole number of at least 1.
pub(super) fn off_whole(x: f64) -> f64 {
    (x - x.round().max(1.0)).abs()
}

/// A tooth period between two kept edges, as [`Teeth`] gives it.
#[derive(Debug, Clone, Copy)]
pub(super) struct Period {
    /// Its number (from 0) and the edges at its ends: times [s], samples.
    pub(super) k: usize,
    pub(super) t: (f64, f64),
    pub(super) index: (usize, usize),
    /// Its length against its neighbours', and the pitches counted across it.
    pub(super) r: f64,
    pub(super) pitches: i64,
    /// Its pitch count is unsure: not near a whole number, or longer than a revolution (a
    /// dropout). The count across it may slip; it is set again at the next gap.
    pub(super) unsure: bool,
}

/// What [`Teeth`] gives as the edges come.
#[derive(Debug, Clone, Copy)]
pub(super) enum Tooth {
    /// An extra edge dropped, at its sample.
    Extra(usize),
    /// A period between kept edges.
    Period(Period),
}

/// The first step of the indexing, as the edges come: drop extra edges — where a period is
/// shorter than [`EXTRA_EDGE`] pitches, whichever of its two ends leaves the period across it
/// nearer a whole number of pitches — then count the pitches across each period between the
/// edges kept. Holds a few edges.
#[derive(Debug, Clone)]
pub(super) struct Teeth {
    teeth: i64,
    /// The ratios of the edges' periods; the edges from `raw_from` on (times, samples).
    raw_rel: Relative,
    raw: VecDeque<(f64, usize)>,
    raw_from: usize,
    /// The kept edges not yet final: the last two.
    top: Option<(f64, usize)>,
    second: Option<(f64, usize)>,
    /// The ratios of the kept edges' periods; the kept edges from `kept_from` on.
    kept_rel: Relative,
    kept: VecDeque<(f64, usize)>,
    kept_from: usize,
    /// Edges seen, and kept.
    pub(super) edges: usize,
    pub(super) n_kept: usize,
}

impl Teeth {
    pub(super) fn new(wheel: Wheel) -> Self {
        Self {
            teeth: i64::from(wheel.teeth),
            raw_rel: Relative::default(),
            raw: VecDeque::new(),
            raw_from: 0,
            top: None,
            second: None,
            kept_rel: Relative::default(),
            kept: VecDeque::new(),
            kept_from: 0,
            edges: 0,
            n_kept: 0,
        }
    }

    /// The next edge: time [s] and sample.
    pub(super) fn push(&mut self, t: f64, index: usize, out: &mut impl FnMut(Tooth)) {
        self.edges += 1;
        self.raw.push_back((t, index));
        self.raw_rel.push(t);
        if self.top.is_none() {
            self.top = Some((t, index));
        }
        while let Some((k, r)) = self.raw_rel.next(false) {
            self.extra(k + 1, r, out);
        }
    }

    /// No more edges.
    pub(super) fn finish(&mut self, out: &mut impl FnMut(Tooth)) {
        while let Some((k, r)) = self.raw_rel.next(true) {
            self.extra(k + 1, r, out);
        }
        for e in [self.second.take(), self.top.take()].into_iter().flatten() {
            self.keep(e, out);
        }
        self.second = None;
        while let Some((k, r)) = self.kept_rel.next(true) {
            self.period(k, r, out);
        }
    }

    /// The edge `j`, the ratio of the period before it `r`: kept, or it or the edge before
    /// dropped.
    fn extra(&mut self, j: usize, r: f64, out: &mut impl FnMut(Tooth)) {
        let raw = |i: usize| self.raw[i - self.raw_from];
        let (tj, ij) = raw(j);
        let q = (tj - raw(j - 1).0) / r;
        let next = (j + 1 < self.edges).then(|| raw(j + 1).0);
        let Some(last) = self.top else { return };
        if (tj - last.0) / q >= EXTRA_EDGE {
            if let Some(below) = self.top.replace((tj, ij)) {
                if let Some(final_) = self.second.replace(below) {
                    self.keep(final_, out);
                }
            }
        } else {
            // Drop the edge before (its predecessor → j), or j (the edge before → j + 1).
            let drop_last = self
                .second
                .map_or(f64::INFINITY, |s| off_whole((tj - s.0) / q));
            let drop_j = next.map_or(0.0, |next| off_whole((next - last.0) / q));
            if drop_last < drop_j {
                out(Tooth::Extra(last.1));
                self.top = Some((tj, ij));
            } else {
                out(Tooth::Extra(ij));
            }
        }
        while self.raw_from < j {
            self.raw.pop_front();
            self.raw_from += 1;
        }
    }

    /// A kept edge, final.
    fn keep(&mut self, e: (f64, usize), out: &mut impl FnMut(Tooth)) {
        self.n_kept += 1;
        self.kept.push_back(e);
        self.kept_rel.push(e.0);
        while let Some((k, r)) = self.kept_rel.next(false) {
            self.period(k, r, out);
        }
    }

    fn period(&mut self, k: usize, r: f64, out: &mut impl FnMut(Tooth)) {
        let (a, b) = (
            self.kept[k - self.kept_from],
            self.kept[k + 1 - self.kept_from],
        );
        let pitches = r.round().max(1.0) as i64;
        out(Tooth::Period(Period {
            k,
            t: (a.0, b.0),
            index: (a.1, b.1),
            r,
            pitches,
            unsure: off_whole(r) > PITCH_TOLERANCE || pitches > self.teeth,
        }));
        while self.kept_from < k + 1 {
            self.kept.pop_front();
            self.kept_from += 1;
        }
    }
}

/// Fewer edges than two revolutions: the error.
pub(super) fn too_few(edges: usize, wheel: Wheel, channel: &str) -> Result<(), WheelError> {
    if edges < 2 * wheel.present() as usize + 2 {
        return Err(WheelError::Invalid(format!(
            "'{channel}': {edges} tooth edges, fewer than two revolutions of a {wheel} wheel ({} edges each)",
            wheel.present()
        )));
    }
    Ok(())
}
