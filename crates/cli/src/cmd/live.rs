//! `physid live`: the live service — a paced virtual test cell, a replayed recording or frames
//! from outside through the applications' stages; the operator's web panel on 127.0.0.1, or
//! headless with the events printed as NDJSON.

use super::live_stages::StageFlags;
use super::monitor::{config, MonitorFlags};
use crate::out::{note, outln};
use miette::{miette, Result};
use physid_live::fleet::{publish::PublishConfig, NatsTarget};
use physid_live::{
    run_live, Access, ControlRequest, Event, FrameSource, Hub, LiveConfig, LiveError, LogState,
    Pace, Panel, PanelFeed, PipedFrames, ReplaySource, ScenarioSource, Source,
};
use physid_sim::run::{OutputBasis, RunOptions};
use physid_sim::scenario::{Fault, Scenario};
use serde_json::json;
use std::fs::File;
use std::io::Write;
use std::io::{BufRead, BufReader};
use std::net::{IpAddr, SocketAddr, ToSocketAddrs};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, SyncSender};
use std::sync::Arc;
use std::time::Duration;

/// Arguments of `physid live`.
#[derive(clap::Args)]
pub struct Args {
    /// Run without the panel, printing the events (needs --json).
    #[arg(long)]
    headless: bool,
    /// The panel's address or host name: 127.0.0.1 unless told otherwise; any address but a
    /// loopback one needs a token. A name (`localhost`, the machine's DNS name) is resolved,
    /// and requests may name it in their `Host`.
    #[arg(
        long,
        value_name = "ADDR|NAME",
        default_value = "127.0.0.1",
        conflicts_with = "headless"
    )]
    bind: String,
    /// The panel's port (0: any free one; the address is printed).
    #[arg(long, default_value_t = 8750, conflicts_with = "headless")]
    port: u16,
    /// Another host name requests may name in their `Host` header (repeatable): a reverse
    /// proxy's, or the machine's DNS name. Every other name is refused (DNS rebinding).
    #[arg(long = "allow-host", value_name = "NAME", conflicts_with = "headless")]
    allow_hosts: Vec<String>,
    /// A secret every panel request must carry (`?token=…` or `Authorization: Bearer …`); at
    /// least 8 characters. Required with a --bind other than loopback. Shown in the process
    /// list: prefer PHYSID_TOKEN or --token-file.
    #[arg(
        long,
        env = "PHYSID_TOKEN",
        hide_env_values = true,
        conflicts_with = "headless"
    )]
    token: Option<String>,
    /// Read the token from this file's first line (kept out of the process list).
    #[arg(long, value_name = "FILE", conflicts_with_all = ["headless", "token"])]
    token_file: Option<PathBuf>,
    /// The panel's starting layout: a JSON file naming the plots shown and the channels each
    /// draws, and the traces' window (`{"plots": {"speed": ["omega_en"]}, "window_s": 30}`;
    /// docs/live.md). What the operator then chooses on the page is kept by the browser.
    #[arg(long, value_name = "FILE", conflicts_with = "headless")]
    layout: Option<PathBuf>,
    /// Where `record` controls (the panel's logging) write their Parquet or MDF4 files.
    #[arg(long, value_name = "DIR", default_value = "physid-logs")]
    log_dir: PathBuf,
    /// Open the panel in the desktop's browser.
    #[arg(long, conflicts_with = "headless")]
    open: bool,
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
    /// Take frames from outside over a local socket: listen on a Unix socket at PATH (mode
    /// 0600: only this user can connect; removed at the end) and read the frames of the first
    /// client that sends any, until it closes its connection.
    #[arg(long, value_name = "PATH", conflicts_with_all = ["scenario", "faults", "duration", "replay", "frames"])]
    frames_socket: Option<PathBuf>,
    /// With --frames-socket: when the client closes its connection, wait for the next (a DAQ
    /// started again goes on after a gap) rather than end; the run ends at SIGINT or SIGTERM.
    #[arg(long, requires = "frames_socket")]
    frames_reconnect: bool,
    /// Control messages, one JSON object per line, from a file or `-` for stdin: for the
    /// virtual cell {"cmd": "speed", "rpm": 1200}, {"cmd": "throttle", "deg": 30},
    /// {"cmd": "fault", "spec": "shaft.k=1000@12"}, {"cmd": "stop"}; for any source
    /// {"cmd": "restart", "stage": "shaft"}, {"cmd": "record", …} (docs/live.md).
    #[arg(long, value_name = "FILE|-")]
    controls: Option<PathBuf>,
    #[command(flatten)]
    input: super::InputArgs,
    // With --replay: the engine angle of a time-basis file decoded from an encoder's counts
    // or a raw trigger wheel or quadrature encoder (as `convert --crank-angle` decodes it),
    // then replayed on a time basis at its mean rate.
    #[command(flatten)]
    angle: super::inspect::AngleArgs,
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
    #[arg(long = "sample-rate", value_name = "HZ", default_value_t = 10_000.0, value_parser = super::range::positive, allow_negative_numbers = true)]
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
    #[command(flatten)]
    stages: StageFlags,
    /// Publish this cell's samples to a NATS JetStream fleet instead of running the stages
    /// here (docs/fleet.md): nats://HOST:PORT, credentials as nats://USER:PASSWORD@HOST:PORT
    /// or nats://TOKEN@HOST:PORT or --nats-credentials.
    #[arg(long, value_name = "URL", requires = "cell", conflicts_with_all = ["friction", "torque", "twin", "controls"])]
    nats: Option<String>,
    /// The cell id on the fleet (1–64 of A–Z a–z 0–9 - _).
    #[arg(long, value_name = "ID", requires = "nats")]
    cell: Option<String>,
    /// With --nats: the recording time one frame carries [s]; the chunks are gathered into
    /// frames of this much, to the nearest chunk (fewer, larger messages: the fleet's cost is
    /// mostly per message). 0: a frame per chunk.
    #[arg(long = "frame", value_name = "S", default_value_t = physid_live::fleet::publish::FRAME_S, requires = "nats", value_parser = super::range::nonnegative, allow_negative_numbers = true)]
    frame: f64,
    /// A file with the NATS credentials: `user = …` and `password = …`, or `token = …`.
    #[arg(long, value_name = "FILE")]
    nats_credentials: Option<PathBuf>,
    /// Serve the fleet view of a NATS JetStream fleet instead of running a cell: every cell,
    /// its state, latest estimates and alarms; a cell's name opens its live view (controls go
    /// to the cell). nats://HOST:PORT as --nats.
    #[arg(long, value_name = "URL", conflicts_with_all = ["nats", "headless", "replay", "frames", "frames_socket", "controls", "friction", "torque", "twin"])]
    fleet: Option<String>,
}

