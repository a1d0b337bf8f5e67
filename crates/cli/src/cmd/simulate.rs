//! `physid simulate`: the virtual test cell — scenario runs into recordings, and the
//! engineer's checks (compression, motored cycle, the dynamometer's torque–speed curve).

use crate::out::outln;
use crate::progress::Progress;
use miette::{miette, Result};
use physid_io::ChunkWriter;
use physid_sim::params::CellParams;
use physid_sim::run::{OutputBasis, Run, RunOptions};
use physid_sim::scenario::{Fault, Scenario, NAMED};
use physid_sim::studies::{compression, dyno_curve, motored_cycle};
use std::path::{Path, PathBuf};

/// Arguments of `physid simulate`.
#[derive(clap::Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct Args {
    #[command(subcommand)]
    study: Option<Study>,
    /// Scenario: a built-in name (see --list) or a TOML file.
    #[arg(long)]
    scenario: Option<String>,
    /// Recorded duration [s] (default: the scenario's).
    #[arg(long, value_name = "S", value_parser = super::range::positive, allow_negative_numbers = true)]
    duration: Option<f64>,
    /// Fault PATH=VALUE@T[+RAMP] (repeatable), e.g. --fault shaft.k=1200@5.
    #[arg(long = "fault", value_name = "SPEC")]
    faults: Vec<String>,
    #[command(flatten)]
    set: SetArgs,
    /// Output basis: time (uniform at --sample-rate) or crank (one sample per --step-deg).
    #[arg(long, default_value = "time")]
    basis: String,
    /// Output sample rate on a time basis [Hz].
    #[arg(long, value_name = "HZ", default_value_t = 10_000.0, value_parser = super::range::positive, allow_negative_numbers = true)]
    sample_rate: f64,
    /// Deprecated: --sample-rate.
    #[arg(long = "rate", hide = true, conflicts_with = "sample_rate", value_parser = super::range::positive, allow_negative_numbers = true)]
    rate_old: Option<f64>,
    /// Output crank-angle step on a crank basis [deg].
    #[arg(long, default_value_t = 1.0, value_parser = super::range::positive, allow_negative_numbers = true)]
    step_deg: f64,
    /// The recording to write (.parquet, .csv or .mf4 by the extension).
    #[arg(long, value_name = "FILE")]
    recording: Option<PathBuf>,
    /// Deprecated: --recording (--out names a report directory in every other verb).
    #[arg(long = "out", hide = true, conflicts_with = "recording")]
    out_old: Option<PathBuf>,
    /// List the built-in scenarios.
    #[arg(long)]
    list: bool,
    /// List every parameter of the virtual test cell with its value, unit and source (the
    /// paths --set takes).
    #[arg(long)]
    list_params: bool,
    /// Deprecated: --list-params (--params gives parameter values in every other verb).
    #[arg(long = "params", hide = true, conflicts_with = "list_params")]
    params_old: bool,
}

/// `--set PATH=VALUE`.
#[derive(clap::Args, Clone, Default)]
pub(crate) struct SetArgs {
    /// Set a parameter PATH=VALUE (repeatable), e.g. --set shaft.k=1340 (see --list-params).
    #[arg(long = "set", value_name = "PATH=VALUE")]
    set: Vec<String>,
}

impl SetArgs {
    /// The `PATH=VALUE` pairs, parsed.
    pub(crate) fn pairs(&self) -> Result<Vec<(String, f64)>> {
        self.set
            .iter()
            .map(|s| {
                let (k, v) = s.split_once('=').ok_or_else(|| {
                    miette!("--set {s}: expected PATH=VALUE, e.g. --set shaft.k=1340")
                })?;
                let v: f64 = v
                    .trim()
                    .parse()
                    .map_err(|_| miette!("--set {s}: '{v}' is not a number"))?;
                Ok((k.trim().to_string(), v))
            })
            .collect()
    }

    /// The default parameters with the `--set` values, checked.
    pub(crate) fn params(&self) -> Result<CellParams> {
        let mut p = CellParams::default();
        for (k, v) in self.pairs()? {
            p.set(&k, v).map_err(|e| miette!("--set: {e}"))?;
        }
        p.validate().map_err(|e| miette!("{e}"))?;
        Ok(p)
    }
}

