//! The live combustion stage is the file verb: `golden/gen_wiebe.py`'s recordings (a known
//! Wiebe burn, solved by scipy) turned into a time-basis stream — `t`, `theta_en` (the
//! continuous crank angle), `p_cyl` — and fed in chunks of every size: each cycle's figures
//! equal `physid cycles`' on the crank-angle file (same number, same values), the burn angles
//! the Wiebe's, misfire and partial burn flagged alike, and a checkpoint mid-stream resumes
//! to the same figures.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{wiebe, wiebe_csv, wiebe_geometry};
use physid_apps::combustion::HeatRelease;
use physid_apps::combustion_stage::{CombustionCycle, CombustionOutput, CombustionStage};
use physid_apps::per_cycle::{figure_columns, CycleFigures, PerCycleSettings};
use physid_apps::pressure::{CycleAnalyser, Pegging};
use physid_apps::stage::Stage;
use physid_core::{Basis, Channel, Recording};
use serde_json::Value;

/// The crank-angle file and the same samples as a time-basis stream.
fn file_and_stream(name: &str) -> (Recording, Recording) {
    let file = wiebe_csv(name);
    let (cycle, deg) = (
        file.values("cycle").unwrap(),
        file.values("crank_deg").unwrap(),
    );
    // The firing TDC of block 0 at θ = 0.
    let theta: Vec<f64> = cycle
        .iter()
        .zip(deg)
        .map(|(c, d)| (c * 720.0 + d).to_radians())
        .collect();
    let mut stream = Recording::new(Basis::Time);
    for (name, unit, values) in [
        ("t", "s", file.values("t").unwrap().to_vec()),
        ("theta_en", "rad", theta),
        ("p_cyl", "Pa", file.values("p_cyl").unwrap().to_vec()),
    ] {
        stream
            .push(Channel {
                name: name.into(),
                unit: unit.into(),
                values,
            })
            .unwrap();
    }
    (file, stream)
}

fn settings(truth: &Value) -> PerCycleSettings {
    PerCycleSettings {
        geometry: Some(wiebe_geometry(truth)),
        peg: Pegging::None,
        heat: HeatRelease::default(),
        knock: None,
        in_pa: true,
        brake: None,
        lowpass: None,
        friction: None,
    }
}

/// The cycles of a clean stream's outputs (a dropout there is a failure).
fn cycles(out: Vec<CombustionOutput>) -> Vec<CombustionCycle> {
    out.into_iter()
        .map(|o| match o {
            CombustionOutput::Cycle(c) => c,
            CombustionOutput::Dropout(d) => panic!("a dropout in a clean stream: {d:?}"),
        })
        .collect()
}

/// The stream in chunks of 1, 2, … 997 samples (cycling), a checkpoint through MessagePack
/// after chunk `checkpoint_at`.
fn streamed(stage: CombustionStage, stream: &Recording, checkpoint_at: usize) -> Vec<CycleFigures> {
    let mut stage = stage;
    let mut out = Vec::new();
    let (mut from, mut k) = (0, 0);
    while from < stream.len() {
        let n = (k % 997 + 1).min(stream.len() - from);
        stage.push(&stream.slice(from..from + n), &mut out).unwrap();
        if k == checkpoint_at {
            let bytes = rmp_serde::to_vec_named(&stage).unwrap();
            stage = rmp_serde::from_slice(&bytes).unwrap();
        }
        from += n;
        k += 1;
    }
    stage.finish(&mut out).unwrap();
    cycles(out).into_iter().map(|c| c.figures).collect()
}

fn same(file: &[CycleFigures], live: &[CycleFigures]) {
    assert_eq!(
        file.iter().map(|c| c.cycle).collect::<Vec<_>>(),
        live.iter().map(|c| c.cycle).collect::<Vec<_>>()
    );
    for col in figure_columns("Pa", &[10.0, 50.0, 90.0], false, false, false) {
        for (f, l) in file.iter().zip(live) {
            let (a, b) = ((col.value)(f), (col.value)(l));
            let close = (a.is_nan() && b.is_nan()) || (a - b).abs() <= 1e-6 * (1.0 + a.abs());
            assert!(
                close,
                "cycle {}: {} {a} (file) against {b} (live)",
                f.cycle, col.name
            );
        }
    }
}

