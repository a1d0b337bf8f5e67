//! The fleet on a real NATS JetStream server, started by each test on a free loopback port with
//! its own store directory: a worker killed with SIGKILL mid-stream and another taking the cell
//! over, the server restarted mid-run, bad frames, authentication. The fleet's events are
//! compared with `physid live --headless --json` on the same source — the same stages run in one
//! process without NATS: every event equal, none lost, none twice.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use futures_util::StreamExt;
use physid_core::{Basis, Channel, Recording};
use physid_live::fleet::local::{nats_server_bin, LocalServer};
use physid_live::fleet::{CellInfo, CELLS_BUCKET};
use physid_live::service::CHECKPOINT_VERSION;
use physid_live::wire::{self, Frame};
use physid_testkit::Scratch;
use serde_json::{json, Value};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

const PHYSID: &str = env!("CARGO_BIN_EXE_physid");

/// A local nats-server (JetStream, file storage in a temporary directory, loopback, a free
/// port) with `auth`; `None` when nats-server is not installed (and not on CI, where it must
/// be: `.ci/run` installs it).
fn nats_server(auth: &[&str]) -> Option<LocalServer> {
    if nats_server_bin().is_none() {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI needs nats-server (apt-get install nats-server)"
        );
        eprintln!("SKIPPED: nats-server not installed");
        return None;
    }
    Some(LocalServer::start(auth).expect("start nats-server"))
}

/// A `physid` process, killed when dropped; its stderr collected on a thread.
struct Proc {
    child: Child,
    stderr: std::sync::Arc<std::sync::Mutex<String>>,
    reader: Option<std::thread::JoinHandle<()>>,
}

/// How a `physid` process ended.
struct Exit {
    status: std::process::ExitStatus,
    stdout: String,
    stderr: String,
}

impl Proc {
    fn start(args: &[&str]) -> Self {
        let mut child = Command::new(PHYSID)
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start physid");
        let stderr = std::sync::Arc::new(std::sync::Mutex::new(String::new()));
        let err = child.stderr.take().expect("stderr");
        let sink = stderr.clone();
        let reader = std::thread::spawn(move || {
            for line in BufReader::new(err).lines().map_while(Result::ok) {
                sink.lock().expect("lock").push_str(&(line + "\n"));
            }
        });
        Self {
            child,
            stderr,
            reader: Some(reader),
        }
    }

    fn stderr(&self) -> String {
        self.stderr.lock().expect("lock").clone()
    }

