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
//!   holds each slot at most the timeout). Both apply before the token is checked. A body
//!   that does not arrive within [`ConnectionLimits::body_timeout`] of its head is cut by the
//!   router ([`crate::server`]), so a slot is never held longer than the two timeouts.
//! - hyper answers a request it cannot parse itself (a garbage request line, a negative
//!   `Content-Length`: 400; a head too large: 431) with an empty body; [`JsonErrors`] gives
//!   those answers the API's JSON error body, as every other error has.

use axum::Router;
use std::future::Future;
use std::io;
use std::pin::Pin;
use std::sync::Arc;
use std::task::{Context, Poll};
use std::time::Duration;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::TcpListener;
use tokio::sync::Semaphore;

/// How long and how many connections the server keeps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConnectionLimits {
    /// Longest wait for a request's head (s), the idle time of a kept-alive connection too.
    pub header_timeout: Duration,
    /// Most open connections.
    pub max_connections: usize,
    /// Longest wait for a request's body after its head (s).
    pub body_timeout: Duration,
}

impl Default for ConnectionLimits {
    fn default() -> Self {
        Self {
            header_timeout: Duration::from_secs(10),
            max_connections: 512,
            body_timeout: Duration::from_secs(10),
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
                .serve_connection(
                    hyper_util::rt::TokioIo::new(JsonErrors::new(stream)),
                    service,
                )
                .await;
        });
    }
}

/// A connection's stream that rewrites hyper's own error answers (written with an empty body,
/// before any answer of the router) into the API's JSON error answers; everything else passes
/// unchanged.
pub struct JsonErrors<S> {
    inner: S,
    /// Bytes of a rewritten answer not yet written.
    pending: Vec<u8>,
}

impl<S> JsonErrors<S> {
    /// Wraps `inner`.
    pub fn new(inner: S) -> Self {
        Self {
            inner,
            pending: Vec::new(),
        }
    }
}

/// The JSON answer replacing `head` when it is one of hyper's own error answers: an error
/// status with `content-length: 0` and nothing after the head. The router never answers an
/// error without a body, so such a head is hyper's.
pub fn rewrite_bare_error(head: &[u8]) -> Option<Vec<u8>> {
    let text = std::str::from_utf8(head).ok()?;
    let status_line = text.split("\r\n").next()?;
    let rest = status_line
        .strip_prefix("HTTP/1.1 ")
        .or_else(|| status_line.strip_prefix("HTTP/1.0 "))?;
    let status: u16 = rest.get(..3)?.parse().ok()?;
    let empty = text
        .to_ascii_lowercase()
        .contains("\r\ncontent-length: 0\r\n");
    if status < 400 || !empty || !text.ends_with("\r\n\r\n") {
        return None;
    }
    let (error, allowed) = match status {
        431 => ("the request head is too large", "a smaller head"),
        414 => ("the request's URI is too long", "a shorter URI"),
        _ => (
            "the request is not valid HTTP/1.1 (its request line, a header or its Content-Length)",
            "a request line `METHOD /path HTTP/1.1` and valid headers (a Content-Length of digits)",
        ),
    };
    let body =
        serde_json::json!({"error": error, "field": "request", "allowed": allowed}).to_string();
    Some(
        format!(
            "{status_line}\r\ncontent-type: application/json\r\ncontent-length: {}\r\nconnection: close\r\n\r\n{body}",
            body.len()
        )
        .into_bytes(),
    )
}

impl<S: AsyncWrite + Unpin> JsonErrors<S> {
    /// Writes what is left of a rewritten answer.
    fn poll_pending(&mut self, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        while !self.pending.is_empty() {
            let n = std::task::ready!(Pin::new(&mut self.inner).poll_write(cx, &self.pending))?;
            if n == 0 {
                return Poll::Ready(Err(io::ErrorKind::WriteZero.into()));
            }
            self.pending.drain(..n);
        }
        Poll::Ready(Ok(()))
    }
}

impl<S: AsyncRead + Unpin> AsyncRead for JsonErrors<S> {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_read(cx, buf)
    }
}

impl<S: AsyncWrite + Unpin> AsyncWrite for JsonErrors<S> {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        let this = &mut *self;
        std::task::ready!(this.poll_pending(cx))?;
        if let Some(answer) = rewrite_bare_error(buf) {
            this.pending = answer;
            // Taken whole: the rest is written by the next write, flush or shutdown.
            let _ = this.poll_pending(cx)?;
            return Poll::Ready(Ok(buf.len()));
        }
        Pin::new(&mut this.inner).poll_write(cx, buf)
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        std::task::ready!(self.poll_pending(cx))?;
        Pin::new(&mut self.inner).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        std::task::ready!(self.poll_pending(cx))?;
        Pin::new(&mut self.inner).poll_shutdown(cx)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_hypers_bare_error_answers_are_rewritten_as_json() {
        let bare = b"HTTP/1.1 400 Bad Request\r\ncontent-length: 0\r\ndate: Sun, 06 Dec 2026 00:00:00 GMT\r\n\r\n";
        let a = String::from_utf8(rewrite_bare_error(bare).unwrap()).unwrap();
        let (head, body) = a.split_once("\r\n\r\n").unwrap();
        assert!(head.starts_with("HTTP/1.1 400 Bad Request\r\n"), "{head}");
        assert!(head.contains("content-type: application/json"));
        assert!(head.contains(&format!("content-length: {}", body.len())));
        let v: serde_json::Value = serde_json::from_str(body).unwrap();
        assert_eq!(v["field"], "request");
        assert!(v["error"].as_str().unwrap().contains("not valid HTTP"));
        let big = b"HTTP/1.1 431 Request Header Fields Too Large\r\ncontent-length: 0\r\n\r\n";
        assert!(String::from_utf8(rewrite_bare_error(big).unwrap())
            .unwrap()
            .contains("too large"));
        // Answers of the router (a body, or not an error) and partial writes pass unchanged.
        for other in [
            &b"HTTP/1.1 404 Not Found\r\ncontent-type: application/json\r\ncontent-length: 9\r\n\r\n{\"a\": 1}"[..],
            b"HTTP/1.1 204 No Content\r\ncontent-length: 0\r\n\r\n",
            b"HTTP/1.1 400 Bad Request\r\ncontent-length: 0\r\n",
            b"{\"error\": \"x\"}",
            b"",
        ] {
            assert_eq!(rewrite_bare_error(other), None, "{}", String::from_utf8_lossy(other));
        }
    }
}
