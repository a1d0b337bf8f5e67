//! Running a scenario: the cell stepped one crank increment at a time with the scenario's
//! demand, throttle and faults, and the acquisition as it goes — each output grid point carried
//! from the two steps around it, then measured by its sensor (SPEC §2.7) — into a
//! [`Recording`] with the DESIGN.md channel names. Only the output is kept: a run's memory is
//! its recording's.
//!
//! Sensors act on the output samples: `y = gain·lag(x) + offset + noise`, quantised; the
//! encoders count `floor(θ/q)` pulses (a lost-pulse fault drops pulses at random, for good);
//! the TDC marker is 1 on the first sample of each engine revolution (θ_en passing a multiple
//! of 2π from firing TDC). The true torque components and the cylinder temperature come along
//! as `true_*` channels, the parameters and faults in the metadata: the ground truth that
//! identification results are checked against.

use crate::cell::{Inputs, Sample, TestCell};
use crate::control::{inverse_park, Demand};
use crate::numeric::{expm1, floor, round, wrap720, SinCosTrack};
use crate::params::{CellParams, SensorParams};
use crate::scenario::{Fault, Scenario};
use physid_core::{Basis, Channel, Recording};
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;
use rand_xoshiro::Xoshiro256PlusPlus;
use std::f64::consts::{PI, TAU};
use thiserror::Error;
use Between::{Hold, Linear};

/// Errors of a run.
#[derive(Debug, Error, PartialEq)]
pub enum SimError {
    /// A bad parameter, scenario or fault, explained.
    #[error("{0}")]
    Invalid(String),
    /// The solution left the physical domain (a volume emptied, a temperature went
    /// negative): the step, time and what.
    #[error("the simulation diverged at t = {t:.6} s: {what}; try a smaller solver.step_deg")]
    Diverged {
        /// Time [s].
        t: f64,
        /// What went wrong.
        what: String,
    },
}

/// The output basis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum OutputBasis {
    /// Uniform time steps at this rate [Hz].
    Time(f64),
    /// One sample per this many crank degrees from the first firing TDC.
    Crank(f64),
}

/// How to run.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// Base parameters. The scenario's own `set` is applied over them: to override one of a
    /// scenario's settings, put it in the scenario's `set` (as `physid simulate --set` does).
    pub params: CellParams,
    /// Recorded duration [s] (the scenario's if `None`).
    pub duration: Option<f64>,
    /// Extra faults (`--fault`).
    pub faults: Vec<Fault>,
    /// Output basis.
    pub basis: OutputBasis,
}

impl Default for RunOptions {
    fn default() -> Self {
        Self {
            params: CellParams::default(),
            duration: None,
            faults: Vec::new(),
            basis: OutputBasis::Time(10_000.0),
        }
    }
}

/// The truth the cell gives at each solver step, in the order of a [`raw_row`] (each is
/// recorded under its name, [`OUTPUT`]).
const RAW: [&str; 30] = [
    "t",
    "theta_en",
    "theta_dy",
    "omega_en",
    "omega_dy",
    "alpha_en",
    "alpha_dy",
    "torque_shaft",
    "torque_engine",
    "torque_dy",
    "p_cyl",
    "p_int",
    "p_exh",
    "T_int",
    "T_exh",
    "T_oil",
    "throttle",
    "speed_demand",
    "i_a",
    "i_b",
    "i_c",
    "v_a",
    "v_b",
    "v_c",
    "true_torque_indicated",
    "true_torque_reciprocating",
    "true_torque_friction",
    "true_T_cyl",
    "true_shaft_k",
    "true_shaft_b",
];

/// The columns the acquisition reads itself: time and the two angles.
const T: usize = 0;
const THETA_EN: usize = 1;
const THETA_DY: usize = 2;

/// One row of truth, [`RAW`]'s columns.
type Row = [f64; RAW.len()];

/// The position of `name` in [`RAW`] (the names are this module's own: an unknown one is a
/// bug, caught by every run in the tests).
fn raw_index(name: &str) -> usize {
    let i = RAW.iter().position(|&c| c == name);
    debug_assert!(i.is_some(), "no raw column {name}");
    i.unwrap_or(0)
}

/// The truth of sample `s`, the cell running with `p`; `sc` is `(sin, cos)` of the machine
/// frame's angle.
fn raw_row(s: &Sample, p: &CellParams, sc: (f64, f64)) -> Row {
    let i = inverse_park(s.i_dq, sc);
    let v = inverse_park(s.v_dq, sc);
    [
        s.t,
        s.theta_en,
        s.theta_dy,
        s.omega_en,
        s.omega_dy,
        s.alpha_en,
        s.alpha_dy,
        s.torque_shaft,
        s.torque_engine,
        s.torque_dy,
        s.gas.p[1],
        s.gas.p[0],
        s.gas.p[2],
        s.temperatures[0],
        s.temperatures[2],
        p.engine.t_oil,
        s.throttle_deg,
        s.demand,
        i[0],
        i[1],
        i[2],
        v[0],
        v[1],
        v[2],
        s.torque_indicated,
        s.torque_reciprocating,
        s.torque_friction,
        s.temperatures[1],
        p.shaft.k,
        p.shaft.b,
    ]
}

/// How a raw column is carried from the solver's steps to the output grid.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Between {
    /// Linear interpolation (the states and what follows from them).
    Linear,
    /// The value of the step that contains the point: for what the cell holds over a step
    /// (the throttle, the demand, the parameters a fault changes), so that a stepped input or
    /// fault never shows a value between its two levels. A point within 1 % of a step's length
    /// before the next step counts as on it (the crank-angle grid's steps land within 0.1 %).
    Hold,
}

