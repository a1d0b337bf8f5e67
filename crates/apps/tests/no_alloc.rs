//! A stage's steady state never touches the heap: once its buffers have grown to the chunk
//! size, the shaft monitor's stage (stream filters, estimator, detector) takes chunk after chunk
//! with a counting global allocator seeing no allocation.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use physid_apps::shaft_monitor::{MonitorConfig, ShaftInputs, ShaftStage};
use physid_testkit::{allocations, Counting};

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn the_shaft_stage_does_not_allocate_per_sample() {
    steady_state_allocations(MonitorConfig::default());
}

/// The same with the excitation supervisor ranking every 10 estimator samples (re-ranking in
/// its workspace; only a freeze or a release, which this excited shaft never needs, rebuilds
/// the estimator).
#[test]
fn the_supervised_shaft_stage_does_not_allocate_per_sample() {
    steady_state_allocations(MonitorConfig {
        supervise: true,
        ..Default::default()
    });
}

fn steady_state_allocations(cfg: MonitorConfig) {
    let fs = 10_000.0;
    let n = 100;
    let mut stage = ShaftStage::new(&cfg, fs).unwrap();
    let (mut samples, mut alarms) = (Vec::with_capacity(4 * n), Vec::with_capacity(16));
    let mut cols: [Vec<f64>; 6] = Default::default();
    let chunk = |k: usize, cols: &mut [Vec<f64>; 6]| {
        for c in cols.iter_mut() {
            c.clear();
        }
        for i in k * n..(k + 1) * n {
            let t = i as f64 / fs;
            let th = 104.7 * t;
            let twist = 0.01 * (2.0 * std::f64::consts::PI * 17.0 * t).sin();
            cols[0].push(t);
            cols[1].push(th + twist);
            cols[2].push(th);
            cols[3].push(104.7 + 1.0 * (2.0 * std::f64::consts::PI * 17.0 * t).cos());
            cols[4].push(104.7);
            cols[5].push(1250.0 * twist + 0.95 * (cols[3][i - k * n] - 104.7));
        }
    };
    let mut run = |k: usize, stage: &mut ShaftStage, cols: &mut [Vec<f64>; 6]| {
        chunk(k, cols);
        samples.clear();
        alarms.clear();
        let x = ShaftInputs {
            t: &cols[0],
            theta_dy: &cols[1],
            theta_en: &cols[2],
            omega_dy: &cols[3],
            omega_en: &cols[4],
            torque_shaft: &cols[5],
        };
        stage.push_inputs(&x, &mut samples, &mut alarms).unwrap();
        samples.len()
    };
    // Warm up: the filters' buffers and the time queue reach their steady size.
    for k in 0..50 {
        run(k, &mut stage, &mut cols);
    }
    let before = allocations();
    let mut produced = 0;
    for k in 50..250 {
        produced += run(k, &mut stage, &mut cols);
    }
    let made = allocations() - before;
    assert!(produced > 3000, "{produced} estimator samples");
    assert_eq!(made, 0, "{made} allocations over 20 000 samples");
}
