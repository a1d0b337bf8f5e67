//! On-line identifiability (thesis §9.2, named as future work): the triangular factor updated
//! row by row with exponential forgetting or over a sliding window, and the current ranking at
//! any sample — which parameters the *recent* data can support.
//!
//! Per row: O(p²) (one Givens sweep; a window adds one downdating sweep), allocation-free. The
//! ranking itself is O(p³) and computed on request. [`OnlineIdent::supported`] is the signal
//! an estimator uses to freeze a parameter that has lost excitation.

use crate::ranking::{rank, Cutoff, RankWorkspace, Ranking};
use crate::triangular::TriangularFactor;
use crate::IdentError;
use serde::{Deserialize, Serialize};

/// What the on-line analysis remembers.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Memory {
    /// Exponential forgetting: row i weighs `λ^(n−i)` (0 < λ ≤ 1).
    Forgetting(f64),
    /// The last N rows exactly.
    Window(usize),
}

/// Recursive orthogonal ranking.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct OnlineIdent {
    factor: TriangularFactor,
    memory: Memory,
    sqrt_lambda: f64,
    /// Window: ring buffer of the rows inside it (N × p).
    ring: Vec<f64>,
    head: usize,
    filled: usize,
    samples: u64,
    rebuilds: u64,
}

impl OnlineIdent {
    /// An analysis of p parameters with the given memory.
    pub fn new(p: usize, memory: Memory) -> Result<Self, IdentError> {
        let (sqrt_lambda, ring) = match memory {
            Memory::Forgetting(l) if l > 0.0 && l <= 1.0 => (l.sqrt(), Vec::new()),
            Memory::Forgetting(l) => {
                return Err(IdentError::Invalid(format!(
                    "forgetting factor {l}: expected 0 < λ ≤ 1",
                    l = physid_core::Num(l)
                )))
            }
            Memory::Window(0) => {
                return Err(IdentError::Invalid("window of 0 rows".into()));
            }
            Memory::Window(w) => (1.0, vec![0.0; w * p]),
        };
        Ok(Self {
            factor: TriangularFactor::new(p),
            memory,
            sqrt_lambda,
            ring,
            head: 0,
            filled: 0,
            samples: 0,
            rebuilds: 0,
        })
    }

    /// Number of parameters.
    pub fn p(&self) -> usize {
        self.factor.p()
    }

    /// Fold in one scaled sensitivity row (length p). A non-finite entry is refused with the
    /// state untouched. Allocation-free.
    pub fn update(&mut self, z: &[f64]) -> Result<(), IdentError> {
        let p = self.p();
        if z.len() != p {
            return Err(IdentError::Invalid(format!(
                "sensitivity row of length {}, expected {p}",
                z.len()
            )));
        }
        if let Some(k) = z.iter().position(|v| !v.is_finite()) {
            return Err(IdentError::BadValue {
                row: self.samples as usize,
                column: format!("sensitivity[{k}]"),
                value: z[k],
            });
        }
        match self.memory {
            Memory::Forgetting(_) => {
                self.factor.scale(self.sqrt_lambda);
                self.factor.add_row(z);
            }
            Memory::Window(w) => {
                if self.filled == w {
                    let old = &self.ring[self.head * p..(self.head + 1) * p];
                    if self.factor.remove_row(old).is_err() {
                        // Rounding has eaten the window's information: rebuild from the rows.
                        self.rebuild_without_head();
                    }
                } else {
                    self.filled += 1;
                }
                self.ring[self.head * p..(self.head + 1) * p].copy_from_slice(z);
                self.head = (self.head + 1) % w;
                self.factor.add_row(z);
            }
        }
        self.samples += 1;
        Ok(())
    }

    /// Refold every row of the ring except the oldest (at `head`).
    fn rebuild_without_head(&mut self) {
        let p = self.p();
        let w = self.ring.len() / p;
        self.factor.clear();
        for k in 1..w {
            let i = (self.head + k) % w;
            self.factor.add_row(&self.ring[i * p..(i + 1) * p]);
        }
        self.rebuilds += 1;
    }

    /// The current ranking (O(p³)).
    pub fn ranking(&self) -> Ranking {
        rank(&self.factor.r())
    }

    /// The same ranking in `ws` (made for [`p`](Self::p) parameters), allocating nothing.
    pub fn ranking_into<'w>(&self, ws: &'w mut RankWorkspace) -> &'w Ranking {
        self.factor.r_into(ws.factor_mut());
        ws.rank()
    }

    /// Which parameters the remembered data supports under `cutoff`: `true` for the first K
    /// of the current ranking.
    pub fn supported(&self, cutoff: Cutoff) -> Vec<bool> {
        let r = self.ranking();
        let k = r.estimable(cutoff);
        let mut s = vec![false; self.p()];
        for step in &r.steps[..k] {
            s[step.param] = true;
        }
        s
    }

    /// Rows seen.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// Times a failed downdate forced a rebuild of the window's factor.
    pub fn rebuilds(&self) -> u64 {
        self.rebuilds
    }

    /// The factor (for inspection and tests).
    pub fn factor(&self) -> &TriangularFactor {
        &self.factor
    }
}
