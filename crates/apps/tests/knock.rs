//! Knock against a closed form and scipy: motored cycles (`p·Vⁿ` constant from BDC to BDC, the
//! volume from the textbook slider crank written here) with a damped 7 kHz oscillation of known
//! amplitude, `A·e^{−t/τ}·sin(2πf·t)` from 8° after TDC, on chosen cycles. The band-pass must
//! keep the oscillation and drop the compression: MAPO within 5 % of the oscillation's own
//! largest value, those cycles flagged, no others; MAPO and IMPO equal to scipy's
//! `sosfiltfilt` on the same cycle (`golden/gen_knock.py`); a step too coarse for the band is
//! said.
//!
//! A band-pass smooths the oscillation's abrupt onset: the first crest comes out low and MAPO
//! falls short of the amplitude the faster the oscillation decays (scipy: 85 % at τ = 0.8 ms,
//! 96.5 % at 3 ms, a usual knock decay) — a property of the metric, not of its computation.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_apps::knock::Knock;
use physid_apps::pressure::{CycleAnalyser, Geometry, Pegging};
use physid_core::{Basis, Channel, Recording};

const BORE: f64 = 0.084;
const STROKE: f64 = 0.09;
const ROD: f64 = 0.15;
const CR: f64 = 10.0;
const N: f64 = 1.3;
const P0: f64 = 1e5;
const RPM: f64 = 1500.0;
/// The knock: frequency [Hz], amplitude [Pa], decay [s], onset [deg ATDC].
const F_KNOCK: f64 = 7e3;
const A_KNOCK: f64 = 3e5;
const TAU: f64 = 3e-3;
const ONSET: f64 = 8.0;

fn volume(atdc_deg: f64) -> f64 {
    let r = STROKE / 2.0;
    let a = atdc_deg.to_radians();
    let s = r * (1.0 - a.cos()) + ROD - (ROD * ROD - (r * a.sin()).powi(2)).sqrt();
    let area = std::f64::consts::PI * BORE * BORE / 4.0;
    area * STROKE / (CR - 1.0) + area * s
}

/// The oscillation at `atdc` [deg] of a knocking cycle, decaying by `tau` [s].
fn oscillation(atdc: f64, tau: f64) -> f64 {
    if atdc < ONSET {
        return 0.0;
    }
    let t = (atdc - ONSET) / (6.0 * RPM);
    A_KNOCK * (-t / tau).exp() * (2.0 * std::f64::consts::PI * F_KNOCK * t).sin()
}

/// The pressure of TDC `c`'s cycle at `atdc` [deg ATDC, −360 … 360].
fn pressure(atdc: f64, knocks: bool, tau: f64) -> f64 {
    let motored = if (-180.0..=180.0).contains(&atdc) {
        P0 * (volume(180.0) / volume(atdc)).powf(N)
    } else {
        P0
    };
    motored + if knocks { oscillation(atdc, tau) } else { 0.0 }
}

/// `blocks` blocks from firing TDC to firing TDC at `step` degrees; the cycles of the TDCs in
/// `knocking` knock, their oscillation decaying by `tau` [s].
fn recording(blocks: usize, step: f64, knocking: &[usize], tau: f64) -> Recording {
    let per = (720.0 / step).round() as usize;
    let (mut t, mut cycle, mut deg, mut p) = (vec![], vec![], vec![], vec![]);
    for c in 0..blocks {
        for k in 0..per {
            let d = k as f64 * step;
            // The block's first half is TDC c's expansion, its second TDC c + 1's compression.
            let (tdc, atdc) = if d < 360.0 {
                (c, d)
            } else {
                (c + 1, d - 720.0)
            };
            t.push((c * per + k) as f64 * step / (6.0 * RPM));
            cycle.push(c as f64);
            deg.push(d);
            p.push(pressure(atdc, knocking.contains(&tdc), tau));
        }
    }
    let mut rec = Recording::new(Basis::CrankAngle);
    for (name, unit, values) in [
        ("t", "s", t),
        ("cycle", "-", cycle),
        ("crank_deg", "deg", deg),
        ("p_cyl", "Pa", p),
    ] {
        rec.push(Channel {
            name: name.into(),
            unit: unit.into(),
            values,
        })
        .unwrap();
    }
    rec
}

