//! Experiment design (issue 45): the predicted standard errors of a designed shaft test hold
//! when the test is simulated with sensor noise and the real monitor runs on it — the
//! estimator and the noise are the witnesses, not the design's sums.

#![allow(clippy::unwrap_used)]

use physid_apps::design::friction::{design_friction, FrictionDesign};
use physid_apps::design::information::Criterion;
use physid_apps::design::profile::{Limits, ThrottleDraw, MULTISINE_BAND};
use physid_apps::design::shaft::{ShaftDesign, PARAMS};
use physid_apps::design::torque::{design_torque, TorqueDesign};
use physid_apps::design::{Design, Designed};
use physid_apps::friction_fit::friction_fit;
use physid_apps::shaft_monitor::{monitor_shaft, MonitorConfig};
use physid_apps::torque_fit::torque_fit;
use physid_sim::params::CellParams;
use physid_sim::run::{simulate, OutputBasis, RunOptions};
use physid_sim::scenario::{named, Scenario};

fn shaft() -> ShaftDesign {
    ShaftDesign {
        monitor: MonitorConfig::default(),
        cell: CellParams::default(),
        rate_hz: 10_000.0,
    }
}

/// A design for K and B over 800–1600 rpm (the cell's envelope at full throttle: its drive
/// holds ≈ 1650 rpm there), full throttle allowed.
fn design(d: &ShaftDesign, duration: f64, candidates: usize, criterion: Criterion) -> Designed {
    let design = Design {
        names: PARAMS.iter().map(|s| s.to_string()).collect(),
        selected: vec![0, 1],
        criterion,
        target_rel_se: Some(0.02),
        limits: Limits::parse("speed=800:1600,throttle=0:90,dspeed=500").unwrap(),
        throttle: ThrottleDraw::Linear,
        band: MULTISINE_BAND,
        duration,
        candidates,
        seed: 1,
        threads: 0,
    };
    let noise = d.noise_autocovariance().unwrap();
    let baselines = [named("shaft-steady").unwrap()];
    design
        .run(&|s| d.evaluate(&design, s, &noise), &baselines, &|_| {})
        .unwrap()
}

/// The errors `ϑ̂ − ϑ` of K and B of the real monitor over `seeds` noisy runs of `scenario`, at
/// the times `at` (estimator samples): `[seed][point][param]`.
fn errors(d: &ShaftDesign, scenario: &Scenario, at: &[f64], seeds: u64) -> Vec<Vec<[f64; 2]>> {
    let truth = [d.cell.shaft.k, d.cell.shaft.b];
    (0..seeds)
        .map(|seed| {
            let mut params = d.cell.clone();
            params.set("sensors.seed", seed as f64 + 1.0).unwrap();
            let rec = simulate(
                scenario,
                &RunOptions {
                    params,
                    basis: OutputBasis::Time(d.rate_hz),
                    ..RunOptions::default()
                },
                |_| {},
            )
            .unwrap();
            let m = monitor_shaft(&rec, &d.monitor).unwrap();
            at.iter()
                .map(|&t| {
                    let j = m.t.partition_point(|&x| x < t - 1e-9);
                    assert!((m.t[j] - t).abs() < 1e-9, "{} {t}", m.t[j]);
                    [m.k[j] - truth[0], m.b[j] - truth[1]]
                })
                .collect()
        })
        .collect()
}

/// The curve's points from `from` s on: their times and indices.
fn points(curve_t: &[f64], from: f64) -> (Vec<f64>, Vec<usize>) {
    let k: Vec<usize> = (0..curve_t.len()).filter(|&k| curve_t[k] >= from).collect();
    (k.iter().map(|&k| curve_t[k]).collect(), k)
}

