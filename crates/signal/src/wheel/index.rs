//! Each edge's angle on the wheel: the periods counted in pitches, the gap found
//! ([`GapSurvey`]), the teeth indexed as they come ([`ToothIndex`]) or over a record
//! ([`index_teeth`]), with the missing and extra edges as findings.

use super::*;

/// A period's pitch count is rounded from its ratio to the neighbours' median; further than
/// this from a whole number, it is reported as irregular.
const PITCH_TOLERANCE: f64 = 0.3;

/// A period shorter than this fraction of a pitch ends on an extra edge.
const EXTRA_EDGE: f64 = 0.6;

/// The wheel's angle at its edges, and what the decoding found.
#[derive(Debug, Clone, PartialEq)]
pub struct WheelAngles {
    /// The wheel.
    pub wheel: Wheel,
    /// Edge times [s] (the extra edges dropped).
    pub t: Vec<f64>,
    /// The wheel's angle at each edge [rad]: 0 at the first edge after the first gap (the
    /// reference tooth), a pitch per tooth, M + 1 pitches across the gap.
    pub angle: Vec<f64>,
    /// The sample index of each edge.
    pub index: Vec<usize>,
    /// Whole revolutions between the first and last gap.
    pub revolutions: usize,
    /// The slowest and fastest speed over a tooth period [rpm].
    pub rpm: (f64, f64),
    /// Missing and extra edges, gaps out of place (findings, by sample), glitches rejected
    /// (a note).
    pub findings: Vec<Finding>,
}

