//! Butterworth filters and zero-phase (forward–backward) filtering, equal to scipy's
//! `butter`, `lfilter_zi`, `filtfilt` and `sosfiltfilt` (thesis §4, SPEC §2.7).
//!
//! Design follows scipy step by step: the analog prototype `buttap` (poles on the unit circle),
//! frequency transformation (`lp2lp`, `lp2hp`, `lp2bp` in zero–pole–gain form) at the
//! pre-warped frequency `4·tan(π·Wn/2)` (Wn normalised to Nyquist), and the bilinear transform
//! at fs = 2. Two realisations:
//!
//! * transfer function `(b, a)` — what `filtfilt` uses; fine for low orders, ill-conditioned
//!   for high orders at low cut-offs (as in scipy);
//! * second-order sections — the well-conditioned alternative (`sosfiltfilt`);
//! * parallel branches ([`parallel`]) — the same filter as the sections to rounding, faster
//!   where it is accurate.
//!
//! Zero-phase filtering pads both ends by odd reflection (`2·x₀ − x`), starts each pass from
//! the steady state of a step of the first value (`lfilter_zi`), filters forwards and
//! backwards, and cuts the padding — scipy's default method, so outputs agree to rounding.

pub mod parallel;

pub use parallel::Parallel;

use nalgebra::{Complex, DMatrix, DVector};
use physid_core::Num;
use serde::{Deserialize, Serialize};
use thiserror::Error;

type C64 = Complex<f64>;

/// Filter design and application errors.
#[derive(Debug, Error, PartialEq)]
pub enum FilterError {
    /// A design parameter is out of range.
    #[error("{0}")]
    Design(String),
    /// The signal is too short for the padding.
    #[error("the signal has {len} samples; zero-phase filtering with this filter needs more than {padlen} (3 × filter length)")]
    TooShort {
        /// Samples given.
        len: usize,
        /// Padding needed.
        padlen: usize,
    },
    /// A non-finite sample.
    #[error("sample {index} is {value}: filtering would spread it over the whole signal")]
    NonFinite {
        /// Index of the sample.
        index: usize,
        /// Its value.
        value: f64,
    },
}

/// The band type.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Band {
    /// Pass below the cut-off.
    Lowpass,
    /// Pass above the cut-off.
    Highpass,
    /// Pass between two cut-offs.
    Bandpass,
}

/// A digital filter in zero–pole–gain form.
#[derive(Debug, Clone)]
pub struct Zpk {
    /// Zeros.
    pub z: Vec<C64>,
    /// Poles.
    pub p: Vec<C64>,
    /// Gain.
    pub k: f64,
}