/// Run `physid live`.
pub fn run(a: &Args) -> Result<()> {
    let stdin = |p: &Option<PathBuf>| p.as_ref().is_some_and(|p| p.as_os_str() == "-");
    if stdin(&a.frames) && stdin(&a.controls) {
        return Err(miette!(
            "--frames - and --controls - both read standard input: give one of them a file (a FIFO, for messages as they come)"
        ));
    }
    if a.nats_credentials.is_some() && a.nats.is_none() && a.fleet.is_none() {
        return Err(miette!(
            "--nats-credentials: for --nats (publishing a cell) or --fleet (the fleet view)"
        ));
    }
    if let Some(url) = &a.fleet {
        return fleet_view(a, url);
    }
    if a.headless && !a.json && a.nats.is_none() {
        return Err(miette!(
            "--headless prints the events as NDJSON: add --json (or drop --headless for the panel)"
        ));
    }
    let mut cfg = LiveConfig {
        monitor: config(&a.monitor)?,
        estimate_every_s: a.estimate_every,
        pace: a.pace,
        log_dir: a.log_dir.clone(),
        ..LiveConfig::default()
    };
    a.stages.apply(&mut cfg)?;
    // SIGINT and SIGTERM end the run as a stop control does: the stages finish, a log being
    // written is closed (a source waiting for a client ends as at its end).
    let stop = super::stop_on_signal()?;
    let (mut source, what, theta_tdc) = source(a, &stop)?;
    cfg.theta_tdc = theta_tdc;
    if let (Some(url), Some(cell)) = (&a.nats, &a.cell) {
        return publish(a, url, cell, source.as_mut(), what, theta_tdc, stop);
    }
    give_up_after_signal(stop.clone());
    cfg.stop = Some(stop.clone());
    if a.headless {
        let controls = match &a.controls {
            None => None,
            Some(path) => {
                let (tx, rx) = std::sync::mpsc::sync_channel(256);
                forward_lines(lines(path, "--controls")?, tx);
                Some(rx)
            }
        };
        // The events go to stdout. When it closes (its reader has gone: `| head`, a consumer
        // that died, a terminal that hung up) the run ends as at a stop control — the stages
        // finish, a log is closed — and what it would have said of its logs goes to stderr.
        let mut closed: Option<std::io::Error> = None;
        let result = run_live(source.as_mut(), &cfg, controls.as_ref(), |e| {
            if closed.is_none() {
                let line = serde_json::to_string(e).map_err(|e| e.to_string())?;
                if let Err(err) = crate::out::try_line(&line) {
                    stop.store(true, Ordering::Relaxed);
                    closed = Some(err);
                }
            } else {
                after_stdout_closed(e);
            }
            Ok(())
        });
        return match closed {
            None => result.map(|_| ()).map_err(|e| miette!("{e}")),
            Some(err) => {
                if let Err(e) = &result {
                    note!("physid live: the run stopped: {e}");
                }
                if err.kind() == std::io::ErrorKind::BrokenPipe {
                    note!("physid live: the events' reader has gone (standard output closed): the run ended as at a stop control");
                    Ok(())
                } else {
                    Err(miette!(
                        "writing the events to standard output: {err}; the run ended as at a stop control"
                    ))
                }
            }
        };
    }
    cfg.panel = Some(PanelFeed::default());
    let hub = Hub::new(physid_live::Hello::run(
        what.to_string(),
        a.pace.to_string(),
        &cfg.monitor,
    ));
    let (tx, rx): (SyncSender<ControlRequest>, Receiver<ControlRequest>) =
        std::sync::mpsc::sync_channel(64);
    if let Some(path) = &a.controls {
        forward_lines(lines(path, "--controls")?, tx.clone());
    }
    let (bind, access) = panel_access(a)?;
    let token = access.token.clone();
    let layout = match &a.layout {
        Some(p) => Some(physid_live::Layout::read(p).map_err(|e| miette!("{e}"))?),
        None => None,
    };
    let panel = Panel::start(bind, access, hub.clone(), tx, layout).map_err(|e| miette!("{e}"))?;
    let url = announce(a, &panel, token.as_deref(), "panel")?;
    let result = run_live(source.as_mut(), &cfg, Some(&rx), |e| hub.publish(e));
    // Controls sent from now on are answered "the run has ended".
    drop(rx);
    if let Err(e) = &result {
        let _ = hub.publish(&Event::finding(f64::NAN, format!("the run stopped: {e}")));
        note!("physid live: the run stopped: {e}");
    }
    if !stop.load(Ordering::Relaxed) {
        note!("physid live: the run has ended; the panel stays at {url} until Ctrl-C");
        // Until SIGINT, SIGTERM or SIGHUP: the signals the run's stop flag is set by.
        while !stop.load(Ordering::Relaxed) {
            std::thread::sleep(Duration::from_millis(100));
        }
    }
    result.map(|_| ()).map_err(|e| miette!("{e}"))
}

