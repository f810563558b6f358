//! What every request passes before the routes, and what every answer gets after them.
//!
//! Before: one `Host` header (and the request URI's authority, when it has one) naming a host
//! the server answers to (403 otherwise: DNS rebinding; 400 for a second `Host`); the token
//! when the server has one (403); a POST saying its body is JSON (415: a cross-site page
//! cannot send one without a preflight, which is never granted); then the body, read whole
//! within the body deadline (408) and the size limit (413, at once when `Content-Length`
//! declares more), both answered with `Connection: close`.
//!
//! After: every error status carries the API's JSON error body, whatever layer refused (the
//! framework's 405 and its plain-text rejections included); text answers are compressed in
//! the coding the client accepts ([`crate::compress`]); every answer carries a strict Content
//! Security Policy and no CORS headers, so other origins cannot read answers.

use crate::access::{query_token, Access, TOKEN_COOKIE};
use crate::compress::{self, Coding};
use crate::request::ApiError;
use axum::body::{Body, HttpBody};
use axum::extract::Request;
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::response::Response;
use http_body_util::{BodyExt, LengthLimitError, Limited};
use std::time::Duration;

/// Largest request body (bytes).
pub const BODY_LIMIT: usize = 64 * 1024;

/// Bodies above this are compressed on the blocking pool, not on the async workers.
const COMPRESS_INLINE_MAX: usize = 64 * 1024;

/// The Content Security Policy of every answer: only the server's own scripts.
const CSP: &str = "default-src 'self'; script-src 'self'; style-src 'self' 'unsafe-inline'; img-src 'self' data: blob:; connect-src 'self'; frame-ancestors 'none'";

/// The refusal of a body over [`BODY_LIMIT`].
pub fn too_large() -> ApiError {
    ApiError {
        status: 413,
        error: format!("the body is larger than {BODY_LIMIT} bytes"),
        field: Some("body".into()),
        allowed: Some(format!("at most {BODY_LIMIT} bytes")),
        retry_after_s: None,
    }
}

/// `e` as an answer after which the connection is closed (its body was not read).
fn closing(e: ApiError) -> Response {
    let mut r = e.response();
    r.headers_mut()
        .insert(header::CONNECTION, HeaderValue::from_static("close"));
    r
}

/// Refuses a request whose host is not served: a second `Host` header (400), or a `Host` or
/// URI authority naming another host (403).
fn host_refusal(access: &Access, req: &Request) -> Option<ApiError> {
    let hosts: Vec<&HeaderValue> = req.headers().get_all(header::HOST).iter().collect();
    if hosts.len() > 1 {
        return Some(ApiError::bad(
            "Host",
            format!("the request has {} `Host` headers", hosts.len()),
            "exactly one `Host` header",
        ));
    }
    let host = hosts.first().and_then(|h| h.to_str().ok()).unwrap_or("");
    let authority = req.uri().authority().map(|a| a.as_str());
    let refused = [Some(host), authority]
        .into_iter()
        .flatten()
        .find(|h| !access.host_allowed(h))?;
    Some(ApiError {
        status: 403,
        error: format!("host `{refused}` is not served here"),
        field: Some("Host".into()),
        allowed: Some(access.hosts.join(", ")),
        retry_after_s: None,
    })
}

/// Whether the request says its body is JSON (`application/json`, any parameters). Requiring
/// it makes every cross-site POST a preflighted one, which the server never grants.
fn is_json(headers: &HeaderMap) -> bool {
    headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.split(';').next())
        .is_some_and(|t| t.trim().eq_ignore_ascii_case("application/json"))
}

/// Host, token and content type of `req`, then its body read whole within `deadline`; the
/// answer of a refusal otherwise.
pub async fn admit(access: &Access, req: Request, deadline: Duration) -> Result<Request, Response> {
    if let Some(e) = host_refusal(access, &req) {
        return Err(e.response());
    }
    if !access.token_ok(req.headers(), req.uri().query()) {
        return Err(ApiError {
            status: 403,
            error: "a token is required: open the URL explore printed (with ?token=)".into(),
            field: Some("token".into()),
            allowed: None,
            retry_after_s: None,
        }
        .response());
    }
    if req.method() == axum::http::Method::POST && !is_json(req.headers()) {
        return Err(ApiError {
            status: 415,
            error: "a POST body must be JSON: send `Content-Type: application/json`".into(),
            field: Some("Content-Type".into()),
            allowed: Some("application/json".into()),
            retry_after_s: None,
        }
        .response());
    }
    read_body(req, deadline).await
}

/// `req` with its body read whole: refused at once when its `Content-Length` is over
/// [`BODY_LIMIT`] (413), cut when more arrives (413) or when it has not arrived within
/// `deadline` of the head (408).
async fn read_body(req: Request, deadline: Duration) -> Result<Request, Response> {
    let (parts, body) = req.into_parts();
    if body.size_hint().exact() == Some(0) {
        return Ok(Request::from_parts(parts, body));
    }
    let declared = parts
        .headers
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.trim().parse::<u64>().ok());
    if declared.is_some_and(|n| n > BODY_LIMIT as u64) {
        return Err(closing(too_large()));
    }
    match tokio::time::timeout(deadline, Limited::new(body, BODY_LIMIT).collect()).await {
        Ok(Ok(collected)) => Ok(Request::from_parts(parts, Body::from(collected.to_bytes()))),
        Ok(Err(e)) if e.downcast_ref::<LengthLimitError>().is_some() => Err(closing(too_large())),
        Ok(Err(e)) => Err(closing(ApiError::bad(
            "body",
            format!("the body could not be read: {e}"),
            "a body of the declared length",
        ))),
        Err(_) => Err(closing(ApiError {
            status: 408,
            error: format!(
                "the body did not arrive within {} s of the request's head",
                deadline.as_secs_f64()
            ),
            field: Some("body".into()),
            allowed: Some(format!(
                "a body sent within {} s (--body-timeout)",
                deadline.as_secs_f64()
            )),
            retry_after_s: None,
        })),
    }
}