/// Butterworth design: `order`, cut-off(s) `wn` in Hz (one, or two for a band-pass), sampling
/// frequency `fs` in Hz.
pub fn butter(order: usize, wn: &[f64], band: Band, fs: f64) -> Result<Zpk, FilterError> {
    if order == 0 || order > 24 {
        return Err(FilterError::Design(format!(
            "order {order}: expected 1 … 24"
        )));
    }
    if !(fs.is_finite() && fs > 0.0) {
        return Err(FilterError::Design(format!(
            "sampling frequency {fs} Hz: expected > 0",
            fs = physid_core::Num(fs)
        )));
    }
    let need = if band == Band::Bandpass { 2 } else { 1 };
    if wn.len() != need {
        return Err(FilterError::Design(format!(
            "{band:?} needs {need} cut-off frequenc{}, got {}",
            if need == 1 { "y" } else { "ies" },
            wn.len()
        )));
    }
    let nyq = fs / 2.0;
    for &w in wn {
        if !(w.is_finite() && w > 0.0 && w < nyq) {
            return Err(FilterError::Design(format!(
                "cut-off {} Hz: expected between 0 and the Nyquist frequency {} Hz",
                Num(w),
                Num(nyq)
            )));
        }
    }
    if need == 2 && wn[0] >= wn[1] {
        return Err(FilterError::Design(format!(
            "band-pass edges {} ≥ {} Hz: expected low < high",
            wn[0], wn[1]
        )));
    }
    // buttap: poles −exp(iπm/(2N)), m = −N+1, −N+3, …, N−1.
    let n = order as f64;
    let proto: Vec<C64> = (0..order)
        .map(|i| {
            let m = -(order as f64) + 1.0 + 2.0 * i as f64;
            -C64::from_polar(1.0, std::f64::consts::PI * m / (2.0 * n))
        })
        .collect();
    let warp = |w: f64| 4.0 * (std::f64::consts::PI * (w / nyq) / 2.0).tan();
    let (z, p, k): (Vec<C64>, Vec<C64>, f64) = match band {
        Band::Lowpass => {
            let wo = warp(wn[0]);
            let p = proto.iter().map(|p| p * wo).collect();
            (Vec::new(), p, wo.powi(order as i32))
        }
        Band::Highpass => {
            let wo = warp(wn[0]);
            let p: Vec<C64> = proto.iter().map(|p| C64::from(wo) / p).collect();
            // k·real(prod(−z)/prod(−p)) with no zeros.
            let prod: C64 = proto.iter().map(|p| -p).product();
            (vec![C64::from(0.0); order], p, (C64::from(1.0) / prod).re)
        }
        Band::Bandpass => {
            let (w1, w2) = (warp(wn[0]), warp(wn[1]));
            let (wo, bw) = ((w1 * w2).sqrt(), w2 - w1);
            let mut p = Vec::with_capacity(2 * order);
            let lp: Vec<C64> = proto.iter().map(|p| p * (bw / 2.0)).collect();
            for q in &lp {
                p.push(q + (q * q - wo * wo).sqrt());
            }
            for q in &lp {
                p.push(q - (q * q - wo * wo).sqrt());
            }
            (vec![C64::from(0.0); order], p, bw.powi(order as i32))
        }
    };
    Ok(bilinear(&z, &p, k))
}

/// Bilinear transform at fs = 2 (scipy's `bilinear_zpk`): zeros at −1 fill the degree.
fn bilinear(z: &[C64], p: &[C64], k: f64) -> Zpk {
    let fs2 = 4.0;
    let zz: Vec<C64> = z
        .iter()
        .map(|z| (C64::from(fs2) + z) / (C64::from(fs2) - z))
        .chain(std::iter::repeat_n(C64::from(-1.0), p.len() - z.len()))
        .collect();
    let pz = p
        .iter()
        .map(|p| (C64::from(fs2) + p) / (C64::from(fs2) - p))
        .collect();
    let num: C64 = z.iter().map(|z| C64::from(fs2) - z).product();
    let den: C64 = p.iter().map(|p| C64::from(fs2) - p).product();
    Zpk {
        z: zz,
        p: pz,
        k: k * (num / den).re,
    }
}

/// Polynomial with the given roots, highest power first (numpy's `poly`), real part.
fn poly(roots: &[C64]) -> Vec<f64> {
    let mut c = vec![C64::from(1.0)];
    for r in roots {
        let mut next = vec![C64::from(0.0); c.len() + 1];
        for (i, ci) in c.iter().enumerate() {
            next[i] += ci;
            next[i + 1] -= ci * r;
        }
        c = next;
    }
    c.iter().map(|c| c.re).collect()
}

impl Zpk {
    /// Transfer-function coefficients `(b, a)`, `a[0] = 1` (scipy's `zpk2tf`).
    pub fn to_ba(&self) -> TransferFunction {
        let b = poly(&self.z).iter().map(|c| c * self.k).collect();
        TransferFunction {
            b,
            a: poly(&self.p),
        }
    }

