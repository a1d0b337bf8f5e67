//! The covariance-form and DSFC steps' loops over P (or S), written in four-lane vectors
//! ([`Lanes`]: one AVX register, or two SSE2 ones — the same results, lane for lane) with every
//! reduction's order written out, so that the step gives the same digits on every CPU
//! (BENCHMARKS.md, issue 47, has what each bought).

use super::lanes::Lanes;

// Where the step has an AVX2 copy (`cfg(avx2_copy)`, build.rs) every kernel is inlined into
// both copies, so that each is compiled for its own instruction set; elsewhere the compiler
// chooses (forcing it costs the native build 15 % at p = 6).

/// `aᵀb` in four lanes (each a running sum of every fourth product, added at the end): four
/// independent chains where one sum would be one chain of p additions.
#[cfg_attr(avx2_copy, inline(always))]
#[cfg_attr(not(avx2_copy), inline)]
pub(super) fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut lanes = [0.0; 4];
    let (ac, bc) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ar, br) = (ac.remainder(), bc.remainder());
    for (x, y) in ac.zip(bc) {
        for l in 0..4 {
            lanes[l] += x[l] * y[l];
        }
    }
    for (l, (x, y)) in ar.iter().zip(br).enumerate() {
        lanes[l] += x * y;
    }
    (lanes[0] + lanes[1]) + (lanes[2] + lanes[3])
}

/// `u = M·x` for a column-major square `m`, as a sum of its columns four at a time: lanes run
/// down the columns (no reduction across them), and `u` is read and written once per four
/// columns. For a symmetric P this is `P·x` (RLS's `u = P·φ̃`).
#[cfg_attr(avx2_copy, inline(always))]
#[cfg_attr(not(avx2_copy), inline)]
pub(super) fn columns_times(m: &[f64], x: &[f64], u: &mut [f64]) {
    let p = u.len();
    u.fill(0.0);
    let (xs, xr) = x[..p].as_chunks::<4>();
    // Blocks and columns by index (as in `downdate`).
    for (k, f) in xs.iter().enumerate() {
        let (c0, rest) = m[4 * k * p..4 * (k + 1) * p].split_at(p);
        let (c1, rest) = rest.split_at(p);
        let (c2, c3) = rest.split_at(p);
        for ((((ui, &a), &b), &c), &d) in u.iter_mut().zip(c0).zip(c1).zip(c2).zip(c3) {
            *ui += (a * f[0] + b * f[1]) + (c * f[2] + d * f[3]);
        }
    }
    for (i, &f) in xr.iter().enumerate() {
        let j = 4 * xs.len() + i;
        for (ui, &a) in u.iter_mut().zip(&m[j * p..(j + 1) * p]) {
            *ui += a * f;
        }
    }
}

/// `f = Mᵀ·x` for a column-major square `m` (`f_j` = column j · x), four columns at a time:
/// each column's products in four lanes, summed `(l0 + l1) + (l2 + l3)` — the order written
/// out, the same on every CPU — as [`dot`] does. DSFC's `f = Sᵀφ`.
#[cfg_attr(avx2_copy, inline(always))]
#[cfg_attr(not(avx2_copy), inline)]
pub(super) fn columns_dot<L: Lanes>(m: &[f64], x: &[f64], f: &mut [f64]) {
    let p = f.len();
    let (x4, xr) = x[..p].as_chunks::<4>();
    let (out, out_rest) = f.as_chunks_mut::<4>();
    // Blocks and columns by index (as in `downdate`).
    for (b, fo) in out.iter_mut().enumerate() {
        let mut acc = [L::splat(0.0); 4];
        let mut tail = [0.0; 4];
        for k in 0..4 {
            let j = 4 * b + k;
            let (c4, cr) = m[j * p..(j + 1) * p].as_chunks::<4>();
            for i in 0..c4.len().min(x4.len()) {
                acc[k] = acc[k] + L::load(&c4[i]) * L::load(&x4[i]);
            }
            tail[k] = cr.iter().zip(xr).map(|(a, b)| a * b).sum::<f64>();
        }
        for k in 0..4 {
            fo[k] = acc[k].sum() + tail[k];
        }
    }
    let done = 4 * out.len();
    for (i, fj) in out_rest.iter_mut().enumerate() {
        let j = done + i;
        *fj = dot(&m[j * p..(j + 1) * p], x);
    }
}

