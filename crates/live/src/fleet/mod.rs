//! The fleet: many test cells on NATS JetStream (docs/fleet.md).
//!
//! * [`publish`] — `physid live --nats URL --cell ID`: a source's chunks as frames
//!   ([`crate::wire`]) on the cell's samples subject, controls taken on its control subject.
//! * [`load`] — `physid bench fleet`: N cells at real time, measured; [`local`] — a local
//!   `nats-server` for the tests and the benchmark.
//! * [`view`] — the panel's fleet view (`physid live --fleet URL`).
//! * [`worker`] — `physid worker --nats URL`: the applications' stages ([`crate::Stages`]) for
//!   whichever cells need them, one worker per cell at a time (a lease), the stages' state
//!   checkpointed so that another worker takes a cell over where it was.
//!
//! The names, stable (documented in docs/fleet.md):
//!
//! | what                         | name                                   |
//! |------------------------------|----------------------------------------|
//! | a cell's samples (frames)    | subject `physid.cell.<ID>.samples`, stream `PHYSID_SAMPLES` |
//! | a cell's events (JSON)       | subject `physid.cell.<ID>.events`, stream `PHYSID_EVENTS`   |
//! | a cell's controls (request)  | subject `physid.cell.<ID>.control`                          |
//! | the cells (registry)         | key-value bucket `physid_cells`, key `<ID>`                 |
//! | which worker has a cell      | key-value bucket `physid_leases`, key `<ID>` (expires)      |
//! | a cell's checkpoint          | key-value bucket `physid_checkpoints`, key `<ID>` (a state over the message limit: in parts, keys `<ID>.<slot>.<k>`) |

mod checkpoint;
pub mod load;
pub mod local;
pub mod publish;
pub mod view;
pub mod worker;

use async_nats::jetstream::{self, kv, stream};
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// The stream of every cell's frames.
pub const SAMPLES_STREAM: &str = "PHYSID_SAMPLES";
/// The stream of every cell's events.
pub const EVENTS_STREAM: &str = "PHYSID_EVENTS";
/// The registry of cells.
pub const CELLS_BUCKET: &str = "physid_cells";
/// The workers' leases on cells.
pub const LEASES_BUCKET: &str = "physid_leases";
/// The cells' checkpoints.
pub const CHECKPOINTS_BUCKET: &str = "physid_checkpoints";
/// A lease not renewed for this long expires, and another worker may take the cell.
pub const LEASE_TTL: Duration = Duration::from_secs(3);
/// How long a message id is remembered: a frame or an event sent again within it (a
/// publisher's retry, a worker's replay after a takeover) is stored once.
pub const DUPLICATE_WINDOW: Duration = Duration::from_secs(600);

/// How long the samples stream keeps a frame: a worker down for longer misses the frames before
/// (it reports them as missing, and goes on); the recordings themselves are logged elsewhere.
pub const SAMPLES_MAX_AGE: Duration = Duration::from_secs(600);
/// How long the events stream keeps an event.
pub const EVENTS_MAX_AGE: Duration = Duration::from_secs(7 * 24 * 3600);

/// A cell's subject of `kind` (`samples`, `events`, `control`).
pub fn subject(cell: &str, kind: &str) -> String {
    format!("physid.cell.{cell}.{kind}")
}

/// Errors of the fleet.
#[derive(Debug, thiserror::Error)]
pub enum FleetError {
    /// Connecting, or a NATS operation that failed.
    #[error("NATS {what}: {detail}")]
    Nats {
        /// What was being done.
        what: String,
        /// The client's error.
        detail: String,
    },
    /// A setting or an input that is not valid.
    #[error("{0}")]
    Invalid(String),
    /// The stages.
    #[error(transparent)]
    Live(Box<crate::LiveError>),
}

impl From<crate::LiveError> for FleetError {
    fn from(e: crate::LiveError) -> Self {
        Self::Live(Box::new(e))
    }
}

/// A NATS error as a [`FleetError`] saying what was being done.
pub(crate) fn nats(
    what: impl Into<String>,
) -> impl FnOnce(Box<dyn std::error::Error + Send + Sync>) -> FleetError {
    let what = what.into();
    move |e| FleetError::Nats {
        what,
        detail: e.to_string(),
    }
}

/// Where the NATS server is and how to authenticate: `nats://HOST:PORT`, with credentials in
/// the URL (`nats://USER:PASSWORD@HOST:PORT`, `nats://TOKEN@HOST:PORT`) or in a credentials
/// file (`user = …`, `password = …` or `token = …` lines; read by the owner only).
#[derive(Clone)]
pub struct NatsTarget {
    /// The server's address without credentials (safe to print).
    pub address: String,
    auth: Auth,
}