    /// Second-order sections: poles paired with their conjugates (a lone real pole, for odd
    /// orders, makes a first-order section placed first), each section given two zeros (the
    /// gain in the first section) — the cascade equals the transfer function.
    pub fn to_sos(&self) -> Sos {
        let pairs = |v: &[C64]| -> Vec<Vec<C64>> {
            let mut reals: Vec<C64> = v.iter().copied().filter(|c| c.im == 0.0).collect();
            let mut cplx: Vec<C64> = v.iter().copied().filter(|c| c.im > 0.0).collect();
            reals.sort_by(|a, b| a.re.total_cmp(&b.re));
            cplx.sort_by(|a, b| a.norm().total_cmp(&b.norm()));
            let mut out: Vec<Vec<C64>> = Vec::new();
            if reals.len() % 2 == 1 {
                out.push(vec![reals.remove(0)]);
            }
            for ch in reals.chunks(2) {
                out.push(ch.to_vec());
            }
            for c in cplx {
                out.push(vec![c, c.conj()]);
            }
            out
        };
        // Poles off the real axis come in exact conjugate pairs from the design; classify by a
        // tolerance so that rounding does not split a pair.
        let clean = |v: &[C64]| -> Vec<C64> {
            v.iter()
                .map(|c| {
                    if c.im.abs() <= 1e-12 * c.norm().max(1.0) {
                        C64::from(c.re)
                    } else {
                        *c
                    }
                })
                .collect()
        };
        let (zs, ps) = (clean(&self.z), clean(&self.p));
        let pp = pairs(&ps);
        let mut zp = pairs(&zs);
        // As many zero groups as pole groups, first-order where the poles are.
        while zp.len() < pp.len() {
            zp.push(Vec::new());
        }
        let mut sections = Vec::with_capacity(pp.len());
        for (i, poles) in pp.iter().enumerate() {
            let zeros = zp.get(i).cloned().unwrap_or_default();
            let mut a = poly(poles);
            let mut b = poly(&zeros);
            a.resize(3, 0.0);
            // Right-align the numerator to the section's order: a first-order section's
            // numerator b0 + b1 z⁻¹ must sit in the first two slots.
            while b.len() < 3 {
                b.push(0.0);
            }
            if i == 0 {
                for v in &mut b {
                    *v *= self.k;
                }
            }
            sections.push([b[0], b[1], b[2], a[0], a[1], a[2]]);
        }
        Sos { sections }
    }
}

/// A transfer function `b(z⁻¹)/a(z⁻¹)`.
#[derive(Debug, Clone, PartialEq)]
pub struct TransferFunction {
    /// Numerator, highest power of z first.
    pub b: Vec<f64>,
    /// Denominator, `a[0] = 1`.
    pub a: Vec<f64>,
}

/// Second-order sections `[b0, b1, b2, a0, a1, a2]` (a0 = 1), applied in order.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Sos {
    /// The sections.
    pub sections: Vec<[f64; 6]>,
}

fn check_finite(x: &[f64]) -> Result<(), FilterError> {
    match x.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(FilterError::NonFinite {
            index,
            value: x[index],
        }),
        None => Ok(()),
    }
}

/// Odd extension by `n` samples at both ends (scipy's `odd_ext`).
fn odd_ext(x: &[f64], n: usize) -> Vec<f64> {
    let len = x.len();
    let mut e = Vec::with_capacity(len + 2 * n);
    e.extend((1..=n).rev().map(|i| 2.0 * x[0] - x[i]));
    e.extend_from_slice(x);
    e.extend((1..=n).map(|i| 2.0 * x[len - 1] - x[len - 1 - i]));
    e
}

impl TransferFunction {
    /// Filter length `max(len(a), len(b))`.
    pub fn len(&self) -> usize {
        self.a.len().max(self.b.len())
    }

    /// Whether the filter has no coefficients.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Coefficients normalised by `a[0]` and padded to the same length.
    fn normalised(&self) -> (Vec<f64>, Vec<f64>) {
        let n = self.len();
        let a0 = self.a[0];
        let mut b: Vec<f64> = self.b.iter().map(|v| v / a0).collect();
        let mut a: Vec<f64> = self.a.iter().map(|v| v / a0).collect();
        b.resize(n, 0.0);
        a.resize(n, 0.0);
        (b, a)
    }

