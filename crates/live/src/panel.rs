//! The operator's panel: a web page (its assets embedded in the binary — it works with no
//! network) served on 127.0.0.1, the events streamed to it as server-sent events, its controls
//! posted back (docs/live.md).
//!
//! | route | what |
//! |---|---|
//! | `GET /` | the page |
//! | `GET /assets/NAME` | its script, style and uPlot (MIT, embedded) |
//! | `GET /api/events` | the event stream (`text/event-stream`; each event's `id` its number) |
//! | `POST /api/control` | a control message (`Content-Type: application/json`), answered `{"ok": true, "cmd": …}` or 400 `{"ok": false, "error": …}` naming the field |
//! | `POST /api/ack` | `{"seq": n}`: acknowledge alarm number `n` |
//! | `GET /api/status` | clients connected, messages slow clients lost |
//!
//! **Security.** The panel binds to 127.0.0.1 unless told otherwise. Binding any other address
//! needs a token; with a token, every `/api/` request must carry it (`Authorization: Bearer T`
//! or `?token=T`). Every request must name the panel in its `Host` ([`Access::host_allowed`]):
//! a web page whose domain an attacker points at 127.0.0.1 (DNS rebinding) names its own domain
//! and is refused on every route. Controls must be posted as JSON (at most
//! [`MAX_CONTROL_BYTES`]), and a request whose `Origin` is not the panel's own is refused:
//! another web site open in the operator's browser cannot drive the cell.

