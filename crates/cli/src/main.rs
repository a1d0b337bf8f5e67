//! `physid` — qualitative adaptive identification of powertrain parameters.
//!
//! Thin verbs over the library crates: argument parsing, tables, JSON, CSV and plots.

mod cmd;
mod out;
mod plot;
mod progress;
mod provenance;
mod report;
mod tracks;

use clap::{Parser, Subcommand};

/// physid: which physical parameters of a powertrain model your data can resolve, and their
/// values, tracked on-line.
#[derive(Parser)]
#[command(name = "physid", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// No progress display on stderr (it is shown only on a terminal, for work longer than a
    /// second).
    #[arg(long, global = true)]
    quiet: bool,
}

// Parsed once per run: the size of the largest variant does not matter.
#[allow(clippy::large_enum_variant)]
#[derive(Subcommand)]
enum Command {
    /// The whole chain on the built-in virtual test cell: simulate, monitor the shaft, rank
    /// and fit the friction model, identify and estimate the cyclic torque; one report.
    ///
    /// Example: physid demo --out demo
    Demo(cmd::demo::Args),
    /// Run a worked example from the thesis.
    ///
    /// Example: physid example 5.2 --out ex52
    Example(cmd::example::Args),
    /// Estimate parameters recursively: a regression y = φᵀϑ (φ columns or formulas over
    /// columns) or a formula model (EKF, UKF, SR-UKF), from a recording (CSV, Parquet, MDF4).
    ///
    /// Example: physid estimate --data shaft.csv --y torque_shaft --phi dtheta,domega
    /// --method rlsf --lambda 0.98 --json
    Estimate(cmd::estimate::Args),
    /// Which parameters of a model a recording can resolve: the orthogonal ranking (Alg. 5.1),
    /// cut-offs, Fisher information, confidence intervals; several --data compare experiments.
    ///
    /// Memory: after its first pass over the file, identify holds the model's columns up to
    /// PHYSID_HOLD_MB (default 256 MiB), so its memory grows with the recording to that bound
    /// (≈ 45 MB for 75 s, 250 MB for 600 s of a 10 kHz run); PHYSID_HOLD_MB=0 reads the file
    /// again on every pass instead, in memory independent of its length.
    ///
    /// Example: physid identify --data ex51.csv --expr 'sin(A)*x + B^2*y*cos(x) + sqrt(C)*x^2 +
    /// D*y^2 + E*x/y + F*2*x/y' --params A=1,B=2,C=3,D=4,E=5,F=6
    Identify(cmd::identify::Args),
    /// The mean-value friction model: evaluate it, rank its design parameters, and fit its
    /// coefficients to a motored recording (Application 2, thesis ch. 7).
    ///
    /// Example: physid friction eval --n 1000 --p-int 100 --t-oil 35
    Friction(cmd::friction::Args),
    /// The chain on a motored pressure trace: which of the motored model's physical
    /// parameters (compression ratio, TDC, sensor offset, polytropic exponent, BDC pressure,
    /// loss rate) the trace resolves, those fitted per TDC with 95 % intervals and fused.
    ///
    /// Example: physid compression fit --data deg.parquet --stroke 0.09 --rod 0.15 --out comp
    Compression(cmd::compression::Args),
    /// Application 3: the cyclic engine torque model's identifiability and EKF/UKF estimation
    /// on a motored recording (thesis ch. 8).
    ///
    /// Example: physid torque fit --data t2.parquet --fix delta,r --out torque
    Torque(cmd::torque::Args),
    /// The live service: the virtual test cell (paced by the wall clock), a replayed recording
    /// or frames from outside through the applications' stages; the web panel with live
    /// controls and logging (127.0.0.1, a token elsewhere), or NDJSON events with --headless.
    ///
    /// Example: physid live --headless --json --scenario shaft-steady --fault shaft.k=1000@5
    /// --pace max --duration 8
    Live(cmd::live::Args),
    /// A fleet worker: the applications' stages for the cells publishing to a NATS JetStream
    /// server (physid live --nats), one worker per cell at a time, checkpointed so that
    /// another worker takes a cell over without loss (docs/fleet.md).
    ///
    /// Example: physid worker --nats nats://127.0.0.1:4222
    Worker(cmd::worker::Args),
    /// The virtual transient engine test cell: scenario runs into recordings, and the
    /// compression, motored-cycle and torque–speed checks.
    ///
    /// Example: physid simulate --scenario shaft-steady --fault shaft.k=1200@10 --recording t01.parquet
    Simulate(cmd::simulate::Args),
    /// The virtual test cell as an FMU (FMI 2.0 or 3.0 co-simulation, linux x86-64) for
    /// Simulink, Dymola, FMPy and the other importers (docs/fmu.md).
    ///
    /// Example: physid fmu export --scenario shaft-steady --fmu cell.fmu --fmi 3
    Fmu(cmd::fmu::Args),
    /// The qualitative adaptive identification loop (thesis Fig. 5.7) from a pipeline file:
    /// identifiability, estimation of the estimable subset, the objective. Exits 1 when the
    /// objective is not met.
    ///
    /// Example: physid run pipelines/torque-ramp.toml --out run
    Run(cmd::run::Args),
    /// Experiment design: which test of the cell's inputs, within its limits, makes an
    /// application's parameters estimable by its recursive estimator, to what standard error,
    /// in how long; the test as a scenario file (docs/design.md).
    ///
    /// Example: physid design --app shaft --params K,B --limits
    /// speed=800:3000,throttle=0:60,dspeed=500 --duration 120 --out shaft-test.toml
    Design(cmd::design::Args),
    /// The self-calibrated test cell (thesis §9.2): which of the virtual cell's physical
    /// parameters a recording resolves, their values and intervals, and the calibrated cell
    /// checked against a recording channel by channel (docs/twin.md).
    ///
    /// Example: physid twin calibrate --data run.parquet --out cell.toml
    Twin(cmd::twin::Args),
    /// Application 1: coupling-shaft health monitoring (thesis ch. 6).
    ///
    /// Example: physid monitor shaft --data t01.parquet --out shaft-report
    Monitor(cmd::monitor::Args),
    /// What is in a recording: channels, units, rate, cycles, and the integrity check.
    ///
    /// Example: physid inspect run.mf4 --strict
    Inspect(cmd::inspect::Args),
    /// Convert between formats (.csv, .parquet, .mf4) and bases (time, crank angle).
    ///
    /// Example: physid convert run.mf4 run-deg.parquet --crank-angle
    Convert(cmd::convert::Args),
    /// Cylinder-pressure figures per cycle: peak and its angle, IMEP, polytropic exponents,
    /// CoV of IMEP, with pegging.
    ///
    /// Example: physid cycles deg.parquet --bore 0.084 --stroke 0.09 --rod 0.15 --compression-ratio 10 --json
    Cycles(cmd::cycles::Args),
    /// Make a recording whose writer was killed (kill -9, a power loss) readable up to its
    /// last commit: a live log, simulate's or convert's output (changed in place). A file whose
    /// writer still writes it is refused (nothing to recover: its writer closes it).
    ///
    /// Example: physid recover physid-logs/run.parquet
    Recover(cmd::recover::Args),
    /// Zero-phase Butterworth filtering of chosen channels.
    ///
    /// Example: physid filter run.csv run-f.csv --lowpass 500 --order 4 --channels torque_shaft
    Filter(cmd::filter::Args),
    /// Measure this machine's real-time capability: estimator updates per second.
    ///
    /// Example: physid bench --json
    Bench(cmd::bench::Args),
}

