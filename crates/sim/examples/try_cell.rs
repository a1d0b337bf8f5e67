use physid_sim::cell::{Inputs, TestCell};
use physid_sim::control::Demand;
use physid_sim::params::CellParams;
fn main() {
    let w = 1000.0 * std::f64::consts::PI / 30.0;
    let thr: f64 = std::env::args().nth(1).map(|s| s.parse().unwrap()).unwrap_or(90.0);
    let mut cell = TestCell::new(CellParams::default(), w, 0.0).unwrap();
    let inp = Inputs { demand: Demand::Speed(w), throttle_deg: thr };
    let t0 = std::time::Instant::now();
    let mut n = 0;
    let mut pmax = 0.0f64; let mut last = None;
    while cell.time() < 5.0 {
        let s = cell.step(&inp);
        n += 1;
        if s.t > 4.88 { pmax = pmax.max(s.gas.p[1]); }
        if n % 720 == 0 && s.t > 4.0 { last = Some(s); }
        if (s.t * 2.0).fract() < 0.0002 {
            println!("t {:.3} w_en {:.2} w_dy {:.2} p_int {:.0} p_cyl {:.0} T_cyl {:.0} tau_sh {:.2} tau_dy {:.2} fric {:.3} i_dq {:.1},{:.1} flux {:.3}", s.t, s.omega_en, s.omega_dy, s.gas.p[0], s.gas.p[1], s.temperatures[1], s.torque_shaft, s.torque_dy, s.torque_friction, s.i_dq[0], s.i_dq[1], s.flux_est);
        }
    }
    let el = t0.elapsed().as_secs_f64();
    println!("{} steps in {:.3} s: {:.0} steps/s, realtime factor {:.1}; pmax last cycle {:.0} Pa", n, el, n as f64 / el, 5.0 / el, pmax);
    let _ = last;
}