/// Standardised errors `(ϑ̂ − ϑ)/σ_predicted` of K and B over `seeds` noisy runs of
/// `scenario`, at the curve's points from `from` s on; and per point the spread over the
/// seeds against the prediction.
fn standardised(
    d: &ShaftDesign,
    scenario: &Scenario,
    curve_t: &[f64],
    curve_se: &[Vec<f64>],
    seeds: u64,
    from: f64,
) -> (Vec<f64>, Vec<f64>) {
    let (at, idx) = points(curve_t, from);
    let e = errors(d, scenario, &at, seeds);
    let mut z = Vec::new();
    let mut ratio = Vec::new();
    for (c, &k) in idx.iter().enumerate() {
        for p in 0..2 {
            let se = curve_se[p][k];
            let vals: Vec<f64> = e.iter().map(|r| r[c][p]).collect();
            z.extend(vals.iter().map(|v| v / se));
            let n = vals.len() as f64;
            ratio.push((vals.iter().map(|v| v * v).sum::<f64>() / n).sqrt() / se);
        }
    }
    (z, ratio)
}

/// The pooled check: the standardised errors' coverage of ±1.96 and their RMS, and the spread
/// over the seeds at each point against the prediction.
fn check(label: &str, z: &[f64], ratio: &mut [f64]) {
    let n = z.len() as f64;
    let cover = z.iter().filter(|v| v.abs() <= 1.959964).count() as f64 / n;
    let rms = (z.iter().map(|v| v * v).sum::<f64>() / n).sqrt();
    ratio.sort_by(f64::total_cmp);
    let median = ratio[ratio.len() / 2];
    eprintln!(
        "{label}: {n} errors, coverage {cover:.3}, RMS of z {rms:.3} (achieved / predicted), per point median {median:.3}, range {:.3}–{:.3}",
        ratio[0],
        ratio[ratio.len() - 1]
    );
    assert!((0.90..=0.99).contains(&cover), "{label}: coverage {cover}");
    assert!((1.0 / 1.5..=1.5).contains(&rms), "{label}: RMS {rms}");
    assert!(
        (1.0 / 1.5..=1.5).contains(&median),
        "{label}: median {median}"
    );
}

/// The design's prediction against the real monitor on the designed test simulated with
/// noise over 20 seeds (issue 45, "Prediction holds"): the standard errors achieved — the
/// spread of K̂ and B̂ about the cell's true values, at every 0.1 s after the start-up — within
/// ×1.5 of the predicted, and the predicted ±1.96σ covering 90–99 % of the estimates.
#[test]
fn predicted_standard_errors_hold_over_noise_seeds() {
    prediction_holds(&shaft(), Criterion::D, 1.5, "default monitor");
}

/// A 6 s test designed by `criterion` for `d`, simulated over 20 seeds: [`check`] from `from` s.
fn prediction_holds(d: &ShaftDesign, criterion: Criterion, from: f64, label: &str) {
    let r = design(d, 6.0, 5, criterion);
    let c = &r.chosen.curve;
    let (z, mut ratio) = standardised(d, &r.scenario, &c.t, &c.std_err, 20, from);
    check(label, &z, &mut ratio);
}

/// The same with another estimator, memory, low-pass and noise — DSFC, λ = 0.995, 200 Hz, a
/// transducer ten times noisier and noisy speed channels (which enter as `B·Δω`'s noise).
#[test]
fn prediction_holds_for_another_monitor_and_noise() {
    let mut d = shaft();
    d.monitor.method = physid_apps::shaft_monitor::MonitorMethod::Dsfc;
    d.monitor.lambda = 0.995;
    d.monitor.cutoff_hz = 200.0;
    d.monitor.rate_hz = 1000.0;
    d.cell.set("sensors.torque_shaft.noise", 0.5).unwrap();
    d.cell.set("sensors.speed.noise", 0.2).unwrap();
    prediction_holds(&d, Criterion::A, 2.0, "dsfc, λ 0.995, noisier");
}

