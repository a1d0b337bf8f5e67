//! The gas network's stiffness: its Jacobian's largest eigenvalue (the explicit solver's
//! step bound).

/// The largest eigenvalue of the symmetric tridiagonal 3×3 matrix with diagonal `a` and
/// off-diagonal `b` (`b[0]` couples 0–1, `b[1]` couples 1–2), approached from above: Newton's
/// method on the characteristic cubic, started at the Gershgorin bound. Right of its largest
/// root the cubic is increasing and convex, so the iterates decrease monotonically onto that
/// root and each is an upper bound; iteration stops when a step is below 1e-3 relative, or at
/// the first bound at or below `enough` (a caller that needs the eigenvalue only above that
/// level; 0 for the eigenvalue itself).
pub fn largest_eigenvalue_tridiag3(a: [f64; 3], b: [f64; 2], enough: f64) -> f64 {
    let (b0, b1) = (b[0] * b[0], b[1] * b[1]);
    let (c0, c1) = (b[0].abs(), b[1].abs());
    let mut l = (a[0] + c0).max(a[1] + c0 + c1).max(a[2] + c1);
    for _ in 0..64 {
        if l <= enough {
            break;
        }
        let (x0, x1, x2) = (l - a[0], l - a[1], l - a[2]);
        let p = x0 * x1 * x2 - b1 * x0 - b0 * x2;
        let dp = x1 * x2 + x0 * x2 + x0 * x1 - b0 - b1;
        if p <= 0.0 || dp <= 0.0 {
            break;
        }
        let step = p / dp;
        l -= step;
        if step <= 1e-3 * l.abs() {
            break;
        }
    }
    l
}
