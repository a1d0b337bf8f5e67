//! A filter as parallel branches: the partial fractions of its transfer function (Oppenheim &
//! Schafer, *Discrete-Time Signal Processing*, 3rd ed., §6.3.3, the parallel form),
//!
//! `H(w) = d + Σᵢ rᵢ/(1 − pᵢ·w)`, `w = z⁻¹`, the poles `pᵢ` distinct,
//! `rᵢ = k·pᵢ^{m−n}·Πⱼ(1 − zⱼ/pᵢ) / Πⱼ≠ᵢ(1 − pⱼ/pᵢ)`, `d = k·Πzⱼ/Πpⱼ` (`n` poles, `m ≤ n`
//! zeros; `d = 0` when `m < n`),
//!
//! each pair of conjugate poles joined into one real branch `(b₀ + b₁w)/(1 + a₁w + a₂w²)`
//! with `b₀ = 2·Re r`, `b₁ = −2·Re(r·p̄)`, `a₁ = −2·Re p`, `a₂ = |p|²`, and a real pole a
//! first-order branch (`b₀ = r`, `a₁ = −p`).
//!
//! **Why.** The cascade of second-order sections ([`Sos`](super::Sos)) runs its sections one
//! after another on each sample: a sample costs the chain of all of them. The branches are
//! independent — four in the lanes of one vector — and a sample costs one branch's recursion
//! and a sum — and two samples a step spread that over both ([`Parallel::filtfilt_from`]): the knock
//! band-pass (four sections) is 3× faster this way (BENCHMARKS.md).
//!
//! **Accuracy.** The output equals the cascade's to rounding, with two sources of difference:
//! the sum's rounding, which grows with the branches' gains, `G = Σ‖hᵢ‖₁ ≤ Σ 2|rᵢ|/(1 − |pᵢ|)`
//! for a pair (`|r|/(1 − |p|)` for a real pole); and the residues', whose relative error grows
//! as `n·ε/δ` when the closest two of the `n` poles are `δ` apart (each factor `1 − pⱼ/pᵢ` is
//! their difference). The form is refused ([`Zpk::to_parallel`] gives `None`) when the
//! estimate `ε·G·(1 + n/δ)` of the difference, relative to the signal's largest value, passes
//! [`MAX_ERROR`] — a narrow band at a high rate, where the cascade serves. The knock band (4th
//! order, 5–20 kHz) at 90 kHz … 3.6 MHz has `G` ≈ 9–12; the two forms differ there by at most
//! 1.4·10⁻¹⁴ of the signal's largest value at 360 kHz, 2.5·10⁻¹³ at 3.6 MHz (tested below
//! against a bound of 10⁻¹²).

use super::{check_finite, odd_ext, FilterError, Zpk, C64};
use wide::f64x4;

/// The largest estimate of the difference from the cascade accepted, relative to the signal's
/// largest value (see the module docs).
pub const MAX_ERROR: f64 = 1e-10;

/// The most branches the fused pass takes (two vectors of four): a 4th-order band-pass has
/// four, an 8th-order one eight.
const MAX_BRANCHES: usize = 8;

/// A filter as parallel branches (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Parallel {
    /// The direct term `d`.
    pub direct: f64,
    /// The branches `[b₀, b₁, a₁, a₂]` (`a₂ = 0` for a real pole's).
    pub branches: Vec<[f64; 4]>,
    /// The poles' largest radius.
    radius: f64,
    /// The padding of zero-phase filtering: the cascade's
    /// ([`Sos::padlen`](super::Sos::padlen)), so that
    /// [`filtfilt_from`](Parallel::filtfilt_from) is `sosfiltfilt`'s.
    padlen: usize,
}