/// 0 if `v` is finite (`v − v` is +0, all bits clear), not 0 if it is infinite or NaN (then
/// `v − v` is NaN): or-ed over a matrix it is one subtraction and one `or` a lane, where a
/// running sum — one chain of p² additions — would not vectorise.
#[inline(always)]
#[allow(clippy::eq_op)] // v − v is the point: 0 or NaN
fn is_nonfinite(v: f64) -> u64 {
    (v - v).to_bits()
}

/// The rank-one term `(a·bᵀ)·g` a [`downdate`] takes off, each entry `(a_i·b_j)·g`: with
/// `a = b` it is bit-for-bit symmetric.
pub(super) struct RankOne<'a> {
    pub(super) a: &'a [f64],
    pub(super) b: &'a [f64],
    pub(super) g: f64,
}

/// How a [`downdate`] scales its entries: not at all (`c` = 1: RLS, Kalman), by one factor `c`
/// (D_post a multiple of I, or 1/λ(t): RLSF; DSFC's 1/√λ), or by `s_i·s_j·c` (D_post per
/// parameter: vector forgetting).
pub(super) const UNIT: u8 = 0;
pub(super) const UNIFORM: u8 = 1;
pub(super) const PER_PARAM: u8 = 2;

/// The covariance update's loop over P (see the module table): column by column,
/// `W_ij = f_ij·(P_ij − (a_i·b_j)·g) [+ Q_ij]` ([`RankOne`]) with `f_ij` as `SCALE` says
/// ([`UNIT`], [`UNIFORM`], [`PER_PARAM`]). Returns whether every entry is finite
/// ([`is_nonfinite`]). Written in four-lane vectors down each column, so that it compiles to
/// whole-vector operations at any p (left to itself, the compiler vectorised a small fixed p
/// across the columns, with gathers, and a larger one with a scalar tail of up to 31 rows).
#[inline(always)]
pub(super) fn downdate<L: Lanes, const SCALE: u8, const WITH_Q: bool>(
    wm: &mut [f64],
    pm: &[f64],
    RankOne { a, b, g }: RankOne,
    s: &[f64],
    c: f64,
    q: &[f64],
) -> bool {
    let p = a.len();
    // Without D_post per parameter (or Q) the slice is not read: any of length p stands in, so
    // that one zip serves every case.
    let s = if SCALE == PER_PARAM { s } else { a };
    let (a4, ar) = a.as_chunks::<4>();
    let (s4, sr) = s[..p].as_chunks::<4>();
    let (cv, gv) = (L::splat(c), L::splat(g));
    let mut bad = L::splat(0.0);
    let mut bad_rest = 0u64;
    // Columns and blocks by index, not by zipped chunk iterators: in the step's inlined whole
    // the compiler left their constructors as calls, dividing by the chunk length at each
    // column (RLS p = 20 lost 15 %).
    for j in 0..p {
        let (wcol, pcol) = (&mut wm[j * p..(j + 1) * p], &pm[j * p..(j + 1) * p]);
        let (bj, sj) = (b[j], s[j]);
        let (bjv, sjv) = (L::splat(bj), L::splat(sj));
        let qcol = if WITH_Q { &q[j * p..(j + 1) * p] } else { pcol };
        let (wo4, wor) = wcol.as_chunks_mut::<4>();
        let (p4, pr) = pcol.as_chunks::<4>();
        let (q4, qr) = qcol.as_chunks::<4>();
        let blocks = wo4
            .len()
            .min(p4.len())
            .min(a4.len())
            .min(s4.len())
            .min(q4.len());
        for i in 0..blocks {
            let d = L::load(&p4[i]) - (L::load(&a4[i]) * bjv) * gv;
            let mut v = match SCALE {
                UNIT => d,
                UNIFORM => cv * d,
                _ => ((L::load(&s4[i]) * sjv) * cv) * d,
            };
            if WITH_Q {
                v = v + L::load(&q4[i]);
            }
            v.store(&mut wo4[i]);
            #[allow(clippy::eq_op)] // as in is_nonfinite
            {
                bad = bad.or(v - v);
            }
        }
        for ((((wo, &pij), &ai), &si), &qi) in wor.iter_mut().zip(pr).zip(ar).zip(sr).zip(qr) {
            let d = pij - (ai * bj) * g;
            let mut v = match SCALE {
                UNIT => d,
                UNIFORM => c * d,
                _ => ((si * sj) * c) * d,
            };
            if WITH_Q {
                v += qi;
            }
            *wo = v;
            bad_rest |= is_nonfinite(v);
        }
    }
    bad.is_zero() && bad_rest == 0
}
