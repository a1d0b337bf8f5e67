//! A sample that is not a number — a sensor's dropout, a DAQ's NaN, a damaged file's cell —
//! held at the signal's last value and taken out like a glitch ([`super::glitch`]): the
//! estimator held around it, the samples told. Before, one such sample stopped the shaft
//! monitor for the rest of the run ("sample 4999: a shaft signal is not finite"). Nothing is
//! absorbed: a held sample never updates the estimator.

use serde::{Deserialize, Serialize};

/// The shaft signals a chunk carries, in [`Dropouts::fill`]'s order.
pub const SIGNALS: [&str; 5] = [
    "theta_dy",
    "theta_en",
    "omega_dy",
    "omega_en",
    "torque_shaft",
];

/// A dropout that started in a chunk: the signal ([`SIGNALS`]' index), the chunk's index of
/// its first sample, and how many dropouts started in the chunk.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Dropout {
    pub signal: usize,
    pub at: usize,
    pub count: usize,
}

/// The shaft signals' last finite values, and whether each is in a dropout, across chunks.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Dropouts {
    last: [Option<f64>; 5],
    within: [bool; 5],
    /// Per signal over the run: dropouts, samples held, the first one's sample.
    runs: [usize; 5],
    samples: [usize; 5],
    first: [Option<usize>; 5],
    /// The last chunk's columns with their dropouts filled (room kept between chunks).
    #[serde(skip)]
    pub(super) filled: [Vec<f64>; 5],
    /// The last chunk's samples held for a dropout of any signal.
    #[serde(skip)]
    pub(super) held: Vec<bool>,
}

impl Dropouts {
    /// Find the samples of `cols` (the [`SIGNALS`], equally long) that are not finite; when
    /// there are any, copy the columns into `filled` with each such sample at its signal's last
    /// finite value (before the signal's first finite value: that value; a signal with none
    /// yet: 0), mark them in `held`, and return the dropouts that started in this chunk, one
    /// per signal (none when they all went on from the chunk before). With every sample
    /// finite, nothing is copied and `None` is returned.
    /// `first` is the stream's index of the chunk's first sample.
    pub fn fill(&mut self, cols: [&[f64]; 5], first: usize) -> Option<Vec<Dropout>> {
        if cols.iter().all(|c| c.iter().all(|v| v.is_finite())) {
            for (k, c) in cols.iter().enumerate() {
                if let Some(&v) = c.last() {
                    self.last[k] = Some(v);
                    self.within[k] = false;
                }
            }
            return None;
        }
        let mut started = Vec::new();
        let n = cols[0].len();
        self.held.clear();
        self.held.resize(n, false);
        for (k, c) in cols.iter().enumerate() {
            let out = &mut self.filled[k];
            out.clear();
            out.extend_from_slice(c);
            let mut hold = self.last[k]
                .or_else(|| c.iter().copied().find(|v| v.is_finite()))
                .unwrap_or(0.0);
            let mut started_here: Option<Dropout> = None;
            for (i, v) in out.iter_mut().enumerate() {
                if v.is_finite() {
                    hold = *v;
                    self.within[k] = false;
                    continue;
                }
                *v = hold;
                self.held[i] = true;
                self.samples[k] += 1;
                if !self.within[k] {
                    self.within[k] = true;
                    self.runs[k] += 1;
                    self.first[k].get_or_insert(first + i);
                    let d = started_here.get_or_insert(Dropout {
                        signal: k,
                        at: i,
                        count: 0,
                    });
                    d.count += 1;
                }
            }
            if n > 0 {
                self.last[k] = Some(hold);
            }
            started.extend(started_here);
        }
        Some(started)
    }

    /// What the run's dropouts were, one line per signal that had any.
    pub fn findings(&self) -> impl Iterator<Item = String> + '_ {
        (0..SIGNALS.len()).filter_map(|k| {
            let at = self.first[k]?;
            Some(format!(
                "'{}' was not a number at {} sample(s) in {} dropout(s), the first from sample {at}: held at its last value and taken out as a sensor's dropout, not the shaft",
                SIGNALS[k], self.samples[k], self.runs[k]
            ))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Held at the last finite value, across chunks; told once per dropout started; a signal
    /// that starts with NaN takes its first finite value.
    #[test]
    fn dropouts_are_held_and_told_once() {
        let nan = f64::NAN;
        let mut d = Dropouts::default();
        let ok = [1.0, 2.0, 3.0];
        assert!(d.fill([&ok, &ok, &ok, &ok, &ok], 0).is_none());
        let torque = [4.0, nan, nan];
        let theta = [nan, 5.0, nan];
        let found = d.fill([&ok, &theta, &ok, &ok, &torque], 3).unwrap();
        assert_eq!(
            found,
            [
                Dropout {
                    signal: 1,
                    at: 0,
                    count: 2
                },
                Dropout {
                    signal: 4,
                    at: 1,
                    count: 1
                }
            ]
        );
        assert_eq!(d.filled[1], [3.0, 5.0, 5.0]);
        assert_eq!(d.filled[4], [4.0, 4.0, 4.0]);
        assert_eq!(d.held, [true, true, true]);
        // The torque's dropout goes on into the next chunk: not told again.
        let torque = [nan, 6.0, 7.0];
        assert_eq!(d.fill([&ok, &ok, &ok, &ok, &torque], 6), Some(vec![]));
        assert_eq!(d.filled[4], [4.0, 6.0, 7.0]);
        assert_eq!(d.held, [true, false, false]);
        let told: Vec<String> = d.findings().collect();
        assert_eq!(told.len(), 2, "{told:?}");
        assert!(told[0].starts_with("'theta_en' was not a number at 2 sample(s) in 2 dropout(s), the first from sample 3:"), "{told:?}");
        assert!(told[1].starts_with("'torque_shaft' was not a number at 3 sample(s) in 1 dropout(s), the first from sample 4:"), "{told:?}");
        // Before any finite value: the first one.
        let mut d = Dropouts::default();
        let w = [nan, 8.0, 9.0];
        d.fill([&ok, &ok, &ok, &w, &ok], 0);
        assert_eq!(d.filled[3], [8.0, 8.0, 9.0]);
    }
}
