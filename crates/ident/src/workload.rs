//! Reproducible workloads for the benchmarks (criterion and `physid bench`): sensitivity rows
//! from a dependency-free low-discrepancy sequence (the ranking's cost does not depend on the
//! values), the batch ranking of n such rows, and the on-line update.

use crate::online::{Memory, OnlineIdent};
use crate::ranking::{rank, Ranking};
use crate::triangular::TriangularFactor;
use crate::IdentError;

/// `n` rows of `p` values in [−1, 1), row-major, with column j scaled by (1 + j) so the
/// ranking has distinct steps.
pub fn rows(n: usize, p: usize) -> Vec<f64> {
    // Additive recurrence with the plastic-number constant (R2 sequence): well spread, no RNG.
    const ALPHA: f64 = 0.754_877_666_246_692_7;
    (0..n * p)
        .map(|k| {
            let j = k % p;
            (((k as f64) * ALPHA + 0.5 * j as f64).fract() * 2.0 - 1.0) * (1.0 + j as f64)
        })
        .collect()
}

/// The batch ranking of row-major `rows` (p columns): stream them into the triangular factor,
/// then rank — Alg. 5.1 in O(n·p²) time and O(p²) memory.
pub fn rank_rows(rows: &[f64], p: usize) -> Ranking {
    let mut f = TriangularFactor::new(p);
    for r in rows.chunks_exact(p) {
        f.add_row(r);
    }
    rank(&f.r())
}

/// The on-line update over a sliding window (one Givens sweep in, one downdating sweep out
/// per row).
#[derive(Debug, Clone)]
pub struct OnlineWorkload {
    ident: OnlineIdent,
    rows: Vec<f64>,
    next: usize,
}

impl OnlineWorkload {
    /// p parameters, a window of `window` rows, cycling through `n` precomputed rows.
    pub fn new(p: usize, window: usize, n: usize) -> Result<Self, IdentError> {
        Ok(Self {
            ident: OnlineIdent::new(p, Memory::Window(window))?,
            rows: rows(n.max(1), p),
            next: 0,
        })
    }

    /// Run `k` updates.
    pub fn run(&mut self, k: usize) -> Result<(), IdentError> {
        let p = self.ident.p();
        let n = self.rows.len() / p;
        for _ in 0..k {
            let i = self.next % n;
            self.ident.update(&self.rows[i * p..(i + 1) * p])?;
            self.next += 1;
        }
        Ok(())
    }

    /// The analysis (to read the ranking after a run).
    pub fn ident(&self) -> &OnlineIdent {
        &self.ident
    }
}
