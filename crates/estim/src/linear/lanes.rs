//! The four lanes the step's loops over P are written in ([`Lanes`]), and the run-time choice of
//! the step's copy compiled for AVX2 (`avx2()`).
//!
//! Two implementations, the same IEEE operations lane for lane (never fused), so the same
//! results on every CPU:
//! - `wide::f64x4`, chosen when the crate is compiled: one AVX register in a build for this
//!   machine (`target-cpu=native`), two SSE2 ones in a portable build (the Python wheel:
//!   x86-64-v2);
//! - `Avx`, one AVX register through `std::arch`, used only in the step's AVX2 copy, which a
//!   portable build on x86-64 carries beside its SSE2 step (`cfg(avx2_copy)`, build.rs) and
//!   runs where the CPU has AVX2, from p = 8 (BENCHMARKS.md, issue 47).
//!
//! (Plain `[f64; 4]` arrays, left to the compiler, do not serve: it vectorises a fixed p across
//! P's columns instead, with gathers — 3 against 8 M updates/s for the Kalman step at p = 20.)

use std::ops::{Add, Mul, Sub};

/// Four doubles: loaded from and stored to slices, added, subtracted and multiplied lane by
/// lane; summed in the order `(l0 + l1) + (l2 + l3)`; and or-ed bit by bit (the finiteness
/// check, `kernels::is_nonfinite`).
pub(super) trait Lanes:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self>
{
    /// Every lane `v`.
    fn splat(v: f64) -> Self;
    /// Four values.
    fn load(x: &[f64; 4]) -> Self;
    /// Into four values.
    fn store(self, out: &mut [f64; 4]);
    /// `(l0 + l1) + (l2 + l3)`.
    fn sum(self) -> f64;
    /// The lanes' bits or-ed with `o`'s.
    fn or(self, o: Self) -> Self;
    /// Whether every bit of every lane is 0.
    fn is_zero(self) -> bool;
}

impl Lanes for wide::f64x4 {
    #[inline(always)]
    fn splat(v: f64) -> Self {
        wide::f64x4::splat(v)
    }
    #[inline(always)]
    fn load(x: &[f64; 4]) -> Self {
        wide::f64x4::new(*x)
    }
    #[inline(always)]
    fn store(self, out: &mut [f64; 4]) {
        *out = *self.as_array();
    }
    #[inline(always)]
    fn sum(self) -> f64 {
        let a = self.as_array();
        (a[0] + a[1]) + (a[2] + a[3])
    }
    #[inline(always)]
    fn or(self, o: Self) -> Self {
        self | o
    }
    #[inline(always)]
    fn is_zero(self) -> bool {
        self.as_array().iter().all(|v| v.to_bits() == 0)
    }
}

/// Whether this CPU runs the step's AVX2 copy: it has AVX2, and the user has not turned it off
/// with `PHYSID_DISABLE_CPU_FEATURES=AVX2` (the results are the same either way; the switch is
/// there to measure, and for the test that shows it). Asked once, then an atomic load.
#[cfg(avx2_copy)]
#[inline]
pub(super) fn avx2() -> bool {
    static ON: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *ON.get_or_init(|| {
        let off = std::env::var("PHYSID_DISABLE_CPU_FEATURES").is_ok_and(|v| {
            v.split([',', ' '])
                .any(|f| f.trim().eq_ignore_ascii_case("avx2"))
        });
        !off && std::arch::is_x86_feature_detected!("avx2")
    })
}

#[cfg(avx2_copy)]
pub(super) use avx::Avx;

/// Four lanes in one AVX register, for the step's AVX2 copy of a build below AVX2.
///
/// SAFETY (of every `unsafe` here): these functions are inlined into the step's AVX2 copy
/// (`LinearEstimator::step_dim_avx2`, `#[target_feature(enable = "avx2")]`), the only code that
/// makes an `Avx`, which runs only where `avx2()` found AVX2; loads and stores are of a
/// `[f64; 4]`, four values by its type.
#[cfg(avx2_copy)]
#[allow(unsafe_code)]
mod avx {
    use std::arch::x86_64::*;
    use std::ops::{Add, Mul, Sub};

    #[derive(Clone, Copy)]
    pub(in super::super) struct Avx(__m256d);

    macro_rules! lane_op {
        ($tr:ident, $f:ident, $intrinsic:ident) => {
            impl $tr for Avx {
                type Output = Avx;
                #[inline(always)]
                fn $f(self, o: Avx) -> Avx {
                    Avx(unsafe { $intrinsic(self.0, o.0) })
                }
            }
        };
    }
    lane_op!(Add, add, _mm256_add_pd);
    lane_op!(Sub, sub, _mm256_sub_pd);
    lane_op!(Mul, mul, _mm256_mul_pd);

    /// One unaligned 256-bit load: the x86-64-v2 build's tuning (Sandy Bridge's) would split
    /// `_mm256_loadu_pd` into two 128-bit halves, which leaves the AVX2 copy no faster than
    /// the SSE2 step (BENCHMARKS.md, issue 47).
    #[target_feature(enable = "avx")]
    #[inline]
    fn load(x: &[f64; 4]) -> __m256d {
        let v: __m256d;
        unsafe {
            std::arch::asm!(
                "vmovupd {v}, ymmword ptr [{p}]",
                v = out(ymm_reg) v,
                p = in(reg) x.as_ptr(),
                options(pure, readonly, nostack, preserves_flags)
            );
        }
        v
    }

    /// One unaligned 256-bit store (as [`load`]).
    #[target_feature(enable = "avx")]
    #[inline]
    fn store(out: &mut [f64; 4], v: __m256d) {
        unsafe {
            std::arch::asm!(
                "vmovupd ymmword ptr [{p}], {v}",
                v = in(ymm_reg) v,
                p = in(reg) out.as_mut_ptr(),
                options(nostack, preserves_flags)
            );
        }
    }

    impl super::Lanes for Avx {
        #[inline(always)]
        fn splat(v: f64) -> Self {
            Avx(unsafe { _mm256_set1_pd(v) })
        }
        #[inline(always)]
        fn load(x: &[f64; 4]) -> Self {
            Avx(unsafe { load(x) })
        }
        #[inline(always)]
        fn store(self, out: &mut [f64; 4]) {
            unsafe { store(out, self.0) }
        }
        #[inline(always)]
        fn sum(self) -> f64 {
            let mut a = [0.0; 4];
            self.store(&mut a);
            (a[0] + a[1]) + (a[2] + a[3])
        }
        #[inline(always)]
        fn or(self, o: Self) -> Self {
            Avx(unsafe { _mm256_or_pd(self.0, o.0) })
        }
        #[inline(always)]
        fn is_zero(self) -> bool {
            let mut a = [0.0f64; 4];
            self.store(&mut a);
            a.iter().all(|v| v.to_bits() == 0)
        }
    }
}
