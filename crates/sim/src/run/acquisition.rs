//! The acquisition (SPEC §2.7) as the cell steps: the output grid placed between the solver's
//! steps, each channel carried to it and measured by its sensor, chunk by chunk; the encoders'
//! counts and the TDC marker; the recording and its metadata at the end.

use super::channels::{raw_index, Between, Row, Source, OUTPUT, RAW, T, THETA_DY, THETA_EN};
use super::dense::Cylinder;
use super::sensors::{Prepared, SensorKind, SensorState};
use super::{OutputBasis, SimError};
use crate::numeric::{floor, wrap720};
use crate::params::CellParams;
use crate::scenario::{Fault, Scenario};
use physid_core::{Basis, Channel, Recording};
use rand::Rng;
use rand_xoshiro::Xoshiro256PlusPlus;
use std::f64::consts::{PI, TAU};
use Between::{Hold, Linear};

/// An output channel being filled.
#[derive(Clone)]
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
/// not a power of two apart (a step's 33 values would otherwise fall in the same few sets of
/// the cache and evict each other).
pub(super) const COLUMN: usize = CHUNK + 8;

/// A chunk's output grid points: for each, the step `j` it follows, its fraction `f` of the
/// way to step `j + 1`, its abscissa `g` (time or engine angle).
#[derive(Clone, Default)]
pub(super) struct Points {
    pub(super) j: Vec<usize>,
    pub(super) f: Vec<f64>,
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
            Linear | Between::Dense(_) => {
                out.extend(each.map(|(j, &f)| Linear.carry(col[j], col[j + 1], f)))
            }
            Hold => out.extend(each.map(|(j, &f)| Hold.carry(col[j], col[j + 1], f))),
        }
    }
}

/// The acquisition (SPEC §2.7) as the cell steps: each output grid point between two
/// consecutive steps is carried from their truth ([`Between`]) and measured by its sensor. The
/// steps are taken in chunks of [`CHUNK`], channel by channel; nothing of the truth is kept
/// beyond the chunk.
#[derive(Clone)]
pub(super) struct Acquisition {
    base: CellParams,
    faults: Vec<Fault>,
    /// Whether a fault changes a sensor (its parameters are then those in force at each
    /// sample).
    sensor_faulted: bool,
    basis: OutputBasis,
    duration: f64,
    outputs: Vec<Output>,
    /// The cylinder's dense output, while a channel acquired needs it.
    cylinder: Option<Cylinder>,
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
    decays: Decays,
}

/// A chunk's lag decays for each time constant: `(1/τ, decays)`, the first `used` of them this
/// chunk's — the others' storage kept for the next chunk (no allocation from chunk to chunk).
#[derive(Clone, Default)]
struct Decays {
    entries: Vec<(f64, Vec<f64>)>,
    used: usize,
}

impl Decays {
    /// A new chunk: none computed yet.
    fn clear(&mut self) {
        self.used = 0;
    }

    /// The lag's decays over the chunk's samples, `dt` apart, for sensor `s`: computed once
    /// per chunk for each time constant.
    fn of(&mut self, s: &Prepared, dt: &[f64]) -> &[f64] {
        let i = match self.entries[..self.used]
            .iter()
            .position(|d| d.0 == s.inv_lag)
        {
            Some(i) => i,
            None => {
                if self.used == self.entries.len() {
                    self.entries.push((0.0, Vec::new()));
                }
                let (inv_lag, values) = &mut self.entries[self.used];
                *inv_lag = s.inv_lag;
                values.clear();
                values.extend(dt.iter().map(|&d| s.decay(d)));
                self.used += 1;
                self.used - 1
            }
        };
        &self.entries[i].1
    }
}