/// The command line, every option's value allowed to be a negative number: `--knock-threshold
/// -1e5` is that value (which its range check then refuses, saying why), not an unknown flag
/// `-1` — as most options already took it.
fn parse_args() -> Cli {
    use clap::{CommandFactory, FromArgMatches};
    fn negative_numbers(cmd: clap::Command) -> clap::Command {
        cmd.mut_args(|a| {
            if a.get_action().takes_values() {
                a.allow_negative_numbers(true)
            } else {
                a
            }
        })
        .mut_subcommands(negative_numbers)
    }
    let mut matches = negative_numbers(Cli::command()).get_matches();
    Cli::from_arg_matches_mut(&mut matches).unwrap_or_else(|e| e.exit())
}

fn main() -> miette::Result<()> {
    // Unwrapped messages: file paths and column lists stay on one line, copyable and greppable.
    miette::set_hook(Box::new(|_| {
        Box::new(miette::MietteHandlerOpts::new().wrap_lines(false).build())
    }))?;
    physid_io::quiet_contained_panics();
    let cli = parse_args();
    progress::set_quiet(cli.quiet);
    match cli.command {
        Command::Demo(a) => cmd::demo::run(&a),
        Command::Example(a) => cmd::example::run(&a),
        Command::Estimate(a) => cmd::estimate::run(&a),
        Command::Bench(a) => cmd::bench::run(&a),
        Command::Friction(a) => cmd::friction::run(&a),
        Command::Compression(a) => cmd::compression::run(&a),
        Command::Torque(a) => cmd::torque::run(&a),
        Command::Identify(a) => cmd::identify::run(&a),
        Command::Inspect(a) => cmd::inspect::run(&a),
        Command::Simulate(a) => cmd::simulate::run(&a),
        Command::Fmu(a) => cmd::fmu::run(&a),
        Command::Live(a) => cmd::live::run(&a),
        Command::Worker(a) => cmd::worker::run(&a),
        Command::Design(a) => cmd::design::run(&a),
        Command::Twin(a) => cmd::twin::run(&a),
        Command::Monitor(a) => cmd::monitor::run(&a),
        Command::Run(a) => cmd::run::run(&a),
        Command::Convert(a) => cmd::convert::run(&a),
        Command::Filter(a) => cmd::filter::run(&a),
        Command::Recover(a) => cmd::recover::run(&a),
        Command::Cycles(a) => cmd::cycles::run(&a),
    }
}