fn geometry() -> Geometry {
    Geometry {
        bore: BORE,
        stroke: STROKE,
        rod: ROD,
        compression_ratio: CR,
    }
}

fn analysed(rec: &Recording) -> physid_apps::pressure::CycleAnalysis {
    let mut a = CycleAnalyser::new(rec, "p_cyl", Some(&geometry()), Pegging::None)
        .unwrap()
        .with_knock(Knock::default())
        .unwrap();
    a.push(rec).unwrap();
    a.finish().unwrap()
}

#[test]
fn a_knocking_cycle_has_its_oscillation_s_amplitude_and_is_flagged() {
    let knocking = [2, 5];
    // 0.1° at 1500 rpm: 90 kHz, well above 2.5 × 20 kHz.
    let step = 0.1;
    let a = analysed(&recording(7, step, &knocking, TAU));
    assert_eq!(a.cycles.len(), 6);
    // The oscillation's largest value on the samples, in the knock window.
    let window = Knock::default().window;
    let peak = (0..=((window.1 - window.0) / step).round() as usize)
        .map(|k| oscillation(window.0 + k as f64 * step, TAU).abs())
        .fold(0.0, f64::max);
    for c in &a.cycles {
        let k = c.knock.expect("knock figures");
        let knocks = knocking.contains(&(c.cycle as usize));
        assert_eq!(k.knock, knocks, "cycle {}: MAPO {} Pa", c.cycle, k.mapo_pa);
        if knocks {
            // Measured: 3.5 % low (see the module docs); the issue asks 5 %.
            assert!(
                (k.mapo_pa / peak - 1.0).abs() < 0.05,
                "cycle {}: MAPO {} Pa against {peak} Pa",
                c.cycle,
                k.mapo_pa
            );
            // Within the oscillation's first two periods.
            let period_deg = 6.0 * RPM / F_KNOCK;
            assert!(
                k.mapo_deg > ONSET && k.mapo_deg < ONSET + 2.0 * period_deg,
                "at {}°",
                k.mapo_deg
            );
        } else {
            // The compression leaves almost nothing in the band.
            assert!(
                k.mapo_pa < 0.02 * peak,
                "cycle {}: {} Pa",
                c.cycle,
                k.mapo_pa
            );
        }
    }
    let names: Vec<String> = a.columns().into_iter().map(|c| c.0).collect();
    for n in ["mapo", "mapo_deg", "impo", "knock"] {
        assert!(names.iter().any(|m| m == n), "{n} in {names:?}");
    }
}

#[test]
fn a_step_too_coarse_for_the_band_is_said() {
    // 1° at 1500 rpm: 9 kHz, below 2.5 × 20 kHz.
    let a = analysed(&recording(3, 1.0, &[1], TAU));
    assert_eq!(a.cycles.len(), 2);
    for c in &a.cycles {
        assert!(c.knock.is_none());
    }
    assert!(
        a.notes.iter().any(|n| n
            .starts_with("2 cycle(s): knock left out: 1° steps at 1500 rpm sample at 9000 Hz")
            && n.contains("a step of at most 0.180°")),
        "{:?}",
        a.notes
    );
}

/// The knocking cycle's MAPO, its angle and IMPO equal scipy's on the same samples, for a fast
/// and a usual decay.
#[test]
fn mapo_and_impo_are_scipy_s() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden/knock.json");
    let golden: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    for (tau, key) in [(0.8e-3, "0.0008"), (3e-3, "0.003")] {
        let want = |k: &str| golden[key][k].as_f64().unwrap();
        let a = analysed(&recording(2, 0.1, &[1], tau));
        let k = a.cycles[0].knock.unwrap();
        // Measured 7e-15.
        assert!(
            (k.mapo_pa / want("mapo_pa") - 1.0).abs() < 1e-9,
            "τ {tau}: {k:?}"
        );
        assert!(
            (k.impo_pa_deg / want("impo_pa_deg") - 1.0).abs() < 1e-9,
            "τ {tau}: {k:?}"
        );
        assert!(
            (k.mapo_deg - want("mapo_deg")).abs() < 1e-9,
            "τ {tau}: {k:?}"
        );
    }
}
