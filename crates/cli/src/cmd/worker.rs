//! `physid worker --nats URL`: a fleet worker (docs/fleet.md) — the shaft monitor, the cycle
//! statistics and the integrity checks (with `--friction`/`--torque` the friction
//! characterisation and the cyclic-torque estimation too) for the cells publishing to the
//! fleet, one worker per cell at a time, checkpointed; ends cleanly at SIGTERM or Ctrl-C (every cell checkpointed
//! and freed for another worker at once).

use super::live_stages::StageFlags;
use super::monitor::{config, MonitorFlags};
use miette::{miette, Result};
use physid_live::fleet::worker::{run_worker, WorkerConfig, WorkerStats};
use physid_live::fleet::NatsTarget;
use physid_live::LiveConfig;
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

/// Arguments of `physid worker`.
#[derive(clap::Args)]
pub struct Args {
    /// The NATS server: nats://HOST:PORT, credentials as nats://USER:PASSWORD@HOST:PORT or
    /// nats://TOKEN@HOST:PORT or --nats-credentials.
    #[arg(long, value_name = "URL")]
    nats: String,
    /// A file with the NATS credentials: `user = …` and `password = …`, or `token = …`.
    #[arg(long, value_name = "FILE")]
    nats_credentials: Option<PathBuf>,
    /// The worker's name in leases and logs [default: worker-PID].
    #[arg(long)]
    name: Option<String>,
    /// At most one estimate event per this much recording time [s].
    #[arg(long, default_value_t = 0.1, value_parser = super::range::positive, allow_negative_numbers = true)]
    estimate_every: f64,
    #[command(flatten)]
    monitor: MonitorFlags,
    // The workers of a fleet share these: a cell taken over runs on from its checkpoint, with
    // the stages it was checkpointed with.
    #[command(flatten)]
    stages: StageFlags,
}

/// Run `physid worker`.
pub fn run(a: &Args) -> Result<()> {
    let target =
        NatsTarget::new(&a.nats, a.nats_credentials.as_deref()).map_err(|e| miette!("{e}"))?;
    let mut live = LiveConfig {
        monitor: config(&a.monitor)?,
        estimate_every_s: a.estimate_every,
        ..LiveConfig::default()
    };
    a.stages.apply(&mut live)?;
    let cfg = WorkerConfig {
        name: a
            .name
            .clone()
            .unwrap_or_else(|| format!("worker-{}", std::process::id())),
        live,
        give_up: Duration::from_secs(60),
    };
    if !physid_live::wire::valid_cell(&cfg.name) {
        return Err(miette!(
            "--name '{}': expected 1–64 of A–Z a–z 0–9 - _",
            cfg.name
        ));
    }
    let stop = super::stop_on_signal()?;
    let stats = Arc::new(WorkerStats::default());
    eprintln!("physid worker {}: on {}", cfg.name, target.address);
    run_worker(&target, &cfg, stop, stats.clone()).map_err(|e| miette!("{e}"))?;
    crate::out::note!(
        "physid worker {}: stopped; {} frames processed, {} refused, {} events, {} cells taken",
        cfg.name,
        stats.frames.load(Ordering::Relaxed),
        stats.refused.load(Ordering::Relaxed),
        stats.events.load(Ordering::Relaxed),
        stats.taken.load(Ordering::Relaxed),
    );
    Ok(())
}