/// The time criterion cuts the test where the target is reached and held; the scenario reads
/// back as written.
#[test]
fn time_criterion_cuts_the_test_at_the_target() {
    let d = shaft();
    let r = design(&d, 4.0, 5, Criterion::Time);
    let t = r.chosen.time_to_target_s.unwrap();
    assert!(
        r.scenario.duration >= t && r.scenario.duration <= t + 0.5 + 1e-9,
        "{} {t}",
        r.scenario.duration
    );
    let back: Scenario = toml::from_str(&r.scenario.to_toml().unwrap()).unwrap();
    assert_eq!(back, r.scenario);
    // The predicted errors are where the test is cut: below the target.
    for (p, scale) in [("K", d.cell.shaft.k), ("B", d.cell.shaft.b)] {
        let se = r.predicted_std_err[p];
        assert!(
            se.is_finite() && se > 0.0 && se / scale <= 0.02,
            "{p}: {se}"
        );
    }
}

/// Better errors than the thesis's own test in the same duration and limits (issue 45,
/// "Beats the thesis's hand-made tests"; with the monitor's 25 ms memory both reach their
/// level within 0.1 s, so the comparison is of the level held): the designed test's median
/// predicted relative standard errors of K and B are below those of T01 (1000 rpm, throttle
/// wide open), and so are the errors the real monitor achieves on both, 20 noise seeds each.
#[test]
fn designed_test_beats_the_thesis_test() {
    let d = shaft();
    let r = design(&d, 4.0, 40, Criterion::D);
    let thesis = &r.baselines[0];
    assert!(thesis.within_limits);
    let mut steady = named("shaft-steady").unwrap();
    steady.duration = 4.0;
    let achieved = |s: &Scenario, curve_t: &[f64]| -> [f64; 2] {
        let (at, _) = points(curve_t, 1.5);
        let e = errors(&d, s, &at, 20);
        let n = (e.len() * at.len()) as f64;
        let rms = |p: usize| (e.iter().flatten().map(|v| v[p] * v[p]).sum::<f64>() / n).sqrt();
        [rms(0), rms(1)]
    };
    let designed = achieved(&r.scenario, &r.chosen.curve.t);
    let t01 = achieved(&steady, &thesis.curve.t);
    for (k, p) in ["K", "B"].iter().enumerate() {
        let (pd, pt) = (r.chosen.median_rel_std_err[k], thesis.median_rel_std_err[k]);
        eprintln!(
            "{p}: predicted median relative σ {pd:.3e} designed, {pt:.3e} T01; achieved RMS error {:.3e} designed, {:.3e} T01 (its unit)",
            designed[k], t01[k]
        );
        assert!(pd < pt, "{p}: predicted {pd} against T01's {pt}");
        assert!(
            designed[k] < t01[k],
            "{p}: achieved {} against T01's {}",
            designed[k],
            t01[k]
        );
    }
}

/// A test the cell cannot follow — 2500 rpm asked with the throttle wide open, where its drive
/// holds ≈ 1650 — is left out of a design, and says why.
#[test]
fn a_test_outside_the_envelope_is_left_out() {
    let d = shaft();
    let design = Design {
        names: PARAMS.iter().map(|s| s.to_string()).collect(),
        selected: vec![0, 1],
        criterion: Criterion::D,
        target_rel_se: None,
        limits: Limits::parse("speed=2500:2500,throttle=90:90").unwrap(),
        throttle: ThrottleDraw::Linear,
        band: MULTISINE_BAND,
        duration: 3.0,
        candidates: 1,
        seed: 1,
        threads: 1,
    };
    let noise = d.noise_autocovariance().unwrap();
    let e = design
        .run(&|s| d.evaluate(&design, s, &noise), &[], &|_| {})
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("none of the 1 candidates") && e.contains("outside the cell's envelope"),
        "{e}"
    );
    assert!(e.contains("against a demand of 2500 rpm"), "{e}");
}