impl Zpk {
    /// The parallel form (see [`parallel`](self)); `None` when it would not be accurate or
    /// cannot be formed: more zeros than poles, a pole at 0, on or outside the unit circle, an
    /// estimated difference from the cascade above [`MAX_ERROR`] (poles close together, or
    /// coinciding), or more than eight branches.
    pub fn to_parallel(&self) -> Option<Parallel> {
        let (n, m) = (self.p.len(), self.z.len());
        if n == 0 || m > n || self.p.iter().any(|p| p.norm() < 1e-300) {
            return None;
        }
        let closest = (0..n)
            .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
            .map(|(i, j)| (self.p[i] - self.p[j]).norm())
            .fold(f64::INFINITY, f64::min);
        let radius = self.p.iter().map(|p| p.norm()).fold(0.0, f64::max);
        if radius.is_nan() || radius >= 1.0 {
            return None;
        }
        let residue = |i: usize| -> C64 {
            let pi = self.p[i];
            let num: C64 = self.z.iter().map(|z| C64::from(1.0) - z / pi).product();
            let den: C64 = (0..n)
                .filter(|&j| j != i)
                .map(|j| C64::from(1.0) - self.p[j] / pi)
                .product();
            num / den * self.k * pi.powi(m as i32 - n as i32)
        };
        let direct = if m == n {
            let zs: C64 = self.z.iter().product();
            let ps: C64 = self.p.iter().product();
            (zs / ps * self.k).re
        } else {
            0.0
        };
        // Poles off the real axis come in conjugate pairs: the one above it makes the branch.
        let real = |p: &C64| p.im.abs() <= 1e-12 * p.norm().max(1.0);
        let (mut branches, mut gain) = (Vec::new(), 0.0);
        for i in 0..n {
            let (p, r) = (self.p[i], residue(i));
            if real(&p) {
                branches.push([r.re, 0.0, -p.re, 0.0]);
                gain += r.norm() / (1.0 - p.norm());
            } else if p.im > 0.0 {
                branches.push([
                    2.0 * r.re,
                    -2.0 * (r * p.conj()).re,
                    -2.0 * p.re,
                    p.norm_sqr(),
                ]);
                gain += 2.0 * r.norm() / (1.0 - p.norm());
            }
        }
        let pairs_below = self.p.iter().filter(|p| !real(p) && p.im < 0.0).count();
        let error = f64::EPSILON * gain * (1.0 + n as f64 / closest);
        if error.is_nan()
            || error > MAX_ERROR
            || branches.len() > MAX_BRANCHES
            || pairs_below + branches.len() != n
        {
            return None;
        }
        Some(Parallel {
            direct,
            branches,
            radius,
            padlen: self.to_sos().padlen(),
        })
    }
}

impl Parallel {
    /// How many samples the filter's free response takes to fall below `tol` of its start (the
    /// slowest pole's `⌈ln tol / ln |p|⌉`), as
    /// [`Sos::settle_samples`](super::Sos::settle_samples).
    pub fn settle_samples(&self, tol: f64) -> usize {
        if self.radius == 0.0 {
            return 2;
        }
        (tol.ln() / self.radius.ln()).ceil().max(0.0) as usize
    }

    /// The padding of zero-phase filtering (the cascade's, [`Sos::padlen`](super::Sos::padlen)).
    pub fn padlen(&self) -> usize {
        self.padlen
    }

    /// Zero-phase filtering, `sosfiltfilt(x)[from..]` of the same filter as a cascade, to
    /// rounding ([`Sos::sosfiltfilt_from`](super::Sos::sosfiltfilt_from): odd padding, each
    /// pass from the steady state of a step of its first value, the backward pass stopped at
    /// `from`).
    pub fn filtfilt_from(&self, x: &[f64], from: usize) -> Result<Vec<f64>, FilterError> {
        check_finite(x)?;
        if x.len() <= self.padlen {
            return Err(FilterError::TooShort {
                len: x.len(),
                padlen: self.padlen,
            });
        }
        let mut buf = odd_ext(x, self.padlen);
        self.pass(&mut buf, false);
        let keep = self.padlen + from.min(x.len());
        self.pass(&mut buf[keep..], true);
        buf.truncate(self.padlen + x.len());
        buf.drain(..keep);
        Ok(buf)
    }

    /// One pass over `buf` in place, forwards or backwards, from the steady state of a step of
    /// its first value.
    fn pass(&self, buf: &mut [f64], backwards: bool) {
        match self.branches.len() {
            0 => buf.iter_mut().for_each(|v| *v *= self.direct),
            1..=4 => self.pass_lanes::<1>(buf, backwards),
            _ => self.pass_lanes::<2>(buf, backwards),
        }
    }