use crate::control::{ControlRequest, MAX_CONTROL_BYTES};
use crate::event::quote;
use crate::fleet::view::FleetView;
use crate::fleet::NatsTarget;
use crate::hub::Hub;
use crate::layout::Layout;
use crate::message::{Hello, PanelMessage, Reply};
use crate::service::LiveError;
use axum::extract::{DefaultBodyLimit, Query, Request, State};
use axum::http::{header, HeaderMap, StatusCode};
use axum::middleware::{self, Next};
use axum::response::sse::{Event as SseEvent, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use futures_util::stream::{self, Stream, StreamExt};
use serde_json::Value;
use std::collections::HashMap;
use std::convert::Infallible;
use std::net::{IpAddr, SocketAddr};
use std::sync::mpsc::{SyncSender, TrySendError};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::broadcast::error::RecvError;

/// The embedded assets: name, content type, content.
const ASSETS: [(&str, &str, &str); 6] = [
    (
        "fleet.js",
        "text/javascript; charset=utf-8",
        include_str!("../assets/fleet.js"),
    ),
    (
        "panel.js",
        "text/javascript; charset=utf-8",
        include_str!("../assets/panel.js"),
    ),
    (
        "panel.css",
        "text/css; charset=utf-8",
        include_str!("../assets/panel.css"),
    ),
    (
        "uPlot.iife.min.js",
        "text/javascript; charset=utf-8",
        include_str!("../assets/uPlot.iife.min.js"),
    ),
    (
        "uPlot.min.css",
        "text/css; charset=utf-8",
        include_str!("../assets/uPlot.min.css"),
    ),
    (
        "LICENSE-uPlot.txt",
        "text/plain; charset=utf-8",
        include_str!("../assets/LICENSE-uPlot.txt"),
    ),
];

const INDEX: &str = include_str!("../assets/index.html");
const FLEET: &str = include_str!("../assets/fleet.html");

/// The page: a fleet panel's fleet view, or the live view (of a run, or of `?cell=ID`).
async fn index(State(app): State<App>, Query(q): Query<HashMap<String, String>>) -> Response {
    let page = if app.fleet.is_some() && !q.contains_key("cell") {
        FLEET
    } else {
        INDEX
    };
    ([(header::CONTENT_TYPE, "text/html; charset=utf-8")], page).into_response()
}

/// `GET /api/layout`: the layout of `--layout FILE`, or `null` (the page's own).
async fn layout_file(State(app): State<App>) -> Response {
    Json(app.layout.as_ref().clone()).into_response()
}

/// `GET /api/fleet`: the fleet's cells (404 on a single-run panel).
async fn fleet_summary(State(app): State<App>) -> Response {
    match &app.fleet {
        Some(f) => Json(f.summary()).into_response(),
        None => refuse(
            StatusCode::NOT_FOUND,
            "this panel shows one run, not a fleet",
        ),
    }
}

/// How long a control request waits for the loop's answer.
const CONTROL_TIMEOUT: Duration = Duration::from_secs(5);

/// The panel's shared state.
#[derive(Clone)]
struct App {
    hub: Arc<Hub>,
    controls: SyncSender<ControlRequest>,
    access: Arc<Access>,
    /// The address the panel listens on.
    bound: SocketAddr,
    /// A fleet panel's cells.
    fleet: Option<Arc<FleetView>>,
    /// The page's starting layout (`--layout FILE`).
    layout: Arc<Option<Layout>>,
}

impl App {
    /// The hub a request is for: a fleet cell's (`cell=ID`) or the run's; a cell the fleet does
    /// not have is a 404.
    fn hub(&self, q: &HashMap<String, String>) -> Result<Arc<Hub>, Box<Response>> {
        match (&self.fleet, q.get("cell")) {
            (Some(f), Some(cell)) => f.hub(cell).ok_or_else(|| {
                Box::new(refuse(
                    StatusCode::NOT_FOUND,
                    format!("the fleet has no cell '{cell}'"),
                ))
            }),
            _ => Ok(self.hub.clone()),
        }
    }
}

/// Who may reach the panel: its token, and the host names (beyond IP addresses and
/// `localhost`) a request may name in its `Host` header.
#[derive(Debug, Clone, Default)]
pub struct Access {
    /// The secret every `/api/` request must carry (at least 8 characters).
    pub token: Option<String>,
    /// Names a request's `Host` may carry besides the panel's address: the name given to
    /// `--bind`, those of `--allow-host` (a reverse proxy's, the machine's DNS name).
    pub hosts: Vec<String>,
}

impl Access {
    /// Whether a request whose `Host` header is `host` is for a panel bound to `bind`. A DNS
    /// rebinding attack serves its page from a domain that resolves to the panel's address,
    /// so the browser sends that domain as `Host`; only the names the panel answers to pass:
    /// - an IP address: the one bound, any loopback one when bound to loopback, any when
    ///   bound to every address (an address literal cannot be rebound);
    /// - `localhost` when bound to loopback or every address;
    /// - a name in [`hosts`](Self::hosts).
    ///
    /// The port is not compared (a reverse proxy may carry its own); names are compared
    /// without case and a trailing dot.
    pub fn host_allowed(&self, host: &str, bind: IpAddr) -> bool {
        let name = host_name(host);
        if name.is_empty() {
            return false;
        }
        let loopback = bind.is_loopback();
        let every = bind.is_unspecified();
        if let Ok(ip) = name
            .trim_start_matches('[')
            .trim_end_matches(']')
            .parse::<IpAddr>()
        {
            return every || ip == bind || (loopback && ip.is_loopback());
        }
        (name == "localhost" && (loopback || every))
            || self.hosts.iter().any(|h| host_name(h) == name)
    }
}

/// The name part of a `Host` value (`[::1]:8750` → `[::1]`, `Example.COM.:80` →
/// `example.com`), lower-case without a trailing dot.
fn host_name(host: &str) -> String {
    let host = host.trim();
    let name = if host.starts_with('[') {
        host.split_inclusive(']').next().unwrap_or(host)
    } else {
        match host.rsplit_once(':') {
            Some((n, port)) if port.bytes().all(|b| b.is_ascii_digit()) => n,
            _ => host,
        }
    };
    name.trim_end_matches('.').to_ascii_lowercase()
}

/// A running panel server (on its own runtime threads).
pub struct Panel {
    /// Where it listens.
    pub addr: SocketAddr,
    rt: tokio::runtime::Runtime,
}

impl Panel {
    /// Serve the panel on `bind` for `hub`'s events, posting controls to `controls`. Binding
    /// an address other than a loopback one needs a token.
    /// `layout`: the page's starting layout (`--layout FILE`), served at `/api/layout`.
    pub fn start(
        bind: SocketAddr,
        access: Access,
        hub: Arc<Hub>,
        controls: SyncSender<ControlRequest>,
        layout: Option<Layout>,
    ) -> Result<Self, LiveError> {
        Self::launch(bind, access, hub, controls, None, layout)
    }

    /// Serve the fleet view of the fleet at `target` on `bind` (the same rules).
    pub fn start_fleet(
        bind: SocketAddr,
        access: Access,
        target: &NatsTarget,
    ) -> Result<Self, LiveError> {
        let hub = Hub::new(Hello::only("the fleet view: open a cell".into()));
        // The fleet view's own controls go to the cells, never here.
        let (controls, _) = std::sync::mpsc::sync_channel(1);
        Self::launch(bind, access, hub, controls, Some(target), None)
    }

    fn launch(
        bind: SocketAddr,
        access: Access,
        hub: Arc<Hub>,
        controls: SyncSender<ControlRequest>,
        fleet: Option<&NatsTarget>,
        layout: Option<Layout>,
    ) -> Result<Self, LiveError> {
        let token = &access.token;
        if !bind.ip().is_loopback() && token.is_none() {
            return Err(LiveError::Invalid(format!(
                "--bind {}: the panel can inject faults into the test cell; to serve it beyond \
                 this machine give --token (every client must then present it)",
                bind.ip()
            )));
        }
        if token.as_deref().is_some_and(|t| t.len() < 8) {
            return Err(LiveError::Invalid(
                "--token: expected at least 8 characters".into(),
            ));
        }
        let rt = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .thread_name("physid-panel")
            .enable_all()
            .build()
            .map_err(|e| LiveError::Invalid(format!("starting the panel's runtime: {e}")))?;
        let listener = rt
            .block_on(tokio::net::TcpListener::bind(bind))
            .map_err(|e| LiveError::Invalid(format!("listening on {bind}: {e}")))?;
        let addr = listener
            .local_addr()
            .map_err(|e| LiveError::Invalid(format!("listening on {bind}: {e}")))?;
        let fleet = match fleet {
            Some(t) => Some(
                rt.block_on(FleetView::start(t))
                    .map_err(|e| LiveError::Invalid(e.to_string()))?,
            ),
            None => None,
        };
        let app = App {
            hub: hub.clone(),
            controls,
            access: Arc::new(access),
            bound: addr,
            fleet,
            layout: Arc::new(layout),
        };
        let api = Router::new()
            .route("/events", get(events))
            .route("/control", post(control))
            .route("/ack", post(ack))
            .route("/status", get(status))
            .route("/fleet", get(fleet_summary))
            .route("/layout", get(layout_file))
            .route_layer(middleware::from_fn_with_state(app.clone(), guard))
            .layer(DefaultBodyLimit::max(MAX_CONTROL_BYTES));
        // The Host rule holds on every route, the page's included.
        let router = Router::new()
            .route("/", get(index))
            .route("/assets/{name}", get(asset))
            .nest("/api", api)
            .layer(middleware::from_fn_with_state(app.clone(), host_guard))
            .with_state(app);
        rt.spawn(async move {
            // Serving ends with the runtime.
            crate::serve::serve(listener, router).await;
        });
        rt.spawn(status_ticker(hub));
        Ok(Self { addr, rt })
    }

    /// Block until SIGINT or SIGTERM.
    pub fn wait_for_shutdown(&self) {
        self.rt.block_on(async {
            #[cfg(unix)]
            {
                use tokio::signal::unix::{signal, SignalKind};
                match signal(SignalKind::terminate()) {
                    Ok(mut term) => {
                        tokio::select! {
                            _ = tokio::signal::ctrl_c() => {}
                            _ = term.recv() => {}
                        }
                    }
                    Err(_) => {
                        let _ = tokio::signal::ctrl_c().await;
                    }
                }
            }
            #[cfg(not(unix))]
            {
                let _ = tokio::signal::ctrl_c().await;
            }
        });
    }
}

/// Publish `{"type": "status", "clients": n, "lagged": n}` each second it changes.
async fn status_ticker(hub: Arc<Hub>) {
    let mut last = (usize::MAX, u64::MAX);
    let mut tick = tokio::time::interval(Duration::from_secs(1));
    loop {
        tick.tick().await;
        let now = (hub.clients(), hub.lagged());
        if now != last {
            hub.publish_message(&PanelMessage::Status {
                clients: now.0,
                lagged: now.1,
            });
            last = now;
        }
    }
}

/// An error reply: `{"ok": false, "error": …}`.
fn refuse(code: StatusCode, error: impl Into<String>) -> Response {
    (code, Json(Reply::refused(error))).into_response()
}

/// The Host rule ([`Access::host_allowed`]) on every route: 421 Misdirected Request.
async fn host_guard(State(app): State<App>, req: Request, next: Next) -> Response {
    let host = req
        .headers()
        .get(header::HOST)
        .and_then(|v| v.to_str().ok())
        .or_else(|| req.uri().authority().map(|a| a.as_str()))
        .unwrap_or("");
    if !app.access.host_allowed(host, app.bound.ip()) {
        return refuse(
            StatusCode::MISDIRECTED_REQUEST,
            format!(
                "a request for host '{}' reached the panel at {}: refused (a page of another site \
                 may be reaching it through DNS rebinding); to serve the panel under a name, \
                 start it with --allow-host NAME",
                quote(host, 100),
                app.bound
            ),
        );
    }
    next.run(req).await
}

/// The token rule and the same-origin rule for `/api/`.
async fn guard(
    State(app): State<App>,
    Query(q): Query<HashMap<String, String>>,
    headers: HeaderMap,
    req: Request,
    next: Next,
) -> Response {
    if let Some(want) = &app.access.token {
        let bearer = headers
            .get(header::AUTHORIZATION)
            .and_then(|v| v.to_str().ok())
            .and_then(|v| v.strip_prefix("Bearer "));
        let given = bearer.or(q.get("token").map(String::as_str));
        if !given.is_some_and(|g| same(g.as_bytes(), want.as_bytes())) {
            return refuse(
                StatusCode::UNAUTHORIZED,
                "this panel needs its token: open the address physid live printed (with ?token=…), \
                 or send Authorization: Bearer TOKEN",
            );
        }
    }
    if let Some(origin) = headers.get(header::ORIGIN).and_then(|v| v.to_str().ok()) {
        let host = headers
            .get(header::HOST)
            .and_then(|v| v.to_str().ok())
            .unwrap_or("");
        let origin_host = origin.split("://").nth(1).unwrap_or("");
        if origin_host != host {
            return refuse(
                StatusCode::FORBIDDEN,
                format!(
                    "a request from {} to the panel at {}: only the panel's own page may send it",
                    quote(origin, 100),
                    quote(host, 100)
                ),
            );
        }
    }
    next.run(req).await
}

/// Compare without stopping at the first difference.
fn same(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

async fn asset(axum::extract::Path(name): axum::extract::Path<String>) -> Response {
    match ASSETS.iter().find(|(n, _, _)| *n == name) {
        Some((_, ty, body)) => (
            [
                (header::CONTENT_TYPE, *ty),
                (header::CACHE_CONTROL, "no-cache"),
            ],
            *body,
        )
            .into_response(),
        None => refuse(StatusCode::NOT_FOUND, format!("no asset '{name}'")),
    }
}

async fn status(State(app): State<App>, Query(q): Query<HashMap<String, String>>) -> Response {
    match app.hub(&q) {
        Ok(hub) => Json(PanelMessage::Status {
            clients: hub.clients(),
            lagged: hub.lagged(),
        })
        .into_response(),
        Err(r) => *r,
    }
}

/// The body must be declared JSON (a cross-site form cannot do that without the panel's
/// consent).
fn json_body(headers: &HeaderMap, body: &str) -> Result<Value, (StatusCode, String)> {
    let ty = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .unwrap_or("");
    if !ty.starts_with("application/json") {
        return Err((
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
            format!(
                "Content-Type '{}': expected application/json",
                quote(ty, 100)
            ),
        ));
    }
    serde_json::from_str(body)
        .map_err(|e| (StatusCode::BAD_REQUEST, format!("not a JSON object: {e}")))
}

async fn control(
    State(app): State<App>,
    Query(q): Query<HashMap<String, String>>,
    headers: HeaderMap,
    body: String,
) -> Response {
    if let Err((code, e)) = json_body(&headers, &body) {
        return refuse(code, e);
    }
    if let (Some(f), Some(cell)) = (&app.fleet, q.get("cell")) {
        return match f.control(cell, body).await {
            Ok(v) if v.ok => Json(v).into_response(),
            Ok(v) => (StatusCode::BAD_REQUEST, Json(v)).into_response(),
            Err(e) => refuse(StatusCode::BAD_GATEWAY, e),
        };
    }
    let (tx, rx) = tokio::sync::oneshot::channel();
    let req = ControlRequest {
        text: Ok(body),
        reply: Some(tx),
    };
    match app.controls.try_send(req) {
        Ok(()) => {}
        Err(TrySendError::Full(_)) => {
            return refuse(
                StatusCode::SERVICE_UNAVAILABLE,
                "too many control messages waiting: try again",
            )
        }
        Err(TrySendError::Disconnected(_)) => {
            return refuse(StatusCode::CONFLICT, "the run has ended")
        }
    }
    match tokio::time::timeout(CONTROL_TIMEOUT, rx).await {
        Ok(Ok(Ok(cmd))) => Json(Reply::applied(cmd)).into_response(),
        Ok(Ok(Err(e))) => refuse(StatusCode::BAD_REQUEST, e),
        Ok(Err(_)) => refuse(StatusCode::CONFLICT, "the run has ended"),
        Err(_) => refuse(
            StatusCode::GATEWAY_TIMEOUT,
            "no answer from the run within 5 s (the message stays queued)",
        ),
    }
}

async fn ack(
    State(app): State<App>,
    Query(q): Query<HashMap<String, String>>,
    headers: HeaderMap,
    body: String,
) -> Response {
    let v = match json_body(&headers, &body) {
        Ok(v) => v,
        Err((code, e)) => return refuse(code, e),
    };
    let hub = match app.hub(&q) {
        Ok(h) => h,
        Err(r) => return *r,
    };
    match v.get("seq").and_then(Value::as_u64) {
        Some(seq) if hub.is_alarm(seq) => {
            hub.acknowledge(seq);
            Json(Reply::acknowledged(seq)).into_response()
        }
        Some(seq) => refuse(
            StatusCode::BAD_REQUEST,
            format!("field 'seq' is {seq}: not an alarm's number"),
        ),
        None => refuse(
            StatusCode::BAD_REQUEST,
            "field 'seq' is missing or not a whole number",
        ),
    }
}

async fn events(State(app): State<App>, Query(q): Query<HashMap<String, String>>) -> Response {
    match app.hub(&q) {
        Ok(hub) => event_stream(hub).into_response(),
        Err(r) => *r,
    }
}

fn event_stream(hub: Arc<Hub>) -> Sse<impl Stream<Item = Result<SseEvent, Infallible>>> {
    let sub = hub.subscribe();
    let sse = |(seq, text): &(u64, Arc<str>)| -> Result<SseEvent, Infallible> {
        Ok(SseEvent::default().id(seq.to_string()).data(&**text))
    };
    let backlog = stream::iter(sub.backlog.iter().map(sse).collect::<Vec<_>>());
    let live = stream::unfold(
        (sub.rx, sub.after, sub.guard, hub),
        move |(mut rx, after, guard, hub)| async move {
            loop {
                match rx.recv().await {
                    Ok((seq, _)) if seq <= after => continue,
                    Ok(m) => return Some((sse(&m), (rx, after, guard, hub))),
                    Err(RecvError::Lagged(n)) => {
                        hub.count_lagged(n);
                        let e =
                            SseEvent::default().data(PanelMessage::Lagged { dropped: n }.to_json());
                        return Some((Ok(e), (rx, after, guard, hub)));
                    }
                    Err(RecvError::Closed) => return None,
                }
            }
        },
    );
    Sse::new(backlog.chain(live)).keep_alive(KeepAlive::default())
}