/// What a headless run tells once its standard output has closed, on stderr: how its logs
/// ended and the errors.
fn after_stdout_closed(e: &Event) {
    match e {
        Event::Log {
            file,
            samples,
            state: LogState::Closed,
            ..
        } => note!("physid live: the log {file} was closed: {samples} samples, readable"),
        Event::Log {
            file,
            state: LogState::Empty,
            ..
        } => note!("physid live: the log {file} was stopped before any sample: no file kept"),
        Event::Error { message, .. } => note!("physid live: {message}"),
        _ => {}
    }
}

/// `physid live --fleet URL`: the fleet view until SIGINT/SIGTERM.
fn fleet_view(a: &Args, url: &str) -> Result<()> {
    let target = NatsTarget::new(url, a.nats_credentials.as_deref()).map_err(|e| miette!("{e}"))?;
    let (bind, access) = panel_access(a)?;
    let token = access.token.clone();
    let panel = Panel::start_fleet(bind, access, &target).map_err(|e| miette!("{e}"))?;
    announce(
        a,
        &panel,
        token.as_deref(),
        &format!("fleet view of {}", target.address),
    )?;
    panel.wait_for_shutdown();
    Ok(())
}

/// `physid live --nats URL --cell ID`: the source's samples published to the fleet until its
/// end or SIGTERM/SIGINT (then an end frame, and exit 0).
fn publish(
    a: &Args,
    url: &str,
    cell: &str,
    source: &mut dyn Source,
    what: String,
    theta_tdc: f64,
    stop: Arc<AtomicBool>,
) -> Result<()> {
    let target = NatsTarget::new(url, a.nats_credentials.as_deref()).map_err(|e| miette!("{e}"))?;
    let cfg = PublishConfig {
        cell: cell.to_string(),
        pace: a.pace,
        source_name: what,
        theta_tdc,
        give_up: std::time::Duration::from_secs(60),
        frame_s: a.frame,
    };
    eprintln!("physid live: cell {cell} publishing to {}", target.address);
    let s = physid_live::fleet::publish::publish(source, &target, &cfg, stop)
        .map_err(|e| miette!("{e}"))?;
    let line = json!({
        "type": "published", "cell": cell, "frames": s.frames, "samples": s.samples,
        "controls": s.controls, "retries": s.retries, "max_behind_s": s.max_behind_s,
    });
    if a.json {
        outln!("{line}");
    } else {
        note!(
            "physid live: cell {cell}: {} samples in {} frames published ({} resent after a lost acknowledgement)",
            s.samples, s.frames, s.retries
        );
    }
    Ok(())
}

