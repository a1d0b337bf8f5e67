//! Heat release and burn angles against a single-zone trace made with numpy and scipy from a
//! known Wiebe burn (`golden/gen_wiebe.py`: constant γ, no wall heat, solved by scipy's
//! `solve_ivp`), read through the crank-angle CSV path as a user's file would be.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{golden, wiebe, wiebe_csv, wiebe_geometry};
use physid_apps::combustion::{BurnMethod, GasTemperature, HeatRelease};
use physid_apps::pressure::{CycleAnalyser, Geometry, Pegging};
use physid_io::ReadOptions;
use serde_json::Value;

#[test]
fn a_wiebe_burn_gives_its_burn_angles_heat_and_work() {
    let truth = wiebe();
    let f = |k: &str| truth[k].as_f64().unwrap();
    let rec = wiebe_csv("wiebe_cycles.csv");
    let geometry = wiebe_geometry(&truth);
    let mut a = CycleAnalyser::new(&rec, "p_cyl", Some(&geometry), Pegging::None)
        .unwrap()
        .with_heat_release(HeatRelease {
            gamma: f("gamma"),
            window: (
                truth["window_deg"][0].as_f64().unwrap(),
                truth["window_deg"][1].as_f64().unwrap(),
            ),
            ..HeatRelease::default()
        })
        .unwrap();
    a.push(&rec).unwrap();
    let a = a.finish().unwrap();
    // Two blocks from firing TDC to firing TDC: one cycle (the first TDC has no compression).
    assert_eq!(a.cycles.len(), 1);
    for c in &a.cycles {
        let b = c.burn.as_ref().expect("heat release");
        assert!(b.fired, "cycle {}", c.cycle);
        for (got, k) in [
            (b.mfb(10.0), "10"),
            (b.mfb(50.0), "50"),
            (b.mfb(90.0), "90"),
        ] {
            let want = truth["mfb_deg"][k].as_f64().unwrap();
            let got = got.expect("MFB");
            // Measured 0.001°; the issue asks 0.2°.
            assert!((got - want).abs() < 0.01, "MFB{k}: {got}° against {want}°");
        }
        let heat = f("heat_j");
        // Measured 3e-7; the issue asks 1 %.
        assert!(
            (b.heat_release_j / heat - 1.0).abs() < 1e-4,
            "heat released {} J against {heat} J",
            b.heat_release_j
        );
        // The work by numpy's trapezoid over the same samples.
        let imep = c.imep_pa.unwrap();
        assert!(
            (imep / f("imep_pa") - 1.0).abs() < 1e-9,
            "IMEP {imep} against {}",
            f("imep_pa")
        );
        // Intake and exhaust at one pressure: no pumping work (PMEP 0 but for rounding).
        let pmep = c.pmep_pa.unwrap();
        assert!(pmep.abs() < 1e-9 * imep, "PMEP {pmep} Pa");
        // Between the 0.25° samples: the peak within 0.02° (measured 0.0002°), the steepest
        // rise within a step (0.035°) and 1 % (0.02 %).
        assert!(
            (c.p_max_deg - f("p_max_deg")).abs() < 0.02,
            "p_max at {}° against {}°",
            c.p_max_deg,
            f("p_max_deg")
        );
        assert!((b.dp_max_deg - f("dp_max_deg")).abs() <= f("step_deg"));
        assert!((b.dp_max_pa_per_deg / f("dp_max_pa_per_deg") - 1.0).abs() < 0.01);
    }
}

