//! Slider-crank kinematics with piston-pin offset (SPEC §2.3; thesis Eq. 3.29–3.32, app. B.4).
//!
//! Crank radius `r`, rod `L`, bore `b`, pin offset `δ`, compression ratio `κ` (SI units);
//! crank angle `θ` in rad from the cylinder axis; TDC is at `θ = φ = asin(δ/(r+L))` (θ = 0 for
//! δ = 0). With `q = r·sin θ − δ`, `w = √(L² − q²)`:
//!
//! ```text
//! s(θ)   = √((r+L)² − δ²) − r·cos θ − w                       (Eq. 3.29, SPEC fix: − r cos)
//! s'(θ)  = r·sin θ + q·r·cos θ / w
//! s''(θ) = r·cos θ + (r²·cos²θ − q·r·sin θ)/w + q²·r²·cos²θ / w³
//! V(θ)   = V_c + A_p·s(θ),  A_p = π b²/4,  V_c = V_d/(κ−1)
//! A_w(θ) = π b²/2 + π b·(V_c/A_p + s(θ))                      (Eq. 3.32)
//! ```
//!
//! *(fix)* SPEC §2.3 writes `s` with `θ − φ` inside and `q = δ + r·sin(θ−φ)`; that puts
//! s(φ) = 0 only when δ = 0. Measured from the cylinder axis as above, s(φ) = 0 exactly
//! (`√(L² − q²) = L·cos φ` there), which is what SPEC's own verification asks for (tested).
//!
//! The thesis's closed forms for the torque (app. B.4) are `ψ = 1 − (q/L)²`,
//! `G = sin θ + √((1−ψ)/ψ)·cos θ`, `G1`, `G2`. Since `1 − ψ = (q/L)²`, the root there must keep
//! the sign of `q`: `√((1−ψ)/ψ) → q/(L√ψ)`. Taken literally (unsigned) the forms are wrong
//! whenever `q < 0` — half of every revolution — and their derivative at TDC is `∞·0`. The
//! signed forms below equal the virtual-work forms (`r·G = s'`, `G1 = s''`, `G2 = s'` at δ = 0),
//! which a test checks over the whole cycle.

use physid_core::Scalar;

/// Slider-crank geometry (SI units). Generic so that any of it can be an estimated parameter.
#[derive(Debug, Clone, Copy)]
pub struct Crank<T> {
    /// Crank radius r [m].
    pub r: T,
    /// Connecting-rod length L [m].
    pub l: T,
    /// Piston-pin offset δ [m].
    pub delta: T,
    /// Bore b [m].
    pub bore: T,
    /// Compression ratio κ [-].
    pub kappa: T,
}

impl Crank<f64> {
    /// `s(θ)` [m] (Eq. 3.29) at an angle that is itself a parameter (a dual number: a TDC
    /// offset being estimated) on a known geometry: `√((L+r)² − δ²) − r·cos θ − √(L² − q²)`,
    /// `q = r·sin θ − δ` — the same form as [`motion_from`](Self::motion_from).
    pub fn s_at<A: Scalar>(&self, theta: A) -> A {
        let q = theta.sin() * self.r - self.delta;
        -(theta.cos() * self.r) - (-(q * q) + self.l * self.l).sqrt() + self.tdc_height()
    }
}

impl<T: Scalar> Crank<T> {
    /// `φ = asin(δ/(r+L))`: the crank angle of TDC [rad].
    pub fn phi(&self) -> T {
        (self.delta / (self.r + self.l)).asin()
    }

    /// `(s, s', s'')` at θ from one evaluation of the trigonometry: displacement from TDC [m]
    /// and its first two derivatives [m/rad, m/rad²].
    pub fn motion(&self, theta: f64) -> (T, T, T) {
        self.motion_sin_cos(theta.sin_cos())
    }

    /// [`motion`](Self::motion) from θ's sine and cosine (a caller that has them already).
    pub fn motion_sin_cos(&self, sc: (f64, f64)) -> (T, T, T) {
        self.motion_from(self.tdc_height(), sc)
    }

    /// The piston pin's height above the crank axis at TDC, `√((L+r)² − δ²)` [m]: a constant
    /// of the geometry, which [`motion_from`](Self::motion_from) takes computed.
    pub fn tdc_height(&self) -> T {
        let rl = self.r + self.l;
        (rl * rl - self.delta * self.delta).sqrt()
    }

