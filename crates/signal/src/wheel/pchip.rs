//! The angle between edges: the monotone piecewise-cubic Hermite curve (Fritsch–Carlson, as
//! scipy's `PchipInterpolator`), on the stream ([`Pchip`]) and over arrays ([`pchip_at`]).

use super::*;

/// The monotone piecewise-cubic Hermite interpolant through `(x, y)` (`x` increasing, at least
/// 2 points) at the points `at` (increasing); NaN outside `[x₀, xₙ]`: [`Pchip`] over the
/// points all given.
pub fn pchip_at(x: &[f64], y: &[f64], at: &[f64]) -> Vec<f64> {
    let mut p = Pchip::default();
    for (&x, &y) in x.iter().zip(y) {
        p.push(x, y);
    }
    p.end();
    at.iter().map(|&a| p.at(a).unwrap_or(f64::NAN)).collect()
}

/// The monotone piecewise-cubic Hermite interpolant (Fritsch–Carlson, with scipy
/// `PchipInterpolator`'s weighted harmonic mean of the slopes inside and its shape-preserving
/// three-point formula at the ends) as its points come: a value between two points is known
/// once the point after them has come (or the points have ended). Holds four points.
#[derive(Debug, Clone, Default)]
pub struct Pchip {
    /// The points from `from` on.
    x: VecDeque<f64>,
    y: VecDeque<f64>,
    from: usize,
    /// The first point's `x`; points so far; no more will come.
    first: f64,
    n: usize,
    ended: bool,
    /// The interval of the last value: from point `k` to `k + 1`.
    k: usize,
}

impl Pchip {
    /// The next point (`x` above the last).
    pub fn push(&mut self, x: f64, y: f64) {
        if self.n == 0 {
            self.first = x;
        }
        self.x.push_back(x);
        self.y.push_back(y);
        self.n += 1;
    }

    /// No more points.
    pub fn end(&mut self) {
        self.ended = true;
    }

    /// The last point's `x`.
    pub fn last_x(&self) -> Option<f64> {
        self.x.back().copied()
    }

    /// The value at `a` (the queries increasing): NaN outside the points' span; `None` while
    /// points after `a` are still to come.
    pub fn at(&mut self, a: f64) -> Option<f64> {
        let n = self.n;
        if n == 0 {
            return (self.ended || a.is_nan()).then_some(f64::NAN);
        }
        if a.is_nan() || a < self.first {
            return Some(f64::NAN);
        }
        let x = |i: usize| self.x[i - self.from];
        if a > x(n - 1) {
            return self.ended.then_some(f64::NAN);
        }
        if self.ended && n < 2 {
            return Some(f64::NAN);
        }
        let mut k = self.k;
        while k + 2 < n && a > x(k + 1) {
            k += 1;
        }
        if !self.ended && k + 2 >= n {
            return None;
        }
        self.k = k;
        while self.from + 1 < k {
            self.x.pop_front();
            self.y.pop_front();
            self.from += 1;
        }
        let (xk, xk1) = (self.x[k - self.from], self.x[k + 1 - self.from]);
        let (yk, yk1) = (self.y[k - self.from], self.y[k + 1 - self.from]);
        let h = xk1 - xk;
        let s = (a - xk) / h;
        let (h00, h10, h01, h11) = (
            (1.0 + 2.0 * s) * (1.0 - s) * (1.0 - s),
            s * (1.0 - s) * (1.0 - s),
            s * s * (3.0 - 2.0 * s),
            s * s * (s - 1.0),
        );
        Some(h00 * yk + h10 * h * self.slope(k) + h01 * yk1 + h11 * h * self.slope(k + 1))
    }

    /// The slope at point `i` (its neighbours here).
    fn slope(&self, i: usize) -> f64 {
        let h = |j: usize| self.x[j + 1 - self.from] - self.x[j - self.from];
        let delta = |j: usize| (self.y[j + 1 - self.from] - self.y[j - self.from]) / h(j);
        let end = |h0: f64, h1: f64, m0: f64, m1: f64| {
            let d = ((2.0 * h0 + h1) * m0 - h0 * m1) / (h0 + h1);
            if d.signum() != m0.signum() {
                0.0
            } else if m0.signum() != m1.signum() && d.abs() > 3.0 * m0.abs() {
                3.0 * m0
            } else {
                d
            }
        };
        let n = self.n;
        if self.ended && n == 2 {
            return delta(0);
        }
        if i == 0 {
            return end(h(0), h(1), delta(0), delta(1));
        }
        if self.ended && i == n - 1 {
            return end(h(n - 2), h(n - 3), delta(n - 2), delta(n - 3));
        }
        let (a, b) = (delta(i - 1), delta(i));
        if a * b <= 0.0 {
            0.0
        } else {
            let w1 = 2.0 * h(i) + h(i - 1);
            let w2 = h(i) + 2.0 * h(i - 1);
            (w1 + w2) / (w1 / a + w2 / b)
        }
    }
}