impl Between {
    /// The value at fraction `f` ∈ [0, 1] of the way from `y0` to `y1`.
    fn carry(self, y0: f64, y1: f64, f: f64) -> f64 {
        match self {
            Between::Linear => y0 + f * (y1 - y0),
            Between::Hold if f >= 0.99 => y1,
            Between::Hold => y0,
        }
    }
}

/// Which sensor measures a channel (SPEC §2.7).
#[derive(Debug, Clone, Copy, PartialEq)]
enum SensorKind {
    Speed,
    TorqueShaft,
    TorqueEngine,
    PCyl,
    PManifold,
    Temperature,
}

impl SensorKind {
    /// This kind's parameters in `p`.
    fn params(self, p: &CellParams) -> SensorParams {
        let s = &p.sensors;
        match self {
            SensorKind::Speed => s.speed,
            SensorKind::TorqueShaft => s.torque_shaft,
            SensorKind::TorqueEngine => s.torque_engine,
            SensorKind::PCyl => s.p_cyl,
            SensorKind::PManifold => s.p_manifold,
            SensorKind::Temperature => s.temperature,
        }
    }
}

/// Where an output channel's values come from.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Source {
    /// The raw column of the channel's name carried to the grid, measured by a sensor if one
    /// is named.
    Raw(Between, Option<SensorKind>),
    /// The sample's time: the grid itself on a time basis, the interpolated time on a crank
    /// basis.
    Time,
    /// Crank basis: the angle from the first firing TDC [rad], the cycle number, the angle
    /// in the cycle [deg].
    Theta,
    Cycle,
    CrankDeg,
    /// The ambient pressure (crankcase and atmosphere).
    Ambient,
    /// Encoder counts `floor(θ/q)`, the engine's less the pulses lost; the TDC marker.
    CountEn,
    CountDy,
    Tdc,
}

/// The recording's channels, in order, with their units (DESIGN.md); the crank-basis ones
/// only there.
const OUTPUT: [(&str, &str, Source); 38] = [
    ("t", "s", Source::Time),
    ("theta", "rad", Source::Theta),
    ("cycle", "-", Source::Cycle),
    ("crank_deg", "deg", Source::CrankDeg),
    ("theta_en", "rad", Source::Raw(Linear, None)),
    ("theta_dy", "rad", Source::Raw(Linear, None)),
    (
        "omega_en",
        "rad/s",
        Source::Raw(Linear, Some(SensorKind::Speed)),
    ),
    (
        "omega_dy",
        "rad/s",
        Source::Raw(Linear, Some(SensorKind::Speed)),
    ),
    ("alpha_en", "rad/s^2", Source::Raw(Linear, None)),
    ("alpha_dy", "rad/s^2", Source::Raw(Linear, None)),
    (
        "torque_shaft",
        "N*m",
        Source::Raw(Linear, Some(SensorKind::TorqueShaft)),
    ),
    (
        "torque_engine",
        "N*m",
        Source::Raw(Linear, Some(SensorKind::TorqueEngine)),
    ),
    ("torque_dy", "N*m", Source::Raw(Linear, None)),
    ("p_cyl", "Pa", Source::Raw(Linear, Some(SensorKind::PCyl))),
    (
        "p_int",
        "Pa",
        Source::Raw(Linear, Some(SensorKind::PManifold)),
    ),
    (
        "p_exh",
        "Pa",
        Source::Raw(Linear, Some(SensorKind::PManifold)),
    ),
    ("p_crank", "Pa", Source::Ambient),
    ("p_atm", "Pa", Source::Ambient),
    (
        "T_oil",
        "K",
        Source::Raw(Hold, Some(SensorKind::Temperature)),
    ),
    (
        "T_int",
        "K",
        Source::Raw(Linear, Some(SensorKind::Temperature)),
    ),
    (
        "T_exh",
        "K",
        Source::Raw(Linear, Some(SensorKind::Temperature)),
    ),
    ("throttle", "deg", Source::Raw(Hold, None)),
    ("speed_demand", "rad/s", Source::Raw(Hold, None)),
    ("i_a", "A", Source::Raw(Linear, None)),
    ("i_b", "A", Source::Raw(Linear, None)),
    ("i_c", "A", Source::Raw(Linear, None)),
    ("v_a", "V", Source::Raw(Linear, None)),
    ("v_b", "V", Source::Raw(Linear, None)),
    ("v_c", "V", Source::Raw(Linear, None)),
    ("count_en", "-", Source::CountEn),
    ("count_dy", "-", Source::CountDy),
    ("tdc", "-", Source::Tdc),
    // The true torques and T_cyl are states'; the shaft's parameters are held over a step.
    ("true_torque_indicated", "N*m", Source::Raw(Linear, None)),
    (
        "true_torque_reciprocating",
        "N*m",
        Source::Raw(Linear, None),
    ),
    ("true_torque_friction", "N*m", Source::Raw(Linear, None)),
    ("true_T_cyl", "K", Source::Raw(Linear, None)),
    ("true_shaft_k", "N*m/rad", Source::Raw(Hold, None)),
    ("true_shaft_b", "N*m*s/rad", Source::Raw(Hold, None)),
];

/// A first-order sensor's state over the output samples, with its own noise stream (so that
/// one sensor's settings never change another's noise).
struct SensorState {
    lagged: Option<f64>,
    rng: Xoshiro256PlusPlus,
}

