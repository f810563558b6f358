//! The accept loop: every connection is served by hyper's HTTP/1 with a header-read timeout
//! and under a cap on open connections (axum's own `serve` sets neither, so idle connections
//! and connections stuck mid-header were never closed).
//!
//! - The header-read timeout closes a connection that has not sent a whole request head within
//!   [`ConnectionLimits::header_timeout`]: one that sends nothing, one stuck mid-header, and a
//!   kept-alive one idle that long between requests (hyper starts the timer whenever it waits
//!   for a request head). A request whose head arrived is never cut: a long solve answers.
//! - Beyond [`ConnectionLimits::max_connections`] open connections a new one is closed at
//!   once, so a flood of idle connections cannot exhaust the process's file descriptors (it
//!   holds each slot at most the timeout). Both apply before the token is checked.

use axum::Router;
use std::future::Future;
use std::sync::Arc;
use std::time::Duration;
use tokio::net::TcpListener;
use tokio::sync::Semaphore;

/// How long and how many connections the server keeps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConnectionLimits {
    /// Longest wait for a request's head (s), the idle time of a kept-alive connection too.
    pub header_timeout: Duration,
    /// Most open connections.
    pub max_connections: usize,
}

impl Default for ConnectionLimits {
    fn default() -> Self {
        Self {
            header_timeout: Duration::from_secs(10),
            max_connections: 512,
        }
    }
}

/// Pause after a failed `accept` (out of file descriptors, say) before the next.
const ACCEPT_RETRY: Duration = Duration::from_millis(100);

/// Serves `router` on `listener` within `limits` until `shutdown` completes.
pub async fn serve(
    listener: TcpListener,
    router: Router,
    limits: ConnectionLimits,
    shutdown: impl Future<Output = ()>,
) {
    let open = Arc::new(Semaphore::new(limits.max_connections.max(1)));
    tokio::pin!(shutdown);
    loop {
        let stream = tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok((stream, _)) => stream,
                Err(_) => {
                    tokio::time::sleep(ACCEPT_RETRY).await;
                    continue;
                }
            },
            () = &mut shutdown => return,
        };
        let Ok(slot) = open.clone().try_acquire_owned() else {
            drop(stream);
            continue;
        };
        let _ = stream.set_nodelay(true);
        let service = hyper_util::service::TowerToHyperService::new(router.clone());
        tokio::spawn(async move {
            let _slot = slot;
            // A connection's end (closed, reset, timed out) is not the server's error.
            let _ = hyper::server::conn::http1::Builder::new()
                .timer(hyper_util::rt::TokioTimer::new())
                .header_read_timeout(limits.header_timeout)
                .serve_connection(hyper_util::rt::TokioIo::new(stream), service)
                .await;
        });
    }
}
