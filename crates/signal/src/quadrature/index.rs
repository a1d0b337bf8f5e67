//! A quadrature encoder's index Z: its comparator's level by a first pass ([`IndexRange`]) and
//! the angle 0 at its first pulse turning forward, the later ones checked ([`IndexZero`]).

use super::{IndexPulse, Transition};
use crate::integrity::{Finding, FindingKind};
use crate::wheel::Pchip;
use std::f64::consts::TAU;

/// The smallest and largest finite sample of an index channel, a chunk at a time: its
/// comparator's level ([`QuadratureDecoder`]'s first pass, and a pulse encoder's index).
#[derive(Debug, Clone, Copy)]
pub struct IndexRange {
    /// Smallest and largest so far.
    pub range: (f64, f64),
}

impl Default for IndexRange {
    fn default() -> Self {
        Self {
            range: (f64::INFINITY, f64::NEG_INFINITY),
        }
    }
}

impl IndexRange {
    /// The next samples.
    pub fn push(&mut self, z: &[f64]) {
        self.range = z
            .iter()
            .filter(|x| x.is_finite())
            .fold(self.range, |(a, b), &x| (a.min(x), b.max(x)));
    }
}

/// The angle 0 of a decoded encoder and the index pulses out of place, as transitions and
/// pulses come: the angle at the first index pulse turning forward (by the monotone cubic
/// through the transitions, [`Pchip`]), or without one the first transition's; every later
/// pulse a whole revolution on within 1.5 counts, else a finding. Holds the pulses not yet
/// placed.
#[derive(Debug, Clone)]
pub struct IndexZero {
    q: f64,
    lines: u32,
    name: String,
    pchip: Pchip,
    pending: std::collections::VecDeque<IndexPulse>,
    first_angle: Option<f64>,
    zero: Option<f64>,
    pulses: usize,
    findings: Vec<Finding>,
}

impl IndexZero {
    /// For an encoder of `lines` lines whose index channel is `name`.
    pub fn new(lines: u32, name: &str) -> Self {
        Self {
            q: TAU / (4.0 * lines as f64),
            lines,
            name: name.to_string(),
            pchip: Pchip::default(),
            pending: std::collections::VecDeque::new(),
            first_angle: None,
            zero: None,
            pulses: 0,
            findings: Vec::new(),
        }
    }

    /// The next transition.
    pub fn transition(&mut self, tr: Transition) {
        let angle = tr.edge as f64 * self.q;
        self.first_angle.get_or_insert(angle);
        self.pchip.push(tr.t, angle);
        self.place();
    }

    /// The next index pulse.
    pub fn pulse(&mut self, p: IndexPulse) {
        self.pulses += 1;
        self.pending.push_back(p);
        self.place();
    }

    /// The pulses whose angle is known.
    fn place(&mut self) {
        while let Some(p) = self.pending.front().copied() {
            let Some(at) = self.pchip.at(p.t) else {
                return;
            };
            self.pending.pop_front();
            match self.zero {
                None => {
                    self.zero = Some(if at.is_finite() {
                        at
                    } else {
                        self.first_angle.unwrap_or(0.0)
                    });
                }
                Some(zero) => {
                    let revs = (at - zero) / TAU;
                    let off = (revs - revs.round()) * 4.0 * self.lines as f64;
                    if off.abs() > 1.5 {
                        self.findings.push(Finding {
                            kind: FindingKind::OutOfSync,
                            index: p.index,
                            detail: format!(
                                "'{}': index pulse at sample {} {:.1} counts after the first, not a whole number of revolutions of {}",
                                self.name,
                                p.index,
                                revs * 4.0 * self.lines as f64,
                                4 * self.lines
                            ),
                        });
                    }
                }
            }
        }
    }

    /// No more transitions or pulses: the angle 0 [rad on the counts' scale], the pulses turning
    /// forward, and the pulses out of place.
    pub fn finish(mut self) -> (f64, usize, Vec<Finding>) {
        self.pchip.end();
        self.place();
        let zero = self.zero.or(self.first_angle).unwrap_or(0.0);
        (zero, self.pulses, self.findings)
    }
}
