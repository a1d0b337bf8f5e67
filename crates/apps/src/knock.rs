//! Knock from one cycle's cylinder pressure: the pressure oscillation that end-gas
//! autoignition excites (the cylinder's acoustic modes, 5–20 kHz in passenger-car engines),
//! band-passed out of the trace and measured in a window after TDC.
//!
//! * **Band-pass**: a Butterworth band-pass (order [`ORDER`] per edge, scipy's `butter`,
//!   [`physid_signal::filter`]) applied forwards and backwards (`sosfiltfilt`: zero phase, so
//!   the oscillation is not shifted in angle) over the window and [`SETTLE_TOL`]'s margin on
//!   each side — as many samples as the filter's slowest pole takes to fall to 10⁻¹², so the
//!   window's values are those of the whole cycle filtered (131° each side at 6000 rpm and
//!   0.1°, 19° at 1000 rpm, for the default band; the whole cycle when the margins reach its
//!   ends). The band-pass runs as parallel branches ([`physid_signal::filter::parallel`]: the
//!   same filter as the sections to 10⁻¹³ of the pressure, 3× faster), as sections
//!   where that form would not be accurate. The cycle's samples are on
//!   a uniform crank-angle grid, so at the cycle's mean speed they are a uniform time series at
//!   `f_s = 6·rpm / step` [Hz]; the band needs `f_s ≥ 2.5·f_high` (a step of at most
//!   `6·rpm / (2.5·f_high)` degrees: 0.12° at 2000 rpm for 20 kHz) — otherwise no knock figures,
//!   and a note says which step the speed needs.
//! * **MAPO**, the maximum amplitude of the pressure oscillation: `max |p̃|` over the window
//!   (Worret, Bernhardt, Schwarz, Spicher, SAE 2002-01-1668, "Application of different cylinder
//!   pressure based knock detection methods in spark ignition engines").
//! * **IMPO**, the integral of its modulus: `∫ |p̃| dθ` over the window [Pa·deg] (same source) —
//!   the knock's energy over its duration rather than its peak.
//! * **Knock flag**: MAPO above a threshold ([`DEFAULT_THRESHOLD_PA`] unless given: the level
//!   must be set for each engine, as every knock system asks).

use physid_signal::filter::{butter, Band, FilterError, Parallel, Sos};
use serde::{Deserialize, Serialize};

/// The band-pass's order (per edge).
pub const ORDER: usize = 4;

/// The band [Hz] when none is given.
pub const DEFAULT_BAND_HZ: (f64, f64) = (5e3, 20e3);

/// The window [deg ATDC] when none is given: from TDC to 60° after, where end-gas
/// autoignition happens.
pub const DEFAULT_WINDOW: (f64, f64) = (0.0, 60.0);

/// The MAPO above which a cycle knocks when no threshold is given [Pa] (1 bar).
pub const DEFAULT_THRESHOLD_PA: f64 = 1e5;

/// The band-pass's free response falls to this fraction of its start over the margin filtered
/// on each side of the window (see the module docs).
pub const SETTLE_TOL: f64 = 1e-12;

/// The source's sample rate must be at least this multiple of the band's upper edge.
pub const RATE_MARGIN: f64 = 2.5;

/// How knock is measured.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Knock {
    /// The band [Hz].
    pub band_hz: (f64, f64),
    /// The window [deg ATDC].
    pub window: (f64, f64),
    /// MAPO above this knocks [Pa].
    pub threshold_pa: f64,
}

impl Default for Knock {
    fn default() -> Self {
        Self {
            band_hz: DEFAULT_BAND_HZ,
            window: DEFAULT_WINDOW,
            threshold_pa: DEFAULT_THRESHOLD_PA,
        }
    }
}

/// One cycle's knock figures.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct KnockFigures {
    /// Maximum amplitude of the pressure oscillation in the window [Pa].
    pub mapo_pa: f64,
    /// Its angle [deg ATDC].
    pub mapo_deg: f64,
    /// Integral of the oscillation's modulus over the window [Pa·deg].
    pub impo_pa_deg: f64,
    /// MAPO above the threshold.
    pub knock: bool,
}

impl Knock {
    /// Refused unless 0 < f_low < f_high, a window within −360° … 360° ATDC and a threshold > 0.
    pub fn validate(&self) -> Result<(), String> {
        let (lo, hi) = self.band_hz;
        if !(lo > 0.0 && hi > lo && hi.is_finite()) {
            return Err(format!(
                "knock band {} … {} Hz: expected 0 < low < high (e.g. 5000,20000)",
                physid_core::Num(lo),
                physid_core::Num(hi)
            ));
        }
        let (a, b) = self.window;
        if !(a < b && a >= -360.0 && b <= 360.0) {
            return Err(format!(
                "knock window {}° … {}° ATDC: expected a start before the end, within −360° … 360°",
                physid_core::Num(a),
                physid_core::Num(b)
            ));
        }
        if !(self.threshold_pa > 0.0 && self.threshold_pa.is_finite()) {
            return Err(format!(
                "knock threshold {} Pa: expected a pressure > 0",
                physid_core::Num(self.threshold_pa)
            ));
        }
        Ok(())
    }