/// The source `a` asks for, a line saying what it is, and the angle of a firing TDC on its
/// `theta_en` (a replay's first TDC marker, as the file verbs take it; else 0).
fn source(a: &Args, stop: &Arc<AtomicBool>) -> Result<(Box<dyn Source>, String, f64)> {
    if let (Some(flag), None) = (a.angle.crank_angle_flag(), &a.replay) {
        return Err(miette!(
            "{flag} is for the engine angle of a --replay file (the virtual cell and frames give their own)"
        ));
    }
    // Everything but --phase-from (which the replay of `theta_en` takes too) needs decoding.
    let decode = a
        .angle
        .crank_angle_flag()
        .is_some_and(|f| f != "--phase-from");
    #[cfg(unix)]
    if let Some(path) = &a.frames_socket {
        let mut socket = physid_live::SocketFrames::bind(path)
            .map_err(|e| miette!("--frames-socket {e}"))?
            .until(stop.clone());
        if a.frames_reconnect {
            socket = socket.reconnecting(|what| note!("physid live: {what}"));
        }
        eprintln!("physid live: waiting for frames on {}", path.display());
        return Ok((
            Box::new(FrameSource::new(socket, a.sample_rate).map_err(|e| miette!("{e}"))?),
            format!("frames on {} at {} Hz", path.display(), a.sample_rate),
            0.0,
        ));
    }
    #[cfg(not(unix))]
    if a.frames_socket.is_some() {
        return Err(miette!(
            "--frames-socket: local sockets are Unix sockets; use --frames - (stdin) here"
        ));
    }
    Ok(match (&a.replay, &a.frames) {
        (_, Some(path)) => (
            Box::new(
                FrameSource::new(frames_input(path)?.until(stop.clone()), a.sample_rate)
                    .map_err(|e| miette!("{e}"))?,
            ),
            format!("frames from {} at {} Hz", path.display(), a.sample_rate),
            0.0,
        ),
        (Some(path), None) => {
            let replay = if decode {
                let plan =
                    super::crank_input::crank_input(&a.input, path, &a.angle, a.stages.crank())?;
                ReplaySource::open_angle(plan, a.chunk)
            } else {
                ReplaySource::open_phased(
                    path,
                    &a.input.options(None)?,
                    a.chunk,
                    a.angle.wheel.phase(),
                )
            }
            .map_err(|e| match e {
                LiveError::Io(e) => miette!("{e}"),
                e => miette!("{}: {e}", path.display()),
            })?;
            let tdc = replay.theta_tdc();
            (
                Box::new(replay),
                format!("replay of {}", path.display()),
                tdc,
            )
        }
        (None, None) => {
            let name = a.scenario.as_deref().unwrap_or("shaft-steady");
            let scenario = Scenario::load(name).map_err(|e| miette!("--scenario: {e}"))?;
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
            (
                Box::new(
                    ScenarioSource::new(&scenario, &opts, a.chunk).map_err(|e| miette!("{e}"))?,
                ),
                format!("virtual cell, scenario {name}"),
                0.0,
            )
        }
    })
}

