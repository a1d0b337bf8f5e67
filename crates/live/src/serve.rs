//! How the panel's HTTP connections are taken: at most [`MAX_CONNECTIONS`] at a time, and a
//! request's header read within [`HEADER_TIMEOUT`]. `axum::serve` takes every connection and
//! waits for a header for ever: a client on the network (or a script gone wrong) holding
//! 12 000 idle connections made the service hold 12 000 file descriptors — past the process's
//! limit, the next log the operator starts cannot open its file. Here a connection past the
//! cap is closed at once (the ones being served go on), and one that does not send its
//! request's header in time is closed, so the slots come back.

use axum::Router;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::service::TowerToHyperService;
use std::sync::Arc;
use std::time::Duration;
use tokio::net::TcpListener;
use tokio::sync::Semaphore;

/// The most connections served at a time: a panel has a few viewers (each page holds one
/// event stream and makes a request now and then).
pub const MAX_CONNECTIONS: usize = 256;

/// How long a connection may take to send a request's header (the first, and each next one
/// on a kept-alive connection) before it is closed.
pub const HEADER_TIMEOUT: Duration = Duration::from_secs(10);

/// Serve `router` on `listener` for ever (until the runtime ends), by the rules above.
pub async fn serve(listener: TcpListener, router: Router) {
    let slots = Arc::new(Semaphore::new(MAX_CONNECTIONS));
    loop {
        let stream = match listener.accept().await {
            Ok((stream, _)) => stream,
            // Out of file descriptors or a connection reset before it was taken: wait a little
            // and go on (as axum::serve does) — never end the panel.
            Err(_) => {
                tokio::time::sleep(Duration::from_millis(50)).await;
                continue;
            }
        };
        // Past the cap: closed at once (dropped), not queued.
        let Ok(slot) = slots.clone().try_acquire_owned() else {
            continue;
        };
        let service = TowerToHyperService::new(router.clone());
        tokio::spawn(async move {
            let _ = hyper::server::conn::http1::Builder::new()
                .timer(TokioTimer::new())
                .header_read_timeout(HEADER_TIMEOUT)
                .serve_connection(TokioIo::new(stream), service)
                .await;
            drop(slot);
        });
    }
}