#[test]
fn the_stream_s_figures_are_the_file_s_cycle_by_cycle() {
    let truth = wiebe();
    let (file, stream) = file_and_stream("wiebe_flags.csv");
    let mut a =
        CycleAnalyser::new(&file, "p_cyl", Some(&wiebe_geometry(&truth)), Pegging::None).unwrap();
    a.push(&file).unwrap();
    let by_file = a.finish().unwrap().cycles;
    let stage = CombustionStage::new("p_cyl", settings(&truth), 0.0, 1.0).unwrap();
    let live = streamed(stage, &stream, 7);
    assert_eq!(live.len(), 10);
    same(&by_file, &live);
    let misfires: Vec<i64> = live
        .iter()
        .filter(|c| c.burn.as_ref().unwrap().misfire)
        .map(|c| c.cycle)
        .collect();
    assert_eq!(misfires, [7]);
}

#[test]
fn the_stream_s_burn_angles_are_the_wiebe_s() {
    let truth = wiebe();
    let (_, stream) = file_and_stream("wiebe_cycles.csv");
    let step = truth["step_deg"].as_f64().unwrap();
    let stage = CombustionStage::new("p_cyl", settings(&truth), 0.0, step).unwrap();
    let live = streamed(stage, &stream, usize::MAX);
    assert_eq!(live.len(), 1);
    let b = live[0].burn.as_ref().unwrap();
    for k in ["10", "50", "90"] {
        let want = truth["mfb_deg"][k].as_f64().unwrap();
        let got = b.mfb(k.parse().unwrap()).unwrap();
        assert!((got - want).abs() < 0.01, "MFB{k}: {got}° against {want}°");
    }
    assert!((b.heat_release_j / truth["heat_j"].as_f64().unwrap() - 1.0).abs() < 1e-4);
}

#[test]
fn a_stream_without_the_pressure_passes_and_a_bad_one_is_named() {
    let truth = wiebe();
    let (_, stream) = file_and_stream("wiebe_cycles.csv");
    let mut stage = CombustionStage::new("p_other", settings(&truth), 0.0, 1.0).unwrap();
    let mut out = Vec::new();
    stage.push(&stream, &mut out).unwrap();
    assert!(out.is_empty());
    // A step that does not divide 720°.
    let e = CombustionStage::new("p_cyl", settings(&truth), 0.0, 0.7).unwrap_err();
    assert!(e.to_string().contains("divisor of 720"), "{e}");
    // A time that is not finite: named with its sample.
    let mut bad = stream.slice(0..2000);
    let mut t = bad.values("t").unwrap().to_vec();
    t[1500] = f64::NAN;
    bad.replace_values("t", t).unwrap();
    let mut stage = CombustionStage::new("p_cyl", settings(&truth), 0.0, 1.0).unwrap();
    let e = stage.push(&bad, &mut out).unwrap_err().to_string();
    assert!(e.contains("sample 1500") && e.contains("time"), "{e}");
}

/// A pressure that is not a number for a while (a sensor's dropout, at samples 1500–1519: 1°
/// samples, in cycle 2, from 1080° to 1800°) and an angle that is not one (sample 5000, cycle
/// 7): each told once with its channel and sample, the cycles they cut left out, every other
/// cycle's figures `physid cycles`' on the clean file, with their numbers — in chunks of every
/// size with a checkpoint. Before, the first stopped the analysis for the rest of the run.
#[test]
fn a_dropout_leaves_out_the_cycle_it_cuts_and_the_analysis_goes_on() {
    let truth = wiebe();
    let (file, stream) = file_and_stream("wiebe_flags.csv");
    let mut a =
        CycleAnalyser::new(&file, "p_cyl", Some(&wiebe_geometry(&truth)), Pegging::None).unwrap();
    a.push(&file).unwrap();
    let by_file: Vec<CycleFigures> = a
        .finish()
        .unwrap()
        .cycles
        .into_iter()
        .filter(|c| c.cycle != 2 && c.cycle != 7)
        .collect();
    let mut bad = stream.clone();
    let mut p = bad.values("p_cyl").unwrap().to_vec();
    p[1500..1520].fill(f64::NAN);
    bad.replace_values("p_cyl", p).unwrap();
    let mut theta = bad.values("theta_en").unwrap().to_vec();
    theta[5000] = f64::NAN;
    bad.replace_values("theta_en", theta).unwrap();
    let mut stage = CombustionStage::new("p_cyl", settings(&truth), 0.0, 1.0).unwrap();
    let mut out = Vec::new();
    let (mut from, mut k) = (0, 0);
    while from < bad.len() {
        let n = (k % 997 + 1).min(bad.len() - from);
        stage.push(&bad.slice(from..from + n), &mut out).unwrap();
        if k == 3 {
            let bytes = rmp_serde::to_vec_named(&stage).unwrap();
            stage = rmp_serde::from_slice(&bytes).unwrap();
        }
        from += n;
        k += 1;
    }
    let (mut live, mut told) = (Vec::new(), Vec::new());
    for o in out {
        match o {
            CombustionOutput::Cycle(c) => live.push(c.figures),
            CombustionOutput::Dropout(d) => told.push(d),
        }
    }
    let told: Vec<(String, usize)> = told.into_iter().map(|d| (d.channel, d.sample)).collect();
    assert_eq!(
        told,
        [("p_cyl".to_string(), 1500), ("theta_en".to_string(), 5000)]
    );
    assert_eq!(live.len(), 8);
    same(&by_file, &live);
}