#[derive(clap::Subcommand)]
enum Study {
    /// The dynamometer machine's steady torque, current and power factor over speed at fixed
    /// voltage and frequency.
    ///
    /// Example: physid simulate dyno-curve --json
    DynoCurve {
        /// Line-to-line voltage [V rms].
        #[arg(long, default_value_t = 400.0)]
        voltage: f64,
        /// Frequency [Hz].
        #[arg(long, default_value_t = 50.0)]
        freq: f64,
        /// Speeds [rpm] (default: 0 to synchronous in 50 steps).
        #[arg(long, value_delimiter = ',')]
        speeds: Vec<f64>,
        #[command(flatten)]
        set: SetArgs,
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
    /// One converged motored cycle at constant speed and throttle.
    ///
    /// Example: physid simulate motored-cycle --rpm 1000 --throttle 90 --json
    MotoredCycle {
        /// Engine speed [rpm].
        #[arg(long, default_value_t = 1000.0)]
        rpm: f64,
        /// Throttle opening above closed [deg] (90: wide open).
        #[arg(long, default_value_t = 90.0)]
        throttle: f64,
        #[command(flatten)]
        set: SetArgs,
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
    /// Closed cylinder from BDC with the valves shut: the compression check.
    ///
    /// Example: physid simulate compression --p-bdc 100000 --t-bdc 300 --rpm 1000 --json
    Compression {
        /// Pressure at BDC [Pa].
        #[arg(long, value_name = "PA", default_value_t = 100_000.0)]
        p_bdc: f64,
        /// Deprecated: --p-bdc (--p0 is the initial covariance in every other verb).
        #[arg(long = "p0", hide = true, conflicts_with = "p_bdc")]
        p0_old: Option<f64>,
        /// Temperature at BDC [K].
        #[arg(long, value_name = "K", default_value_t = 300.0)]
        t_bdc: f64,
        /// Deprecated: --t-bdc.
        #[arg(long = "t0", hide = true, conflicts_with = "t_bdc")]
        t0_old: Option<f64>,
        /// Engine speed [rpm].
        #[arg(long, default_value_t = 1000.0)]
        rpm: f64,
        /// Without wall heat transfer (adiabatic).
        #[arg(long)]
        no_heat_transfer: bool,
        #[command(flatten)]
        set: SetArgs,
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
}

/// Run `physid simulate`.
pub fn run(args: &Args) -> Result<()> {
    if let Some(study) = &args.study {
        return run_study(study);
    }
    if args.list {
        for (name, what) in NAMED {
            outln!("{name:<20} {what}");
        }
        return Ok(());
    }
    if args.list_params
        || super::renamed(args.params_old.then_some(()), "--params", "--list-params").is_some()
    {
        let p = args.set.params()?;
        outln!("{:<32} {:>14} {:<12} source", "parameter", "value", "unit");
        for (path, unit, source) in CellParams::TABLE {
            outln!(
                "{path:<32} {:>14} {unit:<12} {source}",
                p.get(path).map_or(String::new(), |v| format!("{v}"))
            );
        }
        return Ok(());
    }
    let name = args.scenario.as_deref().ok_or_else(|| {
        miette!("choose a scenario: --scenario NAME|FILE (physid simulate --list)")
    })?;
    let out = super::renamed(args.out_old.as_ref(), "--out FILE", "--recording FILE")
        .or(args.recording.as_ref())
        .ok_or_else(|| miette!("where to? --recording FILE.parquet|.csv|.mf4"))?;
    if physid_io::Format::from_extension(out).is_none() {
        return Err(miette!(
            "--recording {}: the extension picks the format: .parquet, .csv or .mf4",
            out.display()
        ));
    }
    let mut scenario = Scenario::load(name).map_err(|e| miette!("{e}"))?;
    // The command line's --set wins over the scenario's own settings (its `set`, applied over
    // the base parameters).
    scenario.set.extend(args.set.pairs()?);
    let faults: Vec<Fault> = args
        .faults
        .iter()
        .map(|f| Fault::parse(f))
        .collect::<std::result::Result<_, _>>()
        .map_err(|e| miette!("--fault {e}"))?;
    let recorded = args.duration.unwrap_or(scenario.duration);
    for (f, text) in faults.iter().zip(&args.faults) {
        if !(0.0..recorded).contains(&f.at) {
            return Err(miette!(
                "--fault {text}: at {} s, outside the recording (0 to {recorded} s): it would never happen",
                f.at
            ));
        }
    }
    let basis = match args.basis.as_str() {
        "time" => OutputBasis::Time(
            super::renamed(args.rate_old, "--rate", "--sample-rate").unwrap_or(args.sample_rate),
        ),
        "crank" => OutputBasis::Crank(args.step_deg),
        b => return Err(miette!("--basis '{b}': expected time or crank")),
    };
    // The run as a stream, each second of recording written as it comes: memory stays flat
    // however long the recording (the file is the one the whole recording would give).
    let opts = RunOptions {
        params: args.set.params()?,
        duration: args.duration,
        faults,
        basis,
        stream: true,
    };
    let mut bar = Progress::new(&format!("simulating {}", scenario.name), Some(100));
    let t0 = std::time::Instant::now();
    let written = write_as_it_goes(&scenario, &opts, out, |f| bar.set((f * 100.0) as u64));
    drop(bar);
    let (channels, samples) = match written {
        Ok(Some(n)) => n,
        Ok(None) => {
            let why = match basis {
                OutputBasis::Crank(_) => " (a crank-angle recording starts at the engine's first TDC after the settling time; an engine cycle at 1000 rpm lasts 0.12 s)",
                OutputBasis::Time(_) => "",
            };
            return Err(miette!(
                "--duration {recorded}: the recording would hold no sample{why}: record longer"
            ));
        }
        Err(e) => return Err(e),
    };
    let seconds = t0.elapsed().as_secs_f64();
    let simulated = opts.duration.unwrap_or(scenario.duration) + scenario.settle;
    outln!(
        "wrote {} ({} channels × {} samples; {:.1} s simulated in {:.2} s, {:.0}× real time)",
        out.display(),
        channels,
        samples,
        simulated,
        seconds,
        simulated / seconds
    );
    Ok(())
}

/// Run `scenario` as a stream and write its recording to `out` as it comes (one second of
/// recording at a time); `progress` gets the fraction done. The number of channels and samples
/// written, `None` (and no file) when the recording holds fewer than two samples; on an error
/// the partial file is removed — but for a write the disk refused, which leaves it readable
/// with what reached the disk, and says so.
fn write_as_it_goes(
    scenario: &Scenario,
    opts: &RunOptions,
    out: &Path,
    mut progress: impl FnMut(f64),
) -> Result<Option<(usize, usize)>> {
    let mut writer: Option<ChunkWriter> = None;
    let (mut rows, mut channels) = (0, 0);
    // SIGINT or SIGTERM: the file written so far is closed (readable) and kept.
    let stop = super::stop_on_signal()?;
    let mut interrupted = false;
    let mut salvaged = false;
    let result = (|| -> Result<()> {
        let mut run = Run::new(scenario, opts).map_err(|e| miette!("{e}"))?;
        // Refused when even its uncompressed float64 size cannot fit on the disk.
        let dir = match out.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        physid_core::memory::check_disk(run.size_bytes(), dir, "the recording")
            .map_err(|e| miette!("--out {}: {e}: record less (--duration)", out.display()))?;
        let duration = run.duration();
        let mut t = 0.0;
        while !run.is_done() {
            if stop.load(std::sync::atomic::Ordering::Relaxed) {
                interrupted = true;
                break;
            }
            t += 1.0;
            run.step_until(t).map_err(|e| miette!("{e}"))?;
            let mut chunk = run.drain().map_err(|e| miette!("{e}"))?;
            if !chunk.is_empty() {
                if writer.is_none() {
                    run.describe(&mut chunk);
                    channels = chunk.channels().len();
                    writer = Some(
                        ChunkWriter::create(out, &chunk, &Default::default())
                            .map_err(|e| miette!("{e}"))?,
                    );
                }
                if let Some(w) = writer.as_mut() {
                    w.append(&chunk).map_err(|e| {
                        salvaged = matches!(e, physid_io::IoError::WriteFailed { .. });
                        miette!("{e}")
                    })?;
                }
                rows += chunk.len();
            }
            progress((run.time() / duration).clamp(0.0, 1.0));
        }
        Ok(())
    })();
    match (result, writer) {
        (Ok(()), Some(w)) if interrupted => {
            w.close().map_err(|e| miette!("{e}"))?;
            Err(miette!(
                "interrupted by a signal: {} holds the first {rows} samples of {channels} \
                 channels, closed and readable",
                out.display()
            ))
        }
        (Ok(()), Some(w)) if rows >= 2 => {
            w.close().map_err(|e| miette!("{e}"))?;
            Ok(Some((channels, rows)))
        }
        (Ok(()), w) => {
            if let Some(w) = w {
                w.discard();
            }
            Ok(None)
        }
        (Err(e), w) => {
            // Only a file it created (a refused creation leaves a file of that name alone).
            if let (false, Some(w)) = (salvaged, w) {
                w.discard();
            }
            Err(e)
        }
    }
}

fn run_study(study: &Study) -> Result<()> {
    match study {
        Study::DynoCurve {
            voltage,
            freq,
            speeds,
            set,
            json,
        } => {
            let p = set.params()?;
            let n_sync = 60.0 * freq / (p.dyno.poles / 2.0);
            let speeds: Vec<f64> = if speeds.is_empty() {
                (0..=50).map(|k| n_sync * k as f64 / 50.0).collect()
            } else {
                speeds.clone()
            };
            let pts = dyno_curve(&p, *voltage, *freq, &speeds).map_err(|e| miette!("{e}"))?;
            if *json {
                let v = serde_json::json!({ "points": pts });
                crate::provenance::print_json_value(v)?;
            } else {
                outln!("dynamometer at {voltage} V, {freq} Hz (synchronous {n_sync:.0} rpm)");
                outln!(
                    "{:>10} {:>9} {:>11} {:>12} {:>8}",
                    "speed rpm",
                    "slip",
                    "torque N·m",
                    "current A",
                    "cos φ"
                );
                for q in &pts {
                    outln!(
                        "{:>10.1} {:>9.4} {:>11.2} {:>12.2} {:>8.3}",
                        q.speed_rpm,
                        q.slip,
                        q.torque_nm,
                        q.current_a_rms,
                        q.power_factor
                    );
                }
            }
        }
        Study::MotoredCycle {
            rpm,
            throttle,
            set,
            json,
        } => {
            let p = set.params()?;
            let c = motored_cycle(&p, *rpm, *throttle).map_err(|e| miette!("{e}"))?;
            if *json {
                crate::provenance::print_json(&c)?;
            } else {
                outln!(
                    "motored cycle at {rpm} rpm, throttle {throttle}° ({} cycles to converge)",
                    c.cycles
                );
                outln!(
                    "  peak cylinder pressure   {:>10.3} bar at {:.1}° after firing TDC",
                    c.p_max_pa / 1e5,
                    c.theta_p_max_deg
                );
                outln!("  IMEP (net)               {:>10.2} kPa", c.imep_pa / 1e3);
                outln!("  PMEP                     {:>10.2} kPa", c.pmep_pa / 1e3);
                outln!(
                    "  manifold pressure        {:>10.2} kPa",
                    c.p_int_mean_pa / 1e3
                );
                outln!(
                    "  trapped mass             {:>10.4} g",
                    c.trapped_mass_kg * 1e3
                );
                outln!("  volumetric efficiency    {:>10.3}", c.vol_eff);
                outln!(
                    "  mean torque [N·m]: indicated {:.3}, reciprocating {:.2e}, friction {:.3}",
                    c.torque_mean_nm.indicated,
                    c.torque_mean_nm.reciprocating,
                    c.torque_mean_nm.friction
                );
            }
        }
        Study::Compression {
            p_bdc,
            p0_old,
            t_bdc,
            t0_old,
            rpm,
            no_heat_transfer,
            set,
            json,
        } => {
            let p0 = &super::renamed(*p0_old, "--p0", "--p-bdc").unwrap_or(*p_bdc);
            let t0 = &super::renamed(*t0_old, "--t0", "--t-bdc").unwrap_or(*t_bdc);
            let p = set.params()?;
            let c =
                compression(&p, *p0, *t0, *rpm, !no_heat_transfer).map_err(|e| miette!("{e}"))?;
            if *json {
                crate::provenance::print_json(&c)?;
            } else {
                outln!(
                    "closed cylinder from BDC at {p0} Pa, {t0} K, {rpm} rpm{}:",
                    if *no_heat_transfer { ", adiabatic" } else { "" }
                );
                outln!(
                    "  peak pressure {:.4} bar at {:.2}°, peak temperature {:.2} K",
                    c.p_max_pa / 1e5,
                    c.theta_p_max_deg,
                    c.t_max_k
                );
                outln!(
                    "  back at BDC: {:.6} bar, {:.4} K",
                    c.p_end_pa / 1e5,
                    c.t_end_k
                );
            }
        }
    }
    Ok(())
}