    /// Steady-state initial conditions for a unit step (scipy's `lfilter_zi`): solve
    /// `(I − Aᵀ) zi = b[1:] − a[1:]·b[0]` with `A` the companion matrix of `a`.
    pub fn lfilter_zi(&self) -> Vec<f64> {
        let (b, a) = self.normalised();
        let m = b.len() - 1;
        if m == 0 {
            return Vec::new();
        }
        // companion(a): first row −a[1:], ones on the sub-diagonal; IminusA = I − companionᵀ.
        let mut ima = DMatrix::<f64>::identity(m, m);
        for j in 0..m {
            ima[(j, 0)] += a[j + 1]; // −(−a[j+1]) in column 0 of the transpose
        }
        for i in 0..m - 1 {
            ima[(i, i + 1)] -= 1.0;
        }
        let rhs = DVector::from_iterator(m, (0..m).map(|i| b[i + 1] - a[i + 1] * b[0]));
        ima.lu()
            .solve(&rhs)
            .map(|v| v.as_slice().to_vec())
            .unwrap_or_else(|| vec![0.0; m])
    }

    /// Direct form II transposed (scipy's `lfilter`) from state `zi` (overwritten with the
    /// final state), writing into `y`.
    pub fn lfilter_into(&self, x: &[f64], zi: &mut [f64], y: &mut [f64]) {
        let (b, a) = self.normalised();
        y.copy_from_slice(x);
        inplace(&b, &a, y, zi, false);
    }

    /// Zero-phase filtering (scipy's `filtfilt` with its default padding).
    pub fn filtfilt(&self, x: &[f64]) -> Result<Vec<f64>, FilterError> {
        check_finite(x)?;
        let padlen = 3 * self.len();
        if x.len() <= padlen {
            return Err(FilterError::TooShort {
                len: x.len(),
                padlen,
            });
        }
        let (b, a) = self.normalised();
        let zi = self.lfilter_zi();
        // One buffer: the padded signal, filtered forwards in place, then backwards in place.
        let mut buf = odd_ext(x, padlen);
        let mut z: Vec<f64> = zi.iter().map(|v| v * buf[0]).collect();
        inplace(&b, &a, &mut buf, &mut z, false);
        let last = buf[buf.len() - 1];
        let mut z: Vec<f64> = zi.iter().map(|v| v * last).collect();
        inplace(&b, &a, &mut buf, &mut z, true);
        buf.truncate(padlen + x.len());
        buf.drain(..padlen);
        Ok(buf)
    }
}

/// The DF2T recursion over `buf` in place, forwards or backwards (the backward pass of
/// zero-phase filtering without reversing the data).
fn inplace(b: &[f64], a: &[f64], buf: &mut [f64], z: &mut [f64], backwards: bool) {
    macro_rules! run {
        ($m:literal) => {
            if backwards {
                df2t_inplace::<$m>(b, a, buf.iter_mut().rev(), z)
            } else {
                df2t_inplace::<$m>(b, a, buf.iter_mut(), z)
            }
        };
    }
    match z.len() {
        2 => run!(2),
        3 => run!(3),
        4 => run!(4),
        5 => run!(5),
        6 => run!(6),
        8 => run!(8),
        _ => {
            if backwards {
                df2t_dyn(b, a, buf.iter_mut().rev(), z)
            } else {
                df2t_dyn(b, a, buf.iter_mut(), z)
            }
        }
    }
}

/// Any order, state in a slice (first order and orders without a monomorphised loop).
fn df2t_dyn<'a>(b: &[f64], a: &[f64], samples: impl Iterator<Item = &'a mut f64>, z: &mut [f64]) {
    let m = z.len();
    for v in samples {
        let xi = *v;
        let out = b[0] * xi + z.first().copied().unwrap_or(0.0);
        for j in 0..m {
            let next = if j + 1 < m { z[j + 1] } else { 0.0 };
            z[j] = b[j + 1] * xi - a[j + 1] * out + next;
        }
        *v = out;
    }
}

