//! The engineer's checks on the cell's subsystems: the closed-cylinder compression, one
//! converged motored cycle at constant speed, and the dynamometer's torque–speed curve.

use crate::engine::{Engine, GasState, Motored, CYL, INT};
use crate::error::SimError;
use crate::machine::Machine;
use crate::params::CellParams;
use physid_models::air;
use serde::Serialize;
use std::f64::consts::PI;

/// Result of the compression check.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Compression {
    /// Peak cylinder pressure [Pa].
    pub p_max_pa: f64,
    /// Peak temperature [K].
    pub t_max_k: f64,
    /// Crank angle of the peak pressure [deg from firing TDC; 360 = the TDC after BDC at 180].
    pub theta_p_max_deg: f64,
    /// Pressure back at BDC after expansion [Pa].
    pub p_end_pa: f64,
    /// Temperature back at BDC [K].
    pub t_end_k: f64,
    /// Cylinder mass at the start and end [kg] (valves shut: equal).
    #[serde(skip)]
    pub mass_kg: [f64; 2],
}

/// RK4 over the gas state at constant speed ω with a fixed crank step.
fn integrate_gas(
    engine: &Engine,
    x: &mut GasState,
    theta: &mut f64,
    omega: f64,
    a_throttle: f64,
    step_rad: f64,
    mut each: impl FnMut(f64, &GasState),
) {
    let dt = step_rad / omega;
    let f = |th: f64, x: &GasState| engine.gas_derivatives(th, omega, a_throttle, x, &Motored).0;
    let add = |a: &GasState, k: &GasState, h: f64| {
        let mut y = *a;
        for (yi, ki) in y.iter_mut().zip(k) {
            *yi += h * ki;
        }
        y
    };
    let k1 = f(*theta, x);
    let k2 = f(*theta + step_rad / 2.0, &add(x, &k1, dt / 2.0));
    let k3 = f(*theta + step_rad / 2.0, &add(x, &k2, dt / 2.0));
    let k4 = f(*theta + step_rad, &add(x, &k3, dt));
    for j in 0..8 {
        x[j] += dt / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
    }
    *theta += step_rad;
    each(*theta, x);
}

/// Closed cylinder from BDC (180°) through TDC (360°) back to BDC (540°), valves shut, at
/// `rpm`, starting at `p0` [Pa], `t0` [K]; heat transfer as in `params` unless switched off.
pub fn compression(
    params: &CellParams,
    p0: f64,
    t0: f64,
    rpm: f64,
    heat_transfer: bool,
) -> Result<Compression, SimError> {
    for (what, v) in [("p0", p0), ("t0", t0), ("rpm", rpm)] {
        if !(v.is_finite() && v > 0.0) {
            return Err(SimError::Invalid(format!("{what} = {v}: expected > 0")));
        }
    }
    let mut p = params.clone();
    p.engine.lift_max = 0.0;
    p.engine.heat_transfer = if heat_transfer {
        p.engine.heat_transfer
    } else {
        0.0
    };
    p.validate()?;
    let engine = Engine::new(&p.engine, &p.ambient);
    let omega = rpm * PI / 30.0;
    let mut theta = PI;
    let r = air::gas_constant();
    let mut x = engine.ambient_state(theta);
    x[CYL] = p0 * engine.volume(theta) / (r * t0);
    x[3 + CYL] = t0;
    let m0 = x[CYL];
    let mut best = (0.0, 0.0, 0.0);
    let step = 0.05f64.to_radians();
    for _ in 0..(2.0 * PI / step).round() as usize {
        integrate_gas(&engine, &mut x, &mut theta, omega, 0.0, step, |th, x| {
            let pc = x[CYL] * r * x[3 + CYL] / engine.volume(th);
            if pc > best.0 {
                best = (pc, x[3 + CYL], th.to_degrees());
            }
        });
    }
    Ok(Compression {
        p_max_pa: best.0,
        t_max_k: best.1,
        theta_p_max_deg: best.2,
        p_end_pa: x[CYL] * r * x[3 + CYL] / engine.volume(theta),
        t_end_k: x[3 + CYL],
        mass_kg: [m0, x[CYL]],
    })
}

/// Mean torque components over a motored cycle [N·m].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MeanTorque {
    /// Indicated (gas, pumping included).
    pub indicated: f64,
    /// Reciprocating (zero at constant speed, up to round-off).
    pub reciprocating: f64,
    /// Friction (mechanical).
    pub friction: f64,
}

/// One converged motored cycle at constant speed.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MotoredCycle {
    /// Peak cylinder pressure [Pa].
    pub p_max_pa: f64,
    /// Its crank angle [deg after firing TDC].
    pub theta_p_max_deg: f64,
    /// Net indicated mean effective pressure `∮p dV / V_d` over 720° [Pa].
    pub imep_pa: f64,
    /// Pumping mean effective pressure: the work of the exhaust and intake strokes
    /// (180°–540°) / V_d, positive for a loss [Pa].
    pub pmep_pa: f64,
    /// Cylinder mass at intake valve closing [kg].
    pub trapped_mass_kg: f64,
    /// Air through the throttle per cycle over ambient density × V_d.
    pub vol_eff: f64,
    /// Mean intake manifold pressure [Pa].
    pub p_int_mean_pa: f64,
    /// Mean torques.
    pub torque_mean_nm: MeanTorque,
    /// Cycles simulated to converge.
    pub cycles: usize,
    /// Cylinder pressure over the last cycle, one value per degree from 0 to 719 [Pa].
    #[serde(skip)]
    pub p_cyl_pa: Vec<f64>,
}