impl Acquisition {
    /// For a run of `duration` [s] with `base` parameters and `faults`, at the starting speed
    /// `w0` [rad/s] (to size the channels).
    pub(super) fn new(
        base: &CellParams,
        faults: &[Fault],
        basis: OutputBasis,
        duration: f64,
        w0: f64,
        stream: bool,
    ) -> Result<Self, SimError> {
        let expected = match basis {
            OutputBasis::Time(rate) if rate.is_finite() && rate > 0.0 => duration * rate,
            OutputBasis::Time(rate) => {
                return Err(SimError::Invalid(format!(
                    "output rate {} Hz: expected > 0",
                    physid_core::Num(rate)
                )))
            }
            OutputBasis::Crank(step) if step.is_finite() && step > 0.0 => {
                1.02 * duration * w0.max(1.0) / step.to_radians()
            }
            OutputBasis::Crank(step) => {
                return Err(SimError::Invalid(format!(
                    "crank step {}°: expected > 0",
                    physid_core::Num(step)
                )))
            }
        };
        // A hint (the channels grow beyond it if the engine speeds up), capped at 2²² samples;
        // a streaming run's samples are drained as it goes: little room.
        let capacity = if stream {
            4 * CHUNK
        } else {
            expected.min(f64::from(1u32 << 22)) as usize + 2
        };
        // Each sensor its own random stream (one sensor's settings never change another's
        // noise); stream 0 is the encoder's.
        let seed = base.sensors.seed as u64 ^ 0x5e5e;
        // The stream is the channel's place in OUTPUT, the same on either basis.
        let outputs = OUTPUT
            .iter()
            .enumerate()
            .filter(|(_, (_, _, src))| src.on(basis))
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
            base: base.clone(),
            faults: faults.to_vec(),
            sensor_faulted: faults.iter().any(|f| f.path.starts_with("sensors.")),
            basis,
            duration,
            outputs,
            cylinder: Some(Cylinder::new(base)),
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
            decays: Decays::default(),
        })
    }

    /// The next solver step's truth: the grid points up to it are placed, and taken when the
    /// chunk is full.
    pub(super) fn accept(&mut self, row: &Row) -> Result<(), SimError> {
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

    /// Acquire only the channels `names` (and the time): the others are neither carried nor
    /// measured. Each kept channel's values, noise included, are those of a run that acquires
    /// every channel (each sensor has its own random stream). Before the first step only.
    pub(super) fn keep(&mut self, names: &[&str]) -> Result<(), SimError> {
        if self.seen > 0 {
            return Err(SimError::Invalid(
                "the channels to acquire are chosen before the run starts".into(),
            ));
        }
        if let Some(bad) = names
            .iter()
            .find(|n| !self.outputs.iter().any(|o| o.name == **n))
        {
            let all: Vec<&str> = self.outputs.iter().map(|o| o.name).collect();
            return Err(SimError::Invalid(format!(
                "no channel '{bad}' on this basis: the channels are {}",
                all.join(", ")
            )));
        }
        self.outputs
            .retain(|o| o.name == "t" || names.contains(&o.name));
        if !self
            .outputs
            .iter()
            .any(|o| matches!(o.source, Source::Raw(Between::Dense(_), _)))
        {
            self.cylinder = None;
        }
        Ok(())
    }

    /// The samples taken so far, moved out (the channels keep their room).
    pub(super) fn drain(&mut self) -> Result<Recording, SimError> {
        self.take_placed();
        let mut rec = Recording::new(match self.basis {
            OutputBasis::Time(_) => Basis::Time,
            OutputBasis::Crank(_) => Basis::CrankAngle,
        });
        for out in &mut self.outputs {
            rec.push(Channel {
                name: out.name.into(),
                unit: out.unit.into(),
                values: out.values.drain(..).collect(),
            })
            .map_err(|e| SimError::Invalid(e.to_string()))?;
        }
        Ok(rec)
    }

    /// The samples acquired since the last call appended to `columns`, one per channel in
    /// the recording's order: [`drain`](Self::drain) without a recording around them (no
    /// allocation once the columns have grown).
    pub(super) fn drain_into(&mut self, columns: &mut [Vec<f64>]) {
        self.take_placed();
        for (out, col) in self.outputs.iter_mut().zip(columns) {
            col.append(&mut out.values);
        }
    }

    /// The grid points placed so far in the current chunk, taken now rather than when the
    /// chunk is full (taking the points in two goes is the same as in one).
    fn take_placed(&mut self) {
        if self.steps > 0 {
            self.take();
        }
    }

    /// A fault added during the run (the live cell's controls): its sensor changes are
    /// applied from now on and it is listed in the metadata.
    pub(super) fn add_fault(&mut self, fault: Fault) {
        self.sensor_faulted |= fault.path.starts_with("sensors.");
        self.faults.push(fault);
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
            cylinder,
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
        let (base, first) = (&*base, *first);
        t.clear();
        match basis {
            OutputBasis::Time(_) => t.extend_from_slice(&points.g),
            OutputBasis::Crank(_) => points.carry_into(&cols[T], Linear, t),
        }
        theta_en.clear();
        points.carry_into(&cols[THETA_EN], Linear, theta_en);
        if let Some(c) = cylinder.as_mut() {
            c.prepare(cols, points, theta_en);
        }
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
            let carry = |v: &mut Vec<f64>, how| match (how, &*cylinder) {
                (Between::Dense(d), Some(c)) => c.carry_into(d, &cols[out.col], points, v),
                _ => points.carry_into(&cols[out.col], how, v),
            };
            match (out.source, &mut out.sensor) {
                (Source::Raw(how, _), None) => carry(v, how),
                (Source::Raw(how, _), Some((kind, state))) => {
                    carry(v, how);
                    let sensor = |k: usize| kind.params(params(k));
                    measure_in_runs(state, &mut v[start..], sensor, *sensor_faulted, decays, dt);
                }
                (Source::Time, _) => v.extend_from_slice(t),
                (Source::Theta, _) => v.extend(since_tdc.clone()),
                (Source::Cycle, _) => {
                    v.extend(since_tdc.clone().map(|a| (a / (4.0 * PI) + 1e-9).floor()))
                }
                (Source::CrankDeg, _) => v.extend(since_tdc.clone().map(crank_deg)),
                (Source::Ambient, _) => v.extend(t.iter().map(|_| base.ambient.p)),
                (Source::CountEn, _) => {
                    for (k, &th) in theta_en.iter().enumerate() {
                        let lose = params(k).sensors.lost_pulses_en;
                        v.push(count_engine(th / pulse_en, lose, count_en, lost, pulses));
                    }
                }
                (Source::CountDy, _) => {
                    points.carry_into(&cols[THETA_DY], Linear, v);
                    for th in &mut v[start..] {
                        *th = floor(*th / pulse_dy);
                    }
                }
                (Source::Tdc, _) => {
                    let crank = matches!(basis, OutputBasis::Crank(_));
                    tdc_marker(theta_en, last.map(|l| l.1), crank, v);
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
    pub(super) fn finish(mut self, scenario: &Scenario) -> Result<Recording, SimError> {
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
        self.describe(&mut rec, scenario);
        for out in self.outputs {
            rec.push(Channel {
                name: out.name.into(),
                unit: out.unit.into(),
                values: out.values,
            })
            .map_err(|e| SimError::Invalid(e.to_string()))?;
        }
        Ok(rec)
    }

    /// The run in `rec`'s metadata: the source, the scenario, the faults so far and the
    /// parameters.
    pub(super) fn describe(&self, rec: &mut Recording, scenario: &Scenario) {
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
        // How the run started: its settling time and, on a torque demand (a scenario's sets the
        // switch as `dyno.torque_mode` does), the speed it settled from — what a replay of the
        // recording needs to start where it started (physid twin).
        rec.meta
            .insert("scenario.settle".into(), format!("{}", scenario.settle));
        if scenario.torque_mode || self.base.dyno.torque_mode != 0.0 {
            rec.meta.insert("param.dyno.torque_mode".into(), "1".into());
            rec.meta.insert(
                "scenario.start_rpm".into(),
                format!("{}", scenario.torque_start_rpm()),
            );
        }
    }
}

/// Measure `x` by a sensor whose parameters at sample `k` are `sensor(k)`: in runs of samples
/// with the same parameters (one run unless a fault changes the sensor, `faulted`).
fn measure_in_runs(
    state: &mut SensorState,
    x: &mut [f64],
    sensor: impl Fn(usize) -> crate::params::SensorParams,
    faulted: bool,
    decays: &mut Decays,
    dt: &[f64],
) {
    let mut a = 0;
    while a < x.len() {
        let s = Prepared::from(sensor(a));
        let b = match faulted {
            true => (a + 1..x.len())
                .find(|&k| sensor(k) != s.p)
                .unwrap_or(x.len()),
            false => x.len(),
        };
        let decay = decays.of(&s, dt);
        state.measure(&s, &mut x[a..b], &decay[a..b]);
        a = b;
    }
}

/// The angle in the cycle [deg] `a` [rad] after the first firing TDC, in [0, 720).
fn crank_deg(a: f64) -> f64 {
    let d = wrap720(a.to_degrees());
    if d > 720.0 - 1e-6 {
        0.0
    } else {
        d
    }
}

/// The engine encoder's count at `pulses_now` ideal pulses: `floor` of it, less the pulses lost
/// so far — each new pulse lost with probability `lose` (a fault), for good. `count` holds the
/// last ideal count, `lost` the pulses lost.
fn count_engine(
    pulses_now: f64,
    lose: f64,
    count: &mut Option<f64>,
    lost: &mut f64,
    rng: &mut Xoshiro256PlusPlus,
) -> f64 {
    let ideal = floor(pulses_now);
    if let Some(before) = *count {
        if lose > 0.0 {
            for _ in 0..((ideal - before).max(0.0) as usize) {
                if rng.random::<f64>() < lose {
                    *lost += 1.0;
                }
            }
        }
    }
    *count = Some(ideal);
    ideal - *lost
}

/// The TDC marker at engine angles `theta_en`: 1 on the first sample of each engine revolution
/// (`before` the angle of the sample before, if any; the first sample of a crank-basis run is
/// on firing TDC), else 0; appended to `out`.
fn tdc_marker(theta_en: &[f64], before: Option<f64>, crank: bool, out: &mut Vec<f64>) {
    let mut before = before.map(|th| floor(th / TAU));
    for &th in theta_en {
        let revolutions = floor(th / TAU);
        out.push(match before {
            Some(b) if revolutions > b => 1.0,
            Some(_) => 0.0,
            None => f64::from(u8::from(crank)),
        });
        before = Some(revolutions);
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::params::SensorParams;
    use crate::scenario::named;

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
            Acquisition::new(&base, &[], OutputBasis::Time(10_000.0), 0.07, 100.0, false).unwrap();
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
            Acquisition::new(&base, &[], OutputBasis::Time(10_000.0), 0.07, 100.0, false).unwrap();
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
            Acquisition::new(&base, &[], OutputBasis::Time(10_000.0), 0.07, 100.0, false).unwrap();
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

        let mut acq =
            Acquisition::new(&base, &[], OutputBasis::Crank(1.0), 1.0, 100.0, false).unwrap();
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
        let mut acq =
            Acquisition::new(&base, &[], OutputBasis::Crank(1.0), 1.0, 100.0, false).unwrap();
        acq.accept(&row(1)).unwrap();
        let e = acq.accept(&row(0)).unwrap_err().to_string();
        assert!(e.contains("turned back at t = -0.000050 s"), "{e}");
        // Too few steps, and a bad grid, are errors.
        let acq = Acquisition::new(&base, &[], OutputBasis::Time(10.0), 1.0, 100.0, false).unwrap();
        assert!(acq.finish(&scenario).is_err());
        for basis in [OutputBasis::Time(0.0), OutputBasis::Crank(f64::NAN)] {
            assert!(Acquisition::new(&base, &[], basis, 1.0, 100.0, false).is_err());
        }
    }
}
