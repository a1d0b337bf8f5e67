//! Zero-phase filtering on a stream: `sosfiltfilt` ([`Sos::sosfiltfilt`]) for samples that
//! arrive in chunks, as the thesis's real-time loop did forward–backward filtering over FIFO
//! blocks (§4.4).
//!
//! The forward pass is causal and runs on every sample as it arrives, from the same odd
//! reflection and steady-state start as the whole-record filter — so it is the whole-record
//! forward pass exactly. The backward pass needs the future: the output is produced in blocks
//! of [`block`](ZeroPhaseStream::block) samples, each filtered backwards from `lookahead`
//! samples beyond its end, started from the steady state of the forward output there (as the
//! whole-record filter starts from the steady state of its last value). The truncation's effect
//! decays with the filter's impulse response: `lookahead` is the length after which that
//! response has fallen below `1e-14` of its total (so the interior equals the whole-record
//! result to ≈ 1e-13 of the signal's scale). At the end of the stream the last samples are
//! filtered backwards from the true end, with the end's odd reflection: they equal the whole
//! record's bit for bit.
//!
//! **Latency:** a sample leaves at most `block + lookahead` samples after it arrived
//! ([`latency`](ZeroPhaseStream::latency)). The output does not depend on how the input is
//! chunked: blocks are placed by sample index, not by chunk.

use crate::filter::{FilterError, Sos};

/// Fraction of the impulse response's total left beyond the lookahead.
const TAIL: f64 = 1e-14;

/// Zero-phase filtering of a stream (see the module docs).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct ZeroPhaseStream {
    sos: Sos,
    zi: Vec<[f64; 2]>,
    padlen: usize,
    lookahead: usize,
    block: usize,
    /// The first `padlen + 1` inputs, until the forward pass can start.
    head: Vec<f64>,
    /// The last `padlen + 1` inputs (the end's reflection).
    tail: Vec<f64>,
    /// Forward-pass state, once started.
    z: Option<Vec<[f64; 2]>>,
    /// Forward output, extended indices `base ..`.
    fwd: Vec<f64>,
    base: usize,
    /// Output samples given so far (the next block starts at extended index `padlen + given`).
    given: usize,
    /// Inputs taken.
    taken: usize,
    work: Vec<f64>,
    zb: Vec<[f64; 2]>,
}

impl ZeroPhaseStream {
    /// A stream through `sos`; `lookahead` samples of future for the backward pass (`None`:
    /// from the filter's impulse response, see the module docs), blocks of `block` samples
    /// (`None`: the lookahead).
    pub fn new(sos: &Sos, lookahead: Option<usize>, block: Option<usize>) -> Self {
        let lookahead = lookahead.unwrap_or_else(|| settling_length(sos));
        let block = block.unwrap_or(lookahead).max(1);
        let padlen = sos.padlen();
        Self {
            zi: sos.sosfilt_zi(),
            sos: sos.clone(),
            padlen,
            lookahead,
            block,
            head: Vec::with_capacity(padlen + 1),
            tail: Vec::with_capacity(padlen + 1),
            z: None,
            fwd: Vec::with_capacity(2 * (block + lookahead) + 2 * padlen + 2),
            base: 0,
            given: 0,
            taken: 0,
            work: Vec::with_capacity(block + lookahead + 2 * padlen + 1),
            zb: vec![[0.0; 2]; sos.sections.len()],
        }
    }

    /// The lookahead [samples].
    pub fn lookahead(&self) -> usize {
        self.lookahead
    }

    /// The block [samples].
    pub fn block(&self) -> usize {
        self.block
    }

    /// The most samples an output waits for after its input arrived: `block + lookahead`.
    pub fn latency(&self) -> usize {
        self.block + self.lookahead
    }

    /// Samples taken so far.
    pub fn taken(&self) -> usize {
        self.taken
    }

    /// Take `x`; append the output samples that are ready to `out`. A non-finite sample is
    /// refused (nothing of `x` taken) with its index in the stream. Allocation-free once
    /// `out` has room.
    pub fn push(&mut self, x: &[f64], out: &mut Vec<f64>) -> Result<(), FilterError> {
        if let Some(i) = x.iter().position(|v| !v.is_finite()) {
            return Err(FilterError::NonFinite {
                index: self.taken + i,
                value: x[i],
            });
        }
        let mut rest = x;
        while self.z.is_none() && !rest.is_empty() {
            self.head.push(rest[0]);
            rest = &rest[1..];
            if self.head.len() == self.padlen + 1 {
                self.start();
            }
        }
        if let Some(z) = self.z.as_mut() {
            let from = self.fwd.len();
            self.fwd.extend_from_slice(rest);
            self.sos.sections_inplace(&mut self.fwd[from..], z, false);
        }
        // The last padlen + 1 inputs.
        let keep = self.padlen + 1;
        if x.len() >= keep {
            self.tail.clear();
            self.tail.extend_from_slice(&x[x.len() - keep..]);
        } else {
            let over = (self.tail.len() + x.len()).saturating_sub(keep);
            self.tail.drain(..over);
            self.tail.extend_from_slice(x);
        }
        self.taken += x.len();
        self.emit_ready(out);
        Ok(())
    }

