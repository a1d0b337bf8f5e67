//! The applications as stages: the file verb is a stream over the file, so streaming the same
//! recording in chunks of 1, 17, 4096 samples or whole gives the very same result; and the
//! stream's zero-phase low-pass reproduces the whole-record computation (sosfiltfilt over the
//! whole file, then the estimator) to 1e-9 relative.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_apps::shaft_monitor::{
    monitor_shaft, monitor_shaft_stream, MonitorConfig, ShaftAlarm, ShaftInputs, ShaftSample,
    ShaftStage, TRACK_MAX,
};
use physid_core::{Basis, Channel, ParamSet, Recording};
use physid_estim::{CovSpec, EstimatorConfig, LinearEstimator, Method};
use physid_signal::filter::{butter, Band};
use physid_sim::run::OutputBasis;

use std::f64::consts::PI;

mod common;

fn stream(
    rec: &Recording,
    cfg: &MonitorConfig,
    chunk: usize,
) -> (Vec<ShaftSample>, Vec<ShaftAlarm>) {
    let all = ShaftInputs::of(rec).unwrap();
    let t = all.t;
    let mut stage = ShaftStage::new(cfg, 1.0 / (t[1] - t[0])).unwrap();
    let (mut s, mut a) = (Vec::new(), Vec::new());
    for start in (0..t.len()).step_by(chunk) {
        let x = all.slice(start..r_end(start, chunk, t.len()));
        stage.push_inputs(&x, &mut s, &mut a).unwrap();
        // Nothing waits longer than the stated latency.
        let waiting = r_end(start, chunk, t.len()) - s.last().map_or(0, |x| x.index + 1);
        assert!(waiting <= stage.latency() + cfg_every(cfg, t), "{waiting}");
    }
    stage.finish_into(&mut s, &mut a).unwrap();
    (s, a)
}

/// Bit for bit (NaN standard errors before the estimator has any included).
fn same(a: &[ShaftSample], b: &[ShaftSample], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}");
    let bits = |s: &ShaftSample| {
        [
            s.t_s,
            s.estimate.k,
            s.estimate.b,
            s.estimate.tau0,
            s.std_err.k,
            s.std_err.b,
        ]
        .map(f64::to_bits)
    };
    if let Some(i) = (0..a.len()).find(|&i| a[i].index != b[i].index || bits(&a[i]) != bits(&b[i]))
    {
        panic!("{what}: sample {i} differs: {:?} vs {:?}", a[i], b[i]);
    }
}

fn r_end(start: usize, chunk: usize, n: usize) -> usize {
    (start + chunk).min(n)
}

fn cfg_every(cfg: &MonitorConfig, t: &[f64]) -> usize {
    ((1.0 / (t[1] - t[0]) / cfg.rate_hz).round() as usize).max(1)
}

#[test]
fn the_shaft_monitor_is_the_same_however_the_file_is_chunked() {
    let rec = common::simulate_scenario(
        "shaft-steady",
        &[],
        &["shaft.k=1000@2"],
        3.0,
        OutputBasis::Time(10_000.0),
    );
    let cfg = MonitorConfig::default();
    let (whole, alarms) = stream(&rec, &cfg, usize::MAX);
    assert!(
        alarms.iter().any(|a| a.param == "K") && alarms.iter().all(|a| a.param == "K"),
        "{alarms:?}"
    );
    for chunk in [1, 17, 4096] {
        let (s, a) = stream(&rec, &cfg, chunk);
        same(&s, &whole, &format!("chunks of {chunk}"));
        assert_eq!(a, alarms, "chunks of {chunk}");
    }
    // The file verb is the same stream.
    let r = monitor_shaft(&rec, &cfg).unwrap();
    assert_eq!(r.k, whole.iter().map(|s| s.estimate.k).collect::<Vec<_>>());
    assert_eq!(r.alarms, alarms);

    // The whole-record computation: sosfiltfilt over the file, then RLS with forgetting on the
    // decimated samples — the stream's estimates agree to 1e-9 relative.
    let get = |n: &str| rec.values(n).unwrap();
    let t = get("t");
    let fs = 1.0 / (t[1] - t[0]);
    let sos = butter(4, &[cfg.cutoff_hz], Band::Lowpass, fs)
        .unwrap()
        .to_sos();
    let d = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x - y).collect::<Vec<_>>();
    let dth = sos
        .sosfiltfilt(&d(get("theta_dy"), get("theta_en")))
        .unwrap();
    let dw = sos
        .sosfiltfilt(&d(get("omega_dy"), get("omega_en")))
        .unwrap();
    let tq = sos.sosfiltfilt(get("torque_shaft")).unwrap();
    let params = ParamSet::new(["K", "B", "tau0"], vec![0.0; 3]).unwrap();
    let mut est = LinearEstimator::new(
        &EstimatorConfig {
            p0: CovSpec::Scaled(cfg.p0),
            ..EstimatorConfig::new(Method::Rlsf { lambda: cfg.lambda })
        },
        &params,
        &params.all_free(),
    )
    .unwrap();
    let every = cfg_every(&cfg, t);
    let mut worst: f64 = 0.0;
    for (s, i) in whole.iter().zip((0..t.len()).step_by(every)) {
        assert_eq!(s.index, i);
        est.update(&[dth[i], dw[i], 1.0], tq[i]).unwrap();
        let e = est.estimate();
        for (a, b) in [(s.estimate.k, e[0]), (s.estimate.b, e[1])] {
            worst = worst.max((a - b).abs() / b.abs());
        }
    }
    eprintln!("stream vs whole record: worst relative difference {worst:.2e}");
    assert!(worst < 1e-9, "{worst:e}");
}

