//! `physid bench`'s combustion analysis against the real-time need of a four-cylinder engine at
//! 6000 rpm (4 × 50 = 200 cycles per second) at 0.1°: `combustion_figures`, one cycle's
//! figures from its pressure on the crank-angle grid ([`PerCycle`]: pegging, IMEP, PMEP,
//! exponents, heat release, burn angles, misfire flags — what `cycles` does per cycle of a
//! crank-angle file); `combustion` and `combustion_knock`, the live stage's whole path
//! ([`CombustionStage`]: the pressure taken onto the grid from a time-basis stream sampled at
//! 0.1° (360 kHz), then the figures; with knock the band-pass, MAPO and IMPO too).

use crate::out::outln;
use miette::Result;
use physid_apps::combustion::HeatRelease;
use physid_apps::combustion_stage::CombustionStage;
use physid_apps::knock::Knock;
use physid_apps::per_cycle::{CycleTimes, PerCycle, PerCycleSettings};
use physid_apps::pressure::{Geometry, Pegging};
use physid_apps::stage::Stage;
use physid_core::{Basis, Channel, Recording};
use serde_json::{json, Value};
use std::f64::consts::PI;
use std::time::Duration;

/// The engine: 6000 rpm, four cylinders.
const RPM: f64 = 6000.0;
const CYLINDERS: f64 = 4.0;
/// Cycles a stream of one cylinder holds: enough that the stage's set-up (the volume at each
/// grid angle, once per stage) weighs as little as in a long live run — under 3 % of the time.
const CYCLES: usize = 100;

/// A time-basis stream of one cylinder at 6000 rpm, a sample every 0.1° (360 kHz): a
/// polytropic compression and expansion with a burn's pressure rise after TDC and a small
/// 7 kHz ring — the shape of a fired cycle, to exercise every figure.
fn stream(g: &Geometry) -> Result<Recording> {
    let crank = g.crank();
    let step = 0.1_f64;
    let n = (CYCLES as f64 * 720.0 / step) as usize;
    let (mut t, mut theta, mut p) = (
        Vec::with_capacity(n),
        Vec::with_capacity(n),
        Vec::with_capacity(n),
    );
    let v_bdc = crank.volume(PI);
    for k in 0..n {
        let deg = k as f64 * step;
        let atdc = (deg + 360.0).rem_euclid(720.0) - 360.0;
        let v = crank.volume(atdc.to_radians());
        let motored = if atdc.abs() <= 180.0 {
            1e5 * (v_bdc / v).powf(1.32)
        } else {
            1e5
        };
        let burn = 3e6 * (-((atdc - 12.0) / 18.0).powi(2)).exp();
        let dt = (atdc - 10.0).max(0.0) / (6.0 * RPM);
        let ring = 2e4 * (-dt / 1e-3).exp() * (2.0 * PI * 7e3 * dt).sin();
        t.push(deg / (6.0 * RPM));
        theta.push(deg.to_radians());
        p.push(motored + burn + ring);
    }
    let mut rec = Recording::new(Basis::Time);
    for (name, unit, values) in [
        ("t", "s", t),
        ("theta_en", "rad", theta),
        ("p_cyl", "Pa", p),
    ] {
        rec.push(Channel {
            name: name.into(),
            unit: unit.into(),
            values,
        })
        .map_err(|e| miette::miette!("{e}"))?;
    }
    Ok(rec)
}

/// Measure, print (unless `json`) and add to `results`.
pub fn combustion(
    budget: Duration,
    json_out: bool,
    results: &mut Vec<Value>,
    rate: impl Fn(usize, Duration, &mut dyn FnMut() -> Result<()>) -> Result<f64>,
) -> Result<()> {
    let g = Geometry {
        bore: 0.086,
        stroke: 0.086,
        rod: 0.145,
        compression_ratio: 10.5,
    };
    let rec = stream(&g)?;
    let chunk = 3600; // 10 ms
    let need = CYLINDERS * RPM / 120.0;
    // The figures alone, on the stream's cycles cut at −360° … 360° ATDC (all alike).
    {
        let per = 7200usize;
        let (t, p) = (
            rec.values("t").map_err(|e| miette::miette!("{e}"))?,
            rec.values("p_cyl").map_err(|e| miette::miette!("{e}"))?,
        );
        let atdc: Vec<f64> = (0..per).map(|k| -360.0 + k as f64 * 0.1).collect();
        let mut pc = PerCycle::new(PerCycleSettings {
            geometry: Some(g),
            peg: Pegging::None,
            heat: HeatRelease::default(),
            knock: None,
            in_pa: true,
            brake: None,
            lowpass: None,
            friction: None,
        });
        let cycles = CYCLES - 1;
        let cycles_per_s = rate(cycles, budget, &mut || {
            for c in 0..cycles {
                // From 360° (the first firing TDC's compression) on.
                let from = per / 2 + c * per;
                std::hint::black_box(pc.figures(
                    c as i64,
                    CycleTimes::of(&t[from..from + per], &atdc),
                    &atdc,
                    &p[from..from + per],
                    None,
                ));
            }
            Ok(())
        })?;
        let realtime = cycles_per_s / need;
        if !json_out {
            outln!(
                "{:<21} {cycles_per_s:>10.0} cycles/s: {realtime:.0}× real time — one cycle's \
                 figures from its pressure at 0.1° (7200 samples), as `cycles` on a crank-angle \
                 file, against a four-cylinder engine at 6000 rpm ({need:.0} cycles/s)",
                "combustion_figures"
            );
        }
        results.push(
            json!({"name": "combustion_figures", "cycles_per_s": cycles_per_s,
            "realtime_factor": realtime, "step_deg": 0.1, "rpm": RPM, "cylinders": CYLINDERS}),
        );
    }
    for (name, knock) in [
        ("combustion", None),
        ("combustion_knock", Some(Knock::default())),
    ] {
        let settings = PerCycleSettings {
            geometry: Some(g),
            peg: Pegging::None,
            heat: HeatRelease::default(),
            knock,
            in_pa: true,
            brake: None,
            lowpass: None,
            friction: None,
        };
        // The chunks as a live source hands them over (decoding frames is the source's work,
        // not the stage's).
        let chunks: Vec<Recording> = (0..rec.len())
            .step_by(chunk)
            .map(|from| rec.slice(from..(from + chunk).min(rec.len())))
            .collect();
        let one = || -> Result<usize> {
            let mut stage = CombustionStage::new("p_cyl", settings.clone(), 0.0, 0.1)
                .map_err(|e| miette::miette!("{e}"))?;
            let mut out = Vec::with_capacity(CYCLES);
            for c in &chunks {
                stage
                    .push(c, &mut out)
                    .map_err(|e| miette::miette!("{e}"))?;
            }
            Ok(out.len())
        };
        let per_stream = one()?;
        let cycles_per_s = rate(per_stream, budget, &mut || one().map(|_| ()))?;
        let realtime = cycles_per_s / need;
        if !json_out {
            outln!(
                "{name:<21} {cycles_per_s:>10.0} cycles/s: {realtime:.0}× real time — the live \
                 stage's whole per-cycle analysis at 0.1° (7200 samples a cycle){}, against a \
                 four-cylinder engine at 6000 rpm ({need:.0} cycles/s)",
                if knock.is_some() { " with knock" } else { "" }
            );
        }
        results.push(json!({"name": name, "cycles_per_s": cycles_per_s,
            "realtime_factor": realtime, "step_deg": 0.1, "rpm": RPM, "cylinders": CYLINDERS}));
    }
    Ok(())
}