    /// Wait for the exit (at most `secs`): its status, stdout and whole stderr.
    fn wait(mut self, secs: u64) -> Exit {
        let deadline = Instant::now() + Duration::from_secs(secs);
        loop {
            if let Some(status) = self.child.try_wait().expect("wait") {
                let mut stdout = String::new();
                if let Some(mut o) = self.child.stdout.take() {
                    let _ = std::io::Read::read_to_string(&mut o, &mut stdout);
                }
                if let Some(r) = self.reader.take() {
                    let _ = r.join();
                }
                return Exit {
                    status,
                    stdout,
                    stderr: self.stderr(),
                };
            }
            assert!(
                Instant::now() < deadline,
                "physid did not end within {secs} s; stderr:\n{}",
                self.stderr()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    fn sigterm(&self) {
        let _ = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status();
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn rt() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("runtime")
}

async fn client(url: &str) -> async_nats::Client {
    let (user, rest) = url
        .strip_prefix("nats://")
        .and_then(|r| r.split_once('@'))
        .map_or((None, url.to_string()), |(u, h)| {
            (Some(u.to_string()), format!("nats://{h}"))
        });
    let opts = match user.as_deref().map(|u| u.split_once(':').ok_or(u)) {
        Some(Ok((u, p))) => async_nats::ConnectOptions::new().user_and_password(u.into(), p.into()),
        Some(Err(token)) => async_nats::ConnectOptions::new().token(token.into()),
        None => async_nats::ConnectOptions::new(),
    };
    opts.connect(rest).await.expect("connect to nats-server")
}

/// Every message stored on `subject` in `stream` so far, in order (none while the stream is
/// not there).
fn stored(url: &str, stream: &str, subject: String) -> Vec<Vec<u8>> {
    rt().block_on(async {
        let js = async_nats::jetstream::new(client(url).await);
        let Ok(stream) = js.get_stream(stream).await else {
            return Vec::new();
        };
        let mut count = 0;
        if let Ok(mut s) = stream.info_with_subjects(&subject).await {
            while let Some(Ok((_, n))) = s.next().await {
                count += n;
            }
        }
        let mut out = Vec::new();
        if count == 0 {
            return out;
        }
        let consumer = stream
            .create_consumer(async_nats::jetstream::consumer::pull::OrderedConfig {
                filter_subject: subject,
                ..Default::default()
            })
            .await
            .expect("consumer");
        let mut messages = consumer.messages().await.expect("messages");
        while out.len() < count {
            match tokio::time::timeout(Duration::from_secs(5), messages.next()).await {
                Ok(Some(Ok(m))) => out.push(m.payload.to_vec()),
                other => panic!(
                    "reading messages: {:?}",
                    other.map(|o| o.map(|r| r.is_ok()))
                ),
            }
        }
        out
    })
}

/// Every event stored for `cell` so far, in order.
fn events(url: &str, cell: &str) -> Vec<Value> {
    stored(url, "PHYSID_EVENTS", format!("physid.cell.{cell}.events"))
        .iter()
        .map(|m| serde_json::from_slice(m).expect("an event is JSON"))
        .collect()
}

/// Wait until `cell`'s events satisfy `done` (at most `secs`).
fn wait_events(url: &str, cell: &str, secs: u64, done: impl Fn(&[Value]) -> bool) -> Vec<Value> {
    let deadline = Instant::now() + Duration::from_secs(secs);
    loop {
        let e = events(url, cell);
        if done(&e) {
            return e;
        }
        assert!(
            Instant::now() < deadline,
            "events of {cell} not as awaited within {secs} s: {} so far, last {:?}",
            e.len(),
            e.last()
        );
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// The fleet's events equal the one-process run's, JSON for JSON, type by type in order. (The
/// order *between* types within a frame follows the chunking: a publisher gathers its chunks
/// into frames of `--frame` seconds, the one-process run takes them one by one.)
fn same_events(got: &[Value], expected: &[Value]) {
    let of = |e: &[Value], kind: &Value| -> Vec<Value> {
        e.iter().filter(|e| &e["type"] == kind).cloned().collect()
    };
    let kinds: std::collections::BTreeSet<String> =
        expected.iter().map(|e| e["type"].to_string()).collect();
    for kind in &kinds {
        let kind: Value = serde_json::from_str(kind).expect("a type");
        let kind = &kind;
        let (g, x) = (of(got, kind), of(expected, kind));
        assert_eq!(g.len(), x.len(), "{kind} events");
        for (k, (g, x)) in g.iter().zip(&x).enumerate() {
            assert_eq!(g, x, "{kind} event {k}");
        }
    }
}

fn has_end(e: &[Value]) -> bool {
    e.iter().any(|e| e["type"] == "end")
}

/// `physid live --headless --json` on the same source: the events of one process, no NATS.
fn reference(source: &[&str]) -> Vec<Value> {
    let mut args = vec!["live", "--headless", "--json", "--pace", "max"];
    args.extend_from_slice(source);
    let out = Command::new(PHYSID)
        .args(&args)
        .output()
        .expect("physid live");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("JSON"))
        .collect()
}

fn credentials(dir: &Path) -> PathBuf {
    let f = dir.join("fleet.creds");
    std::fs::write(
        &f,
        "# the fleet's account\nuser = physid\npassword = s3cret-pw\n",
    )
    .expect("write");
    f
}

const SOURCE: [&str; 4] = ["--scenario", "shaft-steady", "--duration", "6"];

/// Long enough (4 s at pace 3) that a worker stopped after 1.7 s is stopped mid-run.
const LONG: [&str; 4] = ["--scenario", "shaft-steady", "--duration", "12"];

/// A worker killed with SIGKILL mid-stream: another takes the cell over from the checkpoint and
/// the fleet's events are exactly those of an uninterrupted run — equal JSON, none lost, none
/// twice (the replayed frames give the same events from the same state, and their message ids
/// let the stream keep one of each); the end event counts every sample published.
#[test]
fn a_killed_worker_is_replaced_without_loss() {
    failover("c1", false, &LONG, &[], &[]);
}

/// A worker stopped with SIGTERM mid-stream checkpoints its cell and frees it as it exits (its
/// lease is deleted, not left to expire); the other takes it over, and the events are again
/// exactly those of an uninterrupted run.
#[test]
fn a_stopped_worker_hands_its_cell_over_at_once() {
    failover("c3", true, &LONG, &[], &[]);
}

/// Workers running the friction characterisation too (`physid worker --friction`): the one
/// killed mid-run (about 5 s into the 10 s sweep; its last checkpoint a second of wall time,
/// 3 s of recording, before — around the choice of coefficients at cycle 20, 3.0 s in) is
/// replaced from its checkpoint, the friction stage's cycles and regression with it, and the
/// fleet's events, every cycle's friction estimates among them, equal a one-process run's.
#[test]
fn a_killed_worker_hands_on_its_friction_characterisation() {
    let source = ["--scenario", "friction-sweep", "--duration", "10"];
    let Some(got) = failover(
        "c5",
        false,
        &source,
        &["--friction", "cell", "--friction-after", "20"],
        &[],
    ) else {
        return;
    };
    let friction = got.iter().filter(|e| e["type"] == "friction").count();
    assert!(friction > 40, "{friction} cycles' friction estimates");
    let chosen = got
        .iter()
        .find(|e| e["type"] == "identifiability" && e["app"] == "friction")
        .expect("the choice of coefficients");
    assert!(!chosen["estimable"].as_array().expect("names").is_empty());
}

/// The cyclic-torque estimation hands on too: worker a is killed (SIGKILL) mid-ramp; b restores
/// its checkpoint — the torque stage's degree resampling, its choice and its filter — and the
/// fleet's events are one process's, JSON for JSON.
#[test]
fn a_killed_worker_hands_on_its_torque_estimation() {
    let source = ["--scenario", "torque-ramp", "--duration", "10"];
    let Some(got) = failover("c6", false, &source, &["--torque"], &[]) else {
        return;
    };
    let cycles = got.iter().filter(|e| e["type"] == "torque").count();
    assert!(cycles > 40, "{cycles} cycles' torque estimates");
    let chosen = got
        .iter()
        .find(|e| e["type"] == "identifiability" && e["app"] == "torque")
        .expect("the choice of parameters");
    assert!(!chosen["estimable"].as_array().expect("names").is_empty());
}

/// A checkpoint larger than the server's message limit — here 64 KiB, against the ≈ 280 kB of a
/// torque stage holding its first ten cycles for the choice — is stored in parts: the worker
/// goes on (it used to fail at every checkpoint and take its cell again from the start, for
/// ever), and a worker killed mid-run hands on from it.
#[test]
fn a_checkpoint_over_the_message_limit_is_stored_in_parts() {
    let s = Scratch::new("physid-fleet-payload");
    let conf = s.file("small-payload.conf");
    std::fs::write(&conf, "max_payload: 65536\n").expect("write the configuration");
    let source = ["--scenario", "torque-ramp", "--duration", "10"];
    let conf = conf.to_str().expect("utf-8");
    let Some(got) = failover("c7", false, &source, &["--torque"], &["-c", conf]) else {
        return;
    };
    assert!(got.iter().filter(|e| e["type"] == "torque").count() > 40);
}

/// Worker a processes `cell`, a run of `source` (with the `stages` flags), until it is killed
/// (`term`: SIGTERM, else SIGKILL); worker b takes over. `server`: nats-server's further
/// arguments. Returns the fleet's events, asserted equal to a one-process run's (`None`:
/// skipped, no nats-server outside CI).
fn failover(
    cell: &str,
    term: bool,
    source: &[&str],
    stages: &[&str],
    server: &[&str],
) -> Option<Vec<Value>> {
    let auth = ["--user", "physid", "--pass", "s3cret-pw"];
    let server = nats_server(&[&auth[..], server].concat())?;
    let url = server.url("physid:s3cret-pw@");
    let creds = credentials(server.dir());
    let expected = reference(&[stages, source].concat());
    let worker = |name: &str| {
        let mut args = vec!["worker", "--nats", &url, "--name", name];
        args.extend_from_slice(stages);
        Proc::start(&args)
    };
    let a = worker("a");
    let bare = server.url("");
    let mut args = vec!["live", "--nats", &bare];
    args.extend_from_slice(&["--nats-credentials", creds.to_str().expect("utf-8")]);
    args.extend_from_slice(&["--cell", cell, "--pace", "3", "--json"]);
    args.extend_from_slice(source);
    let publisher = Proc::start(&args);
    // A's first checkpoint is written after a second; kill it after its second.
    wait_events(&url, cell, 30, |e| {
        e.iter().filter(|e| e["type"] == "estimate").count() >= 15
    });
    std::thread::sleep(Duration::from_millis(1200));
    let b = worker("b");
    assert!(
        !has_end(&events(&url, cell)),
        "the run ended before the stop"
    );
    let stopped = Instant::now();
    if term {
        a.sigterm();
        let exit = a.wait(20);
        assert!(exit.status.success(), "{}", exit.stderr);
        // a freed the cell as it stopped (its lease is gone, not left to expire): b may take it
        // at its next look (every 0.5 s) — so the lease, if there is one by now, is b's.
        let lease = rt().block_on(async {
            let js = async_nats::jetstream::new(client(&url).await);
            let leases = js.get_key_value("physid_leases").await.expect("bucket");
            leases.get(cell).await.expect("read the lease")
        });
        assert!(
            lease.as_deref() != Some(b"a".as_slice()),
            "a's lease on {cell} is still there"
        );
    } else {
        let mut a = a;
        a.child.kill().expect("kill -9 worker a");
        let _ = a.child.wait();
    }
    eprintln!("stopped {:?} ago", stopped.elapsed());
    let done = publisher.wait(60);
    assert!(done.status.success(), "{}", done.stderr);
    let published: Value = serde_json::from_str(done.stdout.trim()).expect("summary");
    let got = wait_events(&url, cell, 60, has_end);
    let took = b.stderr();
    eprintln!("worker b: {took}");
    assert!(
        took.contains(&format!("took cell {cell}")) && !took.contains("after frame 0\n"),
        "b took over from a checkpoint: {took}"
    );
    let end = got.iter().find(|e| e["type"] == "end").expect("end");
    assert_eq!(end["samples"], published["samples"], "every sample once");
    assert_eq!(end["dropped"], 0);
    let kinds = |e: &[Value]| {
        let mut n = std::collections::BTreeMap::<String, usize>::new();
        for e in e {
            *n.entry(e["type"].to_string()).or_default() += 1;
        }
        n
    };
    assert_eq!(
        kinds(&got),
        kinds(&expected),
        "as many events of each type as the uninterrupted run"
    );
    same_events(&got, &expected);
    b.sigterm();
    assert!(
        b.wait(20).status.success(),
        "the worker ends cleanly at SIGTERM"
    );
    Some(got)
}

/// nats-server killed and restarted (same store) mid-run: the publisher and the worker
/// reconnect, nothing is lost or doubled — the events equal the uninterrupted run's.
#[test]
fn a_server_restart_loses_nothing() {
    let Some(mut server) = nats_server(&["--auth", "tok3n-secret"]) else {
        return;
    };
    let url = server.url("tok3n-secret@");
    let expected = reference(&SOURCE);
    let _w = Proc::start(&["worker", "--nats", &url, "--name", "w"]);
    let mut args = vec![
        "live", "--nats", &url, "--cell", "c2", "--pace", "3", "--json",
    ];
    args.extend_from_slice(&SOURCE);
    let publisher = Proc::start(&args);
    wait_events(&url, "c2", 30, |e| e.len() >= 10);
    let t0 = Instant::now();
    server
        .restart(Duration::from_millis(1500))
        .expect("restart");
    let done = publisher.wait(90);
    eprintln!(
        "publisher done {:?} after the restart; worker: {}",
        t0.elapsed(),
        _w.stderr()
    );
    assert!(done.status.success(), "{}", done.stderr);
    let published: Value = serde_json::from_str(done.stdout.trim()).expect("summary");
    let got = wait_events(&url, "c2", 60, has_end);
    let end = got.iter().find(|e| e["type"] == "end").expect("end");
    assert_eq!(end["samples"], published["samples"]);
    assert_eq!(got.len(), expected.len());
    same_events(&got, &expected);
}

/// A checkpoint this physid cannot take up — one of another layout (a physid of another
/// version wrote it, as during a fleet's rolling upgrade), or a record that is no checkpoint —
/// is told on the cell's events subject, once, with the reason, and the cell is processed from
/// its run's first frame: the fleet's events are then an uninterrupted run's. Before, the first
/// kind failed the cell's task at every take, for ever (the cell was never processed), and the
/// second started the cell afresh without a word.
#[test]
fn a_checkpoint_this_physid_cannot_take_up_is_told_and_the_cell_starts_afresh() {
    let Some(server) = nats_server(&[]) else {
        return;
    };
    let url = server.url("");
    let expected = reference(&SOURCE);
    let cells = ["c8", "c9"];
    let publishers: Vec<Proc> = cells
        .iter()
        .map(|cell| {
            let mut args = vec!["live", "--nats", &url, "--cell", cell, "--json"];
            args.extend_from_slice(&SOURCE);
            Proc::start(&args)
        })
        .collect();
    for p in publishers {
        let done = p.wait(60);
        assert!(done.status.success(), "{}", done.stderr);
    }
    // Each cell's run, from the registry; a checkpoint of that run that this physid cannot
    // take up: c8's state of the layout before this physid's, c9's record no checkpoint.
    let older = CHECKPOINT_VERSION - 1;
    let older_layout =
        rmp_serde::to_vec_named(&(older, "the stages of an older physid")).expect("an older state");
    let record = |run: u64| {
        rmp_serde::to_vec(&(
            run,
            40u64,
            40u64,
            false,
            serde_bytes::ByteBuf::from(older_layout.clone()),
        ))
        .expect("a record")
    };
    rt().block_on(async {
        let js = async_nats::jetstream::new(client(&url).await);
        let registry = js.get_key_value(CELLS_BUCKET).await.expect("registry");
        let checkpoints = js
            .get_key_value("physid_checkpoints")
            .await
            .expect("the checkpoints' bucket");
        let info = registry
            .get("c8")
            .await
            .expect("read")
            .expect("c8 registered");
        let info: CellInfo = serde_json::from_slice(&info).expect("an entry");
        checkpoints
            .put("c8", record(info.run).into())
            .await
            .expect("put c8's checkpoint");
        checkpoints
            .put("c9", b"not a checkpoint".to_vec().into())
            .await
            .expect("put c9's checkpoint");
    });
    let w = Proc::start(&["worker", "--nats", &url, "--name", "w"]);
    let layout =
        format!("a checkpoint of layout {older}: this physid reads layout {CHECKPOINT_VERSION}");
    for (cell, why) in [("c8", layout.as_str()), ("c9", "not a checkpoint")] {
        let got = wait_events(&url, cell, 60, has_end);
        let (told, rest): (Vec<Value>, Vec<Value>) = got
            .into_iter()
            .partition(|e| e["type"] == "error" && e["input"] == "checkpoint");
        assert_eq!(told.len(), 1, "{cell}: told once: {told:?}");
        let message = told[0]["message"].as_str().expect("a message");
        assert!(
            message.contains(why) && message.contains("from its run's first frame"),
            "{cell}: {message}"
        );
        assert_eq!(rest.len(), expected.len(), "{cell}: every event once");
        same_events(&rest, &expected);
    }
    let stderr = w.stderr();
    for cell in cells {
        assert_eq!(
            stderr.matches(&format!("took cell {cell} ")).count(),
            1,
            "{cell} taken once: {stderr}"
        );
    }
    w.sigterm();
    assert!(w.wait(20).status.success(), "the worker ends cleanly");
}

/// A publisher whose replayed file is damaged part-way (64 bytes changed in its third row
/// group of four) publishes what it read, tells the error on the cell's events (`"input":
/// "source"`) and sends the end frame: the worker ends the cell — its `end` counts every sample
/// published — and the publisher exits 1 with the error. Before, it exited without the end
/// frame, and the cell went quiet for ever, its worker waiting.
#[test]
fn a_damaged_replay_ends_its_cell() {
    let Some(server) = nats_server(&[]) else {
        return;
    };
    let url = server.url("");
    let s = Scratch::new("physid-fleet-damaged");
    let file = s.file("run.parquet");
    let o = Command::new(PHYSID)
        .args(["simulate", "--scenario", "shaft-steady", "--duration", "20"])
        .args(["--recording", file.to_str().expect("utf-8")])
        .output()
        .expect("simulate");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut bytes = std::fs::read(&file).expect("read");
    let at = bytes.len() * 5 / 6;
    for b in &mut bytes[at..at + 64] {
        *b ^= 0xff;
    }
    std::fs::write(&file, &bytes).expect("write");
    let _w = Proc::start(&["worker", "--nats", &url, "--name", "w"]);
    let publisher = Proc::start(&[
        "live",
        "--nats",
        &url,
        "--cell",
        "c10",
        "--pace",
        "max",
        "--replay",
        file.to_str().expect("utf-8"),
    ]);
    let done = publisher.wait(60);
    assert_eq!(done.status.code(), Some(1), "{}", done.stderr);
    assert!(done.stderr.contains("corrupt Parquet"), "{}", done.stderr);
    let got = wait_events(&url, "c10", 60, has_end);
    let end = got.iter().find(|e| e["type"] == "end").expect("end");
    let error = got
        .iter()
        .find(|e| e["type"] == "error")
        .expect("the error told");
    assert_eq!(error["input"], "source", "{error}");
    let message = error["message"].as_str().expect("a message");
    assert!(
        message.contains("run.parquet: corrupt Parquet: column '")
            && message.contains("of row group 2 (rows 131072 to 196607"),
        "{message}"
    );
    assert_eq!(
        end["samples"], error["line"],
        "every sample published, once"
    );
    assert_eq!(end["samples"], 131_072, "every sample before the damage");
    assert_eq!(end["dropped"], 0);
}

/// A publisher killed mid-run (`kill -9`: no end frame) and started again on the same cell —
/// a new run in the registry: the worker ends the old run where its frames stopped (a finding,
/// the stages' last outputs, `end`) and processes the new run, whose events equal a
/// one-process run's. Before, the worker kept the old run and refused every frame of the new
/// one, for ever ("a frame of run … while the registry's run is …").
#[test]
fn a_publisher_started_again_starts_a_new_run() {
    let Some(server) = nats_server(&[]) else {
        return;
    };
    let url = server.url("");
    let expected = reference(&SOURCE);
    let _w = Proc::start(&["worker", "--nats", &url, "--name", "w"]);
    let mut first = Proc::start(&[
        "live",
        "--nats",
        &url,
        "--cell",
        "c11",
        "--pace",
        "1",
        "--json",
        "--scenario",
        "shaft-steady",
        "--duration",
        "60",
    ]);
    wait_events(&url, "c11", 30, |e| {
        e.iter().filter(|e| e["type"] == "estimate").count() >= 5
    });
    first.child.kill().expect("kill -9 the first publisher");
    let _ = first.child.wait();
    let mut args = vec!["live", "--nats", &url, "--cell", "c11", "--json"];
    args.extend_from_slice(&SOURCE);
    let again = Proc::start(&args).wait(60);
    assert!(again.status.success(), "{}", again.stderr);
    let published: Value = serde_json::from_str(again.stdout.trim()).expect("summary");
    let got = wait_events(&url, "c11", 60, |e| {
        e.iter().filter(|e| e["type"] == "end").count() == 2
    });
    let first_end = got.iter().position(|e| e["type"] == "end").expect("end");
    let told = got[..first_end]
        .iter()
        .rev()
        .find(|e| e["type"] == "finding");
    assert!(
        told.and_then(|e| e["message"].as_str())
            .is_some_and(|m| m.contains("started run") && m.contains("ends here")),
        "{told:?}"
    );
    assert!(got[first_end]["samples"].as_u64().expect("samples") > 0);
    let second = &got[first_end + 1..];
    assert!(
        !got.iter().any(|e| e["type"] == "error"),
        "no frame refused"
    );
    assert_eq!(
        second.last().expect("events")["samples"],
        published["samples"]
    );
    same_events(second, &expected);
}

fn chunk(t0: usize, n: usize) -> Recording {
    let mut r = Recording::new(Basis::Time);
    let t: Vec<f64> = (t0..t0 + n).map(|k| k as f64 * 1e-3).collect();
    for (name, unit, v) in [
        ("t", "s", t.clone()),
        ("omega_en", "rad/s", t.iter().map(|_| 100.0).collect()),
    ] {
        r.push(Channel {
            name: name.into(),
            unit: unit.into(),
            values: v,
        })
        .expect("channel");
    }
    r
}

fn frame(cell: &str, run: u64, seq: u64, first: usize, n: usize, end: bool) -> Vec<u8> {
    wire::encode(&Frame {
        cell: cell.into(),
        run,
        seq,
        first_sample: first as u64,
        rate_hz: 1000.0,
        end,
        chunk: chunk(first, n),
    })
    .expect("encode")
}

/// Bad input on the wire — bytes that are no frame, another cell's frame, a frame without `t`,
/// a column of the wrong type, a frame again and one out of order, frames for a cell nobody
/// registered, a registry entry with a rate of 0: each counted and reported as an `error` event with its reason, none in an
/// estimate, and the worker goes on to the cell's end.
#[test]
fn bad_frames_are_refused_and_reported() {
    let Some(server) = nats_server(&[]) else {
        return;
    };
    let url = server.url("");
    let w = Proc::start(&["worker", "--nats", &url, "--name", "w"]);
    // The worker makes the buckets; wait for them.
    wait_for_bucket(&url);
    let run = 7;
    let info = CellInfo {
        cell: "bad".into(),
        run,
        rate_hz: 1000.0,
        source: "a test".into(),
        theta_tdc: 0.0,
    };
    let mut no_t = chunk(100, 10);
    no_t = {
        let mut r = Recording::new(Basis::Time);
        r.push(no_t.channel("omega_en").expect("ch").clone())
            .expect("push");
        r
    };
    let no_t = wire::encode(&Frame {
        cell: "bad".into(),
        run,
        seq: 3,
        first_sample: 100,
        rate_hz: 1000.0,
        end: false,
        chunk: no_t,
    })
    .expect("encode");
    let wrong_type = {
        use arrow_array::{Int64Array, RecordBatch};
        use arrow_schema::{DataType, Field, Schema};
        let meta = std::collections::HashMap::from([
            ("physid.wire".to_string(), "1".to_string()),
            ("physid.cell".to_string(), "bad".to_string()),
            ("physid.run".to_string(), run.to_string()),
            ("physid.seq".to_string(), "3".to_string()),
            ("physid.first_sample".to_string(), "100".to_string()),
            ("physid.rate_hz".to_string(), "1000".to_string()),
            ("physid.basis".to_string(), "time".to_string()),
        ]);
        let schema = std::sync::Arc::new(Schema::new_with_metadata(
            vec![Field::new("t", DataType::Int64, false)],
            meta,
        ));
        let batch = RecordBatch::try_new(
            schema.clone(),
            vec![std::sync::Arc::new(Int64Array::from(vec![1, 2, 3]))],
        )
        .expect("batch");
        let mut w = arrow_ipc::writer::StreamWriter::try_new(Vec::new(), &schema).expect("w");
        w.write(&batch).expect("write");
        w.finish().expect("finish");
        w.into_inner().expect("bytes")
    };
    let sent: Vec<(&str, Vec<u8>)> = vec![
        ("bad", frame("bad", run, 1, 0, 50, false)),
        ("bad", b"this is not a frame".to_vec()),
        ("bad", frame("other", run, 2, 50, 50, false)),
        ("bad", no_t),
        ("bad", wrong_type),
        ("bad", frame("bad", run, 2, 50, 50, false)),
        ("bad", frame("bad", run, 2, 50, 50, false)),
        ("bad", frame("bad", run, 4, 150, 50, false)),
        ("bad", frame("bad", run, 3, 100, 50, false)),
        ("bad", frame("bad", run, 5, 200, 0, true)),
        ("ghost", frame("ghost", run, 1, 0, 50, false)),
    ];
    rt().block_on(async {
        let js = async_nats::jetstream::new(client(&url).await);
        let cells = js.get_key_value(CELLS_BUCKET).await.expect("bucket");
        cells
            .put("bad", serde_json::to_vec(&info).expect("json").into())
            .await
            .expect("register");
        let mut zero_rate = info.clone();
        zero_rate.cell = "badreg".into();
        zero_rate.rate_hz = 0.0;
        cells
            .put(
                "badreg",
                serde_json::to_vec(&zero_rate).expect("json").into(),
            )
            .await
            .expect("register");
        for (k, (cell, bytes)) in sent.into_iter().enumerate() {
            js.send_publish(
                format!("physid.cell.{cell}.samples"),
                async_nats::jetstream::message::PublishMessage::build()
                    .payload(bytes.into())
                    .message_id(format!("test-{k}")),
            )
            .await
            .expect("publish")
            .await
            .expect("ack");
        }
    });
    let got = wait_events(&url, "bad", 30, has_end);
    let errors: Vec<String> = got
        .iter()
        .filter(|e| e["type"] == "error")
        .map(|e| e["message"].as_str().unwrap_or_default().to_string())
        .collect();
    let expect = [
        "not a readable Arrow IPC stream",
        "a frame of cell 'other' on cell 'bad''s subject",
        "no column 't'",
        "column 't' is Int64: expected float64",
        "frame 2 again or out of order",
        "frame 3 again or out of order",
    ];
    assert_eq!(errors.len(), expect.len(), "{errors:#?}");
    for (e, x) in errors.iter().zip(expect) {
        assert!(e.contains(x), "'{e}' should say '{x}'");
    }
    assert!(
        got.iter().any(|e| e["type"] == "finding"
            && e["message"]
                .as_str()
                .unwrap_or("")
                .contains("frames 3–3 are missing")),
        "{got:#?}"
    );
    let end = got.iter().find(|e| e["type"] == "end").expect("end");
    assert_eq!(
        end["samples"], 150,
        "frames 1, 2 and 4: 150 samples, nothing else"
    );
    assert_eq!(end["dropped"], expect.len());
    let ghost = wait_events(&url, "ghost", 30, |e| !e.is_empty());
    assert!(
        ghost[0]["message"]
            .as_str()
            .unwrap_or("")
            .contains("unknown cell 'ghost'"),
        "{ghost:?}"
    );
    // A registry entry that is not a valid cell's is told, not processed.
    let badreg = wait_events(&url, "badreg", 30, |e| !e.is_empty());
    assert!(
        badreg[0]["message"]
            .as_str()
            .unwrap_or("")
            .contains("'rate_hz' is 0"),
        "{badreg:?}"
    );
    w.sigterm();
    assert!(
        w.wait(20).status.success(),
        "the worker went on and ends cleanly"
    );
}

fn wait_for_bucket(url: &str) {
    let deadline = Instant::now() + Duration::from_secs(20);
    while rt().block_on(async {
        let js = async_nats::jetstream::new(client(url).await);
        js.get_key_value(CELLS_BUCKET).await.is_err()
    }) {
        assert!(Instant::now() < deadline, "the worker made no buckets");
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// The frames stored for `cell`, decoded, in order.
fn frames(url: &str, cell: &str) -> Vec<Frame> {
    stored(url, "PHYSID_SAMPLES", format!("physid.cell.{cell}.samples"))
        .iter()
        .map(|m| wire::decode(m).expect("a frame"))
        .collect()
}

/// A publisher gathers its source's 10 ms chunks into frames of `--frame` seconds (0.05 by
/// default: fewer, larger messages), or sends a frame per chunk at `--frame 0`; either way
/// every sample once, in order, the frames numbered 1, 2, 3, … and the last an empty end.
#[test]
fn a_publisher_gathers_its_chunks_into_frames() {
    let Some(server) = nats_server(&[]) else {
        return;
    };
    let url = server.url("");
    for (cell, frame, rows) in [
        ("g", None, 500),
        ("g0", Some("0"), 100),
        ("g2", Some("0.2"), 2000),
    ] {
        let mut args = vec![
            "live",
            "--nats",
            &url,
            "--cell",
            cell,
            "--scenario",
            "shaft-steady",
            "--duration",
            "1",
            "--pace",
            "max",
            "--chunk",
            "0.01",
            "--json",
        ];
        if let Some(f) = frame {
            args.extend_from_slice(&["--frame", f]);
        }
        let out = Proc::start(&args).wait(60);
        assert!(out.status.success(), "{}", out.stderr);
        let summary: Value = serde_json::from_str(out.stdout.trim()).expect("summary");
        let got = frames(&url, cell);
        assert_eq!(summary["frames"], got.len(), "{cell}");
        let (last, data) = got.split_last().expect("frames");
        assert!(
            last.end && last.chunk.is_empty(),
            "{cell}: the end frame last"
        );
        let mut first = 0;
        for (k, f) in data.iter().enumerate() {
            assert_eq!(f.seq, k as u64 + 1);
            assert_eq!(f.first_sample, first);
            assert!(!f.end);
            // Every frame but the run's last holds the whole number of 10 ms chunks nearest
            // to `--frame` (a chunk is 99–101 samples).
            let n = f.chunk.len() as i64;
            if k + 1 < data.len() {
                let chunks = (rows / 100).max(1) as i64;
                assert!(
                    (n - rows as i64).abs() <= chunks,
                    "{cell}: frame {} of {n} samples",
                    f.seq
                );
            } else {
                assert!((1..=rows as i64 + 5).contains(&n), "{cell}");
            }
            first += f.chunk.len() as u64;
        }
        assert_eq!(summary["samples"], first, "{cell}: every sample once");
        let t: Vec<f64> = data
            .iter()
            .flat_map(|f| f.chunk.values("t").unwrap().to_vec())
            .collect();
        assert!(t.windows(2).all(|w| w[1] > w[0]), "{cell}: in order");
    }
}

/// A server that requires credentials refuses a client without them or with wrong ones: the
/// worker and the publisher exit at once with an authentication error that shows no secret.
#[test]
fn a_client_without_credentials_is_refused() {
    let Some(server) = nats_server(&["--user", "physid", "--pass", "s3cret-pw"]) else {
        return;
    };
    for url in [server.url(""), server.url("physid:wrong@")] {
        for args in [
            vec!["worker", "--nats", &url],
            vec!["live", "--nats", &url, "--cell", "c", "--duration", "1"],
        ] {
            let exit = Proc::start(&args).wait(20);
            assert!(!exit.status.success(), "{args:?}");
            let err = exit.stderr.to_lowercase();
            assert!(err.contains("authorization"), "{args:?}: {err}");
            assert!(!err.contains("wrong") && !err.contains("s3cret"), "{err}");
        }
    }
}

/// The fleet view in a real Chromium: two cells (one with a stiffness fault) through a worker;
/// the view lists both with their state, K and B, the alarm of the faulty one; its name opens
/// the cell's live view, fed from NATS, which shows the K alarm; a control sent from that view
/// reaches the cell's publisher and is answered; a publisher stopped by SIGTERM ends its run.
#[test]
fn the_fleet_view_in_a_real_browser() {
    let Some(server) = nats_server(&[]) else {
        return;
    };
    let url = server.url("");
    let _w = Proc::start(&["worker", "--nats", &url, "--name", "w"]);
    let common_args = [
        "--scenario",
        "shaft-steady",
        "--duration",
        "30",
        "--pace",
        "2",
    ];
    // `--json`: its summary at the end (what it published), to account for every sample.
    let mut a = vec!["live", "--nats", &url, "--cell", "cell-1", "--json"];
    a.extend_from_slice(&common_args);
    let _c1 = Proc::start(&a);
    let mut b = vec![
        "live",
        "--nats",
        &url,
        "--cell",
        "cell-2",
        "--fault",
        "shaft.k=1000@3",
    ];
    b.extend_from_slice(&common_args);
    let _c2 = Proc::start(&b);
    let scratch = physid_testkit::Scratch::new("physid-fleet-view");
    let view_err = scratch.file("view.err");
    let mut view = Command::new(PHYSID)
        .args(["live", "--fleet", &url, "--port", "0"])
        .stdout(Stdio::piped())
        .stderr(std::fs::File::create(&view_err).expect("view.err"))
        .spawn()
        .expect("physid live --fleet");
    let mut line = String::new();
    BufReader::new(view.stdout.take().expect("stdout"))
        .read_line(&mut line)
        .expect("the address");
    let page = line.trim().rsplit(' ').next().expect("url").to_string();
    assert!(
        page.starts_with("http://127.0.0.1:"),
        "{line}: {}",
        std::fs::read_to_string(&view_err).unwrap_or_default()
    );
    rt().block_on(async {
        let Some(browser) = common::Browser::start("1400,900").await else {
            return;
        };
        let c = browser.client.clone();
        c.goto(&page).await.expect("open the fleet view");
        let two = "window.physidFleet.cells.length === 2 && window.physidFleet.cells.every(c => c.estimate && c.state === 'running')";
        browser.wait(two, 40).await;
        browser
            .wait("window.physidFleet.cells.some(c => c.cell === 'cell-2' && c.alarms > 0)", 40)
            .await;
        let cells = browser.js("window.physidFleet.cells").await;
        let k = |i: usize| cells[i]["estimate"]["params"]["K"].as_f64().expect("K");
        assert_eq!(cells[0]["cell"], "cell-1");
        assert_eq!(cells[0]["alarms"], 0);
        assert!((k(0) - 1250.0).abs() < 10.0, "cell-1 K {}", k(0));
        assert_eq!(cells[1]["last_alarm"]["param"], "K");
        assert_eq!(
            browser.js("document.querySelectorAll('#cells tbody tr').length").await,
            json!(2)
        );
        let png = c.screenshot().await.expect("screenshot");
        std::fs::write(PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("fleet-view.png"), &png)
            .expect("write");
        if std::env::var_os("PHYSID_UPDATE_DOCS").is_some() {
            let docs = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../docs/fleet-view.png");
            std::fs::write(docs, &png).expect("write");
        }
        // The table is updated in place: the row under the operator's pointer is the same
        // element two polls later (rebuilt each second, a click could land on a row gone).
        browser
            .js("(window.heldRow = document.querySelector(\"#cells tr[data-cell='cell-2'] a\"), window.heldPolls = window.physidFleet.polls, true)")
            .await;
        browser.wait("window.physidFleet.polls >= window.heldPolls + 2", 10).await;
        assert_eq!(
            browser
                .js("window.heldRow.isConnected && window.heldRow === document.querySelector(\"#cells tr[data-cell='cell-2'] a\")")
                .await,
            json!(true),
            "the fleet table's rows are replaced on every poll"
        );
        // A click on cell-2 opens its live view, fed from NATS: its K alarm is there.
        c.find(fantoccini::Locator::Css("#cells tr[data-cell='cell-2'] a"))
            .await
            .expect("the link")
            .click()
            .await
            .expect("click");
        browser
            .wait("window.physid && window.physid.estimates > 5 && window.physid.alarms > 0", 30)
            .await;
        assert!(browser.js("location.search").await.as_str().unwrap_or("").contains("cell=cell-2"));
        assert_eq!(browser.js("window.physid.first.alarm.param").await, json!("K"));
        let k2 = browser.js("window.physid.last.estimate.params.K").await.as_f64().expect("K");
        assert!((k2 - 1000.0).abs() < 10.0, "cell-2 K {k2}");
        // A control from the cell's view goes to its publisher and is answered.
        let answer = browser
            .client
            .execute_async(
                "const done = arguments[0]; fetch('api/control?cell=cell-2', {method: 'POST', headers: {'Content-Type': 'application/json'}, body: JSON.stringify({cmd: 'speed', rpm: 1100})}).then(r => r.json()).then(done);",
                vec![],
            )
            .await
            .expect("control");
        assert_eq!(answer["ok"], true, "{answer}");
        assert_eq!(answer["cmd"], "speed");
        // A cell the fleet does not have is refused.
        let missing = browser
            .client
            .execute_async(
                "const done = arguments[0]; fetch('api/events?cell=nope').then(r => done(r.status));",
                vec![],
            )
            .await
            .expect("status");
        assert_eq!(missing, json!(404));
        c.close().await.expect("close");
    });
    let _ = view.kill();
    let _ = view.wait();
    // A publisher stopped by SIGTERM ends its run cleanly: an end frame, exit 0, and the
    // worker finishes the cell with its end event.
    _c1.sigterm();
    let exit = _c1.wait(30);
    assert!(exit.status.success(), "{}", exit.stderr);
    let e = wait_events(&url, "cell-1", 30, has_end);
    let end = e.iter().find(|e| e["type"] == "end").expect("end");
    // Every sample it published before the signal, once.
    let published: Value = serde_json::from_str(exit.stdout.trim()).expect("summary");
    assert!(
        published["samples"].as_u64().unwrap_or(0) > 0,
        "{published}"
    );
    assert_eq!(end["samples"], published["samples"], "{published}");
}

/// `physid bench fleet`'s table gives the sample accounting on every run (not only in
/// `--json`), and its latencies rounded alike; its JSON's latencies are to 0.1 ms.
#[test]
fn bench_fleet_prints_the_sample_accounting() {
    if nats_server_bin().is_none() {
        let _ = nats_server(&[]); // skips (or fails on CI)
        return;
    }
    let out = common::physid(&["bench", "fleet", "--cells", "2", "--seconds", "2"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let line = text
        .lines()
        .find(|l| l.trim_start().starts_with("samples published"))
        .unwrap_or_else(|| panic!("no accounting line in\n{text}"));
    let n: Vec<u64> = line
        .split(|c: char| !c.is_ascii_digit())
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().unwrap())
        .collect();
    // published, processed, refused, resent, cells ended, cells.
    assert_eq!(n.len(), 6, "{line}");
    assert!(
        n[0] > 0 && n[0] == n[1] && n[2] == 0 && n[4] == 2 && n[5] == 2,
        "{line}"
    );
    let json = common::physid(&["bench", "fleet", "--cells", "1", "--seconds", "2", "--json"]);
    let v: Value = serde_json::from_slice(&json.stdout).unwrap();
    for q in v["latency_ms"].as_array().unwrap() {
        let ms = q.as_f64().unwrap();
        assert_eq!((ms * 10.0).round() / 10.0, ms, "{v}");
    }
}