/// A friction test (Application 2, §7.3) designed for c4 and c17 over 160 s — the thesis's four
/// sweeps' duration — within their limits (750–1500 rpm, throttle 1–90°), from 20 candidates.
fn friction_design() -> (FrictionDesign, Design, Designed) {
    let fd = FrictionDesign::new(CellParams::default(), 10_000.0);
    let design = Design {
        names: vec!["c4".into(), "c17".into()],
        selected: vec![0, 1],
        criterion: Criterion::D,
        target_rel_se: None,
        limits: Limits::parse("speed=750:1500,throttle=1:90,dspeed=500").unwrap(),
        throttle: ThrottleDraw::Pressure,
        band: MULTISINE_BAND,
        duration: 160.0,
        candidates: 20,
        seed: 1,
        threads: 0,
    };
    let r = design_friction(&fd, &design, &|_| {}).unwrap();
    (fd, design, r)
}

/// The real friction fit's estimates of `names` on `scenario` at the times `at` [s of the
/// recording], for the noise
/// seeds `seeds` (`None`: without noise, the estimates' centre): `[run][point][param]`.
fn friction_estimates(
    fd: &FrictionDesign,
    scenario: &Scenario,
    names: &[String],
    at: &[f64],
    seeds: &[Option<u64>],
) -> Vec<Vec<Vec<f64>>> {
    let mut cfg = fd.fit.clone();
    cfg.estimate = Some(names.to_vec());
    let one = |seed: Option<u64>| {
        let quiet = ["sensors.torque_engine.noise", "sensors.p_manifold.noise"];
        let rec = seeded(
            &fd.cell,
            seed,
            &quiet,
            scenario,
            OutputBasis::Time(fd.rate_hz),
        );
        let fit = friction_fit(&rec, &cfg).unwrap();
        at.iter()
            .map(|&t| {
                let c = fit.cycles.iter().rev().find(|c| c.t_s <= t + 1e-9).unwrap();
                c.params.clone()
            })
            .collect::<Vec<_>>()
    };
    per_seed(seeds, one)
}

/// `scenario` recorded on `cell` with the sensors' noise of seed `seed`, or — `None` — without
/// the noise of `quiet`, the temperature's and the speed's.
fn seeded(
    cell: &CellParams,
    seed: Option<u64>,
    quiet: &[&str],
    scenario: &Scenario,
    basis: OutputBasis,
) -> physid_core::Recording {
    let mut params = cell.clone();
    match seed {
        Some(s) => params.set("sensors.seed", s as f64 + 1.0).unwrap(),
        None => {
            for p in quiet
                .iter()
                .chain(&["sensors.temperature.noise", "sensors.speed.noise"])
            {
                params.set(p, 0.0).unwrap();
            }
        }
    }
    let opts = RunOptions {
        params,
        basis,
        ..RunOptions::default()
    };
    simulate(scenario, &opts, |_| {}).unwrap()
}

/// `one` for each of `seeds` on two threads, in order.
fn per_seed<T: Clone + Send>(
    seeds: &[Option<u64>],
    one: impl Fn(Option<u64>) -> T + Sync,
) -> Vec<T> {
    let out = std::sync::Mutex::new(vec![None; seeds.len()]);
    let next = std::sync::atomic::AtomicUsize::new(0);
    std::thread::scope(|s| {
        for _ in 0..2 {
            s.spawn(|| loop {
                let k = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let Some(&seed) = seeds.get(k) else { break };
                let v = one(seed);
                out.lock().unwrap()[k] = Some(v);
            });
        }
    });
    out.into_inner()
        .unwrap()
        .into_iter()
        .map(Option::unwrap)
        .collect()
}

/// The noiseless run first, then `n` noise seeds.
fn centre_and_seeds(n: u64) -> Vec<Option<u64>> {
    std::iter::once(None).chain((0..n).map(Some)).collect()
}