/// Rassweiler & Withrow's burn angles on the same trace: equal to numpy's computation of the
/// method on the file's pressures (`gen_wiebe.py`, `rw_mfb_deg`, n = γ) to rounding, and — the
/// method being the constant-γ heat release to first order in the step — within 0.2° of the
/// Wiebe's own (measured 0.025°); with each cycle's compression exponent (this trace's is γ)
/// alike. The heat released stays the heat-release method's.
#[test]
fn rassweiler_withrow_gives_numpy_s_burn_angles() {
    let truth = wiebe();
    let rec = wiebe_csv("wiebe_cycles.csv");
    let geometry = wiebe_geometry(&truth);
    let window = (
        truth["window_deg"][0].as_f64().unwrap(),
        truth["window_deg"][1].as_f64().unwrap(),
    );
    let n = truth["rw_exponent"].as_f64().unwrap();
    for exponent in [Some(n), None] {
        let mut a = CycleAnalyser::new(&rec, "p_cyl", Some(&geometry), Pegging::None)
            .unwrap()
            .with_heat_release(HeatRelease {
                gamma: truth["gamma"].as_f64().unwrap(),
                window,
                method: BurnMethod::RassweilerWithrow { exponent },
                ..HeatRelease::default()
            })
            .unwrap();
        a.push(&rec).unwrap();
        let a = a.finish().unwrap();
        let b = a.cycles[0].burn.as_ref().unwrap();
        assert!(
            (b.heat_release_j / truth["heat_j"].as_f64().unwrap() - 1.0).abs() < 1e-4,
            "{}",
            b.heat_release_j
        );
        for k in ["10", "50", "90"] {
            let got = b.mfb(k.parse().unwrap()).unwrap();
            let numpy = truth["rw_mfb_deg"][k].as_f64().unwrap();
            let wiebe = truth["mfb_deg"][k].as_f64().unwrap();
            let tol = if exponent.is_some() { 1e-9 } else { 0.02 };
            assert!(
                (got - numpy).abs() < tol,
                "MFB{k} ({exponent:?}): {got}° against numpy's {numpy}°"
            );
            assert!((got - wiebe).abs() < 0.2, "MFB{k}: {got}° against {wiebe}°");
        }
    }
    // Bad settings are refused, naming the flag.
    for (name, n, want) in [
        ("rw", Some(0.9), "--rw-exponent 0.9"),
        ("heat", Some(1.3), "with --mfb-method rw"),
        ("wiebe", None, "--mfb-method wiebe"),
    ] {
        let e = BurnMethod::parse(name, n).and_then(|method| {
            HeatRelease {
                method,
                ..HeatRelease::default()
            }
            .validate()
        });
        assert!(e.unwrap_err().to_string().contains(want), "{name} {n:?}");
    }
}

/// A motored recording (`golden/gen_motored.py`: polytropic compression and expansion with a
/// heat loss, no burn) releases no heat: every cycle motored, no burn angles.
#[test]
fn a_motored_cycle_is_told_from_a_fired_one() {
    let rec = physid_io::read(golden("motored_deg.parquet"), &ReadOptions::default()).unwrap();
    let truth: Value =
        serde_json::from_str(&std::fs::read_to_string(golden("motored.json")).unwrap()).unwrap();
    let g = |k: &str| truth["geometry"][k].as_f64().unwrap();
    let geometry = Geometry {
        bore: 0.084,
        stroke: g("stroke"),
        rod: g("rod"),
        compression_ratio: truth["deg"]["eps"].as_f64().unwrap(),
    };
    let mut a = CycleAnalyser::new(&rec, "p_cyl", Some(&geometry), Pegging::None).unwrap();
    a.push(&rec).unwrap();
    let a = a.finish().unwrap();
    assert_eq!(a.cycles.len(), 11);
    for c in &a.cycles {
        let b = c.burn.as_ref().expect("heat release");
        assert!(!b.fired, "cycle {}: {} J", c.cycle, b.heat_release_j);
        assert_eq!((b.mfb(10.0), b.mfb(50.0), b.mfb(90.0)), (None, None, None));
        assert!(!b.misfire && !b.partial_burn, "cycle {}", c.cycle);
    }
}

/// Fired and motored cycles in one recording (`golden/gen_wiebe.py`'s `wiebe_mixed.csv`: five
/// fired, then three motored — p·V^γ constant, peaking at TDC): the TDC is placed on the motored
/// ones only. The peaks' median, which five fired cycles at +14.7° would take, is the motored
/// cycles' TDC; the motored fit leaves the fired windows out (four: the first TDC has no
/// compression before it), says so, and finds the engine (ε, and n = γ).
#[test]
fn the_tdc_is_placed_on_the_motored_cycles_only() {
    use physid_apps::compression::{compression_fit, CompressionConfig, PeakAngles};
    let truth = wiebe();
    let f = |k: &str| truth[k].as_f64().unwrap();
    let rec = wiebe_csv("wiebe_mixed.csv");
    let mut peaks = PeakAngles::new("p_cyl", 1.0);
    peaks.push(&rec).unwrap();
    assert_eq!(peaks.fired(), 5);
    let peak = peaks.finish().unwrap();
    let from_tdc = (peak + 180.0).rem_euclid(360.0) - 180.0;
    assert!(
        from_tdc.abs() < 0.5,
        "the motored cycles peak at TDC: {peak}°"
    );
    let fit = compression_fit(
        &rec,
        &CompressionConfig::new("p_cyl", f("stroke"), f("rod")),
    )
    .unwrap();
    assert!(
        fit.notes
            .iter()
            .any(|n| n.starts_with("4 fired TDC window(s) left out")),
        "{:?}",
        fit.notes
    );
    assert!(fit.implausible.is_empty(), "{:?}", fit.implausible);
    let eps = fit.get("eps").unwrap().value;
    assert!(
        (eps / f("compression_ratio") - 1.0).abs() < 0.01,
        "eps {eps}"
    );
    let n = fit.get("n").unwrap().value;
    assert!((n - f("gamma")).abs() < 0.01, "n {n}");
    // Every cycle fired: refused, saying why.
    let fired_only = rec.slice(0..5 * 720);
    let mut peaks = PeakAngles::new("p_cyl", 1.0);
    peaks.push(&fired_only).unwrap();
    let e = peaks.finish().unwrap_err().to_string();
    assert!(e.contains("all 5 complete cycles fired"), "{e}");
}

