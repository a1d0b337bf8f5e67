use physid_sim::params::CellParams;
use physid_sim::run::{simulate, OutputBasis, RunOptions};
use physid_sim::scenario::{named, Scenario};
fn main() {
    let step: f64 = std::env::args()
        .nth(1)
        .map(|s| s.parse().unwrap())
        .unwrap_or(2.0);
    let dur: f64 = std::env::args()
        .nth(2)
        .map(|s| s.parse().unwrap())
        .unwrap_or(20.0);
    let scenario = Scenario {
        settle: 0.0,
        ..named("torque-steady").unwrap()
    };
    let opts = RunOptions {
        params: CellParams {
            order: 2.0,
            step_deg: step,
            ..CellParams::default()
        },
        duration: Some(0.5),
        basis: OutputBasis::Crank(1.0),
        ..RunOptions::default()
    };
    let t = std::time::Instant::now();
    let n = (dur / 0.5) as usize;
    for _ in 0..n {
        let r = simulate(&scenario, &opts, |_| {}).unwrap();
        std::hint::black_box(r);
    }
    let el = t.elapsed().as_secs_f64();
    eprintln!("{:.0}x real time", dur / el);
}
