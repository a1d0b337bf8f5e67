//! The flow areas: valve curtain areas ([`valve_area`], [`ValveGeometry`]), the throttle plate
//! ([`throttle_area`]) and the cam lift profiles ([`Cam`]).

use super::*;

/// Valve flow area (Eq. 3.33–3.35): curtain area up to the lift where it equals the port area,
/// the port area beyond.
pub fn valve_area(lift: f64, d: f64, di: f64, seat_deg: f64) -> f64 {
    ValveGeometry::new(d, di, seat_deg).area(lift)
}

/// A valve's flow-area constants, computed once (the seat angle's cosine, the lift where the
/// curtain area reaches the port area): [`valve_area`] without its trigonometry per call.
#[derive(Debug, Clone, Copy)]
pub struct ValveGeometry {
    /// `π·(d + di)/2` [m].
    half_perimeter: f64,
    /// cos(seat angle).
    cos_seat: f64,
    /// Lift where curtain = port area [m].
    lv: f64,
    /// Port area `π·di²/4` [m²].
    port: f64,
}

impl ValveGeometry {
    /// Head diameter `d`, inner seat diameter `di` [m], seat angle [deg].
    pub fn new(d: f64, di: f64, seat_deg: f64) -> Self {
        let c = seat_deg.to_radians().cos();
        Self {
            half_perimeter: PI * (d + di) / 2.0,
            cos_seat: c,
            lv: di * di / (2.0 * c * (d + di)),
            port: PI * di * di / 4.0,
        }
    }

    /// The port's area `π·di²/4` [m²], the largest flow area.
    pub fn port_area(&self) -> f64 {
        self.port
    }

    /// `dA/dlift` [m] at `lift`: the curtain's slope while the curtain is the smaller area, 0
    /// shut or on the port area.
    pub fn area_slope(&self, lift: f64) -> f64 {
        if lift > 0.0 && lift <= self.lv {
            self.half_perimeter * self.cos_seat
        } else {
            0.0
        }
    }

    /// Flow area at `lift` [m].
    pub fn area(&self, lift: f64) -> f64 {
        if lift <= 0.0 {
            0.0
        } else if lift <= self.lv {
            self.half_perimeter * lift * self.cos_seat
        } else {
            self.port
        }
    }
}

/// Throttle flow area (Eq. 3.36, Moskwa/Heywood) at opening `thr` [deg] above the closed angle
/// `psi0`, plus the leakage area.
pub fn throttle_area(thr_deg: f64, d: f64, shaft: f64, psi0_deg: f64, leak: f64) -> f64 {
    let a = shaft / d;
    let psi0 = psi0_deg.to_radians();
    let psi = (psi0_deg + thr_deg.max(0.0)).to_radians();
    let full = PI * d * d / 4.0;
    let max = full - d * shaft;
    let (c, c0) = (psi.cos(), psi0.cos());
    let area = if c >= a * c0 && psi < PI / 2.0 {
        full * (1.0 - c / c0
            + 2.0 / PI
                * ((a / c) * (c * c - a * a * c0 * c0).max(0.0).sqrt()
                    + (c / c0) * (a * c0 / c).clamp(-1.0, 1.0).asin()
                    - a * (1.0 - a * a).sqrt()
                    - a.asin()))
    } else {
        max
    };
    area.clamp(0.0, max) + leak
}

/// A valve's lift profile: `l_max·sinⁿ(π·x)`, x the fraction of the open duration (SPEC §2.3
/// suggests n = 2; the cell's default is 5, see [`EngineParams::lift_exponent`]), with the
/// open duration computed once.
#[derive(Debug, Clone, Copy)]
pub struct Cam {
    open: f64,
    dur: f64,
    inv_dur: f64,
    l_max: f64,
    n: u32,
}

impl Cam {
    /// Open from `open` to `close` [deg], peak lift `l_max` [m], exponent `n`.
    pub fn new(open: f64, close: f64, l_max: f64, n: u32) -> Self {
        let dur = wrap720(close - open);
        Self {
            open,
            dur,
            inv_dur: 1.0 / dur,
            l_max,
            n,
        }
    }

    /// Lift [m] at `deg` within the cycle.
    pub fn lift(&self, deg: f64) -> f64 {
        // Shut (the common case) decided before dividing.
        let r = wrap720(deg - self.open);
        if self.dur <= 0.0 || r >= self.dur {
            0.0
        } else {
            let s = (PI * (r * self.inv_dur)).sin();
            self.l_max * powi(s, self.n)
        }
    }

    /// Lift [m] and its slope `dl/dθ` [m/deg] at `deg` within the cycle: `n·l_max·sinⁿ⁻¹(π·x)·
    /// cos(π·x)·π/Δ`, the cosine as `±√(1 − sin²)` (negative past the peak).
    pub fn lift_and_slope(&self, deg: f64) -> (f64, f64) {
        let r = wrap720(deg - self.open);
        if self.dur <= 0.0 || r >= self.dur || self.n == 0 {
            return (self.lift(deg), 0.0);
        }
        let x = r * self.inv_dur;
        let s = (PI * x).sin();
        let c = (1.0 - s * s).max(0.0).sqrt();
        let c = if x > 0.5 { -c } else { c };
        let sn1 = powi(s, self.n - 1);
        (
            self.l_max * sn1 * s,
            self.l_max * f64::from(self.n) * sn1 * c * PI * self.inv_dur,
        )
    }
}
