//! A pulse encoder with an index: a single channel of N pulses per revolution (a wheel of N
//! pitches and no gap, `Wheel { teeth: N, missing: 0 }`) whose reference is a separate
//! once-per-revolution index pulse, not a gap. [`IndexSurvey`] is the first pass: where, modulo
//! N pulses, the first edge after each index pulse falls — the [`Gap`] the indexing
//! ([`ToothIndex`] with [`ToothIndex::index_pulse`]) then counts from, checking every index pulse
//! against it. The edges go through the same extra-edge and pitch counting as a wheel's; the
//! index pulses through their own [`EdgeDetector`] (the same glitch rejection).

use super::*;

/// The edges kept whose counts a late index pulse can still be placed against.
pub const RECENT_EDGES: usize = 64;

/// Edges `(time [s], sample)` and index pulses `[s]`, each in order, handed on merged in time
/// order: what [`IndexSurvey`] and [`ToothIndex`] take.
pub fn in_time_order(
    edges: &[(f64, usize)],
    pulses: &[f64],
    mut edge: impl FnMut(f64, usize),
    mut pulse: impl FnMut(f64),
) {
    let mut p = pulses.iter().peekable();
    for &(t, i) in edges {
        while let Some(&&tp) = p.peek().filter(|&&&tp| tp <= t) {
            pulse(tp);
            p.next();
        }
        edge(t, i);
    }
    p.for_each(|&tp| pulse(tp));
}

/// Where the first edge after each index pulse falls, modulo the pulses per revolution (see the
/// module docs).
#[derive(Debug, Clone)]
pub struct IndexSurvey {
    teeth: Teeth,
    tally: Placing,
}

/// The index pulses placed on the edges' count.
#[derive(Debug, Clone)]
struct Placing {
    wheel: Wheel,
    channel: String,
    index: String,
    count: i64,
    /// The last kept edges: time [s], count.
    recent: VecDeque<(f64, i64)>,
    /// Index pulses not yet placed (no edge after them yet) [s].
    pulses: VecDeque<f64>,
    /// The count of the first edge after each index pulse placed.
    placed: Vec<i64>,
}

impl Placing {
    fn take(&mut self, tooth: Tooth) {
        let Tooth::Period(p) = tooth else { return };
        if p.k == 0 {
            self.recent.push_back((p.t.0, 0));
        }
        self.count += p.pitches;
        self.recent.push_back((p.t.1, self.count));
        while self.recent.len() > RECENT_EDGES {
            self.recent.pop_front();
        }
        self.place();
    }

    /// Place the pulses waiting that an edge now follows.
    fn place(&mut self) {
        while let Some(&tp) = self.pulses.front() {
            let Some(&(_, c)) = self.recent.iter().find(|(t, _)| *t > tp) else {
                return;
            };
            self.pulses.pop_front();
            // Before the oldest edge held: too late to place (not expected, an index pulse
            // comes within a few edges).
            if self.recent.front().is_some_and(|(t, _)| *t > tp) && c != 0 {
                continue;
            }
            self.placed.push(c);
        }
    }
}

impl IndexSurvey {
    /// A survey of an encoder of `pulses` per revolution on `channel` with its index on
    /// `index` (both named in the errors).
    pub fn new(pulses: u32, channel: &str, index: &str) -> Self {
        let wheel = Wheel {
            teeth: pulses,
            missing: 0,
        };
        Self {
            teeth: Teeth::new(wheel),
            tally: Placing {
                wheel,
                channel: channel.to_string(),
                index: index.to_string(),
                count: 0,
                recent: VecDeque::new(),
                pulses: VecDeque::new(),
                placed: Vec::new(),
            },
        }
    }

    /// The next edge of the encoder: time [s] and sample.
    pub fn push(&mut self, t: f64, index: usize) {
        let tally = &mut self.tally;
        self.teeth.push(t, index, &mut |tooth| tally.take(tooth));
    }

    /// The next index pulse's time [s]: edges and pulses given in time order (a pulse may come
    /// up to [`RECENT_EDGES`] edges late — its detector ends a pulse after it began; see
    /// [`in_time_order`]).
    pub fn pulse(&mut self, t: f64) {
        self.tally.pulses.push_back(t);
        self.tally.place();
    }

    /// Where the reference is, or why it cannot be told: too few edges, no index pulse, index
    /// pulses not a whole number of revolutions apart (the pulses per revolution wrong).
    pub fn finish(mut self) -> Result<Gap, WheelError> {
        let tally = &mut self.tally;
        self.teeth.finish(&mut |tooth| tally.take(tooth));
        let p = &self.tally;
        let (wheel, channel, index) = (p.wheel, p.channel.as_str(), p.index.as_str());
        too_few(self.teeth.edges, wheel, channel)?;
        too_few(self.teeth.n_kept, wheel, channel)?;
        let n = i64::from(wheel.teeth);
        let mut votes = vec![0usize; wheel.teeth as usize];
        for c in &p.placed {
            votes[c.rem_euclid(n) as usize] += 1;
        }
        let (residue, &best) = votes
            .iter()
            .enumerate()
            .max_by_key(|v| *v.1)
            .unwrap_or((0, &0));
        // What the pulses show: the edges between consecutive index pulses.
        let mut between: Vec<i64> = p.placed.windows(2).map(|w| w[1] - w[0]).collect();
        between.sort_unstable();
        let mismatch = match (p.placed.len(), between.get(between.len() / 2)) {
            (0, _) => format!(
                "'{index}': no index pulse among {} edges of '{channel}': expected one a revolution (is the channel the index? --threshold is the encoder's, the index's level is found from its own range)",
                self.teeth.edges
            ),
            (_, Some(m)) => format!(
                "'{channel}': {m} edges between the index pulses of '{index}' (the median), but the encoder was given {} pulses a revolution",
                wheel.teeth
            ),
            _ => format!("'{index}': one index pulse only: the reference needs two revolutions"),
        };
        if p.placed.len() < 2 || 2 * best <= p.placed.len() {
            return Err(WheelError::Invalid(mismatch));
        }
        Ok(Gap {
            wheel,
            residue: residue as i64,
            mismatch,
        })
    }
}