    /// [`pass`](Self::pass) with the branches in `V` vectors of four (unused lanes zero), two
    /// samples a step.
    ///
    /// Each branch is in direct form II transposed, `yₙ = b₀xₙ + s₀ₙ`,
    /// `s₀ₙ₊₁ = b₁xₙ − a₁yₙ + s₁ₙ`, `s₁ₙ₊₁ = −a₂yₙ`; with `y` and `s₁` substituted, its first
    /// state alone is an all-pole recursion, `s₀ₙ₊₁ = uₙ − a₂s₀ₙ₋₁ − a₁s₀ₙ` with
    /// `uₙ = c₁xₙ + c₂xₙ₋₁` (`c₁ = b₁ − a₁b₀`, `c₂ = −a₂b₀`), and two steps of it at once are
    /// `s₀ₙ₊₂ = (uₙ₊₁ − a₁uₙ) + a₁a₂·s₀ₙ₋₁ + (a₁² − a₂)·s₀ₙ`: both new states a multiplication
    /// and an addition from the last — the recursion's latency, which bounds a pass, spread
    /// over two samples (1.4× faster than one sample a step). The sum over the branches is
    /// taken in a fixed order (lanes 0 + 1, 2 + 3, then the two), the same on every CPU.
    fn pass_lanes<const V: usize>(&self, buf: &mut [f64], backwards: bool) {
        let Some(&first) = (if backwards { buf.last() } else { buf.first() }) else {
            return;
        };
        let lane = |f: &dyn Fn(&[f64; 4]) -> f64| -> [f64x4; V] {
            std::array::from_fn(|v| {
                f64x4::from(std::array::from_fn::<f64, 4, _>(|l| {
                    self.branches.get(4 * v + l).map_or(0.0, f)
                }))
            })
        };
        let b0 = lane(&|b| b[0]);
        let c1 = lane(&|b| b[1] - b[2] * b[0]);
        let c2 = lane(&|b| -b[3] * b[0]);
        let a1 = lane(&|b| b[2]);
        let a2 = lane(&|b| b[3]);
        let e = lane(&|b| b[2] * b[2] - b[3]);
        let h = lane(&|b| b[2] * b[3]);
        // The steady state of a step of `first` (each branch's output its DC gain times it):
        // s₀ the same at every sample, the input before the first `first`.
        let y = lane(&|b| (b[0] + b[1]) / (1.0 + b[2] + b[3]) * first);
        let mut s0: [f64x4; V] = std::array::from_fn(|v| y[v] - b0[v] * f64x4::splat(first));
        let mut s0_before = s0;
        let mut x_before = f64x4::splat(first);
        let direct = self.direct;
        let sum = |out: [f64x4; V]| {
            let all = (1..V).fold(out[0], |s, k| s + out[k]);
            let l = all.to_array();
            (l[0] + l[1]) + (l[2] + l[3])
        };
        // Two samples: (xₙ, xₙ₊₁) in, (yₙ, yₙ₊₁) out.
        let mut two = |xa: &mut f64, xb: &mut f64| {
            let (a, b) = (f64x4::splat(*xa), f64x4::splat(*xb));
            let mut out_a = [f64x4::ZERO; V];
            let mut out_b = [f64x4::ZERO; V];
            for k in 0..V {
                let u_a = c1[k] * a + c2[k] * x_before;
                let u_b = c1[k] * b + c2[k] * a;
                let next = (u_a - a2[k] * s0_before[k]) - a1[k] * s0[k];
                let after = ((u_b - a1[k] * u_a) + h[k] * s0_before[k]) + e[k] * s0[k];
                out_a[k] = b0[k] * a + s0[k];
                out_b[k] = b0[k] * b + next;
                (s0_before[k], s0[k]) = (next, after);
            }
            x_before = b;
            (*xa, *xb) = (direct * *xa + sum(out_a), direct * *xb + sum(out_b));
        };
        // The samples in the pass's order, two at a time; an odd one last, alone (its partner
        // a dummy).
        if backwards {
            each_pair(buf.rchunks_exact_mut(2), true, &mut two);
        } else {
            each_pair(buf.chunks_exact_mut(2), false, &mut two);
        }
        let n = buf.len();
        if n % 2 == 1 {
            two(&mut buf[if backwards { 0 } else { n - 1 }], &mut 0.0);
        }
    }
}