impl SensorState {
    /// Stream `stream` of `seed`: xoshiro256++ seeded through SplitMix64 from `seed` and the
    /// stream number spread by the golden ratio (so that neighbouring streams and seeds start
    /// far apart in the generator's 2²⁵⁶ − 1 period).
    fn new(seed: u64, stream: u64) -> Self {
        let rng =
            Xoshiro256PlusPlus::seed_from_u64(seed ^ stream.wrapping_mul(0x9e37_79b9_7f4a_7c15));
        Self { lagged: None, rng }
    }

    /// Measure consecutive samples `x` in place, all with the sensor's parameters `s`:
    /// `y = gain·lag(x) + offset + noise`, quantised. `decay[k]` is the lag's
    /// [`Prepared::decay`] over the time since the sample before `x[k]`. Each step of the
    /// measurement is one pass over the samples (no choice made per sample).
    fn measure(&mut self, s: &Prepared, x: &mut [f64], decay: &[f64]) {
        if s.inv_lag > 0.0 {
            // The exact discretisation of τ·l' = x − l with x held over dt:
            // l ← l + (x − l)·(1 − e^(−dt/τ)).
            for (xi, &a) in x.iter_mut().zip(decay) {
                if let Some(prev) = self.lagged {
                    *xi = prev + (*xi - prev) * a;
                }
                self.lagged = Some(*xi);
            }
        } else if let Some(&last) = x.last() {
            self.lagged = Some(last);
        }
        if (s.p.gain, s.p.offset) != (1.0, 0.0) {
            for xi in x.iter_mut() {
                *xi = s.p.gain * *xi + s.p.offset;
            }
        }
        if s.p.noise > 0.0 {
            for xi in x.iter_mut() {
                *xi += s.p.noise * self.rng.sample::<f64, _>(StandardNormal);
            }
        }
        if s.p.quantum > 0.0 {
            for xi in x.iter_mut() {
                *xi = round(*xi * s.inv_quantum) * s.p.quantum;
            }
        }
    }

    /// One sample `x`, `dt` [s] after the one before.
    fn measure_one(&mut self, s: &Prepared, x: f64, dt: f64) -> f64 {
        let mut y = [x];
        self.measure(s, &mut y, &[s.decay(dt)]);
        y[0]
    }
}

/// A sensor's parameters with the reciprocals of its lag and quantum (0 where it has none).
#[derive(Debug, Clone, Copy)]
struct Prepared {
    p: SensorParams,
    inv_lag: f64,
    inv_quantum: f64,
}

impl From<SensorParams> for Prepared {
    fn from(p: SensorParams) -> Self {
        let inv = |x: f64| if x > 0.0 { 1.0 / x } else { 0.0 };
        Self {
            p,
            inv_lag: inv(p.lag),
            inv_quantum: inv(p.quantum),
        }
    }
}

impl Prepared {
    /// The lag's `1 − e^(−dt/τ)` over `dt` [s] (by `expm1`: no cancellation); 0 without a lag.
    fn decay(&self, dt: f64) -> f64 {
        if self.inv_lag > 0.0 {
            -expm1(-dt * self.inv_lag)
        } else {
            0.0
        }
    }
}

/// An output channel being filled.
struct Output {
    name: &'static str,
    unit: &'static str,
    source: Source,
    /// The raw column of a `Source::Raw`.
    col: usize,
    /// Its sensor's kind and state.
    sensor: Option<(SensorKind, SensorState)>,
    values: Vec<f64>,
}

/// Steps buffered before their samples are taken (≈ 60 kB of truth: the chunk stays in cache
/// while each channel is taken from it in turn).
const CHUNK: usize = 256;

/// A column's length in the chunk: [`CHUNK`] padded by a cache line, so that the columns are
/// not a power of two apart (a step's 30 values would otherwise fall in the same few sets of
/// the cache and evict each other).
const COLUMN: usize = CHUNK + 8;

/// A chunk's output grid points: for each, the step `j` it follows, its fraction `f` of the
/// way to step `j + 1`, its abscissa `g` (time or engine angle).
#[derive(Default)]
struct Points {
    j: Vec<usize>,
    f: Vec<f64>,
    g: Vec<f64>,
}

impl Points {
    fn push(&mut self, j: usize, f: f64, g: f64) {
        self.j.push(j);
        self.f.push(f);
        self.g.push(g);
    }

    fn clear(&mut self) {
        self.j.clear();
        self.f.clear();
        self.g.clear();
    }

    /// Raw column `col` (its values at the chunk's steps) carried to the points, appended to
    /// `out`.
    fn carry_into(&self, col: &[f64; COLUMN], how: Between, out: &mut Vec<f64>) {
        // A point follows one of the chunk's steps but its last: `j ≤ COLUMN − 2` said to the
        // compiler (no bounds checks in the loop).
        let each = self.j.iter().map(|&j| j.min(COLUMN - 2)).zip(&self.f);
        // One loop for each way of carrying, so that the choice is not made per point.
        match how {
            Linear => out.extend(each.map(|(j, &f)| Linear.carry(col[j], col[j + 1], f))),
            Hold => out.extend(each.map(|(j, &f)| Hold.carry(col[j], col[j + 1], f))),
        }
    }
}