fn median(v: &mut [f64]) -> f64 {
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
fn off_whole(x: f64) -> f64 {
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
    r: f64,
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

/// The first pass of the indexing ([`index_teeth`]): where the gap is, modulo N pitches — where
/// most periods of M + 1 pitches end, over the periods before the first unsure one when they
/// span two revolutions, else over all. Holds N votes twice, and the places of the longest
/// periods (for the error that says what the periods show, about one a revolution).
#[derive(Debug, Clone)]
pub struct GapSurvey {
    teeth: Teeth,
    tally: Tally,
}

/// [`GapSurvey`]'s count of the periods.
#[derive(Debug, Clone)]
struct Tally {
    wheel: Wheel,
    channel: String,
    /// The pitch count so far, and the votes over all periods and before the first unsure.
    count: i64,
    votes: Vec<usize>,
    votes_sure: Vec<usize>,
    periods: usize,
    sure: Option<usize>,
    /// The longest periods' pitches and places.
    longest: i64,
    longest_at: Vec<usize>,
}

/// Where a wheel's gap is: what [`GapSurvey`] found, for [`ToothIndex`].
#[derive(Debug, Clone, PartialEq)]
pub struct Gap {
    /// The wheel.
    pub wheel: Wheel,
    /// The pitch count, modulo N, where the gap ends.
    pub residue: i64,
    /// The error to give if no period turns out to be the gap (what the periods show).
    pub(super) mismatch: String,
}

impl GapSurvey {
    /// A survey of the edges of a `wheel` on the channel `channel` (named in the errors).
    pub fn new(wheel: Wheel, channel: &str) -> Self {
        let n = wheel.teeth as usize;
        Self {
            teeth: Teeth::new(wheel),
            tally: Tally {
                wheel,
                channel: channel.to_string(),
                count: 0,
                votes: vec![0; n],
                votes_sure: vec![0; n],
                periods: 0,
                sure: None,
                longest: 1,
                longest_at: Vec::new(),
            },
        }
    }

    /// The next edge: time [s] and sample.
    pub fn push(&mut self, t: f64, index: usize) {
        let tally = &mut self.tally;
        self.teeth.push(t, index, &mut |tooth| tally.take(tooth));
    }

    /// Where the gap is, or why it cannot be told (too few edges; no gap where the wheel has
    /// it).
    pub fn finish(mut self) -> Result<Gap, WheelError> {
        let tally = &mut self.tally;
        self.teeth.finish(&mut |tooth| tally.take(tooth));
        let (wheel, channel) = (tally.wheel, tally.channel.as_str());
        too_few(self.teeth.edges, wheel, channel)?;
        too_few(self.teeth.n_kept, wheel, channel)?;
        let sure = tally.sure.unwrap_or(tally.periods);
        let (voters, votes) = if sure >= 2 * wheel.present() as usize {
            (sure, &tally.votes_sure)
        } else {
            (tally.periods, &tally.votes)
        };
        let span = voters / wheel.present() as usize;
        let (residue, &best) = votes
            .iter()
            .enumerate()
            .max_by_key(|v| *v.1)
            .unwrap_or((0, &0));
        let mismatch = tally.mismatch(span);
        if 2 * best < span.max(1) {
            return Err(WheelError::Invalid(mismatch));
        }
        Ok(Gap {
            wheel,
            residue: residue as i64,
            mismatch,
        })
    }
}

impl Tally {
    fn take(&mut self, tooth: Tooth) {
        let Tooth::Period(p) = tooth else { return };
        let (n, m) = (i64::from(self.wheel.teeth), i64::from(self.wheel.missing));
        self.periods += 1;
        if p.unsure && self.sure.is_none() {
            self.sure = Some(p.k);
        }
        self.count += p.pitches;
        if p.pitches == m + 1 {
            let at = self.count.rem_euclid(n) as usize;
            self.votes[at] += 1;
            if self.sure.is_none() {
                self.votes_sure[at] += 1;
            }
        }
        if p.pitches > self.longest {
            self.longest = p.pitches;
            self.longest_at.clear();
        }
        if p.pitches > 1 && p.pitches == self.longest {
            self.longest_at.push(p.k);
        }
    }

    /// Why the periods do not show the wheel's gap: what they show instead.
    fn mismatch(&self, span: usize) -> String {
        let (wheel, channel, longest) = (self.wheel, &self.channel, self.longest);
        let expected = format!(
            "a {wheel} wheel has a gap of {} pitches every {} teeth",
            wheel.missing + 1,
            wheel.present()
        );
        // The longest periods that recur, and the teeth between them.
        if longest <= 1 {
            return format!(
                "'{channel}': no gap — every tooth period is within {PITCH_TOLERANCE} of its neighbours over {} edges, but {expected}",
                self.periods + 1
            );
        }
        let at = &self.longest_at;
        let mut between: Vec<f64> = at.windows(2).map(|w| (w[1] - w[0]) as f64).collect();
        let teeth = if between.is_empty() {
            None
        } else {
            Some(median(&mut between))
        };
        match teeth {
            Some(teeth) if at.len() * 2 >= span => format!(
                "'{channel}': {teeth:.0} teeth between gaps of {longest} pitches, expected {} ({expected}) — is it a {}-{} wheel?",
                wheel.present(),
                teeth as i64 + longest - 1,
                longest - 1
            ),
            _ => format!(
                "'{channel}': no regular gap of {} pitches; the longest periods, of {longest} pitches, come {} times over {span} revolutions — {expected}",
                wheel.missing + 1,
                at.len()
            ),
        }
    }
}

/// The second pass of the indexing ([`index_teeth`]), as the edges come: each kept edge's
/// angle on the wheel, the gap placed by the [`Gap`] the first pass found. Inside a period,
/// every pitch position that is not one of the M missing teeth should have had an edge; a
/// period of M + 1 pitches ending out of the gap's place is the gap itself — when M ≥ 2 (so it
/// is no single missing edge) or after an unsure period — and the count is set again from it.
/// Angle 0 is the first gap's edge: the edges before it are held until it comes (less than a
/// revolution). Holds the findings.
#[derive(Debug, Clone)]
pub struct ToothIndex {
    teeth: Teeth,
    counting: Counting,
}

/// [`ToothIndex`]'s count of the pitches.
#[derive(Debug, Clone)]
struct Counting {
    gap: Gap,
    channel: String,
    count: i64,
    resync: bool,
    /// The count at the first gap's edge, once it has come, and the edges before it: time [s],
    /// count, sample, and whether the period ending there was sure.
    zero: Option<i64>,
    held: VecDeque<(f64, i64, usize, bool)>,
    /// The angles ready: time [s], angle [rad], sample.
    ready: VecDeque<(f64, f64, usize)>,
    /// The last edge given: time, angle.
    last: Option<(f64, f64)>,
    gaps: usize,
    rpm: (f64, f64),
    glitches: Option<(usize, usize)>,
    extras: Vec<Finding>,
    findings: Vec<Finding>,
    /// An encoder with an index ([`crate::wheel::IndexSurvey`]): the index pulses not yet
    /// placed [s], the last kept edges (time, count, sample) a late one is placed against, the
    /// pulses placed.
    pulses: VecDeque<f64>,
    recent: VecDeque<(f64, i64, usize)>,
    index_pulses: usize,
}

/// What the indexing found besides the angles ([`ToothIndex::finish`]).
#[derive(Debug, Clone, PartialEq)]
pub struct ToothReport {
    /// The wheel.
    pub wheel: Wheel,
    /// Edges kept (the extra ones dropped).
    pub edges: usize,
    /// Whole revolutions between the first and last gap.
    pub revolutions: usize,
    /// The slowest and fastest speed over a tooth period [rpm].
    pub rpm: (f64, f64),
    /// Glitch pulses the edge detector rejected.
    pub glitches: usize,
    /// Missing and extra edges, gaps out of place (findings, by sample), glitches rejected
    /// (a note).
    pub findings: Vec<Finding>,
}

impl ToothIndex {
    /// The indexing of the edges on `channel` with the gap found by a first pass over them.
    pub fn new(gap: &Gap, channel: &str) -> Self {
        Self {
            teeth: Teeth::new(gap.wheel),
            counting: Counting {
                gap: gap.clone(),
                channel: channel.to_string(),
                count: 0,
                resync: false,
                zero: None,
                held: VecDeque::new(),
                ready: VecDeque::new(),
                last: None,
                gaps: 0,
                rpm: (f64::INFINITY, 0.0),
                glitches: None,
                extras: Vec::new(),
                findings: Vec::new(),
                pulses: VecDeque::new(),
                recent: VecDeque::new(),
                index_pulses: 0,
            },
        }
    }

    /// An encoder's index pulse at `t` [s] (a wheel without a gap, [`crate::wheel::IndexSurvey`]):
    /// the first edge after it must sit at the reference — else an integrity finding there,
    /// and the count is set again from it. Edges and pulses in time order, as the survey's.
    pub fn index_pulse(&mut self, t: f64) {
        self.counting.pulses.push_back(t);
        self.counting.place_pulses();
    }

    /// The next edge: time [s] and sample.
    pub fn push(&mut self, t: f64, index: usize) {
        let counting = &mut self.counting;
        self.teeth.push(t, index, &mut |tooth| counting.take(tooth));
    }

    /// Glitch pulses rejected by the edge detector: how many, the first's sample (a note).
    pub fn glitches(&mut self, count: usize, first: usize) {
        if count > 0 {
            self.counting.glitches = Some((count, first));
        }
    }

    /// The next edge whose angle is known: time [s], angle [rad], sample.
    pub fn pop(&mut self) -> Option<(f64, f64, usize)> {
        self.counting.ready.pop_front()
    }

    /// No more edges: what was found (the findings sorted by sample), or the error when no
    /// period was the gap. The last angles are then ready ([`pop`](Self::pop)).
    pub fn finish(&mut self) -> Result<ToothReport, WheelError> {
        let counting = &mut self.counting;
        self.teeth.finish(&mut |tooth| counting.take(tooth));
        counting.report(self.teeth.n_kept)
    }
}

impl Counting {
    fn take(&mut self, tooth: Tooth) {
        let p = match tooth {
            Tooth::Extra(i) => {
                let channel = &self.channel;
                self.extras.push(Finding {
                    kind: FindingKind::ExtraPulses,
                    index: i,
                    detail: format!(
                        "'{channel}': an extra edge at sample {i} (less than {EXTRA_EDGE} of a tooth pitch after the one before), dropped"
                    ),
                });
                return;
            }
            Tooth::Period(p) => p,
        };
        if p.k == 0 {
            self.recent.push_back((p.t.0, 0, p.index.0));
            let reference = self.gap.wheel.missing == 0
                && (-self.gap.residue).rem_euclid(i64::from(self.gap.wheel.teeth)) == 0;
            self.edge(p.t.0, 0, p.index.0, true, reference);
        }
        let (n, m) = (
            i64::from(self.gap.wheel.teeth),
            i64::from(self.gap.wheel.missing),
        );
        let residue = self.gap.residue;
        let channel = &self.channel;
        let start = self.count;
        self.count += p.pitches;
        let c = self.count;
        let off = (c - residue).rem_euclid(n);
        let mut gap = false;
        if p.unsure {
            let detail = if p.pitches > n {
                format!(
                    "'{channel}': no tooth edge for {:.4} s before sample {} (about {} pitches at the speed around): the angle across is uncertain and is counted again from the next gap",
                    p.t.1 - p.t.0,
                    p.index.1,
                    p.pitches
                )
            } else {
                format!(
                    "'{channel}': the tooth period ending at sample {} is {:.2} pitches, not a whole number (taken as {})",
                    p.index.1, p.r, p.pitches
                )
            };
            self.findings.push(Finding {
                kind: FindingKind::OutOfSync,
                index: p.index.1,
                detail,
            });
            self.resync = true;
        } else if m > 0 && p.pitches == m + 1 && (m >= 2 || self.resync) && off != 0 {
            self.resync = false;
            let correction = if off > n / 2 { n - off } else { -off };
            self.findings.push(Finding {
                kind: FindingKind::OutOfSync,
                index: p.index.1,
                detail: format!(
                    "'{channel}': the gap ends at sample {} {} pitch(es) from where the teeth before place it: the angle is counted again from it",
                    p.index.1,
                    -correction
                ),
            });
            self.count += correction;
            gap = true;
        } else {
            let lost = (start + 1..c)
                .filter(|q| (q - residue).rem_euclid(n) < n - m)
                .count();
            if lost > 0 {
                self.findings.push(Finding {
                    kind: FindingKind::PulseLoss,
                    index: p.index.1,
                    detail: format!(
                        "'{channel}': {lost} tooth edge(s) missing before sample {} (the angle counts the pitches across)",
                        p.index.1
                    ),
                });
            }
            if off == 0 {
                gap = true;
                self.resync = false;
            }
        }
        self.edge(p.t.1, self.count, p.index.1, !p.unsure, gap);
        if m == 0 {
            self.recent.push_back((p.t.1, self.count, p.index.1));
            while self.recent.len() > crate::wheel::index_pulse::RECENT_EDGES {
                self.recent.pop_front();
            }
            self.place_pulses();
        }
    }

    /// The index pulses an edge now follows: the first edge after each must be at the
    /// reference; when it is not, a finding, and the edges after it counted from it (those
    /// already given keep their angle).
    fn place_pulses(&mut self) {
        let n = i64::from(self.gap.wheel.teeth);
        while let Some(&tp) = self.pulses.front() {
            let Some(&(_, c, index)) = self.recent.iter().find(|(t, ..)| *t > tp) else {
                return;
            };
            self.pulses.pop_front();
            if self.recent.front().is_some_and(|(t, ..)| *t > tp) && c != 0 {
                continue;
            }
            self.index_pulses += 1;
            let off = (c - self.gap.residue).rem_euclid(n);
            if off != 0 {
                let correction = if off > n / 2 { n - off } else { -off };
                self.findings.push(Finding {
                    kind: FindingKind::OutOfSync,
                    index,
                    detail: format!(
                        "'{}': the first edge after an index pulse is at sample {index} {} pulse(s) from where the edges before place it: the angle is counted again from it",
                        self.channel, -correction
                    ),
                });
                self.count += correction;
                for e in &mut self.recent {
                    if e.0 >= tp {
                        e.1 += correction;
                    }
                }
            }
        }
    }

    /// A kept edge's count (`sure`: the period ending there; `gap`: it ends the gap).
    fn edge(&mut self, t: f64, count: i64, index: usize, sure: bool, gap: bool) {
        self.held.push_back((t, count, index, sure));
        if gap {
            self.gaps += 1;
            self.zero.get_or_insert(count);
        }
        let Some(zero) = self.zero else { return };
        let pitch = self.gap.wheel.pitch();
        while let Some((t, c, index, sure)) = self.held.pop_front() {
            let angle = (c - zero) as f64 * pitch;
            if let (Some((tp, ap)), true) = (self.last, sure) {
                let rpm = (angle - ap) / (t - tp) * 30.0 / std::f64::consts::PI;
                self.rpm = (self.rpm.0.min(rpm), self.rpm.1.max(rpm));
            }
            self.last = Some((t, angle));
            self.ready.push_back((t, angle, index));
        }
    }

    /// What was found, once the edges have ended.
    fn report(&mut self, edges: usize) -> Result<ToothReport, WheelError> {
        if self.zero.is_none() {
            return Err(WheelError::Invalid(self.gap.mismatch.clone()));
        }
        let channel = &self.channel;
        let mut findings: Vec<Finding> = self
            .glitches
            .map(|(count, first)| Finding {
                kind: FindingKind::Note,
                index: first,
                detail: format!(
                    "'{channel}': {count} glitch pulse(s) narrower than {:.0} % of a tooth rejected (the first at sample {first})",
                    GLITCH_WIDTH * 100.0,
                ),
            })
            .into_iter()
            .collect();
        findings.append(&mut self.extras);
        findings.append(&mut self.findings);
        findings.sort_by_key(|f| f.index);
        Ok(ToothReport {
            wheel: self.gap.wheel,
            edges,
            revolutions: self.gaps.saturating_sub(1),
            rpm: self.rpm,
            glitches: self.glitches.map_or(0, |g| g.0),
            findings,
        })
    }
}

/// The angle of every edge on the wheel `wheel` (see the module docs), from edges found on
/// the channel `channel` (named in the findings and errors): [`GapSurvey`] over them, then
/// [`ToothIndex`] — the two passes a stream makes, over the edges held.
pub fn index_teeth(edges: &Edges, wheel: Wheel, channel: &str) -> Result<WheelAngles, WheelError> {
    if edges.index.len() != edges.t.len() {
        return Err(WheelError::Invalid(format!(
            "'{channel}': {} edge times but {} samples",
            edges.t.len(),
            edges.index.len()
        )));
    }
    let pairs = || edges.t.iter().copied().zip(edges.index.iter().copied());
    let mut survey = GapSurvey::new(wheel, channel);
    for (t, i) in pairs() {
        survey.push(t, i);
    }
    let gap = survey.finish()?;
    let mut index = ToothIndex::new(&gap, channel);
    index.glitches(
        edges.glitches.len(),
        edges.glitches.first().copied().unwrap_or(0),
    );
    let (mut t, mut angle, mut at) = (Vec::new(), Vec::new(), Vec::new());
    let mut take = |index: &mut ToothIndex| {
        while let Some((x, a, i)) = index.pop() {
            t.push(x);
            angle.push(a);
            at.push(i);
        }
    };
    for (x, i) in pairs() {
        index.push(x, i);
        take(&mut index);
    }
    let report = index.finish()?;
    take(&mut index);
    Ok(WheelAngles {
        wheel,
        t,
        angle,
        index: at,
        revolutions: report.revolutions,
        rpm: report.rpm,
        findings: report.findings,
    })
}

impl WheelAngles {
    /// The wheel's angle at the times `at` [s] (increasing), by the monotone cubic through the
    /// edges; NaN before the first edge and after the last.
    pub fn angle_at(&self, at: &[f64]) -> Vec<f64> {
        pchip_at(&self.t, &self.angle, at)
    }
}