#[derive(Clone)]
enum Auth {
    None,
    Token(String),
    UserPassword(String, String),
}

impl std::fmt::Debug for NatsTarget {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let auth = match self.auth {
            Auth::None => "none",
            Auth::Token(_) => "token",
            Auth::UserPassword(..) => "user and password",
        };
        write!(f, "{} (auth: {auth})", self.address)
    }
}

impl NatsTarget {
    /// The target of `url`, with the credentials of `credentials_file` if given (a file and
    /// credentials in the URL both is refused: which one was meant?).
    pub fn new(url: &str, credentials_file: Option<&Path>) -> Result<Self, FleetError> {
        let bad = |what: &str| {
            FleetError::Invalid(format!(
                "--nats '{}': {what} (expected nats://[USER:PASSWORD@ | TOKEN@]HOST:PORT)",
                redact(url)
            ))
        };
        let rest = url
            .strip_prefix("nats://")
            .ok_or_else(|| bad("the scheme is not nats://"))?;
        let (userinfo, hostport) = match rest.rsplit_once('@') {
            Some((u, h)) => (Some(u), h),
            None => (None, rest),
        };
        if hostport.is_empty() || hostport.contains('/') {
            return Err(bad("expected HOST:PORT after the scheme"));
        }
        let mut auth = match userinfo {
            None => Auth::None,
            Some(u) => match u.split_once(':') {
                Some((user, pass)) if !user.is_empty() => {
                    Auth::UserPassword(percent_decode(user), percent_decode(pass))
                }
                Some(_) => return Err(bad("an empty user name")),
                None if !u.is_empty() => Auth::Token(percent_decode(u)),
                None => return Err(bad("empty credentials before '@'")),
            },
        };
        if let Some(path) = credentials_file {
            if !matches!(auth, Auth::None) {
                return Err(bad(
                    "credentials both in the URL and in --nats-credentials; give one",
                ));
            }
            auth = read_credentials(path)?;
        }
        Ok(Self {
            address: format!("nats://{hostport}"),
            auth,
        })
    }

    /// Connect as `name` (shown in the server's monitoring), reconnecting for ever when the
    /// connection drops (each connection counted in `connections`: a consumer made before a
    /// reconnection is made again); the first connection is tried for up to `first_try`.
    pub async fn connect(
        &self,
        name: &str,
        first_try: Duration,
        connections: Arc<AtomicU64>,
    ) -> Result<async_nats::Client, FleetError> {
        let options = || {
            let connections = connections.clone();
            let opts = async_nats::ConnectOptions::new()
                .event_callback(move |e| {
                    if matches!(e, async_nats::Event::Connected) {
                        connections.fetch_add(1, Ordering::Relaxed);
                    }
                    async {}
                })
                .name(name)
                .max_reconnects(None)
                .reconnect_delay_callback(|n| Duration::from_millis((50 * n as u64).min(1000)))
                .connection_timeout(Duration::from_secs(2));
            match &self.auth {
                Auth::None => opts,
                Auth::Token(t) => opts.token(t.clone()),
                Auth::UserPassword(u, p) => opts.user_and_password(u.clone(), p.clone()),
            }
        };
        let deadline = tokio::time::Instant::now() + first_try;
        loop {
            match options().connect(self.address.as_str()).await {
                Ok(c) => return Ok(c),
                Err(e) => {
                    let auth = matches!(
                        e.kind(),
                        async_nats::ConnectErrorKind::Authentication
                            | async_nats::ConnectErrorKind::AuthorizationViolation
                    );
                    if auth || tokio::time::Instant::now() >= deadline {
                        return Err(FleetError::Nats {
                            what: format!("connecting to {}", self.address),
                            detail: e.to_string(),
                        });
                    }
                    tokio::time::sleep(Duration::from_millis(200)).await;
                }
            }
        }
    }
}

/// `url` with its credentials replaced by `***`.
pub fn redact(url: &str) -> String {
    match (url.split_once("://"), url.rsplit_once('@')) {
        (Some((scheme, _)), Some((_, host))) => format!("{scheme}://***@{host}"),
        _ => url.to_string(),
    }
}

fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut k = 0;
    while k < b.len() {
        if b[k] == b'%' && k + 2 < b.len() {
            if let Ok(v) = u8::from_str_radix(&s[k + 1..k + 3], 16) {
                out.push(v);
                k += 3;
                continue;
            }
        }
        out.push(b[k]);
        k += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// A credentials file: `user = NAME` and `password = SECRET`, or `token = SECRET` (blank lines
/// and `#` comments allowed).
fn read_credentials(path: &Path) -> Result<Auth, FleetError> {
    let p = path.display();
    let text = std::fs::read_to_string(path)
        .map_err(|e| FleetError::Invalid(format!("--nats-credentials {p}: {e}")))?;
    let (mut user, mut pass, mut token) = (None, None, None);
    for (k, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let Some((key, value)) = line.split_once('=') else {
            return Err(FleetError::Invalid(format!(
                "{p} line {}: expected KEY = VALUE (keys: user, password, token)",
                k + 1
            )));
        };
        let value = value.trim().trim_matches('"').to_string();
        match key.trim() {
            "user" => user = Some(value),
            "password" => pass = Some(value),
            "token" => token = Some(value),
            other => {
                return Err(FleetError::Invalid(format!(
                    "{p} line {}: unknown key '{other}' (keys: user, password, token)",
                    k + 1
                )))
            }
        }
    }
    match (user, pass, token) {
        (Some(u), Some(pw), None) => Ok(Auth::UserPassword(u, pw)),
        (None, None, Some(t)) => Ok(Auth::Token(t)),
        _ => Err(FleetError::Invalid(format!(
            "{p}: expected 'user' and 'password', or 'token' alone"
        ))),
    }
}

/// What the registry says of a cell (JSON in [`CELLS_BUCKET`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CellInfo {
    /// The cell id.
    pub cell: String,
    /// The run in progress (its publisher's start, ms since the Unix epoch).
    pub run: u64,
    /// The nominal sample rate [Hz].
    pub rate_hz: f64,
    /// What it publishes (a scenario's name, a replayed file).
    pub source: String,
    /// The angle of a firing TDC on `theta_en` [rad] (where cycles start).
    pub theta_tdc: f64,
}

/// Publish `payload` to JetStream as message `id` until the stream acknowledges it, retrying
/// with the same id (the stream stores it once) while the server is away, for up to `give_up`.
pub(crate) async fn send_until_acked(
    js: &jetstream::Context,
    subject: String,
    payload: bytes::Bytes,
    id: String,
    give_up: Duration,
) -> Result<u64, FleetError> {
    let started = tokio::time::Instant::now();
    let mut retries = 0;
    loop {
        let result = async {
            let ack = js
                .send_publish(
                    subject.clone(),
                    jetstream::message::PublishMessage::build()
                        .payload(payload.clone())
                        .message_id(&id),
                )
                .await
                .map_err(|e| e.to_string())?;
            tokio::time::timeout(Duration::from_secs(2), ack)
                .await
                .map_err(|_| "no acknowledgement within 2 s".to_string())?
                .map_err(|e| e.to_string())
        }
        .await;
        match result {
            Ok(_) => return Ok(retries),
            Err(e) if started.elapsed() >= give_up => {
                return Err(FleetError::Nats {
                    what: format!("publishing {id} to {subject} (tried for {give_up:?})"),
                    detail: e,
                })
            }
            Err(_) => {
                retries += 1;
                tokio::time::sleep(Duration::from_millis(100)).await;
            }
        }
    }
}

/// The streams and buckets of the fleet, created when missing (file storage).
pub struct Fleet {
    /// The connection (its server's `max_payload` bounds a checkpoint's part).
    pub client: async_nats::Client,
    /// The JetStream context.
    pub js: jetstream::Context,
    /// [`SAMPLES_STREAM`].
    pub samples: stream::Stream,
    /// [`CELLS_BUCKET`].
    pub cells: kv::Store,
    /// [`LEASES_BUCKET`].
    pub leases: kv::Store,
    /// [`CHECKPOINTS_BUCKET`].
    pub checkpoints: kv::Store,
}

/// Attempts at opening the fleet's streams and buckets before giving up: a JetStream request
/// can time out on a loaded server, and processes starting together race to create them.
const OPEN_ATTEMPTS: u32 = 5;

impl Fleet {
    /// Open (creating what is missing) the fleet's streams and buckets on `client`, trying again
    /// ([`OPEN_ATTEMPTS`] in all, 0.2, 0.4, 0.8 … s apart) when JetStream does not answer or
    /// another process created one meanwhile.
    pub async fn open(client: async_nats::Client) -> Result<Self, FleetError> {
        let mut wait = Duration::from_millis(200);
        let mut attempt = 1;
        loop {
            match Self::open_once(client.clone()).await {
                Ok(f) => return Ok(f),
                Err(e) if attempt >= OPEN_ATTEMPTS => return Err(e),
                Err(_) => {
                    tokio::time::sleep(wait).await;
                    wait *= 2;
                    attempt += 1;
                }
            }
        }
    }