/// With curves (the live panel's view): one cycle's every 0.2 s of stream time, its pressure on
/// the coarse grid the stream's own samples (to rounding), its heat release rate over each coarse step
/// adding up — a telescoping sum — to the heat released over the window, `Q(120°) − Q(−90°)`:
/// for a Wiebe burn, whose apparent heat rises all but monotonically, the figures'
/// `heat_release_j = Q_max − Q_min` to 4e-5 (the rounding of the file's pressures before the
/// burn); none outside the window.
#[test]
fn the_curves_heat_release_rate_adds_up_to_the_heat_released() {
    use physid_apps::combustion_stage::CURVE_INTERVAL_S;
    let truth = wiebe();
    let (file, stream) = file_and_stream("wiebe_flags.csv");
    let mut stage = CombustionStage::new("p_cyl", settings(&truth), 0.0, 1.0)
        .unwrap()
        .with_curves(2.0);
    let mut out = Vec::new();
    for from in (0..stream.len()).step_by(500) {
        stage
            .push(
                &stream.slice(from..(from + 500).min(stream.len())),
                &mut out,
            )
            .unwrap();
    }
    let out = cycles(out);
    assert_eq!(out.len(), 10);
    let with: Vec<_> = out.iter().filter(|c| c.curve.is_some()).collect();
    let times: Vec<f64> = with.iter().map(|c| c.figures.t_start_s).collect();
    assert!(times.len() >= 3 && times.windows(2).all(|w| w[1] - w[0] >= CURVE_INTERVAL_S));
    let (deg, cyc, p) = (
        file.values("crank_deg").unwrap(),
        file.values("cycle").unwrap(),
        file.values("p_cyl").unwrap(),
    );
    for c in with {
        let k = c.curve.as_ref().unwrap();
        assert_eq!((k.step_deg, k.p.len(), k.hrr.len()), (2.0, 360, 360));
        // −360° ATDC + 2j: the block before's 360° + 2j, then this block's 2j − 360°.
        for j in [0, 45, 179, 180, 250, 359] {
            let (block, d) = if j < 180 {
                (c.figures.cycle - 1, 360.0 + 2.0 * j as f64)
            } else {
                (c.figures.cycle, 2.0 * j as f64 - 360.0)
            };
            let i = (0..deg.len())
                .find(|&i| cyc[i] == block as f64 && deg[i] == d)
                .unwrap();
            // The stream's grid meets the samples to rounding.
            assert!(
                (k.p[j] / p[i] - 1.0).abs() < 1e-12,
                "cycle {}, point {j}: {} against {}",
                c.figures.cycle,
                k.p[j],
                p[i]
            );
        }
        // The window −90° … 120° ATDC: points 135 … 240.
        assert!(k.hrr[..135].iter().chain(&k.hrr[241..]).all(|h| h.is_nan()));
        let sum: f64 =
            k.hrr[135..=240].iter().map(|h| h * 2.0).sum::<f64>() - (k.hrr[135] + k.hrr[240]) * 1.0;
        let b = c.figures.burn.as_ref().unwrap();
        if b.fired {
            assert!(
                (sum / b.heat_release_j - 1.0).abs() < 1e-4,
                "cycle {}: {sum} J against {} J",
                c.figures.cycle,
                b.heat_release_j
            );
        }
    }
}