/// `two` on each pair of samples, in the order they come (`reversed`: the later of a pair
/// first).
#[inline(always)]
fn each_pair<'a>(
    pairs: impl Iterator<Item = &'a mut [f64]>,
    reversed: bool,
    two: &mut impl FnMut(&mut f64, &mut f64),
) {
    for pair in pairs {
        if let [x, y] = pair {
            if reversed {
                two(y, x);
            } else {
                two(x, y);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::filter::{butter, Band};

    /// A pressure-like trace: a compression peak, a 7 kHz ring, a little noise-like ripple.
    fn trace(n: usize, fs: f64) -> Vec<f64> {
        (0..n)
            .map(|i| {
                let t = i as f64 / fs;
                let u = (i as f64 - n as f64 / 2.0) / (n as f64 / 10.0);
                1e5 + 3e6 * (-u * u).exp()
                    + 2e4 * (2.0 * std::f64::consts::PI * 7e3 * t).sin()
                    + 50.0 * (i as f64 * 1.7).cos()
            })
            .collect()
    }

    /// The parallel form's zero-phase filtering against the cascade's (`sosfiltfilt`, itself
    /// checked against scipy): the knock band-pass at 90 kHz … 3.6 MHz, a low-pass and a
    /// high-pass with a real pole (odd order), every `from`.
    #[test]
    fn parallel_is_the_cascade_to_rounding() {
        let cases: [(usize, &[f64], Band, f64); 7] = [
            (4, &[5e3, 20e3], Band::Bandpass, 90e3),
            (4, &[5e3, 20e3], Band::Bandpass, 360e3),
            (4, &[5e3, 20e3], Band::Bandpass, 3.6e6),
            (2, &[5e3, 20e3], Band::Bandpass, 360e3),
            (4, &[2e3], Band::Lowpass, 50e3),
            (3, &[2e3], Band::Lowpass, 50e3),
            (5, &[1e3], Band::Highpass, 50e3),
        ];
        for (order, wn, band, fs) in cases {
            let zpk = butter(order, wn, band, fs).unwrap();
            let par = zpk.to_parallel().unwrap();
            let sos = zpk.to_sos();
            assert_eq!(par.padlen(), sos.padlen());
            let x = trace(4000, fs);
            let scale = x.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            for from in [0, 1, 1234, 3999] {
                let (a, b) = (
                    par.filtfilt_from(&x, from).unwrap(),
                    sos.sosfiltfilt_from(&x, from).unwrap(),
                );
                assert_eq!(a.len(), b.len());
                let worst = a
                    .iter()
                    .zip(&b)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f64::max);
                assert!(
                    worst < 1e-12 * scale,
                    "order {order} {band:?} {wn:?} at {fs} Hz from {from}: differs by {worst} (scale {scale})"
                );
            }
            // The slowest pole's settling as the cascade's, within a sample.
            let (a, b) = (par.settle_samples(1e-12), sos.settle_samples(1e-12));
            assert!(a.abs_diff(b) <= 1, "settling {a} against {b}");
        }
    }

    /// The branches add up to the transfer function: `d + Σ Hᵢ(e^{iω})` against `k·Π(e^{iω} −
    /// zⱼ)/Π(e^{iω} − pⱼ)` on the unit circle.
    #[test]
    fn branches_sum_to_the_transfer_function() {
        let zpk = butter(4, &[5e3, 20e3], Band::Bandpass, 360e3).unwrap();
        let par = zpk.to_parallel().unwrap();
        for k in 0..50 {
            let e = C64::from_polar(1.0, std::f64::consts::PI * k as f64 / 50.0);
            let w = C64::from(1.0) / e;
            let want: C64 = zpk.z.iter().map(|z| e - z).product::<C64>()
                / zpk.p.iter().map(|p| e - p).product::<C64>()
                * zpk.k;
            let got = par.branches.iter().fold(C64::from(par.direct), |s, b| {
                s + (w * b[1] + b[0]) / (w * w * b[3] + w * b[2] + 1.0)
            });
            assert!(
                (got - want).norm() < 1e-12,
                "at ω = {k}π/50: {got} against {want}"
            );
        }
    }

    /// Refused where it would not be accurate: a repeated pole, a pole outside the circle, a
    /// band so narrow at its rate that the poles crowd together.
    #[test]
    fn refused_where_inaccurate() {
        let twice = Zpk {
            z: vec![],
            p: vec![C64::from(0.5), C64::from(0.5)],
            k: 1.0,
        };
        assert!(twice.to_parallel().is_none());
        let unstable = Zpk {
            z: vec![],
            p: vec![C64::from(1.5)],
            k: 1.0,
        };
        assert!(unstable.to_parallel().is_none());
        let narrow = butter(4, &[100.0, 101.0], Band::Bandpass, 1e6).unwrap();
        assert!(narrow.to_parallel().is_none());
        // Signals too short for the padding are an error, as the cascade's.
        let par = butter(4, &[5e3, 20e3], Band::Bandpass, 360e3)
            .unwrap()
            .to_parallel()
            .unwrap();
        assert!(matches!(
            par.filtfilt_from(&[1.0; 10], 0),
            Err(FilterError::TooShort { .. })
        ));
    }
}