    async fn open_once(client: async_nats::Client) -> Result<Self, FleetError> {
        let js = jetstream::new(client.clone());
        let stream_of = |name: &str, kind: &str, max_age: Duration| stream::Config {
            name: name.to_string(),
            subjects: vec![format!("physid.cell.*.{kind}")],
            storage: stream::StorageType::File,
            duplicate_window: DUPLICATE_WINDOW,
            max_age,
            ..Default::default()
        };
        let samples = js
            .get_or_create_stream(stream_of(SAMPLES_STREAM, "samples", SAMPLES_MAX_AGE))
            .await
            .map_err(|e| nats(format!("opening the stream {SAMPLES_STREAM}"))(e.into()))?;
        js.get_or_create_stream(stream_of(EVENTS_STREAM, "events", EVENTS_MAX_AGE))
            .await
            .map_err(|e| nats(format!("opening the stream {EVENTS_STREAM}"))(e.into()))?;
        // A bucket is the stream the client's `create_key_value` makes; made here because that
        // call first asks for the account's limits, which nats-server 2.9 (Debian 12's) answers
        // in a form this client does not read.
        let mut stores = Vec::new();
        for (name, max_age) in [
            (CELLS_BUCKET, Duration::ZERO),
            (LEASES_BUCKET, LEASE_TTL),
            (CHECKPOINTS_BUCKET, Duration::ZERO),
        ] {
            let config = stream::Config {
                name: format!("KV_{name}"),
                subjects: vec![format!("$KV.{name}.>")],
                max_messages_per_subject: 1,
                max_age,
                storage: stream::StorageType::File,
                allow_rollup: true,
                deny_delete: true,
                allow_direct: true,
                discard: stream::DiscardPolicy::New,
                num_replicas: 1,
                ..Default::default()
            };
            let what = format!("opening the bucket {name}");
            js.get_or_create_stream(config)
                .await
                .map_err(|e| nats(what.clone())(e.into()))?;
            stores.push(
                js.get_key_value(name)
                    .await
                    .map_err(|e| nats(what)(e.into()))?,
            );
        }
        let checkpoints = stores
            .pop()
            .ok_or_else(|| FleetError::Invalid("bucket".into()))?;
        let leases = stores
            .pop()
            .ok_or_else(|| FleetError::Invalid("bucket".into()))?;
        let cells = stores
            .pop()
            .ok_or_else(|| FleetError::Invalid("bucket".into()))?;
        Ok(Self {
            client,
            js,
            samples,
            cells,
            leases,
            checkpoints,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urls_and_credentials() {
        let t = NatsTarget::new("nats://127.0.0.1:4222", None).unwrap();
        assert_eq!(t.address, "nats://127.0.0.1:4222");
        assert!(matches!(t.auth, Auth::None));
        let t = NatsTarget::new("nats://ann:p%40ss@127.0.0.1:4222", None).unwrap();
        assert!(matches!(&t.auth, Auth::UserPassword(u, p) if u == "ann" && p == "p@ss"));
        assert_eq!(
            format!("{t:?}"),
            "nats://127.0.0.1:4222 (auth: user and password)"
        );
        let t = NatsTarget::new("nats://s3cret@127.0.0.1:4222", None).unwrap();
        assert!(matches!(&t.auth, Auth::Token(s) if s == "s3cret"));
        for bad in [
            "http://127.0.0.1:4222",
            "nats://",
            "nats://:x@h:1",
            "nats://@h:1",
        ] {
            let e = NatsTarget::new(bad, None).unwrap_err().to_string();
            assert!(e.contains("expected nats://"), "{bad}: {e}");
            assert!(
                !e.contains('x') || !bad.contains(":x@") || e.contains("***"),
                "{e}"
            );
        }
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("creds");
        std::fs::write(&f, "# fleet\nuser = ann\npassword = \"pw\"\n").unwrap();
        let t = NatsTarget::new("nats://127.0.0.1:1", Some(&f)).unwrap();
        assert!(matches!(&t.auth, Auth::UserPassword(u, p) if u == "ann" && p == "pw"));
        std::fs::write(&f, "user = ann\n").unwrap();
        assert!(NatsTarget::new("nats://127.0.0.1:1", Some(&f)).is_err());
        std::fs::write(&f, "secret\n").unwrap();
        let e = NatsTarget::new("nats://127.0.0.1:1", Some(&f))
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 1"), "{e}");
        assert!(NatsTarget::new("nats://u:p@127.0.0.1:1", Some(&f)).is_err());
    }
}