/// Simulate the engine at constant `rpm` and throttle [deg] until the cycle repeats (mean
/// manifold pressure within 1e-6 relative between cycles, at most 200 cycles), and report the
/// last cycle.
pub fn motored_cycle(
    params: &CellParams,
    rpm: f64,
    throttle_deg: f64,
) -> Result<MotoredCycle, SimError> {
    if !(rpm.is_finite() && rpm >= 100.0) {
        return Err(SimError::Invalid(format!("rpm = {rpm}: expected ≥ 100")));
    }
    params.validate()?;
    let engine = Engine::new(&params.engine, &params.ambient);
    let omega = rpm * PI / 30.0;
    let a_th = engine.throttle_cd_area(throttle_deg);
    let r = air::gas_constant();
    let mut theta = 0.0;
    let mut x = engine.ambient_state(theta);
    let step = 0.25f64.to_radians();
    let per_cycle = (4.0 * PI / step).round() as usize;
    let mut prev_mean = f64::NAN;
    let mut cycles = 0;
    let fric = engine.friction_torque(omega, params.ambient.p);
    loop {
        cycles += 1;
        let (mut p_sum, mut work, mut pump, mut t_ind, mut t_rec) = (0.0, 0.0, 0.0, 0.0, 0.0);
        let (mut p_max, mut th_max, mut trapped) = (0.0, 0.0, 0.0);
        let mut p_deg = vec![0.0; 720];
        let m_in0 = x[6];
        let mut prev_p = x[CYL] * r * x[4] / engine.volume(theta);
        let mut prev_v = engine.volume(theta);
        for k in 0..per_cycle {
            integrate_gas(&engine, &mut x, &mut theta, omega, a_th, step, |_, _| {});
            let v = engine.volume(theta);
            let pc = x[CYL] * r * x[4] / v;
            let dw = 0.5 * (pc + prev_p) * (v - prev_v);
            let deg = theta.to_degrees().rem_euclid(720.0);
            work += dw;
            if (180.0..540.0).contains(&(deg - 0.125).rem_euclid(720.0)) {
                pump += dw;
            }
            if pc > p_max {
                p_max = pc;
                th_max = deg;
            }
            if ((deg - params.engine.ivc).rem_euclid(720.0)) < 0.25 {
                trapped = x[CYL];
            }
            let q = engine.torque(theta, omega, pc, fric);
            t_ind += q.indicated;
            t_rec += q.rec_velocity;
            p_sum += x[INT] * r * x[3] / params.engine.v_int;
            if k % 4 == 3 {
                let d = (deg.round() as usize) % 720;
                p_deg[d] = pc;
            }
            prev_p = pc;
            prev_v = v;
        }
        let n = per_cycle as f64;
        let mean = p_sum / n;
        let converged = (mean - prev_mean).abs() <= 1e-6 * mean;
        prev_mean = mean;
        if converged || cycles >= 200 {
            let vd = engine.displacement();
            let rho = params.ambient.p / (r * params.ambient.t);
            return Ok(MotoredCycle {
                p_max_pa: p_max,
                theta_p_max_deg: th_max,
                imep_pa: work / vd,
                pmep_pa: -pump / vd,
                trapped_mass_kg: trapped,
                vol_eff: (x[6] - m_in0) / (rho * vd),
                p_int_mean_pa: mean,
                torque_mean_nm: MeanTorque {
                    indicated: t_ind / n,
                    reciprocating: -t_rec / n,
                    friction: fric,
                },
                cycles,
                p_cyl_pa: p_deg,
            });
        }
    }
}

/// A point of the dynamometer's torque–speed curve (the dq model's steady state).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DynoPoint {
    /// Shaft speed [rpm].
    pub speed_rpm: f64,
    /// Slip.
    pub slip: f64,
    /// Electromagnetic torque [N·m].
    pub torque_nm: f64,
    /// Stator current [A rms per phase].
    pub current_a_rms: f64,
    /// Power factor.
    pub power_factor: f64,
}

/// The machine's steady state at line voltage `v_ll` [V rms], frequency `f` [Hz] and the
/// given shaft speeds [rpm], from the dq model (power-invariant: `|v_dq| = V_LL`).
pub fn dyno_curve(
    params: &CellParams,
    v_ll: f64,
    f: f64,
    speeds_rpm: &[f64],
) -> Result<Vec<DynoPoint>, SimError> {
    if !(v_ll.is_finite() && v_ll > 0.0 && f.is_finite() && f > 0.0) {
        return Err(SimError::Invalid(format!(
            "voltage {v_ll} V, frequency {f} Hz: expected > 0"
        )));
    }
    // Inductances from the reactances at f_nom; the steady state at f.
    let m = Machine::new(&params.dyno);
    let n_sync = 60.0 * f / (params.dyno.poles / 2.0);
    speeds_rpm
        .iter()
        .map(|&n| {
            let slip = (n_sync - n) / n_sync;
            let l = m.dq_steady_state(v_ll, f, slip);
            let i = m.currents(&l);
            let i_mag = (i[0] * i[0] + i[1] * i[1]).sqrt();
            // Power-invariant: |i_dq| = √3·I_rms; v along d: cos φ = i_sd/|i_dq|.
            Ok(DynoPoint {
                speed_rpm: n,
                slip,
                torque_nm: m.torque(&l),
                current_a_rms: i_mag / 3f64.sqrt(),
                power_factor: i[0] / i_mag,
            })
        })
        .collect()
}