/// The acquisition (SPEC §2.7) as the cell steps: each output grid point between two
/// consecutive steps is carried from their truth ([`Between`]) and measured by its sensor. The
/// steps are taken in chunks of [`CHUNK`], channel by channel; nothing of the truth is kept
/// beyond the chunk.
struct Acquisition<'a> {
    base: &'a CellParams,
    faults: &'a [Fault],
    /// Whether a fault changes a sensor (its parameters are then those in force at each
    /// sample).
    sensor_faulted: bool,
    basis: OutputBasis,
    duration: f64,
    outputs: Vec<Output>,
    /// The chunk's truth, column by column (so that a channel is taken from contiguous
    /// memory): `cols[c][j]` is raw column `c` at the chunk's step `j`, step 0 being the
    /// previous chunk's last; the steps in it; its grid points.
    cols: Vec<[f64; COLUMN]>,
    steps: usize,
    points: Points,
    /// Rows seen.
    seen: usize,
    /// The next grid point's index, and the index past the last (time basis).
    k: u64,
    end: u64,
    /// Crank basis: the first firing TDC [rad], from the first row.
    first: f64,
    /// The last sample's time and engine angle.
    last: Option<(f64, f64)>,
    /// The engine encoder: its last ideal count, the pulses lost, its random stream.
    count_en: Option<f64>,
    lost: f64,
    pulses: Xoshiro256PlusPlus,
    /// A chunk's samples' time, engine angle and time since the sample before, and the lags'
    /// decays over them for each time constant (`1/τ`, decays): kept from chunk to chunk.
    t: Vec<f64>,
    theta_en: Vec<f64>,
    dt: Vec<f64>,
    decays: Vec<(f64, Vec<f64>)>,
}

impl<'a> Acquisition<'a> {
    /// For a run of `duration` [s] with `base` parameters and `faults`, at the starting speed
    /// `w0` [rad/s] (to size the channels).
    fn new(
        base: &'a CellParams,
        faults: &'a [Fault],
        basis: OutputBasis,
        duration: f64,
        w0: f64,
    ) -> Result<Self, SimError> {
        let expected = match basis {
            OutputBasis::Time(rate) if rate.is_finite() && rate > 0.0 => duration * rate,
            OutputBasis::Time(rate) => {
                return Err(SimError::Invalid(format!(
                    "output rate {rate} Hz: expected > 0"
                )))
            }
            OutputBasis::Crank(step) if step.is_finite() && step > 0.0 => {
                1.02 * duration * w0.max(1.0) / step.to_radians()
            }
            OutputBasis::Crank(step) => {
                return Err(SimError::Invalid(format!(
                    "crank step {step}°: expected > 0"
                )))
            }
        };
        // A hint (the channels grow beyond it if the engine speeds up), capped at 2²² samples.
        let capacity = expected.min(f64::from(1u32 << 22)) as usize + 2;
        let crank = matches!(basis, OutputBasis::Crank(_));
        // Each sensor its own random stream (one sensor's settings never change another's
        // noise); stream 0 is the encoder's.
        let seed = base.sensors.seed as u64 ^ 0x5e5e;
        // The stream is the channel's place in OUTPUT, the same on either basis.
        let outputs = OUTPUT
            .iter()
            .enumerate()
            .filter(|(_, (_, _, src))| {
                crank || !matches!(src, Source::Theta | Source::Cycle | Source::CrankDeg)
            })
            .map(|(stream, &(name, unit, source))| {
                let (col, sensor) = match source {
                    Source::Raw(_, sensor) => (raw_index(name), sensor),
                    _ => (0, None),
                };
                Output {
                    name,
                    unit,
                    source,
                    col,
                    sensor: sensor.map(|kind| (kind, SensorState::new(seed, stream as u64 + 1))),
                    values: Vec::with_capacity(capacity),
                }
            })
            .collect();
        Ok(Self {
            base,
            faults,
            sensor_faulted: faults.iter().any(|f| f.path.starts_with("sensors.")),
            basis,
            duration,
            outputs,
            cols: vec![[0.0; COLUMN]; RAW.len()],
            steps: 0,
            points: Points::default(),
            seen: 0,
            k: 0,
            end: u64::MAX,
            first: 0.0,
            last: None,
            count_en: None,
            lost: 0.0,
            pulses: SensorState::new(seed, 0).rng,
            t: Vec::with_capacity(4 * CHUNK),
            theta_en: Vec::with_capacity(4 * CHUNK),
            dt: Vec::with_capacity(4 * CHUNK),
            decays: Vec::new(),
        })
    }

    /// The next solver step's truth: the grid points up to it are placed, and taken when the
    /// chunk is full.
    fn accept(&mut self, row: &Row) -> Result<(), SimError> {
        self.seen += 1;
        if self.steps == 0 {
            // The grid starts at or after the first row: t = 0, or the first firing TDC.
            match self.basis {
                OutputBasis::Time(rate) => {
                    self.k = (row[T] * rate).ceil().max(0.0) as u64;
                    self.end = (self.duration * rate).floor() as u64 + 1;
                }
                OutputBasis::Crank(_) => {
                    self.first = (row[THETA_EN] / (4.0 * PI)).ceil() * 4.0 * PI
                }
            }
            self.put(row);
            return Ok(());
        }
        let j = self.steps - 1;
        let c = match self.basis {
            OutputBasis::Time(_) => T,
            OutputBasis::Crank(_) => THETA_EN,
        };
        let (x0, x1) = (self.cols[c][j], row[c]);
        if matches!(self.basis, OutputBasis::Crank(_)) && x1 <= x0 {
            return Err(SimError::Invalid(format!(
                "the engine stopped or turned back at t = {:.6} s: a crank-angle basis needs it \
                 turning forwards",
                row[T]
            )));
        }
        while self.k < self.end {
            let g = match self.basis {
                OutputBasis::Time(rate) => self.k as f64 / rate,
                OutputBasis::Crank(step) => self.first + self.k as f64 * step.to_radians(),
            };
            if g > x1 {
                break;
            }
            let f = if x1 > x0 {
                ((g - x0) / (x1 - x0)).clamp(0.0, 1.0)
            } else {
                0.0
            };
            self.points.push(j, f, g);
            self.k += 1;
        }
        self.put(row);
        if self.steps == CHUNK {
            self.take();
            // The chunk's last step starts the next.
            for col in &mut self.cols {
                col[0] = col[CHUNK - 1];
            }
            self.steps = 1;
        }
        Ok(())
    }