/// With the excitation supervisor, too: the freezes and releases, the estimates and the
/// reported state are the same whatever the chunk (the motored sweep, whose quiet cycle parts
/// make the estimator freeze and release K and B within each cycle).
#[test]
fn the_supervised_monitor_is_the_same_however_the_file_is_chunked() {
    let rec =
        common::simulate_scenario("friction-sweep", &[], &[], 3.0, OutputBasis::Time(10_000.0));
    let cfg = MonitorConfig {
        supervise: true,
        ..Default::default()
    };
    let (whole, alarms) = stream(&rec, &cfg, usize::MAX);
    for chunk in [1, 17, 4096] {
        let (s, a) = stream(&rec, &cfg, chunk);
        same(&s, &whole, &format!("chunks of {chunk}"));
        assert!(
            s.iter().zip(&whole).all(|(x, y)| x.frozen == y.frozen),
            "chunks of {chunk}"
        );
        assert_eq!(a, alarms, "chunks of {chunk}");
    }
    let r = monitor_shaft(&rec, &cfg).unwrap();
    assert_eq!(r.k, whole.iter().map(|s| s.estimate.k).collect::<Vec<_>>());
}

/// A long synthetic shaft record at 2 kHz: twist and twist rate of two incommensurate
/// sinusoids, torque `K·Δθ + B·Δω + τ0` exactly (Eq. 6.1), the truth alongside.
fn synthetic_shaft(seconds: f64) -> Recording {
    let fs = 2000.0;
    let n = (seconds * fs) as usize;
    let (k, b, tau0) = (1200.0, 0.9, 2.0);
    let t: Vec<f64> = (0..n).map(|i| i as f64 / fs).collect();
    let twist = |t: f64| 0.01 * (2.0 * PI * 7.0 * t).sin() + 0.004 * (2.0 * PI * 23.0 * t).sin();
    let rate = |t: f64| {
        0.01 * 2.0 * PI * 7.0 * (2.0 * PI * 7.0 * t).cos()
            + 0.004 * 2.0 * PI * 23.0 * (2.0 * PI * 23.0 * t).cos()
    };
    let theta_en: Vec<f64> = t.iter().map(|t| 100.0 * t).collect();
    let omega_en = vec![100.0; n];
    let mut r = Recording::new(Basis::Time);
    for (name, values) in [
        ("t", t.clone()),
        ("theta_en", theta_en.clone()),
        (
            "theta_dy",
            t.iter()
                .zip(&theta_en)
                .map(|(t, e)| e + twist(*t))
                .collect(),
        ),
        ("omega_en", omega_en.clone()),
        ("omega_dy", t.iter().map(|t| 100.0 + rate(*t)).collect()),
        (
            "torque_shaft",
            t.iter()
                .map(|t| k * twist(*t) + b * rate(*t) + tau0)
                .collect(),
        ),
        ("true_shaft_k", vec![k; n]),
        ("true_shaft_b", vec![b; n]),
    ] {
        r.push(Channel {
            name: name.into(),
            unit: String::new(),
            values,
        })
        .unwrap();
    }
    r
}

/// 75 s at 2 kHz (150 000 estimator samples, more than [`TRACK_MAX`]): read in chunks as a
/// file is, the monitor's tracks are every other sample of the stage's output — bounded — while
/// the final estimate, the alarms, the NMSE (Eq. 6.4, against `metrics::nmse` over every
/// sample after settling) and the ±5 % times are those of every sample; and the whole-record
/// function is the same stream.
#[test]
fn a_long_file_keeps_bounded_tracks_and_exact_summaries() {
    let rec = synthetic_shaft(75.0);
    let cfg = MonitorConfig {
        rate_hz: 2000.0,
        ..Default::default()
    };
    let (all, alarms) = stream(&rec, &cfg, 4096);
    assert!(all.len() > TRACK_MAX, "{}", all.len());
    let chunks = (0..rec.len())
        .step_by(65_536)
        .map(|s| Ok::<_, physid_apps::error::AppError>(rec.slice(s..s + 65_536)));
    let r = monitor_shaft_stream(chunks, &cfg).unwrap();
    assert!(
        r.t.len() <= TRACK_MAX && r.t.len() > TRACK_MAX / 2,
        "{}",
        r.t.len()
    );
    let every_other: Vec<f64> = all.iter().step_by(2).map(|s| s.estimate.k).collect();
    assert_eq!(r.k, every_other);
    assert_eq!(r.alarms, alarms);
    let last = all.last().unwrap();
    assert_eq!(r.final_estimate.k, last.estimate.k);
    assert!(
        (r.final_estimate.k / 1200.0 - 1.0).abs() < 1e-3,
        "{:?}",
        r.final_estimate
    );
    let start = all.iter().position(|s| s.t_s >= cfg.settle_s).unwrap();
    let k: Vec<f64> = all[start..].iter().map(|s| s.estimate.k).collect();
    let want = physid_estim::metrics::nmse(&vec![1200.0; k.len()], &k).unwrap();
    assert_eq!(r.nmse.unwrap().k, want);
    // The whole-record function streams the same samples: the same summary.
    let whole = monitor_shaft(&rec, &cfg).unwrap();
    assert_eq!(whole.k, r.k);
    assert_eq!(whole.nmse, r.nmse);
    assert_eq!(whole.within_5pct_s, r.within_5pct_s);
}
