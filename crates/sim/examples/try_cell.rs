use physid_sim::run::{simulate, OutputBasis, RunOptions};
use physid_sim::scenario::Scenario;
fn main() {
    let name = std::env::args().nth(1).unwrap_or("shaft-steady".into());
    let sc = Scenario::load(&name).unwrap();
    let t0 = std::time::Instant::now();
    let rec = simulate(&sc, &RunOptions { basis: OutputBasis::Crank(1.0), duration: Some(5.0), ..Default::default() }, |_| {}).unwrap();
    println!("{} samples, {} channels in {:.3} s", rec.len(), rec.channels().len(), t0.elapsed().as_secs_f64());
    for ch in ["omega_en", "omega_dy", "torque_shaft", "torque_engine", "p_cyl", "p_int", "true_torque_friction", "i_a", "cycle"] {
        let v = rec.values(ch).unwrap();
        let (lo, hi) = v.iter().fold((f64::MAX, f64::MIN), |(a, b), &x| (a.min(x), b.max(x)));
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        println!("{ch:>22}: min {lo:12.4} mean {mean:12.4} max {hi:12.4}");
    }
}