    /// Store a step's truth in the chunk.
    fn put(&mut self, row: &Row) {
        for (col, v) in self.cols.iter_mut().zip(row) {
            col[self.steps] = *v;
        }
        self.steps += 1;
    }

    /// Take the chunk's samples, channel by channel.
    fn take(&mut self) {
        let Self {
            base,
            faults,
            sensor_faulted,
            basis,
            outputs,
            cols,
            points,
            first,
            last,
            count_en,
            lost,
            pulses,
            t,
            theta_en,
            dt,
            decays,
            ..
        } = self;
        let (base, first) = (*base, *first);
        t.clear();
        match basis {
            OutputBasis::Time(_) => t.extend_from_slice(&points.g),
            OutputBasis::Crank(_) => points.carry_into(&cols[T], Linear, t),
        }
        theta_en.clear();
        points.carry_into(&cols[THETA_EN], Linear, theta_en);
        dt.clear();
        let mut before = last.map(|l| l.0);
        for &ti in t.iter() {
            dt.push(before.map_or(0.0, |b| ti - b));
            before = Some(ti);
        }
        decays.clear();
        // The sensors' parameters in force at each sample when a fault changes them.
        let faulted: Vec<CellParams> = if *sensor_faulted {
            t.iter()
                .map(|&ti| {
                    let mut p = base.clone();
                    Fault::apply_all(faults, base, &mut p, ti);
                    p
                })
                .collect()
        } else {
            Vec::new()
        };
        let params = |k: usize| faulted.get(k).unwrap_or(base);
        // The encoders' pulse angles [rad] (their resolutions are fixed for a run).
        let (pulse_en, pulse_dy) = (TAU / base.sensors.ppr_en, TAU / base.sensors.ppr_dy);
        let since_tdc = points.g.iter().map(move |g| g - first);
        for out in outputs.iter_mut() {
            let v = &mut out.values;
            let start = v.len();
            match (out.source, &mut out.sensor) {
                (Source::Raw(how, _), None) => points.carry_into(&cols[out.col], how, v),
                (Source::Raw(how, _), Some((kind, state))) => {
                    points.carry_into(&cols[out.col], how, v);
                    let x = &mut v[start..];
                    // In runs of samples with the same parameters (all of them without a
                    // sensor fault).
                    let mut a = 0;
                    while a < x.len() {
                        let s = Prepared::from(kind.params(params(a)));
                        let b = match sensor_faulted {
                            true => (a + 1..x.len())
                                .find(|&k| kind.params(params(k)) != s.p)
                                .unwrap_or(x.len()),
                            false => x.len(),
                        };
                        let decay = lag_decays(decays, &s, dt);
                        state.measure(&s, &mut x[a..b], &decay[a..b]);
                        a = b;
                    }
                }
                (Source::Time, _) => v.extend_from_slice(t),
                (Source::Theta, _) => v.extend(since_tdc.clone()),
                (Source::Cycle, _) => {
                    v.extend(since_tdc.clone().map(|a| (a / (4.0 * PI) + 1e-9).floor()))
                }
                (Source::CrankDeg, _) => v.extend(since_tdc.clone().map(|a| {
                    let d = wrap720(a.to_degrees());
                    if d > 720.0 - 1e-6 {
                        0.0
                    } else {
                        d
                    }
                })),
                (Source::Ambient, _) => v.extend(t.iter().map(|_| base.ambient.p)),
                (Source::CountEn, _) => {
                    for (k, &th) in theta_en.iter().enumerate() {
                        let s = &params(k).sensors;
                        let ideal = floor(th / pulse_en);
                        if let Some(before) = *count_en {
                            if s.lost_pulses_en > 0.0 {
                                for _ in 0..((ideal - before).max(0.0) as usize) {
                                    if pulses.random::<f64>() < s.lost_pulses_en {
                                        *lost += 1.0;
                                    }
                                }
                            }
                        }
                        *count_en = Some(ideal);
                        v.push(ideal - *lost);
                    }
                }
                (Source::CountDy, _) => {
                    points.carry_into(&cols[THETA_DY], Linear, v);
                    for th in &mut v[start..] {
                        *th = floor(*th / pulse_dy);
                    }
                }
                (Source::Tdc, _) => {
                    // The engine revolutions completed, sample by sample.
                    let mut before = last.map(|l| floor(l.1 / TAU));
                    for &th in theta_en.iter() {
                        let revolutions = floor(th / TAU);
                        v.push(match before {
                            Some(b) if revolutions > b => 1.0,
                            Some(_) => 0.0,
                            // The first sample is on firing TDC on a crank basis.
                            None => f64::from(u8::from(matches!(basis, OutputBasis::Crank(_)))),
                        });
                        before = Some(revolutions);
                    }
                }
            }
        }
        if let (Some(&tl), Some(&thl)) = (t.last(), theta_en.last()) {
            *last = Some((tl, thl));
        }
        points.clear();
    }
    /// The recording: the channels, the scenario, the faults and the parameters in the
    /// metadata.
    fn finish(mut self, scenario: &Scenario) -> Result<Recording, SimError> {
        if self.seen < 2 {
            return Err(SimError::Invalid(
                "the run produced fewer than 2 samples".into(),
            ));
        }
        self.take();
        let mut rec = Recording::new(match self.basis {
            OutputBasis::Time(_) => Basis::Time,
            OutputBasis::Crank(_) => Basis::CrankAngle,
        });
        for out in self.outputs {
            rec.push(Channel {
                name: out.name.into(),
                unit: out.unit.into(),
                values: out.values,
            })
            .map_err(|e| SimError::Invalid(e.to_string()))?;
        }
        rec.meta.insert("source".into(), "physid simulate".into());
        rec.meta.insert("scenario".into(), scenario.name.clone());
        rec.meta.insert(
            "faults".into(),
            self.faults
                .iter()
                .map(|f| format!("{}={}@{}+{}", f.path, f.value, f.at, f.ramp))
                .collect::<Vec<_>>()
                .join(" "),
        );
        for (path, _, _) in CellParams::TABLE {
            if let Some(v) = self.base.get(path) {
                rec.meta.insert(format!("param.{path}"), format!("{v}"));
            }
        }
        Ok(rec)
    }
}