    /// The forward pass from the start's odd reflection, over the inputs held so far.
    fn start(&mut self) {
        let (x0, n) = (self.head[0], self.padlen);
        self.fwd.clear();
        self.fwd
            .extend((1..=n).rev().map(|i| 2.0 * x0 - self.head[i]));
        self.fwd.extend_from_slice(&self.head);
        // From the steady state of the extended signal's first value, as sosfiltfilt.
        let e0 = self.fwd[0];
        let mut z: Vec<[f64; 2]> = self.zi.iter().map(|s| [s[0] * e0, s[1] * e0]).collect();
        self.sos.sections_inplace(&mut self.fwd, &mut z, false);
        self.z = Some(z);
        self.base = 0;
    }

    /// Every whole block whose lookahead has arrived.
    fn emit_ready(&mut self, out: &mut Vec<f64>) {
        if self.z.is_none() {
            return;
        }
        loop {
            let start = self.padlen + self.given; // extended index of the block's first sample
            let end = start + self.block;
            let reach = end + self.lookahead; // one past the backward pass's first sample
            if self.base + self.fwd.len() < reach {
                return;
            }
            self.backward(start, reach, end - start, out);
        }
    }

    /// Backward pass over forward outputs `[start, reach)` (extended indices), from the steady
    /// state of its last value; the first `count` results leave.
    fn backward(&mut self, start: usize, reach: usize, count: usize, out: &mut Vec<f64>) {
        let (a, b) = (start - self.base, reach - self.base);
        self.work.clear();
        self.work.extend_from_slice(&self.fwd[a..b]);
        let last = self.work[self.work.len() - 1];
        for (z, s) in self.zb.iter_mut().zip(&self.zi) {
            *z = [s[0] * last, s[1] * last];
        }
        self.sos
            .sections_inplace(&mut self.work, &mut self.zb, true);
        out.extend_from_slice(&self.work[..count]);
        self.given += count;
        // Forward outputs before the next block are no longer needed.
        let keep_from = self.padlen + self.given - self.base;
        self.fwd.drain(..keep_from);
        self.base += keep_from;
    }

    /// The end of the stream: the rest of the output, the last samples exactly as the whole
    /// record's. Refused if the stream had no more samples than the padding.
    pub fn finish(&mut self, out: &mut Vec<f64>) -> Result<(), FilterError> {
        if self.taken <= self.padlen {
            return Err(FilterError::TooShort {
                len: self.taken,
                padlen: self.padlen,
            });
        }
        let Some(z) = self.z.as_mut() else {
            unreachable!("the forward pass starts at padlen + 1 samples");
        };
        // The end's odd reflection, through the forward pass.
        let t = &self.tail;
        let xl = t[t.len() - 1];
        let from = self.fwd.len();
        for i in 1..=self.padlen {
            self.fwd.push(2.0 * xl - t[t.len() - 1 - i]);
        }
        self.sos.sections_inplace(&mut self.fwd[from..], z, false);
        let start = self.padlen + self.given;
        let reach = self.base + self.fwd.len();
        let count = self.taken - self.given;
        self.backward(start, reach, count, out);
        Ok(())
    }
}

/// Samples after which the filter's impulse response has fallen below [`TAIL`] of its total
/// absolute sum (at least the padding; at most 10⁶).
pub fn settling_length(sos: &Sos) -> usize {
    const MAX: usize = 1_000_000;
    let mut z = vec![[0.0; 2]; sos.sections.len()];
    let mut h = Vec::with_capacity(4096);
    let mut x = [1.0];
    let mut total = 0.0;
    // The response, until it has been negligible for a while.
    let mut quiet = 0;
    for n in 0..MAX {
        x[0] = if n == 0 { 1.0 } else { 0.0 };
        sos.sections_inplace(&mut x, &mut z, false);
        let v = x[0].abs();
        total += v;
        h.push(v);
        quiet = if v < 1e-18 * total { quiet + 1 } else { 0 };
        if quiet > 64 {
            break;
        }
    }
    let mut tail = 0.0;
    let mut len = h.len();
    for (n, v) in h.iter().enumerate().rev() {
        tail += v;
        if tail > TAIL * total {
            len = n + 1;
            break;
        }
    }
    len.max(sos.padlen()).min(MAX)
}
