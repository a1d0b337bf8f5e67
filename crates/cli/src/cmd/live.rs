//! `physid live`: the live service. Headless so far: a paced virtual test cell or a replayed
//! recording through the applications' stages, the events printed as NDJSON.

use super::monitor::{config, MonitorFlags};
use crate::out::outln;
use miette::{miette, Result};
use physid_live::{
    run_headless, FrameSource, LiveConfig, Pace, ReplaySource, ScenarioSource, Source,
};
use physid_sim::run::{OutputBasis, RunOptions};
use physid_sim::scenario::{Fault, Scenario};
use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};

/// Arguments of `physid live`.
#[derive(clap::Args)]
pub struct Args {
    /// Run without the panel, printing the events (needs --json).
    #[arg(long)]
    headless: bool,
    /// Print one JSON object per event and line (NDJSON).
    #[arg(long)]
    json: bool,
    /// Replay a recording (any format physid reads) instead of running the virtual cell.
    #[arg(long, conflicts_with_all = ["scenario", "faults", "duration"])]
    replay: Option<PathBuf>,
    /// Take frames from outside: JSON lines from a file, or `-` for stdin (docs/live.md has
    /// the format); the sample rate is --sample-rate.
    #[arg(long, value_name = "FILE|-", conflicts_with_all = ["scenario", "faults", "duration", "replay"])]
    frames: Option<PathBuf>,
    /// Control messages for the virtual cell, one JSON object per line, from a file or `-` for
    /// stdin: {"cmd": "speed", "rpm": 1200}, {"cmd": "throttle", "deg": 30},
    /// {"cmd": "fault", "spec": "shaft.k=1000@12"}, {"cmd": "stop"} (docs/live.md).
    #[arg(long, value_name = "FILE|-", conflicts_with_all = ["replay", "frames"])]
    controls: Option<PathBuf>,
    #[command(flatten)]
    input: super::InputArgs,
    /// The virtual cell's scenario: a built-in name or a TOML file [default: shaft-steady].
    #[arg(long)]
    scenario: Option<String>,
    /// Fault PATH=VALUE@T[+RAMP] for the virtual cell (repeatable).
    #[arg(long = "fault", value_name = "SPEC")]
    faults: Vec<String>,
    /// Seconds of the virtual cell to run [default: the scenario's].
    #[arg(long, value_name = "S", value_parser = super::range::positive, allow_negative_numbers = true)]
    duration: Option<f64>,
    /// The sample rate of the virtual cell, or of the frames from outside [Hz].
    #[arg(long = "sample-rate", default_value_t = 10_000.0, value_parser = super::range::positive, allow_negative_numbers = true)]
    sample_rate: f64,
    /// Recording seconds per wall-clock second: 1 real time, 10, … or max.
    #[arg(long, default_value = "1")]
    pace: Pace,
    /// Chunk length [s]: how much recording the source hands on at a time.
    #[arg(long, default_value_t = 0.01, value_parser = super::range::positive, allow_negative_numbers = true)]
    chunk: f64,
    /// At most one estimate event per this much recording time [s].
    #[arg(long, default_value_t = 0.1, value_parser = super::range::positive, allow_negative_numbers = true)]
    estimate_every: f64,
    #[command(flatten)]
    monitor: MonitorFlags,
}

/// Run `physid live`.
pub fn run(a: &Args) -> Result<()> {
    if !(a.headless && a.json) {
        return Err(miette!(
            "the live panel is not built yet: run headless with --headless --json (events as NDJSON on stdout)"
        ));
    }
    let cfg = LiveConfig {
        monitor: config(&a.monitor)?,
        estimate_every_s: a.estimate_every,
        pace: a.pace,
    };
    let mut source: Box<dyn Source> = match (&a.replay, &a.frames) {
        (_, Some(path)) => Box::new(
            FrameSource::new(lines(path, "--frames")?, a.sample_rate)
                .map_err(|e| miette!("{e}"))?,
        ),
        (Some(path), None) => {
            let rec = a.input.read(path, None)?;
            Box::new(
                ReplaySource::new(rec, a.chunk).map_err(|e| miette!("{}: {e}", path.display()))?,
            )
        }
        (None, None) => {
            let scenario = Scenario::load(a.scenario.as_deref().unwrap_or("shaft-steady"))
                .map_err(|e| miette!("--scenario: {e}"))?;
            let faults = a
                .faults
                .iter()
                .map(|f| Fault::parse(f).map_err(|e| miette!("--fault {e}")))
                .collect::<Result<Vec<_>>>()?;
            let opts = RunOptions {
                duration: a.duration,
                faults,
                basis: OutputBasis::Time(a.sample_rate),
                ..Default::default()
            };
            Box::new(ScenarioSource::new(&scenario, &opts, a.chunk).map_err(|e| miette!("{e}"))?)
        }
    };
    // Control lines, read on their own thread so that the run never waits for them.
    let controls = match &a.controls {
        None => None,
        Some(path) => {
            let reader = lines(path, "--controls")?;
            let (tx, rx) = std::sync::mpsc::sync_channel(256);
            std::thread::spawn(move || {
                for line in reader.lines().map_while(|l| l.ok()) {
                    if !line.trim().is_empty() && tx.send(line).is_err() {
                        break;
                    }
                }
            });
            Some(rx)
        }
    };
    run_headless(source.as_mut(), &cfg, controls.as_ref(), |e| {
        let line = serde_json::to_string(e).map_err(|e| e.to_string())?;
        outln!("{line}");
        Ok(())
    })
    .map_err(|e| miette!("{e}"))?;
    Ok(())
}

/// A file's lines, or standard input's for `-` (`flag` names the option in an error).
fn lines(path: &Path, flag: &str) -> Result<Box<dyn BufRead + Send>> {
    if path.as_os_str() == "-" {
        return Ok(Box::new(BufReader::new(std::io::stdin())));
    }
    let f = File::open(path).map_err(|e| miette!("{flag} {}: {e}", path.display()))?;
    Ok(Box::new(BufReader::new(f)))
}
