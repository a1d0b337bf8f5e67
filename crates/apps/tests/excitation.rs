//! On-line identifiability steering RLSF (issue 4): on Example 5.2-style data with a second
//! without excitation of B, the unguarded estimator's covariance winds up by orders of
//! magnitude while the supervised one freezes B, keeps trace(P) at its normal level, and
//! releases B when excitation returns.
// Test helpers panic on failure by design.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_apps::excitation::{
    lost_excitation, ExcitationSupervisor, LostExcitationConfig, SupervisorConfig,
};
use physid_core::ParamSet;
use physid_estim::{EstimatorConfig, LinearEstimator, Method};

#[test]
fn frozen_estimate_does_not_wind_up() {
    let cfg = LostExcitationConfig::default();
    let r = lost_excitation(&cfg).unwrap();
    let idx = |t: f64| r.t.iter().position(|&s| s >= t - 1e-9).unwrap();
    let (q0, q1) = (idx(cfg.quiet.0), idx(cfg.quiet.1));
    let normal = r.unguarded.trace[q0 - 1];
    let max = |v: &[f64]| v.iter().cloned().fold(0.0, f64::max);
    // Wind-up: P_BB grows by 1/λ per sample, λ^−1000 ≈ 6e8 over the quiet second.
    let unguarded_peak = max(&r.unguarded.trace[q0..q1]);
    assert!(
        unguarded_peak > 1e6 * normal,
        "{unguarded_peak} vs {normal}"
    );
    // Supervised: B frozen within 0.3 s of the excitation ending, trace(P) stays normal.
    let frozen_at = (q0..q1).find(|&i| !r.supervised.b_free[i]).unwrap();
    assert!(
        r.t[frozen_at] - cfg.quiet.0 < 0.3,
        "frozen at {}",
        r.t[frozen_at]
    );
    assert!(r.supervised.b_free[..q0].iter().all(|&f| f));
    assert!(r.supervised.b_free[frozen_at..q1].iter().all(|&f| !f));
    let sup_peak = max(&r.supervised.trace[q0..]);
    assert!(sup_peak < 10.0 * normal, "{sup_peak} vs {normal}");
    // While frozen B does not move; afterwards it is released once and tracks again.
    let b_frozen = r.supervised.b[frozen_at];
    assert!(r.supervised.b[frozen_at..q1].iter().all(|&b| b == b_frozen));
    assert_eq!((r.freezes, r.releases), (1, 1));
    assert!(r.supervised.b_free[r.t.len() - 1]);
    // Estimate quality after the quiet period: the wound-up estimator's first samples of
    // renewed excitation jerk B̂; the supervised one barely moves.
    let err = |b: &[f64]| b[q0..].iter().map(|b| (b - 0.5).abs()).fold(0.0, f64::max);
    let (eu, es) = (err(&r.unguarded.b), err(&r.supervised.b));
    assert!(es < 0.002, "supervised B error {es}");
    assert!(eu > 3.0 * es, "unguarded {eu} vs supervised {es}");
}

#[test]
fn supervisor_checks_its_configuration() {
    let params = ParamSet::zeros(["A", "B"]).unwrap();
    let est = || {
        LinearEstimator::new(
            &EstimatorConfig::new(Method::Rlsf { lambda: 0.98 }),
            &params,
            &params.all_free(),
        )
        .unwrap()
    };
    let cfg = SupervisorConfig::for_lambda(0.98);
    let e = ExcitationSupervisor::new(est(), vec![1.0], cfg).unwrap_err();
    assert!(
        e.to_string().contains("1 scales for 2 free parameters"),
        "{e}"
    );
    let bad = SupervisorConfig {
        freeze_below: 0.5,
        release_above: 0.2,
        ..cfg
    };
    assert!(ExcitationSupervisor::new(est(), vec![1.0, 1.0], bad).is_err());
}

/// The supervisor is a `Recursive` estimator like any other: driven through `dyn Recursive`,
/// checkpointed mid-run — while B is frozen — and restored (through MessagePack, as the live
/// service stores it) into a supervisor built afresh, it continues bit for bit: the same
/// estimates, the same freezes and releases.
#[test]
fn a_supervisor_checkpointed_while_b_is_frozen_continues_exactly() {
    use physid_estim::{Recursive, Snapshot};
    let params = ParamSet::zeros(["A", "B"]).unwrap();
    let build = || {
        let est = LinearEstimator::new(
            &EstimatorConfig::new(Method::Rlsf { lambda: 0.98 }),
            &params,
            &params.all_free(),
        )
        .unwrap();
        ExcitationSupervisor::new(est, vec![1.0, 1.0], SupervisorConfig::for_lambda(0.98)).unwrap()
    };
    // z = 10·sin(x) + 0.5·y², y = 0 (B unexcited) between samples 2000 and 3000.
    let sample = |i: usize| {
        let t = i as f64 * 1e-3;
        let x = std::f64::consts::TAU * 47.0 * t;
        let y = if (2000..3000).contains(&i) {
            0.0
        } else {
            2.0 + (1.3 * t).sin()
        };
        let phi = [x.sin(), y * y];
        (phi, 10.0 * phi[0] + 0.5 * phi[1] + 1e-3 * (7.0 * t).cos())
    };
    let mut a = build();
    let run: &mut dyn Recursive = &mut a;
    for i in 0..2500 {
        let (phi, z) = sample(i);
        run.update(&phi, z).unwrap();
    }
    assert_eq!(run.free_names(), ["A"], "B frozen at the checkpoint");
    let bytes = rmp_serde::to_vec_named(&run.snapshot()).unwrap();
    let mut b = build();
    b.restore(&rmp_serde::from_slice::<Snapshot>(&bytes).unwrap())
        .unwrap();
    assert_eq!(b.free_names(), ["A"]);
    for i in 2500..6000 {
        let (phi, z) = sample(i);
        let sa = a.update(&phi, z).unwrap();
        let sb = b.update(&phi, z).unwrap();
        assert_eq!(sa.prediction_error.to_bits(), sb.prediction_error.to_bits());
        let (ea, eb) = (Recursive::estimate_full(&a), Recursive::estimate_full(&b));
        assert_eq!(ea, eb, "sample {i}");
    }
    assert_eq!((a.freezes(), a.releases()), (1, 1));
    assert_eq!((b.freezes(), b.releases()), (1, 1));
    assert_eq!(Recursive::free_names(&b), ["A", "B"], "B released again");
    // A checkpoint of a plain estimator is refused, and changes nothing.
    let plain = LinearEstimator::new(
        &EstimatorConfig::new(Method::Rlsf { lambda: 0.98 }),
        &params,
        &params.all_free(),
    )
    .unwrap();
    let before = Recursive::estimate_full(&b);
    let err = b.restore(&plain.snapshot()).unwrap_err().to_string();
    assert!(err.contains("taken of a linear estimator"), "{err}");
    assert_eq!(Recursive::estimate_full(&b), before);
}