    /// [`motion_sin_cos`](Self::motion_sin_cos) with [`tdc_height`](Self::tdc_height) given
    /// (a caller evaluating many angles of one geometry computes it once). With
    /// `q = r·sin θ − δ` and `w = √(L² − q²)`: `s = √((L+r)² − δ²) − r·cos θ − w`,
    /// `s' = r·sin θ + q·r·cos θ/w`, `s'' = r·cos θ + (r²cos²θ − q·r·sin θ)/w + q²r²cos²θ/w³`
    /// (one division, for 1/w).
    pub fn motion_from(&self, tdc_height: T, (sa, ca): (f64, f64)) -> (T, T, T) {
        let r = self.r;
        let q = r * sa - self.delta;
        let w = (self.l * self.l - q * q).sqrt();
        let iw = w.recip();
        let s = tdc_height - r * ca - w;
        let rca = r * ca;
        let ds = r * sa + q * rca * iw;
        let dds = rca + (rca * rca - q * r * sa) * iw + q * q * rca * rca * (iw * iw * iw);
        (s, ds, dds)
    }

    /// Piston displacement from TDC, s(θ) [m].
    pub fn s(&self, theta: f64) -> T {
        self.motion(theta).0
    }

    /// ds/dθ [m/rad].
    pub fn ds(&self, theta: f64) -> T {
        self.motion(theta).1
    }

    /// d²s/dθ² [m/rad²].
    pub fn dds(&self, theta: f64) -> T {
        self.motion(theta).2
    }

    /// Stroke: the distance between TDC and BDC, `√((L+r)² − δ²) − √((L−r)² − δ²)` [m].
    pub fn stroke(&self) -> T {
        let (lp, lm) = (self.l + self.r, self.l - self.r);
        let d2 = self.delta * self.delta;
        (lp * lp - d2).sqrt() - (lm * lm - d2).sqrt()
    }

    /// Piston area `π b²/4` [m²].
    pub fn piston_area(&self) -> T {
        self.bore * self.bore * (std::f64::consts::PI / 4.0)
    }

    /// Clearance volume `V_d/(κ−1)` [m³].
    pub fn clearance_volume(&self) -> T {
        self.piston_area() * self.stroke() / (self.kappa - 1.0)
    }

    /// Cylinder volume V(θ) [m³].
    pub fn volume(&self, theta: f64) -> T {
        self.clearance_volume() + self.piston_area() * self.s(theta)
    }

    /// dV/dt = A_p·s'(θ)·ω [m³/s] (Eq. 3.30).
    pub fn dvolume_dt(&self, theta: f64, omega: f64) -> T {
        self.piston_area() * self.ds(theta) * omega
    }

    /// Heat-transfer area: head + piston + liner (Eq. 3.32) [m²].
    pub fn wall_area(&self, theta: f64) -> T {
        let pi = std::f64::consts::PI;
        self.bore * self.bore * (pi / 2.0)
            + self.bore * pi * (self.clearance_volume() / self.piston_area() + self.s(theta))
    }

    /// The thesis's closed forms (app. B.4) with the signed root: `(G, G1, G2)` at θ, so that
    /// `τ_ind = (p − p_crank)·A_p·r·G` and `τ_rec = M_rec·r·G·(G1·ω² + G2·α)`. Written as in the
    /// thesis, with `a = θ − φ` and `q = δ + r·sin a`; they agree with the virtual-work forms at
    /// δ = 0 (tested), which is where the thesis used them.
    pub fn thesis_g(&self, theta: f64) -> (T, T, T) {
        self.thesis_g_at(theta.sin_cos())
    }

    /// [`thesis_g`](Self::thesis_g) from θ's sine and cosine `(st, ct)` (computed once for
    /// several crank trains at the same angle: an unscented filter's sigma points).
    pub fn thesis_g_at(&self, (st, ct): (f64, f64)) -> (T, T, T) {
        // Each elementary function once (√ψ, 1/(l·√ψ)): the gradient engine's dual numbers pay
        // for every operation in every lane.
        // a = θ − φ with sin φ = δ/(r + l): sin a and cos a by the angle-difference identities
        // from θ's sine and cosine (no arcsine, no trigonometry of a dual number).
        let s_phi = self.delta / (self.r + self.l);
        let c_phi = (-(s_phi * s_phi) + 1.0).sqrt();
        let sa = c_phi * st - s_phi * ct;
        let ca = c_phi * ct + s_phi * st;
        let q = self.delta + self.r * sa;
        let q_l = q / self.l;
        let psi = -(q_l * q_l) + 1.0;
        let inv = (self.l * psi.sqrt()).recip(); // 1/(l·√ψ)
        let root = q * inv; // √((1−ψ)/ψ) with the sign of q
        let g = root * ct + st;
        // (r/l)·ca/ψ^(3/2) = r·ca·inv/ψ
        let g1 = self.r * (ca * (self.r * ca * inv / psi + 1.0) - root * sa);
        let g2 = self.r * (root * ca + sa);
        (g, g1, g2)
    }
}