/// How long a run may take to end after SIGINT or SIGTERM before the process exits anyway (a
/// source waiting for input that does not come).
const SIGNAL_GRACE: Duration = Duration::from_secs(5);

/// Exit with status 130 when the run has not ended [`SIGNAL_GRACE`] after `stop` was set.
fn give_up_after_signal(stop: Arc<AtomicBool>) {
    std::thread::spawn(move || {
        while !stop.load(Ordering::Relaxed) {
            std::thread::sleep(Duration::from_millis(50));
        }
        std::thread::sleep(SIGNAL_GRACE);
        note!(
            "physid live: the run did not end within {} s of the signal or of its standard \
             output closing (its source waits for input): exiting; a log being written holds \
             every sample committed up to a second before (docs/live.md, No data lost)",
            SIGNAL_GRACE.as_secs()
        );
        std::process::exit(130);
    });
}

/// Send each line of `reader` as a control message, on a thread of its own (the run never
/// waits for it).
fn forward_lines(reader: Box<dyn BufRead + Send>, tx: SyncSender<ControlRequest>) {
    std::thread::spawn(move || physid_live::forward_control_lines(reader, tx));
}

/// Where the panel listens and who may reach it: `--bind` resolved (a name is allowed in
/// `Host` too), `--allow-host`, and the token from `--token`, `PHYSID_TOKEN` or
/// `--token-file`.
fn panel_access(a: &Args) -> Result<(SocketAddr, Access)> {
    let mut hosts = a.allow_hosts.clone();
    let ip = match a.bind.parse::<IpAddr>() {
        Ok(ip) => ip,
        Err(_) => {
            let name = a.bind.trim();
            let found: Vec<SocketAddr> = (name, a.port)
                .to_socket_addrs()
                .map_err(|e| {
                    miette!("--bind {name}: not an address, and resolving it failed: {e}")
                })?
                .collect();
            // IPv4 first: what `localhost` means to most clients.
            let ip = found
                .iter()
                .find(|s| s.is_ipv4())
                .or(found.first())
                .map(SocketAddr::ip)
                .ok_or_else(|| miette!("--bind {name}: the name resolves to no address"))?;
            hosts.push(name.to_string());
            ip
        }
    };
    if ip.is_unspecified() {
        // Every address: the machine's own name is one a browser on the network may use.
        hosts.extend(machine_name());
    }
    let token = match &a.token_file {
        Some(path) => {
            let text = physid_core::memory::read_small(path, 64 << 10)
                .map_err(|e| miette!("--token-file {}: {e}", path.display()))?;
            let t = text.lines().next().unwrap_or("").trim().to_string();
            if t.is_empty() {
                return Err(miette!(
                    "--token-file {}: the first line is empty: expected the token",
                    path.display()
                ));
            }
            Some(t)
        }
        None => a.token.clone(),
    };
    Ok((SocketAddr::new(ip, a.port), Access { token, hosts }))
}