/// The lag's decays over a chunk's samples, `dt` apart, for sensor `s`: computed once per chunk
/// for each time constant (the three temperature channels share theirs).
fn lag_decays<'d>(decays: &'d mut Vec<(f64, Vec<f64>)>, s: &Prepared, dt: &[f64]) -> &'d [f64] {
    let i = match decays.iter().position(|d| d.0 == s.inv_lag) {
        Some(i) => i,
        None => {
            decays.push((s.inv_lag, dt.iter().map(|&d| s.decay(d)).collect()));
            decays.len() - 1
        }
    };
    &decays[i].1
}

/// Run a scenario.
pub fn simulate(
    scenario: &Scenario,
    opts: &RunOptions,
    mut progress: impl FnMut(f64),
) -> Result<Recording, SimError> {
    scenario.validate().map_err(SimError::Invalid)?;
    let mut base = opts.params.clone();
    for (k, v) in &scenario.set {
        base.set(k, *v).map_err(SimError::Invalid)?;
    }
    base.validate().map_err(SimError::Invalid)?;
    let mut faults: Vec<Fault> = scenario
        .faults
        .iter()
        .map(|f| Fault::parse(f))
        .collect::<Result<_, _>>()
        .map_err(SimError::Invalid)?;
    faults.extend(opts.faults.iter().cloned());
    let duration = opts.duration.unwrap_or(scenario.duration);
    if !(duration.is_finite() && duration > 0.0) {
        return Err(SimError::Invalid(format!(
            "duration {duration}: expected > 0 s"
        )));
    }
    let torque_mode = scenario.torque_mode || base.dyno.torque_mode != 0.0;
    // The recording's size, known in advance: refused when it cannot fit (a typo such as
    // `duration = 1e6` would otherwise grow until the allocator aborts).
    let per_second = match opts.basis {
        OutputBasis::Time(rate) => rate,
        OutputBasis::Crank(step) => {
            // The fastest demanded speed over the run (1000 rpm when the demand is a torque).
            let rpm = if torque_mode {
                1000.0
            } else {
                (0..=1000)
                    .map(|k| scenario.speed.value(duration * f64::from(k) / 1000.0))
                    .fold(0.0, f64::max)
            };
            rpm / 60.0 * 360.0 / step
        }
    };
    physid_core::memory::check_fits(
        duration * per_second * OUTPUT.len() as f64 * 8.0,
        &if duration < 1e5 {
            format!("a recording of {duration} s")
        } else {
            format!("a recording of {duration:e} s")
        },
    )
    .map_err(|e| SimError::Invalid(format!("{e}: record less (duration)")))?;
    let demand_at = |t: f64| {
        let v = scenario.speed.value(t.max(0.0));
        if torque_mode {
            Demand::Torque(v)
        } else {
            Demand::Speed(v * PI / 30.0)
        }
    };
    let w0 = if torque_mode {
        1000.0 * PI / 30.0
    } else {
        scenario.speed.value(0.0) * PI / 30.0
    };
    // The cell starts at BDC before firing TDC so the first cycle begins with compression.
    let mut cell = TestCell::new(base.clone(), w0.max(1.0), -PI).map_err(SimError::Invalid)?;
    let settle = scenario.settle;
    let mut acquisition = Acquisition::new(&base, &faults, opts.basis, duration, w0)?;
    // The drive's own speed sensor, at every step (from the time of the one before).
    let mut speed_sensor = SensorState::new(base.sensors.seed as u64, 0);
    let mut measured_at = cell.time();
    // The machine frame's angle, for the phase currents and voltages.
    let mut frame = SinCosTrack::default();
    let mut last_report = -1.0;
    loop {
        let t_rel = cell.time() - settle;
        Fault::apply_all(&faults, &base, &mut cell.params, t_rel.max(0.0));
        cell.refresh_live_parameters();
        let inputs = Inputs {
            demand: demand_at(t_rel),
            throttle_deg: scenario.throttle.value(t_rel.max(0.0)),
        };
        let w_true = cell.state()[9];
        let ss = Prepared::from(cell.params.dyno.speed_sensor);
        let w_meas = speed_sensor.measure_one(&ss, w_true, cell.time() - measured_at);
        measured_at = cell.time();
        let mut s = cell.step_with(&inputs, w_meas);
        check(&s, base.engine.active != 0.0)?;
        // From the step that spans t = 0 on, so that the output grid starts at 0.
        if cell.time() - settle > 0.0 {
            s.t = t_rel;
            acquisition.accept(&raw_row(&s, &cell.params, frame.at(s.theta_syn)))?;
        }
        if t_rel - last_report >= duration / 100.0 {
            progress((t_rel / duration).clamp(0.0, 1.0));
            last_report = t_rel;
        }
        // One sample past the end, so that the output grid reaches it.
        if t_rel > duration {
            break;
        }
    }
    progress(1.0);
    acquisition.finish(scenario)
}

