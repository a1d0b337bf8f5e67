//! Each edge's angle on the wheel: from the periods counted in pitches (`teeth.rs`), the gap
//! found ([`GapSurvey`]), the teeth indexed as they come ([`ToothIndex`]) or over a record
//! ([`index_teeth`]), with the missing and extra edges as findings.

use super::*;

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

    /// The samples not finite the edge detector skipped on `channel` (the wheel's, or an
    /// encoder's index): a finding at each run kept, a note for the rest. An edge they hid is
    /// counted as a missing tooth, as any edge the sensor lost.
    pub fn dropouts(&mut self, channel: &str, d: &Dropouts) {
        let found = d.findings(channel, "skipped, no edge is found across them");
        self.counting.extras.extend(found);
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
    index.dropouts(channel, &edges.dropouts);
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
