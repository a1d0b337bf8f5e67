//! The sensors (SPEC §2.7): which measures a channel, and a first-order sensor's state —
//! `y = gain·lag(x) + offset + noise`, quantised — with its own noise stream.

use crate::numeric::{expm1, round};
use crate::params::{CellParams, SensorParams};
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;
use rand_xoshiro::Xoshiro256PlusPlus;

/// Which sensor measures a channel (SPEC §2.7).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum SensorKind {
    Speed,
    TorqueShaft,
    TorqueEngine,
    PCyl,
    PManifold,
    Temperature,
}

impl SensorKind {
    /// This kind's parameters in `p`.
    pub(super) fn params(self, p: &CellParams) -> SensorParams {
        let s = &p.sensors;
        match self {
            SensorKind::Speed => s.speed,
            SensorKind::TorqueShaft => s.torque_shaft,
            SensorKind::TorqueEngine => s.torque_engine,
            SensorKind::PCyl => s.p_cyl,
            SensorKind::PManifold => s.p_manifold,
            SensorKind::Temperature => s.temperature,
        }
    }
}

/// A first-order sensor's state over the output samples, with its own noise stream (so that
/// one sensor's settings never change another's noise).
#[derive(Clone)]
pub(super) struct SensorState {
    lagged: Option<f64>,
    pub(super) rng: Xoshiro256PlusPlus,
}

impl SensorState {
    /// Stream `stream` of `seed`: xoshiro256++ seeded through SplitMix64 from `seed` and the
    /// stream number spread by the golden ratio (so that neighbouring streams and seeds start
    /// far apart in the generator's 2²⁵⁶ − 1 period).
    pub(super) fn new(seed: u64, stream: u64) -> Self {
        let rng =
            Xoshiro256PlusPlus::seed_from_u64(seed ^ stream.wrapping_mul(0x9e37_79b9_7f4a_7c15));
        Self { lagged: None, rng }
    }

    /// Measure consecutive samples `x` in place, all with the sensor's parameters `s`:
    /// `y = gain·lag(x) + offset + noise`, quantised. `decay[k]` is the lag's
    /// [`Prepared::decay`] over the time since the sample before `x[k]`. Each step of the
    /// measurement is one pass over the samples (no choice made per sample).
    pub(super) fn measure(&mut self, s: &Prepared, x: &mut [f64], decay: &[f64]) {
        if s.inv_lag > 0.0 {
            // The exact discretisation of τ·l' = x − l with x held over dt:
            // l ← l + (x − l)·(1 − e^(−dt/τ)).
            for (xi, &a) in x.iter_mut().zip(decay) {
                if let Some(prev) = self.lagged {
                    *xi = prev + (*xi - prev) * a;
                }
                self.lagged = Some(*xi);
            }
        } else if let Some(&last) = x.last() {
            self.lagged = Some(last);
        }
        if (s.p.gain, s.p.offset) != (1.0, 0.0) {
            for xi in x.iter_mut() {
                *xi = s.p.gain * *xi + s.p.offset;
            }
        }
        if s.p.noise > 0.0 {
            for xi in x.iter_mut() {
                *xi += s.p.noise * self.rng.sample::<f64, _>(StandardNormal);
            }
        }
        if s.p.quantum > 0.0 {
            for xi in x.iter_mut() {
                *xi = round(*xi * s.inv_quantum) * s.p.quantum;
            }
        }
    }

    /// One sample `x`, `dt` [s] after the one before.
    pub(super) fn measure_one(&mut self, s: &Prepared, x: f64, dt: f64) -> f64 {
        let mut y = [x];
        self.measure(s, &mut y, &[s.decay(dt)]);
        y[0]
    }
}

/// A sensor's parameters with the reciprocals of its lag and quantum (0 where it has none).
#[derive(Debug, Clone, Copy)]
pub(super) struct Prepared {
    pub(super) p: SensorParams,
    pub(super) inv_lag: f64,
    inv_quantum: f64,
}

impl From<SensorParams> for Prepared {
    fn from(p: SensorParams) -> Self {
        let inv = |x: f64| if x > 0.0 { 1.0 / x } else { 0.0 };
        Self {
            p,
            inv_lag: inv(p.lag),
            inv_quantum: inv(p.quantum),
        }
    }
}

impl Prepared {
    /// The lag's `1 − e^(−dt/τ)` over `dt` [s] (by `expm1`: no cancellation); 0 without a lag.
    pub(super) fn decay(&self, dt: f64) -> f64 {
        if self.inv_lag > 0.0 {
            -expm1(-dt * self.inv_lag)
        } else {
            0.0
        }
    }
}