/// This machine's host name (Linux: /proc/sys/kernel/hostname), if it has one.
fn machine_name() -> Option<String> {
    let name = std::fs::read_to_string("/proc/sys/kernel/hostname").ok()?;
    let name = name.trim();
    (!name.is_empty() && name != "localhost").then(|| name.to_string())
}

/// The first address of this machine's network interfaces that is not a loopback one
/// (IPv4 first).
fn network_address() -> Option<IpAddr> {
    let ips: Vec<IpAddr> = if_addrs::get_if_addrs()
        .ok()?
        .into_iter()
        .map(|i| i.ip())
        .filter(|ip| !ip.is_loopback())
        .collect();
    ips.iter().find(|ip| ip.is_ipv4()).or(ips.first()).copied()
}

/// The panel's address (with its token), printed as the first line on stdout (`physid live:
/// WHAT at URL`, which scripts and the tests read) and opened with `--open`. Bound to every
/// address, the URL names one a browser can reach: the first network interface's (else
/// 127.0.0.1).
fn announce(a: &Args, panel: &Panel, token: Option<&str>, what: &str) -> Result<String> {
    let query = token.map_or(String::new(), |t| format!("?token={t}"));
    let url = if panel.addr.ip().is_unspecified() {
        let host = network_address()
            .map(|ip| SocketAddr::new(ip, 0).to_string())
            .and_then(|s| s.rsplit_once(':').map(|(h, _)| h.to_string()))
            .unwrap_or_else(|| "127.0.0.1".into());
        eprintln!(
            "physid live: listening on every address of this machine (port {}); on this machine \
             also http://127.0.0.1:{}/",
            panel.addr.port(),
            panel.addr.port()
        );
        format!("http://{host}:{}/{query}", panel.addr.port())
    } else {
        format!("http://{}/{query}", panel.addr)
    };
    if token.is_some() {
        eprintln!(
            "physid live: the token travels in clear over HTTP: beyond this machine put TLS in \
             front of the panel (docs/live.md, Security)"
        );
    }
    outln!("physid live: {what} at {url}");
    let _ = std::io::stdout().flush();
    if a.open {
        open_browser(&url);
    }
    Ok(url)
}

/// Open `url` in the desktop's browser (a failure is said, not fatal).
fn open_browser(url: &str) {
    let opener = if cfg!(target_os = "macos") {
        "open"
    } else if cfg!(windows) {
        "explorer"
    } else {
        "xdg-open"
    };
    if let Err(e) = std::process::Command::new(opener).arg(url).spawn() {
        eprintln!("physid live: could not open a browser ({opener}: {e}); open {url} yourself");
    }
}

/// `--frames PATH`: the file (a FIFO too), or standard input for `-`, read on a thread of its
/// own so that a signal ends a wait for a silent sender ([`PipedFrames`]).
fn frames_input(path: &Path) -> Result<PipedFrames> {
    let input: Box<dyn std::io::Read + Send> = if path.as_os_str() == "-" {
        Box::new(std::io::stdin())
    } else {
        Box::new(File::open(path).map_err(|e| miette!("--frames {}: {e}", path.display()))?)
    };
    PipedFrames::new(input, &path.display().to_string())
        .map_err(|e| miette!("--frames {}: starting its reader: {e}", path.display()))
}

/// A file's lines, or standard input's for `-` (`flag` names the option in an error).
fn lines(path: &Path, flag: &str) -> Result<Box<dyn BufRead + Send>> {
    if path.as_os_str() == "-" {
        return Ok(Box::new(BufReader::new(std::io::stdin())));
    }
    let f = File::open(path).map_err(|e| miette!("{flag} {}: {e}", path.display()))?;
    Ok(Box::new(BufReader::new(f)))
}