/// The achieved standard errors `[param][point]` of `runs` (`[run][point][param]`, the
/// noiseless run first): the spread of the noisy estimates about the noiseless run's, and the
/// standardised errors against `predicted[param][point]` (none for a parameter whose is empty).
fn spread(runs: &[Vec<Vec<f64>>], predicted: Option<&[Vec<f64>]>) -> (Vec<Vec<f64>>, Vec<f64>) {
    let centre = &runs[0];
    let (points, params) = (centre.len(), centre[0].len());
    let mut achieved = vec![vec![0.0; points]; params];
    let mut z = Vec::new();
    for (p, a) in achieved.iter_mut().enumerate() {
        for (k, v) in a.iter_mut().enumerate() {
            let e: Vec<f64> = runs[1..].iter().map(|r| r[k][p] - centre[k][p]).collect();
            *v = (e.iter().map(|x| x * x).sum::<f64>() / e.len() as f64).sqrt();
            if let Some(se) = predicted.and_then(|pr| pr[p].get(k)) {
                z.extend(e.iter().map(|x| x / se));
            }
        }
    }
    (achieved, z)
}

/// The friction fit's achieved standard errors on `scenario` ([`spread`]).
fn friction_spread(
    fd: &FrictionDesign,
    scenario: &Scenario,
    names: &[String],
    at: &[f64],
    predicted: Option<&[Vec<f64>]>,
    seeds: u64,
) -> (Vec<Vec<f64>>, Vec<f64>) {
    let runs = friction_estimates(fd, scenario, names, at, &centre_and_seeds(seeds));
    spread(&runs, predicted)
}

/// The friction design's prediction against the real fit (issue 45, "Prediction holds", for
/// Application 2): the designed test simulated with noise over 20 seeds, the fit (DSFC, λ = 1,
/// the coefficients chosen beforehand) run on each; the spread of ĉ4 and ĉ17 about the
/// noiseless run's estimates — the design predicts the noise's part of the error, not the
/// friction model's structural bias against the cell's gas-exchange torque, which every seed
/// shares — within ×1.5 of the predicted standard errors every 10 s once the test resolves both, over 40
/// seeds (20 seeds' spread is itself ±16 % uncertain), and the predicted ±1.96σ covering
/// 90–99 % of them. And it beats the thesis's four sweeps (`friction-sweep`) in the same
/// 160 s ("Beats the thesis's hand-made tests"): the standard errors achieved at its end, the
/// sweeps' measured the same way over 20 seeds, are smaller for both; an 80 s design (the A
/// criterion) reaches the sweeps' c4 within 10 % and a smaller c17 in half their time.
#[test]
fn friction_design_prediction_holds_and_beats_the_sweeps() {
    let (fd, design, r) = friction_design();
    // Every 10 s where the design calls both resolved (a relative standard error below 1 %;
    // before, the fit holds the unresolved direction at its start, and the design says so with
    // an error as large as the data leave it).
    let c = &r.chosen.curve;
    let (mut at, mut idx) = (Vec::new(), Vec::new());
    for t in (1..=16).map(|k| (k as f64 * 10.0).min(159.0)) {
        let k = c.t.iter().rposition(|&x| x <= t + 1e-9).unwrap();
        if (0..2).all(|p| c.std_err[p][k] / r.chosen.std_err[p] * r.chosen.rel_std_err[p] < 0.01) {
            at.push(t);
            idx.push(k);
        }
    }
    assert!(at.len() >= 3, "resolved at {at:?} only");
    let predicted: Vec<Vec<f64>> = (0..2)
        .map(|p| idx.iter().map(|&k| c.std_err[p][k]).collect())
        .collect();
    let (achieved, z) = friction_spread(&fd, &r.scenario, &design.names, &at, Some(&predicted), 40);
    let mut ratio: Vec<f64> = (0..2)
        .flat_map(|p| (0..at.len()).map(move |k| (p, k)))
        .map(|(p, k)| achieved[p][k] / predicted[p][k])
        .collect();
    eprintln!("friction: predicted {predicted:?}, achieved {achieved:?}");
    check("friction c4, c17", &z, &mut ratio);
    let sweep = named("friction-sweep").unwrap();
    let (sw, _) = friction_spread(&fd, &sweep, &design.names, &[159.0], None, 20);
    let end = at.len() - 1;
    for p in 0..2 {
        eprintln!(
            "{}: the designed test achieves {:.3e} in 160 s, the sweeps {:.3e}",
            design.names[p], achieved[p][end], sw[p][0]
        );
        assert!(
            achieved[p][end] < sw[p][0],
            "{}: {} against the sweeps' {}",
            design.names[p],
            achieved[p][end],
            sw[p][0]
        );
    }
    // In half the sweeps' duration: an 80 s test designed by the A criterion (the mean
    // relative variance, which weighs c4 as much as c17) reaches the sweeps' c4 — within 10 %,
    // the margin 20 seeds resolve (it measured 0.236 against 0.240) — and a smaller c17.
    let half = Design {
        criterion: Criterion::A,
        duration: 80.0,
        seed: 2,
        ..design.clone()
    };
    let h = design_friction(&fd, &half, &|_| {}).unwrap();
    let (ha, _) = friction_spread(&fd, &h.scenario, &design.names, &[79.0], None, 20);
    for p in 0..2 {
        eprintln!(
            "{}: the 80 s designed test ({}) achieves {:.3e}, predicted {:.3e}; the sweeps in 160 s {:.3e}",
            design.names[p], h.chosen.name, ha[p][0], h.chosen.std_err[p], sw[p][0]
        );
    }
    assert!(
        ha[0][0] < 1.1 * sw[0][0],
        "c4 in 80 s: {} against {}",
        ha[0][0],
        sw[0][0]
    );
    assert!(
        ha[1][0] < sw[1][0],
        "c17 in 80 s: {} against {}",
        ha[1][0],
        sw[1][0]
    );
}