/// Orders 2–8: the state in an array, so it stays in registers.
fn df2t_inplace<'a, const M: usize>(
    b: &[f64],
    a: &[f64],
    samples: impl Iterator<Item = &'a mut f64>,
    zs: &mut [f64],
) {
    let mut z = [0.0; M];
    z.copy_from_slice(&zs[..M]);
    let mut bb = [0.0; M];
    let mut aa = [0.0; M];
    bb.copy_from_slice(&b[1..=M]);
    aa.copy_from_slice(&a[1..=M]);
    let b0 = b[0];
    for v in samples {
        let xi = *v;
        let out = b0 * xi + z[0];
        for j in 0..M - 1 {
            z[j] = bb[j] * xi - aa[j] * out + z[j + 1];
        }
        z[M - 1] = bb[M - 1] * xi - aa[M - 1] * out;
        *v = out;
    }
    zs[..M].copy_from_slice(&z);
}

impl Sos {
    /// How many samples the filter's free response takes to fall below `tol` of its start: the
    /// slowest pole's `⌈ln tol / ln r⌉` (`r`, its radius, from each section's `z² + a₁z + a₂`);
    /// `usize::MAX` for a filter that is not stable. What a stretch of a signal filtered alone
    /// needs on each side to equal, within `tol`, the whole signal filtered there.
    pub fn settle_samples(&self, tol: f64) -> usize {
        let radius = self
            .sections
            .iter()
            .map(|s| {
                let (a1, a2) = (s[4] / s[3], s[5] / s[3]);
                let disc = a1 * a1 - 4.0 * a2;
                if disc < 0.0 {
                    a2.sqrt()
                } else {
                    let r = disc.sqrt();
                    ((-a1 + r) / 2.0).abs().max(((-a1 - r) / 2.0).abs())
                }
            })
            .fold(0.0_f64, f64::max);
        if radius.is_nan() || radius >= 1.0 {
            return usize::MAX;
        }
        if radius == 0.0 {
            return 2 * self.sections.len();
        }
        (tol.ln() / radius.ln()).ceil().max(0.0) as usize
    }

    /// Padding of `sosfiltfilt`: `3·(2·sections + 1 − min(#b2 = 0, #a2 = 0))`.
    pub fn padlen(&self) -> usize {
        let nb = self.sections.iter().filter(|s| s[2] == 0.0).count();
        let na = self.sections.iter().filter(|s| s[5] == 0.0).count();
        3 * (2 * self.sections.len() + 1 - nb.min(na))
    }

    /// Per-section steady-state initial conditions for a unit step (scipy's `sosfilt_zi`).
    pub fn sosfilt_zi(&self) -> Vec<[f64; 2]> {
        let mut scale = 1.0;
        self.sections
            .iter()
            .map(|s| {
                let tf = TransferFunction {
                    b: s[..3].to_vec(),
                    a: s[3..].to_vec(),
                };
                let zi = tf.lfilter_zi();
                let out = [scale * zi[0], scale * zi[1]];
                scale *= (s[0] + s[1] + s[2]) / (s[3] + s[4] + s[5]);
                out
            })
            .collect()
    }

    /// The cascade from per-section states `zi` (overwritten), into `y`.
    pub fn sosfilt_into(&self, x: &[f64], zi: &mut [[f64; 2]], y: &mut [f64]) {
        y.copy_from_slice(x);
        self.sections_inplace(y, zi, false);
    }

    /// Zero-phase filtering with sections (scipy's `sosfiltfilt`).
    pub fn sosfiltfilt(&self, x: &[f64]) -> Result<Vec<f64>, FilterError> {
        self.sosfiltfilt_from(x, 0)
    }