/// Cycle by cycle on the same fired-then-motored recording: a cycle is its TDC's compression
/// and expansion (−360° … 360° ATDC), so the fired cycles are 1 … 4 (cycle 0 has no compression
/// before its TDC) and 5 … 7 are motored; the burn angles of the fired ones are the Wiebe's at
/// 1° steps too, and the CoV and LNV of IMEP are over the fired cycles only, saying so.
#[test]
fn cycle_by_cycle_the_fired_are_told_from_the_motored() {
    let truth = wiebe();
    let rec = wiebe_csv("wiebe_mixed.csv");
    let geometry = wiebe_geometry(&truth);
    let mut a = CycleAnalyser::new(&rec, "p_cyl", Some(&geometry), Pegging::None).unwrap();
    a.push(&rec).unwrap();
    let a = a.finish().unwrap();
    let fired: Vec<(i64, bool)> = a
        .cycles
        .iter()
        .map(|c| (c.cycle, c.burn.as_ref().unwrap().fired))
        .collect();
    assert_eq!(
        fired,
        (1..8).map(|c| (c, c < 5)).collect::<Vec<_>>(),
        "{fired:?}"
    );
    for c in a.cycles.iter().filter(|c| c.cycle < 5) {
        let b = c.burn.as_ref().unwrap();
        let want = truth["mfb_deg"]["50"].as_f64().unwrap();
        let got = b.mfb(50.0).unwrap();
        assert!((got - want).abs() < 0.05, "cycle {}: MFB50 {got}°", c.cycle);
    }
    // Four identical fired cycles: no spread, the lowest at the mean.
    assert!(a.cov_imep.unwrap() < 1e-12 && (a.lnv_imep.unwrap() - 1.0).abs() < 1e-12);
    assert!(
        a.notes
            .iter()
            .any(|n| n == "CoV and LNV of IMEP over the 4 fired cycle(s); 3 motored left out"),
        "{:?}",
        a.notes
    );
}