/// The cyclic-torque design of M_rec, b and L, the friction level c1 estimated alongside (r
/// and δ held: Eq. 8.2's scaling symmetry leaves only three of M_rec, b, L, r estimable
/// together), for a 5 s test (T2's duration) within `limits`, and the design.
fn torque_design(limits: &Limits) -> (TorqueDesign, Design, Designed) {
    let td = TorqueDesign::new(CellParams::default()).unwrap();
    let design = Design {
        names: ["M_rec", "b", "L", "c1"].map(String::from).to_vec(),
        selected: vec![0, 1, 2],
        criterion: Criterion::D,
        target_rel_se: None,
        limits: *limits,
        throttle: ThrottleDraw::Linear,
        band: MULTISINE_BAND,
        duration: 5.0,
        candidates: 20,
        seed: 1,
        threads: 0,
    };
    let r = design_torque(&td, &design, &|_| {}).unwrap();
    (td, design, r)
}

/// The real cyclic-torque fit's (UKF) estimates of `names` on `scenario` at the times `at`
/// [s of the recording], for the noise seeds `seeds` (`None`: without noise, the estimates'
/// centre): `[run][point][param]`.
fn torque_estimates(
    td: &TorqueDesign,
    scenario: &Scenario,
    names: &[String],
    at: &[f64],
    seeds: &[Option<u64>],
) -> Vec<Vec<Vec<f64>>> {
    let mut cfg = td.fit.clone();
    cfg.estimate = Some(names.to_vec());
    let one = |seed: Option<u64>| {
        let quiet = ["sensors.torque_engine.noise", "sensors.p_cyl.noise"];
        let rec = seeded(
            &td.cell,
            seed,
            &quiet,
            scenario,
            OutputBasis::Crank(td.step_deg),
        );
        let fit = torque_fit(&rec, &cfg).unwrap();
        at.iter()
            .map(|&t| {
                let k = fit.t.iter().rposition(|&x| x <= t + 1e-9).unwrap();
                names
                    .iter()
                    .map(|n| fit.tracks.iter().find(|tr| &tr.param == n).unwrap().value[k])
                    .collect::<Vec<f64>>()
            })
            .collect::<Vec<_>>()
    };
    per_seed(seeds, one)
}