    /// [`sosfiltfilt`](Self::sosfiltfilt)`(x)[from..]`, the same values, without the backward
    /// pass's work before `from`: that pass runs from the end, so what it gives at and after
    /// `from` does not depend on what lies before.
    pub fn sosfiltfilt_from(&self, x: &[f64], from: usize) -> Result<Vec<f64>, FilterError> {
        check_finite(x)?;
        let padlen = self.padlen();
        if x.len() <= padlen {
            return Err(FilterError::TooShort {
                len: x.len(),
                padlen,
            });
        }
        let zi = self.sosfilt_zi();
        let mut buf = odd_ext(x, padlen);
        let mut z: Vec<[f64; 2]> = zi.iter().map(|s| [s[0] * buf[0], s[1] * buf[0]]).collect();
        self.sections_inplace(&mut buf, &mut z, false);
        let last = buf[buf.len() - 1];
        let mut z: Vec<[f64; 2]> = zi.iter().map(|s| [s[0] * last, s[1] * last]).collect();
        let keep = padlen + from.min(x.len());
        self.sections_inplace(&mut buf[keep..], &mut z, true);
        buf.truncate(padlen + x.len());
        buf.drain(..keep);
        Ok(buf)
    }

    /// Every section over `buf` in place, forwards or backwards: up to four sections (order 8)
    /// fused into one pass with the states in registers, section by section beyond.
    pub(crate) fn sections_inplace(&self, buf: &mut [f64], zi: &mut [[f64; 2]], backwards: bool) {
        macro_rules! fused {
            ($n:literal) => {
                if backwards {
                    cascade::<$n>(&self.sections, buf.iter_mut().rev(), zi)
                } else {
                    cascade::<$n>(&self.sections, buf.iter_mut(), zi)
                }
            };
        }
        match self.sections.len() {
            1 => fused!(1),
            2 => fused!(2),
            3 => fused!(3),
            4 => fused!(4),
            _ => {
                for (s, z) in self.sections.iter().zip(zi.iter_mut()) {
                    let one = std::slice::from_ref(s);
                    let zs = std::slice::from_mut(z);
                    if backwards {
                        cascade::<1>(one, buf.iter_mut().rev(), zs);
                    } else {
                        cascade::<1>(one, buf.iter_mut(), zs);
                    }
                }
            }
        }
    }
}

/// `N` second-order sections (DF2T) in cascade over the samples in place, one pass:
/// `y = b₀x + z₀`, `z₀' = b₁x − a₁y + z₁`, `z₁' = b₂x − a₂y`, section after section.
///
/// Up to two sections the update is computed with `y` substituted, `z₀' = (c₁x + z₁) − a₁z₀`,
/// `z₁' = c₂x − a₂z₀` (`c₁ = b₁ − a₁b₀`, `c₂ = b₂ − a₂b₀`): the same state, but the recursion
/// from one sample to the next is a multiply and a subtraction instead of four operations in a
/// row — a pass is bound by that latency there (29 % faster for two sections). From three
/// sections on the pass is bound by the number of operations, and the direct form is the
/// faster (the substituted one was 16 % slower for four: BENCHMARKS.md).
fn cascade<'a, const N: usize>(
    sections: &[[f64; 6]],
    samples: impl Iterator<Item = &'a mut f64>,
    zs: &mut [[f64; 2]],
) {
    let substituted = N <= 2;
    let mut c = [[0.0; 5]; N];
    let mut z = [[0.0; 2]; N];
    for k in 0..N {
        let s = &sections[k];
        let [b0, b1, b2, a1, a2] = [
            s[0] / s[3],
            s[1] / s[3],
            s[2] / s[3],
            s[4] / s[3],
            s[5] / s[3],
        ];
        c[k] = if substituted {
            [b0, b1 - a1 * b0, b2 - a2 * b0, a1, a2]
        } else {
            [b0, b1, b2, a1, a2]
        };
        z[k] = zs[k];
    }
    for v in samples {
        let mut x = *v;
        for k in 0..N {
            let [b0, c1, c2, a1, a2] = c[k];
            let [z0, z1] = z[k];
            let out = b0 * x + z0;
            z[k] = if substituted {
                [(c1 * x + z1) - a1 * z0, c2 * x - a2 * z0]
            } else {
                [c1 * x - a1 * out + z1, c2 * x - a2 * out]
            };
            x = out;
        }
        *v = x;
    }
    zs[..N].copy_from_slice(&z);
}
