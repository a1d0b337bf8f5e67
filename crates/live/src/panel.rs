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
//! or `?token=T`). Controls must be posted as JSON, and a request whose `Origin` is not the
//! panel's own is refused: another web site open in the operator's browser cannot drive the
//! cell.

use crate::control::ControlRequest;
use crate::fleet::view::FleetView;
use crate::fleet::NatsTarget;
use crate::hub::Hub;
use crate::service::LiveError;
use axum::extract::{Query, Request, State};
use axum::http::{header, HeaderMap, StatusCode};
use axum::middleware::{self, Next};
use axum::response::sse::{Event as SseEvent, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use futures_util::stream::{self, Stream, StreamExt};
use serde_json::{json, Value};
use std::collections::HashMap;
use std::convert::Infallible;
use std::net::SocketAddr;
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
    token: Option<Arc<str>>,
    /// A fleet panel's cells.
    fleet: Option<Arc<FleetView>>,
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

/// A running panel server (on its own runtime threads).
pub struct Panel {
    /// Where it listens.
    pub addr: SocketAddr,
    rt: tokio::runtime::Runtime,
}

impl Panel {
    /// Serve the panel on `bind` for `hub`'s events, posting controls to `controls`. Binding
    /// an address other than a loopback one needs a `token`.
    pub fn start(
        bind: SocketAddr,
        token: Option<String>,
        hub: Arc<Hub>,
        controls: SyncSender<ControlRequest>,
    ) -> Result<Self, LiveError> {
        Self::launch(bind, token, hub, controls, None)
    }

    /// Serve the fleet view of the fleet at `target` on `bind` (the same rules).
    pub fn start_fleet(
        bind: SocketAddr,
        token: Option<String>,
        target: &NatsTarget,
    ) -> Result<Self, LiveError> {
        let hub = Hub::new(json!({"type": "hello", "source": "the fleet view: open a cell"}));
        // The fleet view's own controls go to the cells, never here.
        let (controls, _) = std::sync::mpsc::sync_channel(1);
        Self::launch(bind, token, hub, controls, Some(target))
    }

    fn launch(
        bind: SocketAddr,
        token: Option<String>,
        hub: Arc<Hub>,
        controls: SyncSender<ControlRequest>,
        fleet: Option<&NatsTarget>,
    ) -> Result<Self, LiveError> {
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
            token: token.map(Into::into),
            fleet,
        };
        let api = Router::new()
            .route("/events", get(events))
            .route("/control", post(control))
            .route("/ack", post(ack))
            .route("/status", get(status))
            .route("/fleet", get(fleet_summary))
            .route_layer(middleware::from_fn_with_state(app.clone(), guard));
        let router = Router::new()
            .route("/", get(index))
            .route("/assets/{name}", get(asset))
            .nest("/api", api)
            .with_state(app);
        rt.spawn(async move {
            // Serving ends with the runtime.
            let _ = axum::serve(listener, router).await;
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
            hub.publish_json(&json!({"type": "status", "clients": now.0, "lagged": now.1}));
            last = now;
        }
    }
}

/// An error reply: `{"ok": false, "error": …}`.
fn refuse(code: StatusCode, error: impl Into<String>) -> Response {
    (code, Json(json!({"ok": false, "error": error.into()}))).into_response()
}

/// The token rule and the same-origin rule for `/api/`.
async fn guard(
    State(app): State<App>,
    Query(q): Query<HashMap<String, String>>,
    headers: HeaderMap,
    req: Request,
    next: Next,
) -> Response {
    if let Some(want) = &app.token {
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
                format!("a request from {origin} to the panel at {host}: only the panel's own page may send it"),
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
        Ok(hub) => Json(json!({"clients": hub.clients(), "lagged": hub.lagged()})).into_response(),
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
            format!("Content-Type '{ty}': expected application/json"),
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
            Ok(v) if v["ok"] == true => Json(v).into_response(),
            Ok(v) => (StatusCode::BAD_REQUEST, Json(v)).into_response(),
            Err(e) => refuse(StatusCode::BAD_GATEWAY, e),
        };
    }
    let (tx, rx) = tokio::sync::oneshot::channel();
    let req = ControlRequest {
        text: body,
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
        Ok(Ok(Ok(cmd))) => Json(json!({"ok": true, "cmd": cmd})).into_response(),
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
            Json(json!({"ok": true, "seq": seq})).into_response()
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
                        let e = SseEvent::default()
                            .data(json!({"type": "lagged", "dropped": n}).to_string());
                        return Some((Ok(e), (rx, after, guard, hub)));
                    }
                    Err(RecvError::Closed) => return None,
                }
            }
        },
    );
    Sse::new(backlog.chain(live)).keep_alive(KeepAlive::default())
}