/// Misfire and partial burn (`golden/gen_wiebe.py`'s `wiebe_flags.csv`: each firing TDC burns
/// `flags_heat_j`, full burns with one of 250 J and one of nothing among them): the 250 J cycle
/// is a partial burn, the one with nothing a misfire, no other flagged; `--mfb` gives the angles
/// asked for, the 50 % one equal to the default's.
#[test]
fn misfires_and_partial_burns_are_flagged() {
    let truth = wiebe();
    let rec = wiebe_csv("wiebe_flags.csv");
    let heat: Vec<f64> = truth["flags_heat_j"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let mut a = CycleAnalyser::new(&rec, "p_cyl", Some(&wiebe_geometry(&truth)), Pegging::None)
        .unwrap()
        .with_heat_release(HeatRelease {
            mfb: vec![5.0, 50.0, 95.0],
            ..HeatRelease::default()
        })
        .unwrap();
    a.push(&rec).unwrap();
    let a = a.finish().unwrap();
    assert_eq!(a.cycles.len(), heat.len() - 1);
    let full = heat[1];
    for c in &a.cycles {
        let b = c.burn.as_ref().unwrap();
        let q = heat[c.cycle as usize];
        assert_eq!(b.misfire, q == 0.0, "cycle {} ({q} J)", c.cycle);
        assert_eq!(
            b.partial_burn,
            q > 0.0 && q < 0.5 * full,
            "cycle {} ({q} J)",
            c.cycle
        );
        assert_eq!(b.fired, q > 0.0, "cycle {}", c.cycle);
        if q == full {
            let want = truth["mfb_deg"]["50"].as_f64().unwrap();
            let got = b.mfb(50.0).unwrap();
            assert!((got - want).abs() < 0.05, "cycle {}: MFB50 {got}°", c.cycle);
            assert!(b.mfb(5.0).unwrap() < b.mfb(50.0).unwrap());
            assert!(b.mfb(95.0).unwrap() > b.mfb(50.0).unwrap());
            assert_eq!(b.mfb(10.0), None);
        }
    }
    let names: Vec<String> = a.columns().into_iter().map(|c| c.0).collect();
    for n in [
        "mfb5_deg",
        "mfb50_deg",
        "mfb95_deg",
        "misfire",
        "partial_burn",
        "pmep",
    ] {
        assert!(names.iter().any(|m| m == n), "{n} in {names:?}");
    }
    // The ensemble mean: IMEP is linear in the pressure, so the mean cycle's is the cycles'
    // mean IMEP; its curves kept with the last cycle's.
    let mean = a.mean_cycle.as_ref().unwrap();
    assert_eq!(mean.cycle as usize, a.cycles.len());
    let imeps: Vec<f64> = a.cycles.iter().map(|c| c.imep_pa.unwrap()).collect();
    let mean_imep = imeps.iter().sum::<f64>() / imeps.len() as f64;
    assert!((mean.imep_pa.unwrap() / mean_imep - 1.0).abs() < 1e-12);
    let curves = a.curves.as_ref().unwrap();
    assert_eq!(
        curves.chosen.as_ref().unwrap().cycle,
        a.cycles.last().unwrap().cycle
    );
    assert_eq!(curves.mean.as_ref().unwrap().p.len(), curves.atdc.len());
    assert_eq!(
        curves.mean.as_ref().unwrap().heat.len(),
        curves.heat_deg.len()
    );
    let partial = a.cycles.iter().find(|c| c.cycle == 6).unwrap();
    let json = serde_json::to_value(partial).unwrap();
    assert_eq!(json["partial_burn"], true, "{json}");
    assert!(json.get("mfb95_deg").is_some(), "{json}");
}

/// The virtual cell fired (`fired-steady`: a Wiebe burn of 250 J from −15° over 50°, a = 6.9,
/// m = 2, at 1500 rpm), its crank-angle recording at 0.25°: adiabatic (`engine.heat_transfer`
/// 0), the heat release with γ(T) at the mean gas temperature — which for the cell's ideal gas
/// is its energy equation — recovers the Wiebe's closed-form burn angles within 0.1° (measured
/// 0.015° at MFB50, 0.07° at MFB90) and its heat within 0.5 % (measured 0.16 %), and the peak
/// gas temperature the cell's own within 1 % (0.3 %: the pressure sensor's noise and quantum);
/// with constant γ = 1.35 MFB90 falls 5° late (the method's known limit, said in the docs). With
/// wall heat (the cell's Woschni) the cycles still fire, MFB50 within 1°, the net heat below
/// the fuel's.
#[test]
fn the_fired_virtual_cell_gives_the_wiebe_s_burn() {
    use physid_sim::run::OutputBasis;
    let (q, start, duration, a, m) = (250.0, -15.0, 50.0, 6.9, 2.0);
    let wiebe = |x: f64| start + duration * (-(1.0 - x).ln() / a).powf(1.0 / (m + 1.0));
    let geometry = Geometry {
        bore: 0.054,
        stroke: 2.0 * 0.0257,
        rod: 0.088,
        compression_ratio: 9.5,
    };
    let rec = common::simulate_scenario(
        "fired-steady",
        &[("engine.heat_transfer", 0.0), ("solver.step_deg", 0.25)],
        &[],
        0.5,
        OutputBasis::Crank(0.25),
    );
    // The cell's IVC is 616° after firing TDC: −104° ATDC; its gas temperature there.
    let (deg, cyc, t_true) = (
        rec.values("crank_deg").unwrap(),
        rec.values("cycle").unwrap(),
        rec.values("true_T_cyl").unwrap(),
    );
    let at_ivc = (0..deg.len())
        .find(|&i| cyc[i] == 1.0 && (deg[i] - 616.0).abs() < 1e-6)
        .unwrap();
    let analysed = |temperature: Option<GasTemperature>| {
        let mut an = CycleAnalyser::new(&rec, "p_cyl", Some(&geometry), Pegging::None)
            .unwrap()
            .with_heat_release(HeatRelease {
                temperature,
                ..HeatRelease::default()
            })
            .unwrap();
        an.push(&rec).unwrap();
        an.finish().unwrap()
    };
    let hot = analysed(Some(GasTemperature {
        ivc_deg: -104.0,
        t_ivc_k: t_true[at_ivc],
    }));
    assert!(hot.cycles.len() >= 4);
    let c = hot.cycles.iter().find(|c| c.cycle == 2).unwrap();
    let b = c.burn.as_ref().unwrap();
    assert!(b.fired);
    for k in [10.0, 50.0, 90.0] {
        let (got, want) = (b.mfb(k).unwrap(), wiebe(k / 100.0));
        assert!((got - want).abs() < 0.1, "MFB{k}: {got}° against {want}°");
    }
    // The heat burned by the window's end (120° ATDC).
    let burned = q * (1.0 - (-a * ((120.0 - start) / duration).powf(m + 1.0)).exp());
    assert!(
        (b.heat_release_j / burned - 1.0).abs() < 5e-3,
        "{} J against {burned} J",
        b.heat_release_j
    );
    // The cell's own peak temperature in the cycle's window.
    let t_peak = (0..deg.len())
        .filter(|&i| cyc[i] == 2.0 && deg[i] <= 120.0)
        .map(|i| t_true[i])
        .fold(f64::NEG_INFINITY, f64::max);
    let t_max = b.t_max_k.unwrap();
    assert!(
        (t_max / t_peak - 1.0).abs() < 0.01,
        "{t_max} K against {t_peak} K"
    );
    // Constant γ: the late burn angles drift (γ falls as the gas heats).
    let cold = analysed(None);
    let late = cold.cycles.iter().find(|c| c.cycle == 2).unwrap();
    let drift = late.burn.as_ref().unwrap().mfb(90.0).unwrap() - wiebe(0.9);
    assert!(drift > 2.0, "constant γ: MFB90 {drift}° late");
    // With the cell's wall heat (its Woschni, walls at 293 K): the net heat release falls
    // short of the fuel's; the gross, the analysis's Woschni at the mean gas temperature added,
    // finds it again — within 2 % (measured 0.07 %: 237.2 J net, 250.2 J gross) and the burn
    // angles within 0.2° (MFB50 measured 0.012° off, 0.29° net).
    let warm = common::simulate_scenario(
        "fired-steady",
        &[("solver.step_deg", 0.25)],
        &[],
        0.5,
        OutputBasis::Crank(0.25),
    );
    let t_warm = warm.values("true_T_cyl").unwrap();
    let (deg_w, cyc_w) = (
        warm.values("crank_deg").unwrap(),
        warm.values("cycle").unwrap(),
    );
    let ivc = (0..deg_w.len())
        .find(|&i| cyc_w[i] == 1.0 && (deg_w[i] - 616.0).abs() < 1e-6)
        .unwrap();
    let analyse_warm = |wall: Option<physid_apps::combustion::WallHeat>| {
        let mut an = CycleAnalyser::new(&warm, "p_cyl", Some(&geometry), Pegging::None)
            .unwrap()
            .with_heat_release(HeatRelease {
                temperature: Some(GasTemperature {
                    ivc_deg: -104.0,
                    t_ivc_k: t_warm[ivc],
                }),
                wall,
                ..HeatRelease::default()
            })
            .unwrap();
        an.push(&warm).unwrap();
        let a = an.finish().unwrap();
        a.cycles
            .into_iter()
            .find(|c| c.cycle == 2)
            .unwrap()
            .burn
            .unwrap()
    };
    let net = analyse_warm(None);
    // The cell's Woschni is the motored form (C2 = 0).
    let gross = analyse_warm(Some(physid_apps::combustion::WallHeat {
        t_wall_k: 293.0,
        c1: physid_apps::combustion::WOSCHNI_C1,
        c2: 0.0,
    }));
    eprintln!(
        "fired cell with wall heat: net {:.2} J, gross {:.2} J of {burned:.2} J; MFB50 {:.3}° / {:.3}° against {:.3}°",
        net.heat_release_j,
        gross.heat_release_j,
        net.mfb(50.0).unwrap(),
        gross.mfb(50.0).unwrap(),
        wiebe(0.5)
    );
    assert!(net.heat_release_j < 0.95 * burned);
    assert!((gross.heat_release_j / burned - 1.0).abs() < 0.02);
    for k in [10.0, 50.0, 90.0] {
        let (got, want) = (gross.mfb(k).unwrap(), wiebe(k / 100.0));
        assert!(
            (got - want).abs() < 0.2,
            "gross MFB{k}: {got}° against {want}°"
        );
    }
    // With the cell's wall heat.
    let rec = common::simulate_scenario("fired-steady", &[], &[], 0.5, OutputBasis::Crank(1.0));
    let mut an = CycleAnalyser::new(&rec, "p_cyl", Some(&geometry), Pegging::None).unwrap();
    an.push(&rec).unwrap();
    for c in an.finish().unwrap().cycles {
        let b = c.burn.unwrap();
        assert!(b.fired && !b.misfire, "cycle {}", c.cycle);
        assert!(
            (b.mfb(50.0).unwrap() - wiebe(0.5)).abs() < 1.0,
            "cycle {}",
            c.cycle
        );
        assert!(
            b.heat_release_j < q && b.heat_release_j > 0.7 * q,
            "cycle {}",
            c.cycle
        );
    }
}

/// BMEP and FMEP on the fired virtual cell at steady speed, against the cell's own friction:
/// over a cycle that starts and ends at one speed the engine's equation of motion,
/// `J·α = T_ind + T_rec − T_fric − T_shaft`, integrates to `W_ind = ∮T_shaft dθ + ∮T_fric dθ`
/// (the reciprocating masses' and the inertia's work return to zero), so `FMEP = IMEP − BMEP`
/// is the friction's `4π·T̄_fric/V_d` — a conservation law physid's analysis does not use. The
/// brake torque is positive when the engine delivers: the cell's shaft torque counts the
/// dynamometer driving positive, so it is negated (`--scale torque_shaft=-1,0`); its engine
/// torque (`T_ind − T_rec − T_fric`, through its sensor) is as it is. Measured: FMEP within
/// 0.08 % (shaft) and 0.13 % (engine torque) of the friction's.
///
/// Beside it the friction model's FMEP (`--friction-model cell`, at the run's mean manifold
/// pressure and the cell's oil temperature): the cell's friction is that model at its
/// instantaneous speed and manifold pressure, so the model at the cycle's mean speed is the
/// cell's friction within the ripple's second-order effect (measured 0.04 %); the model equals
/// `physid friction`'s at the same point to rounding; a speed outside its domain is said.
#[test]
fn fmep_is_the_cells_friction() {
    use physid_apps::fmep_model::FrictionModel;
    use physid_apps::pressure::Brake;
    use physid_core::Channel;
    use physid_sim::run::OutputBasis;
    let geometry = Geometry {
        bore: 0.054,
        stroke: 2.0 * 0.0257,
        rod: 0.088,
        compression_ratio: 9.5,
    };
    let mut rec = common::simulate_scenario(
        "fired-steady",
        &[("solver.step_deg", 0.25)],
        &[],
        1.0,
        OutputBasis::Crank(0.25),
    );
    let brake: Vec<f64> = rec
        .values("torque_shaft")
        .unwrap()
        .iter()
        .map(|t| -t)
        .collect();
    rec.push(Channel {
        name: "brake".into(),
        unit: "N*m".into(),
        values: brake,
    })
    .unwrap();
    let vd = std::f64::consts::PI / 4.0 * geometry.bore.powi(2) * geometry.stroke;
    let (deg, cyc, fric) = (
        rec.values("crank_deg").unwrap(),
        rec.values("cycle").unwrap(),
        rec.values("true_torque_friction").unwrap(),
    );
    let p_int = rec.values("p_int").unwrap();
    let p_int_kpa = p_int.iter().sum::<f64>() / p_int.len() as f64 / 1e3;
    let model = FrictionModel::new("cell", &[], p_int_kpa, 101.325, 90.0).unwrap();
    for (channel, tol) in [("brake", 2e-3), ("torque_engine", 2e-3)] {
        let mut an = CycleAnalyser::new(&rec, "p_cyl", Some(&geometry), Pegging::None)
            .unwrap()
            .with_brake(
                &rec,
                Brake {
                    channel: channel.into(),
                    cylinders: 1,
                },
            )
            .unwrap()
            .with_friction_model(model.clone())
            .unwrap();
        an.push(&rec).unwrap();
        let a = an.finish().unwrap();
        assert!(a.brake && a.cycles.len() >= 8, "{}", a.cycles.len());
        for c in &a.cycles {
            // The cell's friction over the same samples: −360° … 360° ATDC of cycle c.
            let (sum, n) = (0..deg.len())
                .filter(|&i| {
                    (cyc[i] == (c.cycle - 1) as f64 && deg[i] >= 360.0 - 1e-9)
                        || (cyc[i] == c.cycle as f64 && deg[i] < 360.0 - 1e-9)
                })
                .fold((0.0, 0), |(s, n), i| (s + fric[i], n + 1));
            assert_eq!(n, 2880);
            let want = 4.0 * std::f64::consts::PI * (sum / n as f64) / vd;
            let (imep, bmep, fmep) = (c.imep_pa.unwrap(), c.bmep_pa.unwrap(), c.fmep_pa.unwrap());
            assert!((imep - bmep - fmep).abs() < 1e-9 * imep);
            let t = c.torque_nm.unwrap();
            assert!((bmep - 4.0 * std::f64::consts::PI * t / vd).abs() < 1e-9 * bmep);
            assert!(
                (fmep / want - 1.0).abs() < tol,
                "{channel}, cycle {}: FMEP {fmep} Pa against the cell's friction {want} Pa",
                c.cycle
            );
            let modelled = c.fmep_model_pa.unwrap();
            let (d, st) = physid_apps::cell::cell_friction_model();
            let op = physid_models::friction::OperatingPoint {
                n_rpm: c.rpm,
                p_int_kpa,
                p_atm_kpa: 101.325,
                t_oil_c: 90.0,
            };
            let direct = physid_models::friction::fmep(&d, &st, &op).mechanical() * 1e3;
            assert!((modelled / direct - 1.0).abs() < 1e-12);
            assert!(
                (modelled / want - 1.0).abs() < 5e-3,
                "cycle {}: the model's FMEP {modelled} Pa against the cell's friction {want} Pa",
                c.cycle
            );
        }
        assert!(a.friction);
    }
    // Outside the model's domain: refused at once, or said per cycle.
    let e = FrictionModel::new("cell", &[], 101.0, 101.0, 400.0).unwrap_err();
    assert!(e.contains("oil temperature"), "{e}");
    let e = FrictionModel::new("nope", &[], 101.0, 101.0, 90.0).unwrap_err();
    assert!(e.contains("thesis, sandoval2002, cell"), "{e}");
    assert!(model
        .fmep_pa(-5.0)
        .unwrap_err()
        .starts_with("fmep_model left out: engine speed"));
    // A channel of another quantity is refused, naming it.
    let e = CycleAnalyser::new(&rec, "p_cyl", Some(&geometry), Pegging::None)
        .unwrap()
        .with_brake(
            &rec,
            Brake {
                channel: "omega_en".into(),
                cylinders: 1,
            },
        )
        .unwrap_err();
    assert!(e.to_string().contains("--brake-torque omega_en"), "{e}");
}

/// The pressure's zero-phase low-pass (`--pressure-lowpass`) against scipy's on the same noisy
/// cycle (`golden/gen_wiebe_noisy.py`: the Wiebe trace with 0.3 bar of white noise, scipy's
/// `butter` + `sosfiltfilt` at the cycle's own sample rate): the filtered cycle's IMEP and peak
/// are scipy's to rounding; its burn angles are back near the Wiebe's while the raw noisy
/// trace's are not (measured: MFB10/50/90 1.2/0.14/1.95° from the Wiebe's filtered, 85/0.5/12°
/// raw; the steepest rise 16 % above the true one filtered, 170 % raw).
#[test]
fn the_pressure_lowpass_is_scipys() {
    use physid_apps::pressure::PressureLowpass;
    let truth = wiebe();
    let noisy: Value =
        serde_json::from_str(&std::fs::read_to_string(golden("wiebe_noisy.json")).unwrap())
            .unwrap();
    let rec = wiebe_csv("wiebe_noisy.csv");
    let geometry = wiebe_geometry(&truth);
    let analysed = |lowpass: Option<PressureLowpass>| {
        let mut a = CycleAnalyser::new(&rec, "p_cyl", Some(&geometry), Pegging::None)
            .unwrap()
            .with_heat_release(HeatRelease {
                gamma: truth["gamma"].as_f64().unwrap(),
                ..HeatRelease::default()
            })
            .unwrap();
        if let Some(lp) = lowpass {
            a = a.with_lowpass(lp).unwrap();
        }
        a.push(&rec).unwrap();
        a.finish().unwrap().cycles.remove(0)
    };
    let lp = PressureLowpass {
        cutoff_hz: noisy["cutoff_hz"].as_f64().unwrap(),
        order: noisy["order"].as_u64().unwrap() as usize,
    };
    let (raw, filtered) = (analysed(None), analysed(Some(lp)));
    let rel = |a: f64, b: f64| (a / b - 1.0).abs();
    let (imep, p_max) = (
        noisy["imep_pa"].as_f64().unwrap(),
        noisy["p_max_pa"].as_f64().unwrap(),
    );
    assert!(rel(filtered.imep_pa.unwrap(), imep) < 1e-9, "{filtered:?}");
    assert!(rel(filtered.p_max, p_max) < 1e-12, "{}", filtered.p_max);
    let (fb, rb) = (filtered.burn.unwrap(), raw.burn.unwrap());
    for k in ["10", "50", "90"] {
        let want = truth["mfb_deg"][k].as_f64().unwrap();
        let f = fb.mfb(k.parse().unwrap()).unwrap();
        assert!(
            (f - want).abs() < 2.5,
            "MFB{k} filtered: {f}° against {want}°"
        );
    }
    let raw10 = rb.mfb(10.0).unwrap();
    assert!((raw10 - truth["mfb_deg"]["10"].as_f64().unwrap()).abs() > 20.0);
    let dp = truth["dp_max_pa_per_deg"].as_f64().unwrap();
    assert!(rel(fb.dp_max_pa_per_deg, dp) < 0.25 && rel(rb.dp_max_pa_per_deg, dp) > 1.0);
    // A cut-off the grid cannot carry: left out, said, the figures the raw pressure's.
    let too_high = PressureLowpass {
        cutoff_hz: 30e3,
        order: 4,
    };
    let c = analysed(Some(too_high));
    assert!(
        c.notes.iter().any(|n| n.contains("Nyquist")),
        "{:?}",
        c.notes
    );
    assert_eq!(c.imep_pa, raw.imep_pa);
    assert!(PressureLowpass {
        cutoff_hz: -1.0,
        order: 4
    }
    .validate()
    .is_err());
}

/// Woschni's wall heat with its combustion term against numpy's (`golden/gen_woschni.py`, on
/// the Wiebe trace at T_IVC = 330 K, walls at 420 K): the gross heat release less the net is,
/// sample by sample, the sum of numpy's per-step wall heat — the motored form's (C2 = 0) up to
/// the start of combustion (the net heat release's smallest before its largest) and the full
/// form's after it; with C2 = 0, the motored form's throughout. The cycle's compression exponent,
/// which the motored pressure takes, is numpy's least squares'. Measured: 57.0 J over the
/// window by the motored form, 108.4 J with C2 from −11.25° ATDC (the Wiebe's start −12°).
#[test]
fn woschni_s_combustion_term_is_numpy_s() {
    use physid_apps::combustion::{apparent_heat, Cylinder, WallHeat, WOSCHNI_C1, WOSCHNI_C2};
    let truth = wiebe();
    let g: Value =
        serde_json::from_str(&std::fs::read_to_string(golden("woschni.json")).unwrap()).unwrap();
    let f = |k: &str| g[k].as_f64().unwrap();
    let floats = |k: &str| -> Vec<f64> {
        g[k].as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let (wall_c1, wall_full) = (floats("wall_c1"), floats("wall_full"));
    let geometry = wiebe_geometry(&truth);
    let gas = GasTemperature {
        ivc_deg: truth["ivc_deg"].as_f64().unwrap(),
        t_ivc_k: f("t_ivc_k"),
    };
    // The cycle's compression exponent, as physid finds it, is numpy's.
    let rec = wiebe_csv("wiebe_cycles.csv");
    let mut an = CycleAnalyser::new(&rec, "p_cyl", Some(&geometry), Pegging::None).unwrap();
    an.push(&rec).unwrap();
    let n = an.finish().unwrap().cycles[0].n_compression.unwrap();
    assert!((n - f("n_compression")).abs() < 1e-9, "{n}");
    // One cycle, −360° … 360° ATDC, from the trace's first (every cycle is the same).
    let (deg, cyc, p_cyl) = (
        rec.values("crank_deg").unwrap(),
        rec.values("cycle").unwrap(),
        rec.values("p_cyl").unwrap(),
    );
    let step = truth["step_deg"].as_f64().unwrap();
    let atdc: Vec<f64> = (0..2880).map(|k| -360.0 + k as f64 * step).collect();
    let p: Vec<f64> = atdc
        .iter()
        .map(|&a| {
            let d = if a < 0.0 { a + 720.0 } else { a };
            let i = (0..deg.len())
                .find(|&i| cyc[i] == 0.0 && (deg[i] - d).abs() < 1e-9)
                .unwrap();
            p_cyl[i]
        })
        .collect();
    let crank = geometry.crank();
    let v: Vec<f64> = atdc.iter().map(|a| crank.volume(a.to_radians())).collect();
    let cyl = Cylinder {
        bore: geometry.bore,
        stroke: geometry.stroke,
        rpm: truth["rpm"].as_f64().unwrap(),
        n_compression: Some(n),
    };
    let heat = |c2: Option<f64>| {
        let hr = HeatRelease {
            temperature: Some(gas),
            wall: c2.map(|c2| WallHeat {
                t_wall_k: f("t_wall_k"),
                c1: WOSCHNI_C1,
                c2,
            }),
            ..HeatRelease::default()
        };
        apparent_heat(&hr, &atdc, &p, &v, &cyl).unwrap().q
    };
    let (net, motored, full) = (heat(None), heat(Some(0.0)), heat(Some(WOSCHNI_C2)));
    assert_eq!(net.len(), wall_c1.len());
    assert_eq!(WOSCHNI_C2, f("c2"));
    // The start of combustion: the net's smallest before its largest.
    let top = (0..net.len()).fold(0, |m, k| if net[k] >= net[m] { k } else { m });
    let start = (0..=top).fold(0, |m, k| if net[k] < net[m] { k } else { m });
    assert!(start > 0 && start < top);
    let (mut sum_motored, mut sum_full) = (0.0, 0.0);
    let total: f64 = wall_full.iter().sum();
    for k in 0..net.len() {
        sum_motored += wall_c1[k];
        sum_full += if k > start { wall_full[k] } else { wall_c1[k] };
        for (label, gross, want) in [
            ("C2 = 0", motored[k], sum_motored),
            ("C2", full[k], sum_full),
        ] {
            assert!(
                ((gross - net[k]) - want).abs() < 1e-9 * total,
                "{label}, sample {k}: {} J against numpy's {want} J",
                gross - net[k]
            );
        }
    }
    // Combustion stirs the gas: more heat to the walls than the motored form says.
    assert!(
        sum_full > 1.3 * sum_motored,
        "{sum_full} J, {sum_motored} J"
    );
    eprintln!(
        "wall heat over the window: {sum_motored:.3} J motored form, {sum_full:.3} J with C2 from sample {start} ({:.2}° ATDC)",
        truth["window_deg"][0].as_f64().unwrap() + start as f64 * step
    );
}