/// Catch a state that left the physical domain.
fn check(s: &Sample, engine_active: bool) -> Result<(), SimError> {
    let bad = |what: String| Err(SimError::Diverged { t: s.t, what });
    for (k, name) in ["intake", "cylinder", "exhaust"]
        .iter()
        .enumerate()
        .filter(|_| engine_active)
    {
        if !(s.gas.p[k].is_finite() && s.gas.p[k] > 0.0) {
            return bad(format!("{name} pressure {}", s.gas.p[k]));
        }
        if !(s.temperatures[k].is_finite() && s.temperatures[k] > 0.0) {
            return bad(format!("{name} temperature {}", s.temperatures[k]));
        }
    }
    if !s.omega_en.is_finite() || !s.omega_dy.is_finite() || !s.torque_dy.is_finite() {
        return bad("speeds or machine torque not finite".into());
    }
    Ok(())
}

/// The true value of a cell parameter at times `t`, from a simulated recording's metadata (its
/// `param.PATH` value and the faults on PATH); `None` for a recording that does not carry it
/// (measured data).
pub fn parameter_truth(rec: &Recording, path: &str, t: &[f64]) -> Option<Vec<f64>> {
    let v0: f64 = rec.meta.get(&format!("param.{path}"))?.parse().ok()?;
    let faults: Vec<Fault> = rec
        .meta
        .get("faults")
        .map(|s| {
            s.split_whitespace()
                .filter_map(|f| Fault::parse(f).ok())
                .filter(|f| f.path == path)
                .collect()
        })
        .unwrap_or_default();
    Some(
        t.iter()
            .map(|&ti| {
                // As `Fault::apply_all`: each fault moves from the base value; a later one on
                // the same path overrides an earlier one once it has started.
                faults.iter().fold(v0, |v, f| match f.progress(ti) {
                    x if x > 0.0 => v0 + (f.value - v0) * x,
                    _ => v,
                })
            })
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::scenario::named;

    /// Every raw column is recorded under its own name (the time through `Source::Time`,
    /// which reads it on a crank basis), and every channel taken from a raw column names one.
    #[test]
    fn every_raw_column_is_a_channel() {
        let raw: Vec<&str> = OUTPUT
            .iter()
            .filter(|c| matches!(c.2, Source::Raw(..) | Source::Time))
            .map(|c| c.0)
            .collect();
        let mut sorted = raw.clone();
        sorted.sort_unstable();
        let mut want = RAW.to_vec();
        want.sort_unstable();
        assert_eq!(sorted, want);
        assert_eq!(
            [RAW[T], RAW[THETA_EN], RAW[THETA_DY]],
            ["t", "theta_en", "theta_dy"]
        );
    }

    /// Linear between the steps; held at the containing step's value, a point within 1 % of
    /// a step before the next counting as on it.
    #[test]
    fn carried_linear_and_held() {
        for (f, lin, held) in [
            (0.0, 10.0, 10.0),
            (0.5, 15.0, 10.0),
            (0.985, 19.85, 10.0),
            (0.995, 19.95, 20.0),
            (1.0, 20.0, 20.0),
        ] {
            assert!((Linear.carry(10.0, 20.0, f) - lin).abs() < 1e-12, "{f}");
            assert_eq!(Hold.carry(10.0, 20.0, f), held, "{f}");
        }
    }

    /// The temperature sensors' first-order lag (τ = 0.5 s, noise off) against its closed
    /// form: a step of 300 → 400 K in T_int at 20 ms reads `400 − 100·e^(−(j+1)·dt/τ)` j samples
    /// after it, through several chunks; T_exh, constant and measured by the same kind of
    /// sensor, stays exactly where it is; the manifold pressure (no lag) reads the truth.
    #[test]
    fn the_lag_is_the_exact_first_order_response() {
        let mut base = CellParams::default();
        base.sensors.temperature.noise = 0.0;
        base.sensors.p_manifold.noise = 0.0;
        let tau = base.sensors.temperature.lag;
        assert_eq!(tau, 0.5);
        let scenario = named("shaft-steady").unwrap();
        let (t_int, t_exh, p_int) = (raw_index("T_int"), raw_index("T_exh"), raw_index("p_int"));
        let mut acq =
            Acquisition::new(&base, &[], OutputBasis::Time(10_000.0), 0.07, 100.0).unwrap();
        for k in 0..1500 {
            let t = k as f64 * 50e-6;
            let mut r = [0.0; RAW.len()];
            r[T] = t;
            r[THETA_EN] = 100.0 * t;
            r[t_int] = if k >= 400 { 400.0 } else { 300.0 };
            r[t_exh] = 500.0;
            r[p_int] = 1e5 + 1e6 * t;
            acq.accept(&r).unwrap();
        }
        let rec = acq.finish(&scenario).unwrap();
        let (t, y) = (rec.values("t").unwrap(), rec.values("T_int").unwrap());
        assert_eq!(y.len(), 701);
        for (m, (&tm, &ym)) in t.iter().zip(y).enumerate() {
            let want = if m < 200 {
                300.0
            } else {
                400.0 - 100.0 * (-((m - 199) as f64) * 1e-4 / tau).exp()
            };
            assert!((ym - want).abs() < 1e-9, "{tm}: {ym} against {want}");
        }
        assert!(rec.values("T_exh").unwrap().iter().all(|&v| v == 500.0));
        for (&tm, &pm) in t.iter().zip(rec.values("p_int").unwrap()) {
            assert!((pm - (1e5 + 1e6 * tm)).abs() < 1e-6, "{tm}");
        }
    }

    /// A manifold-pressure sensor with gain 1.01, offset 50 Pa, a 100 Pa quantum and no noise:
    /// every reading is a whole number of quanta within half a quantum of `1.01·p + 50`, and the
    /// quantisation error averages out over a ramp.
    #[test]
    fn gain_offset_and_quantum() {
        let mut base = CellParams::default();
        base.sensors.p_manifold = SensorParams {
            gain: 1.01,
            offset: 50.0,
            noise: 0.0,
            quantum: 100.0,
            lag: 0.0,
        };
        let scenario = named("shaft-steady").unwrap();
        let p_int = raw_index("p_int");
        let mut acq =
            Acquisition::new(&base, &[], OutputBasis::Time(10_000.0), 0.07, 100.0).unwrap();
        for k in 0..1500 {
            let t = k as f64 * 50e-6;
            let mut r = [0.0; RAW.len()];
            r[T] = t;
            r[p_int] = 1e5 + 3.7e5 * t;
            acq.accept(&r).unwrap();
        }
        let rec = acq.finish(&scenario).unwrap();
        let t = rec.values("t").unwrap();
        let mut error_sum = 0.0;
        for (&tm, &pm) in t.iter().zip(rec.values("p_int").unwrap()) {
            let ideal = 1.01 * (1e5 + 3.7e5 * tm) + 50.0;
            assert_eq!(pm, (pm / 100.0).round() * 100.0, "{tm}: {pm}");
            assert!((pm - ideal).abs() <= 50.0 + 1e-9, "{tm}: {pm} for {ideal}");
            error_sum += pm - ideal;
        }
        assert!((error_sum / t.len() as f64).abs() < 5.0, "{error_sum}");
    }

    /// Steps of 130 µs from −50 µs, sampled at 10 kHz from 0 to the duration (the steps going
    /// through several chunks): a column linear
    /// in time comes out on the line, a column held over each step at its step's value, the
    /// grid from 0 to the duration inclusive; on a crank basis, from the first firing TDC
    /// (the first multiple of 4π), with the TDC marker there, and an engine turning back is
    /// refused with the time.
    #[test]
    fn the_output_grid_between_the_steps() {
        let base = CellParams::default();
        let scenario = named("shaft-steady").unwrap();
        let (dq, thr) = (raw_index("torque_dy"), raw_index("throttle"));
        let row = |k: usize| {
            let t = -50e-6 + k as f64 * 130e-6;
            let mut r = [0.0; RAW.len()];
            r[0] = t;
            r[1] = 12.5 + 1000.0 * t;
            r[dq] = 3.0 + 2.0 * t;
            r[thr] = k as f64;
            r
        };
        // Across several chunks of steps.
        let mut acq =
            Acquisition::new(&base, &[], OutputBasis::Time(10_000.0), 0.07, 100.0).unwrap();
        for k in 0..3 * CHUNK {
            acq.accept(&row(k)).unwrap();
        }
        let rec = acq.finish(&scenario).unwrap();
        let t = rec.values("t").unwrap();
        assert_eq!(t.len(), 701);
        for (i, &ti) in t.iter().enumerate() {
            assert_eq!(ti, i as f64 / 10_000.0);
            assert!((rec.values("torque_dy").unwrap()[i] - (3.0 + 2.0 * ti)).abs() < 1e-14);
            // A point on a step's start (to round-off) counts as on that step.
            let step = ((ti + 50e-6) / 130e-6 + 1e-9).floor();
            assert_eq!(rec.values("throttle").unwrap()[i], step, "{ti}");
        }
        assert!(rec.values("theta").is_err());

        let mut acq = Acquisition::new(&base, &[], OutputBasis::Crank(1.0), 1.0, 100.0).unwrap();
        for k in 0..8 {
            acq.accept(&row(k)).unwrap();
        }
        let rec = acq.finish(&scenario).unwrap();
        let th = rec.values("theta_en").unwrap();
        let first = 4.0 * PI;
        assert!((th[0] - first).abs() < 1e-12 && (th[1] - first - 1f64.to_radians()).abs() < 1e-12);
        assert_eq!(rec.values("tdc").unwrap()[0], 1.0);
        let deg = rec.values("crank_deg").unwrap();
        assert!(deg[0] == 0.0 && (deg[1] - 1.0).abs() < 1e-12);
        let mut acq = Acquisition::new(&base, &[], OutputBasis::Crank(1.0), 1.0, 100.0).unwrap();
        acq.accept(&row(1)).unwrap();
        let e = acq.accept(&row(0)).unwrap_err().to_string();
        assert!(e.contains("turned back at t = -0.000050 s"), "{e}");
        // Too few steps, and a bad grid, are errors.
        let acq = Acquisition::new(&base, &[], OutputBasis::Time(10.0), 1.0, 100.0).unwrap();
        assert!(acq.finish(&scenario).is_err());
        for basis in [OutputBasis::Time(0.0), OutputBasis::Crank(f64::NAN)] {
            assert!(Acquisition::new(&base, &[], basis, 1.0, 100.0).is_err());
        }
    }
}