/// The cyclic-torque design's prediction against the real fit (issue 45, "Prediction holds",
/// for Application 3): the designed 5 s test simulated with noise over 40 seeds, the fit (UKF
/// on 1° samples of M_rec, b, L and, alongside, the friction level c1, chosen beforehand —
/// without c1 the cubic's 4 % error at the test's point moves L by 3 %, M_rec by 0.7 %) run on
/// each; the spread of the four estimates about the noiseless run's every second within ×1.5
/// of the predicted standard errors and the predicted ±1.96σ covering 90–99 % of them. And it
/// beats the thesis's tests ("Beats the thesis's hand-made tests", 20 seeds each): smaller
/// standard errors of M_rec, b and L than the ramp T2 in its own 5 s, and than the steady T1
/// in half of its 10 s.
#[test]
fn torque_design_prediction_holds_and_beats_the_thesis_tests() {
    let (td, design, r) = torque_design(&Limits::parse("speed=800:1400").unwrap());
    let (achieved, predicted) = torque_prediction_holds(&td, &design, &r, 40);
    let names = &design.names;
    let end = predicted[0].len() - 1;
    let thesis = |name: &str, end: f64| {
        let s = named(name).unwrap();
        let runs = torque_estimates(&td, &s, names, &[end], &centre_and_seeds(20));
        spread(&runs, None).0
    };
    let (t2, t1) = (thesis("torque-ramp", 4.99), thesis("torque-steady", 9.99));
    for &p in &design.selected {
        let ours = achieved[p][end];
        eprintln!(
            "{}: the designed 5 s test achieves {ours:.3e} (predicted {:.3e}); T2 in 5 s {:.3e}, T1 in 10 s {:.3e}",
            names[p], predicted[p][end], t2[p][0], t1[p][0]
        );
        assert!(
            ours < t2[p][0],
            "{}: {ours} against T2's {}",
            names[p],
            t2[p][0]
        );
        assert!(
            ours < t1[p][0],
            "{}: {ours} against T1's {}",
            names[p],
            t1[p][0]
        );
    }
}

/// The same on a design whose candidates are the dynamometer's torque demands (torque mode:
/// −2 to 3 N·m against the motored engine's drag, the engine kept within 800–1600 rpm, the
/// runs that leave it left out), over 20 seeds.
#[test]
fn torque_mode_design_prediction_holds() {
    let limits = Limits::parse("speed=800:1600,torque=-2:3,dtorque=20").unwrap();
    let (td, design, r) = torque_design(&limits);
    assert!(r.scenario.torque_mode, "{:?}", r.scenario);
    assert!(r.evaluated > 0 && !r.failed.is_empty(), "{:?}", r.failed);
    torque_prediction_holds(&td, &design, &r, 20);
}

/// The designed test `r` simulated with noise over `seeds` seeds and fitted: the spread of the
/// estimates about the noiseless run's every second against the design's prediction (the
/// pooled check), and c1's — estimated alongside — at the end within ×1.5 of its prediction.
/// The achieved and predicted standard errors `[param][second]` (none predicted along the
/// test for c1).
fn torque_prediction_holds(
    td: &TorqueDesign,
    design: &Design,
    r: &Designed,
    seeds: u64,
) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let names = &design.names;
    let c = &r.chosen.curve;
    let at: Vec<f64> = (1..=5).map(|k| k as f64 - 0.01).collect();
    let idx: Vec<usize> = at
        .iter()
        .map(|&t| c.t.iter().rposition(|&x| x <= t + 1e-9).unwrap())
        .collect();
    // The curve holds the designed-for parameters; c1's comes from the covariance at the end.
    let cov = r.chosen.covariance.as_ref().unwrap();
    let predicted: Vec<Vec<f64>> = (0..names.len())
        .map(|p| match design.selected.iter().position(|&s| s == p) {
            Some(c_at) => idx.iter().map(|&k| c.std_err[c_at][k]).collect(),
            None => Vec::new(),
        })
        .collect();
    let runs = torque_estimates(td, &r.scenario, names, &at, &centre_and_seeds(seeds));
    let (achieved, z) = spread(&runs, Some(&predicted));
    let mut ratio: Vec<f64> = design
        .selected
        .iter()
        .flat_map(|&p| (0..at.len()).map(move |k| (p, k)))
        .map(|(p, k)| achieved[p][k] / predicted[p][k])
        .collect();
    // c1, estimated alongside: its predicted standard error at the end.
    let end = at.len() - 1;
    let c1 = achieved[3][end] / cov[(3, 3)].sqrt();
    eprintln!("c1 alongside: achieved / predicted {c1:.3}");
    assert!((1.0 / 1.5..=1.5).contains(&c1), "c1: {c1}");
    eprintln!(
        "torque: chosen {} ({:?}, throttle {:?}); predicted {predicted:?}, achieved {achieved:?}",
        r.chosen.name, r.scenario.speed.segments, r.scenario.throttle.segments
    );
    check("torque M_rec, b, L", &z, &mut ratio);
    (achieved, predicted)
}

