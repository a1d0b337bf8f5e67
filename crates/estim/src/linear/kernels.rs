//! The covariance-form and DSFC steps' loops over P (or S), written in four-lane vectors
//! (`wide::f64x4`: AVX, or two SSE2 halves — the same results, lane for lane) with every
//! reduction's order written out, so that the step gives the same digits on every CPU
//! (BENCHMARKS.md, issue 47, has what each bought).

use wide::f64x4;

/// `aᵀb` in four lanes (each a running sum of every fourth product, added at the end): four
/// independent chains where one sum would be one chain of p additions.
#[inline]
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
#[inline]
pub(super) fn columns_times(m: &[f64], x: &[f64], u: &mut [f64]) {
    let p = u.len();
    u.fill(0.0);
    let mut blocks = m[..p * p].chunks_exact(4 * p);
    let mut xs = x[..p].chunks_exact(4);
    for (block, f) in (&mut blocks).zip(&mut xs) {
        let (c0, rest) = block.split_at(p);
        let (c1, rest) = rest.split_at(p);
        let (c2, c3) = rest.split_at(p);
        for ((((ui, &a), &b), &c), &d) in u.iter_mut().zip(c0).zip(c1).zip(c2).zip(c3) {
            *ui += (a * f[0] + b * f[1]) + (c * f[2] + d * f[3]);
        }
    }
    for (col, &f) in blocks.remainder().chunks_exact(p).zip(xs.remainder()) {
        for (ui, &a) in u.iter_mut().zip(col) {
            *ui += a * f;
        }
    }
}

/// `f = Mᵀ·x` for a column-major square `m` (`f_j` = column j · x), four columns at a time:
/// each column's products in four lanes, summed `(l0 + l1) + (l2 + l3)` — the order written
/// out, the same on every CPU — as [`dot`] does. DSFC's `f = Sᵀφ`.
#[inline]
pub(super) fn columns_dot(m: &[f64], x: &[f64], f: &mut [f64]) {
    let p = f.len();
    let split = p - p % 4;
    let (x4, xr) = x[..p].split_at(split);
    let sum = |v: f64x4| {
        let a = v.as_array();
        (a[0] + a[1]) + (a[2] + a[3])
    };
    let mut cols = m[..p * p].chunks_exact(4 * p);
    let mut out = f.chunks_exact_mut(4);
    for (block, fo) in (&mut cols).zip(&mut out) {
        let mut acc = [f64x4::ZERO; 4];
        let mut tail = [0.0; 4];
        for (k, col) in block.chunks_exact(p).enumerate() {
            let (c4, cr) = col.split_at(split);
            for (c, xc) in c4.chunks_exact(4).zip(x4.chunks_exact(4)) {
                acc[k] += lanes(c) * lanes(xc);
            }
            tail[k] = cr.iter().zip(xr).map(|(a, b)| a * b).sum::<f64>();
        }
        for k in 0..4 {
            fo[k] = sum(acc[k]) + tail[k];
        }
    }
    for (col, fj) in cols.remainder().chunks_exact(p).zip(out.into_remainder()) {
        *fj = dot(col, x);
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
pub(super) fn downdate<const SCALE: u8, const WITH_Q: bool>(
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
    let split = p - p % 4;
    let (a4, ar) = a.split_at(split);
    let (s4, sr) = s.split_at(split);
    let (cv, gv) = (f64x4::splat(c), f64x4::splat(g));
    let mut bad = f64x4::ZERO;
    let mut bad_rest = 0u64;
    for (j, (wcol, pcol)) in wm.chunks_exact_mut(p).zip(pm.chunks_exact(p)).enumerate() {
        let (bj, sj) = (b[j], s[j]);
        let (bjv, sjv) = (f64x4::splat(bj), f64x4::splat(sj));
        let qcol = if WITH_Q { &q[j * p..(j + 1) * p] } else { pcol };
        let (wo4, wor) = wcol.split_at_mut(split);
        let (p4, pr) = pcol.split_at(split);
        let (q4, qr) = qcol.split_at(split);
        for ((((wo, pi), ai), si), qi) in wo4
            .chunks_exact_mut(4)
            .zip(p4.chunks_exact(4))
            .zip(a4.chunks_exact(4))
            .zip(s4.chunks_exact(4))
            .zip(q4.chunks_exact(4))
        {
            let d = lanes(pi) - (lanes(ai) * bjv) * gv;
            let mut v = match SCALE {
                UNIT => d,
                UNIFORM => cv * d,
                _ => ((lanes(si) * sjv) * cv) * d,
            };
            if WITH_Q {
                v += lanes(qi);
            }
            wo.copy_from_slice(v.as_array());
            #[allow(clippy::eq_op)] // as in is_nonfinite
            {
                bad |= v - v;
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
    bad.as_array().iter().all(|b| b.to_bits() == 0) && bad_rest == 0
}

/// Four values of a slice as a vector.
#[inline(always)]
fn lanes(x: &[f64]) -> f64x4 {
    f64x4::new([x[0], x[1], x[2], x[3]])
}