/// An error answer of the framework (405 with `Allow`, a rejection of an extractor in plain
/// text, an empty 413) as the API's JSON error; every other answer unchanged.
pub async fn as_json_error(r: Response) -> Response {
    let status = r.status();
    let json = r
        .headers()
        .get(header::CONTENT_TYPE)
        .is_some_and(|v| v.as_bytes().starts_with(b"application/json"));
    if json || !(status.is_client_error() || status.is_server_error()) {
        return r;
    }
    let allow = r.headers().get(header::ALLOW).cloned();
    let (_, body) = r.into_parts();
    let text = axum::body::to_bytes(body, 4096)
        .await
        .map(|b| String::from_utf8_lossy(&b).trim().to_owned())
        .unwrap_or_default();
    let e = match status {
        StatusCode::METHOD_NOT_ALLOWED => ApiError {
            status: 405,
            error: "method not allowed on this path (see docs/explore.md)".into(),
            field: None,
            allowed: allow
                .as_ref()
                .and_then(|a| a.to_str().ok())
                .map(|a| format!("methods: {a}")),
            retry_after_s: None,
        },
        StatusCode::PAYLOAD_TOO_LARGE => too_large(),
        s => ApiError {
            status: s.as_u16(),
            error: if text.is_empty() {
                s.canonical_reason().unwrap_or("error").to_owned()
            } else {
                text
            },
            field: None,
            allowed: None,
            retry_after_s: None,
        },
    };
    let mut answer = e.response();
    if let Some(a) = allow {
        answer.headers_mut().insert(header::ALLOW, a);
    }
    answer
}

/// The coding the request's `Accept-Encoding` asks for, when any.
pub fn accepted_coding(headers: &HeaderMap) -> Option<Coding> {
    let accept: Vec<&str> = headers
        .get_all(header::ACCEPT_ENCODING)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .collect();
    compress::negotiate(&accept.join(","))
}

/// `r` compressed in `coding` when its type is text and it is long enough (`Vary:
/// Accept-Encoding` on every such answer).
pub async fn compressed(r: Response, coding: Option<Coding>) -> Response {
    let text = r
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(compress::compressible);
    if !text || r.headers().contains_key(header::CONTENT_ENCODING) {
        return r;
    }
    let (mut parts, body) = r.into_parts();
    parts
        .headers
        .append(header::VARY, HeaderValue::from_static("accept-encoding"));
    let Some(coding) = coding else {
        return Response::from_parts(parts, body);
    };
    let bytes = match axum::body::to_bytes(body, usize::MAX).await {
        Ok(b) => b,
        Err(e) => return ApiError::internal(format!("reading the answer: {e}")).response(),
    };
    if bytes.len() < compress::MIN_BYTES {
        return Response::from_parts(parts, Body::from(bytes));
    }
    let packed = if bytes.len() > COMPRESS_INLINE_MAX {
        let b = bytes.clone();
        tokio::task::spawn_blocking(move || compress::compress(coding, &b))
            .await
            .ok()
            .and_then(Result::ok)
    } else {
        compress::compress(coding, &bytes).ok()
    };
    match packed {
        Some(z) => {
            parts.headers.insert(
                header::CONTENT_ENCODING,
                HeaderValue::from_static(coding.token()),
            );
            parts.headers.remove(header::CONTENT_LENGTH);
            Response::from_parts(parts, Body::from(z))
        }
        None => Response::from_parts(parts, Body::from(bytes)),
    }
}

/// `r` with the security headers, and the token cookie when `cookie` holds the token the page
/// was opened with.
pub fn secured(mut r: Response, cookie: Option<&str>) -> Response {
    let h = r.headers_mut();
    h.insert(
        header::CONTENT_SECURITY_POLICY,
        HeaderValue::from_static(CSP),
    );
    h.insert(
        header::X_CONTENT_TYPE_OPTIONS,
        HeaderValue::from_static("nosniff"),
    );
    h.insert(
        header::REFERRER_POLICY,
        HeaderValue::from_static("no-referrer"),
    );
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    if let Some(t) = cookie {
        if let Ok(v) = HeaderValue::from_str(&format!(
            "{TOKEN_COOKIE}={t}; HttpOnly; SameSite=Strict; Path=/"
        )) {
            h.insert(header::SET_COOKIE, v);
        }
    }
    r
}

/// The token cookie to set on the answer: the server's token, when the request opened the
/// page with it (`?token=`).
pub fn cookie_to_set<'a>(access: &'a Access, req: &Request) -> Option<&'a str> {
    let token = access.token.as_deref()?;
    query_token(req.uri().query()).is_some().then_some(token)
}