/// Eq. 8.2 is invariant under `r → λr, L → λL, b → b/√λ, M_rec → M_rec/λ²`: no test resolves
/// all four, and a design for them says which is structurally unidentifiable instead of giving
/// it a huge standard error (issue 45, "Structural zeros").
#[test]
fn torque_design_refuses_the_scaling_symmetry() {
    let td = TorqueDesign::new(CellParams::default()).unwrap();
    let design = Design {
        names: ["M_rec", "b", "L", "r"].map(String::from).to_vec(),
        selected: vec![0, 1, 2, 3],
        criterion: Criterion::D,
        target_rel_se: None,
        limits: Limits::parse("speed=800:1400").unwrap(),
        throttle: ThrottleDraw::Linear,
        band: MULTISINE_BAND,
        duration: 2.0,
        candidates: 10,
        seed: 1,
        threads: 0,
    };
    let e = design_torque(&td, &design, &|_| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("structurally unidentifiable"), "{e}");
}

/// A design's candidates run at the solver's 2° step (`candidate_cell`, half the steps of
/// `physid simulate`'s 1°): the same candidate is chosen and the predicted standard errors
/// move by under 1 % (measured: under 0.2 %) — for the shaft (a 10 kHz recording) and the
/// cyclic torque (1° samples, between the 2° steps by the acquisition's interpolation).
#[test]
fn candidates_at_two_degrees_predict_as_at_one() {
    use physid_apps::design::run::{candidate_cell, CANDIDATE_STEP_DEG};
    let two = candidate_cell(CellParams::default(), &[]);
    assert_eq!(two.step_deg, CANDIDATE_STEP_DEG);
    // A step set by the user stays.
    let set = [("solver.step_deg".to_string(), 1.0)];
    assert_eq!(candidate_cell(CellParams::default(), &set).step_deg, 1.0);
    let same = |a: &Designed, b: &Designed| {
        assert_eq!(a.chosen.name, b.chosen.name);
        for (p, s1) in &a.predicted_std_err {
            let s2 = b.predicted_std_err[p];
            assert!((s2 / s1 - 1.0).abs() < 0.01, "{p}: {s1} at 1°, {s2} at 2°");
        }
    };
    let one = design(&shaft(), 3.0, 6, Criterion::D);
    let at_two = ShaftDesign {
        cell: two.clone(),
        ..shaft()
    };
    same(&one, &design(&at_two, 3.0, 6, Criterion::D));
    let torque = |cell: CellParams| {
        let td = TorqueDesign::new(cell).unwrap();
        let design = Design {
            names: ["M_rec", "b", "L"].map(String::from).to_vec(),
            selected: vec![0, 1, 2],
            criterion: Criterion::D,
            target_rel_se: None,
            limits: Limits::parse("speed=800:1400").unwrap(),
            throttle: ThrottleDraw::Linear,
            band: MULTISINE_BAND,
            duration: 2.0,
            candidates: 6,
            seed: 1,
            threads: 0,
        };
        design_torque(&td, &design, &|_| {}).unwrap()
    };
    same(&torque(CellParams::default()), &torque(two));
}
