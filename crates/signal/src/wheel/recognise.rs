//! Which N−M wheel a record of edges came from, when it is not given ([`recognise`]).

use super::*;

/// What a signal's edges say about the wheel it came from ([`recognise`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Recognised {
    /// The wheel: teeth between gaps + the gap's pitches − 1 = N, M from the gap's length.
    pub wheel: Wheel,
    /// The gaps seen.
    pub gaps: usize,
    /// Edges found.
    pub edges: usize,
}

/// Whether `edges` look like a toothed wheel's — a regular pulse train with a longer gap at a
/// fixed count of teeth — and which N−M: each gap is a period of about M+1 pitches (1.6 … 6,
/// relative to the median of its neighbours), N−M teeth lie between consecutive gaps. Needs
/// 50 edges, 3 gaps, four in five of the counts between them and of their lengths the same,
/// and nine periods in ten regular (a tooth or a gap).
pub fn recognise(edges: &Edges) -> Option<Recognised> {
    let t = &edges.t;
    if t.len() < 50 {
        return None;
    }
    let r = relative_periods(t);
    let gaps: Vec<usize> = (0..r.len())
        .filter(|&k| (1.6..6.0).contains(&r[k]))
        .collect();
    let regular = r.iter().filter(|x| (0.7..1.4).contains(*x)).count();
    if gaps.len() < 3 || (regular + gaps.len()) * 10 < r.len() * 9 {
        return None;
    }
    // The most common spacing and gap length, and how many agree with them.
    let mode = |v: &[usize]| {
        let mut best = (0, 0);
        for &x in v {
            let c = v.iter().filter(|&&y| y == x).count();
            if c > best.1 {
                best = (x, c);
            }
        }
        best
    };
    let spacing: Vec<usize> = gaps.windows(2).map(|w| w[1] - w[0]).collect();
    let lengths: Vec<usize> = gaps.iter().map(|&k| r[k].round() as usize).collect();
    let (present, agree) = mode(&spacing);
    let (gap, agree_gap) = mode(&lengths);
    let m = gap.checked_sub(1)?;
    if agree * 5 < spacing.len() * 4 || agree_gap * 5 < lengths.len() * 4 || m == 0 || present < 2 {
        return None;
    }
    Some(Recognised {
        wheel: Wheel {
            teeth: u32::try_from(present + m).ok()?,
            missing: u32::try_from(m).ok()?,
        },
        gaps: gaps.len(),
        edges: t.len(),
    })
}