    /// The largest crank-angle step [deg] that resolves the band at `rpm`.
    pub fn max_step_deg(&self, rpm: f64) -> f64 {
        6.0 * rpm / (RATE_MARGIN * self.band_hz.1)
    }

    /// The knock figures of a cycle: `atdc` a uniform grid [deg ATDC] in increasing order, `p`
    /// the pressure there [Pa], `rpm` the cycle's mean speed. An error (why, for the cycle's
    /// notes) when the step is too coarse for the band or the cycle too short to filter.
    pub fn figures(&self, atdc: &[f64], p: &[f64], rpm: f64) -> Result<KnockFigures, String> {
        let n = atdc.len();
        if n < 3 || rpm.is_nan() || rpm <= 0.0 {
            return Err(
                "knock left out: the cycle is too short or its speed is not positive".into(),
            );
        }
        let step = (atdc[n - 1] - atdc[0]) / (n - 1) as f64;
        if step > self.max_step_deg(rpm) {
            return Err(format!(
                "knock left out: {step}° steps at {rpm:.0} rpm sample at {:.0} Hz; the {}–{} Hz band needs a step of at most {:.3}° ({RATE_MARGIN} × its upper edge: a finer --step-deg, from a source sampled that fast)",
                6.0 * rpm / step,
                self.band_hz.0,
                self.band_hz.1,
                self.max_step_deg(rpm)
            ));
        }
        let fs = 6.0 * rpm / step;
        let zpk = butter(ORDER, &[self.band_hz.0, self.band_hz.1], Band::Bandpass, fs)
            .map_err(|e| format!("knock left out: {e}"))?;
        // The parallel form where it is accurate (the same filter to rounding, 3× faster),
        // else the cascade.
        let filter = match zpk.to_parallel() {
            Some(parallel) => ZeroPhase::Parallel(parallel),
            None => ZeroPhase::Cascade(zpk.to_sos()),
        };
        let (from, to) = (
            atdc.partition_point(|&a| a < self.window.0),
            atdc.partition_point(|&a| a <= self.window.1),
        );
        if to <= from {
            return Err("knock left out: no sample in the knock window".into());
        }
        // The window and the filter's settling on each side (the whole cycle at most).
        let margin = filter.settle_samples(SETTLE_TOL);
        let (mut lo, mut hi) = (
            from.saturating_sub(margin),
            to.saturating_add(margin).min(n),
        );
        if hi - lo <= filter.padlen() {
            (lo, hi) = (0, n);
        }
        // The window's values on (the backward pass need not go before it).
        let stretch = filter
            .filtfilt_from(&p[lo..hi], from - lo)
            .map_err(|e| format!("knock left out: {e}"))?;
        let filtered = |k: usize| stretch[k - from];
        let (mut mapo, mut mapo_deg, mut impo) = (0.0_f64, atdc[from], 0.0);
        for k in from..to {
            let m = filtered(k).abs();
            if m > mapo {
                (mapo, mapo_deg) = (m, atdc[k]);
            }
            if k > from {
                impo += 0.5 * (m + filtered(k - 1).abs()) * (atdc[k] - atdc[k - 1]);
            }
        }
        Ok(KnockFigures {
            mapo_pa: mapo,
            mapo_deg,
            impo_pa_deg: impo,
            knock: mapo > self.threshold_pa,
        })
    }
}

/// The band-pass in the form it runs in.
enum ZeroPhase {
    Parallel(Parallel),
    Cascade(Sos),
}

impl ZeroPhase {
    fn settle_samples(&self, tol: f64) -> usize {
        match self {
            Self::Parallel(f) => f.settle_samples(tol),
            Self::Cascade(f) => f.settle_samples(tol),
        }
    }

    fn padlen(&self) -> usize {
        match self {
            Self::Parallel(f) => f.padlen(),
            Self::Cascade(f) => f.padlen(),
        }
    }

    /// `sosfiltfilt(x)[from..]`.
    fn filtfilt_from(&self, x: &[f64], from: usize) -> Result<Vec<f64>, FilterError> {
        match self {
            Self::Parallel(f) => f.filtfilt_from(x, from),
            Self::Cascade(f) => f.sosfiltfilt_from(x, from),
        }
    }
}
