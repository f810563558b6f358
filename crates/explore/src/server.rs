//! The HTTP server: axum on tokio, the embedded pages and the JSON API of `docs/explore.md`.
//!
//! - Every request passes [`crate::guard`]: its host and token ([`crate::access`]), a JSON
//!   POST, its body within the deadline and the size limit; every answer gets the API's JSON
//!   error body (whatever layer refused), its compression and the security headers.
//! - Model work runs on the blocking pool, so the async workers keep accepting while a
//!   prediction or a solve computes; started studies run on their own pool at a lower CPU priority
//!   ([`crate::studies`]), so interactive requests never queue behind them and win the cores.
//! - The Studies page's routes list the pipeline's studies and those started from the sweep
//!   view ([`crate::studies`]) and serve their files by the names listed.
//! - Solves pass a [`SolveGate`]: at most `workers` run and `queue` wait; beyond, 429 with
//!   `Retry-After`. A solve whose client disconnects is cancelled: hyper drops the handler's
//!   future, whose `CancelOnDrop` guard sets the engine's stop flag.

use crate::download;
use crate::encoding;
use crate::glance;
use crate::guard;
use crate::request::{self, ApiError, DesignRequest, Encoding};
use crate::session::{Explorer, Response};
use crate::solve::{relative_error, relative_l2};
use crate::studies::{self, Source, Studies};
use axum::body::{Body, Bytes};
use axum::extract::{DefaultBodyLimit, Path, Query, Request, State};
use axum::http::{header, HeaderValue, StatusCode};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response as HttpResponse};
use axum::routing::{get, post};
use axum::Router;
use orchestrator::spec::Pipeline;
use serde_json::{json, Value};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Instant;
use tokio::sync::Semaphore;

pub use crate::access::{Access, MIN_TOKEN_CHARS};
pub use crate::guard::BODY_LIMIT;

/// At most `workers` solves run and `queue` wait.
pub struct SolveGate {
    admitted: AtomicUsize,
    capacity: usize,
    running: Semaphore,
    /// Solves finished.
    pub completed: AtomicU64,
    /// Solves cancelled because their client went away.
    pub cancelled: AtomicU64,
}

impl SolveGate {
    /// A gate for `workers` running and `queue` waiting solves.
    pub fn new(workers: usize, queue: usize) -> Self {
        Self {
            admitted: AtomicUsize::new(0),
            capacity: workers.max(1) + queue,
            running: Semaphore::new(workers.max(1)),
            completed: AtomicU64::new(0),
            cancelled: AtomicU64::new(0),
        }
    }

    fn admit(self: &Arc<Self>) -> Result<Admitted, ApiError> {
        if self.admitted.fetch_add(1, Ordering::SeqCst) >= self.capacity {
            self.admitted.fetch_sub(1, Ordering::SeqCst);
            return Err(ApiError::busy(1));
        }
        Ok(Admitted(self.clone()))
    }
}

/// A place in the gate, given back on drop.
struct Admitted(Arc<SolveGate>);

impl Drop for Admitted {
    fn drop(&mut self) {
        self.0.admitted.fetch_sub(1, Ordering::SeqCst);
    }
}

/// Sets the flag when dropped unless disarmed: the handler's future dropped before the solve
/// finished means the client went away.
struct CancelOnDrop {
    flag: Arc<AtomicBool>,
    gate: Arc<SolveGate>,
    armed: bool,
}

impl Drop for CancelOnDrop {
    fn drop(&mut self) {
        if self.armed {
            self.flag.store(true, Ordering::Relaxed);
            self.gate.cancelled.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// The server's state.
pub struct App {
    /// The model session.
    pub explorer: Arc<Explorer>,
    /// The pipeline, when the model came from one.
    pub pipeline: Option<Arc<Pipeline>>,
    /// Access rules.
    pub access: Access,
    /// The solve gate.
    pub solves: Arc<SolveGate>,
    /// The studies started from the sweep view.
    pub studies: Arc<Studies>,
    /// Longest wait for a request's body after its head.
    pub body_timeout: std::time::Duration,
}

type Shared = Arc<App>;

fn error_response(e: ApiError) -> HttpResponse {
    e.response()
}

fn json_ok(v: Value) -> HttpResponse {
    axum::Json(v).into_response()
}

/// Runs `f` on the blocking pool.
async fn blocking<T: Send + 'static>(
    f: impl FnOnce() -> Result<T, ApiError> + Send + 'static,
) -> Result<T, ApiError> {
    tokio::task::spawn_blocking(f)
        .await
        .map_err(|e| ApiError::internal(format!("worker failed: {e}")))?
}

/// Every request passes [`guard::admit`] (host, token, content type, its body within the
/// deadline); every answer gets the JSON error body, its compression and the security headers.
async fn guard(State(app): State<Shared>, req: Request, next: Next) -> HttpResponse {
    let coding = guard::accepted_coding(req.headers());
    let (answer, cookie) = match guard::admit(&app.access, req, app.body_timeout).await {
        Ok(req) => {
            let cookie = guard::cookie_to_set(&app.access, &req).map(str::to_owned);
            (guard::as_json_error(next.run(req).await).await, cookie)
        }
        Err(refused) => (refused, None),
    };
    guard::secured(guard::compressed(answer, coding).await, cookie.as_deref())
}

fn asset(name: &str) -> HttpResponse {
    match crate::assets::get(name) {
        Some(a) => ([(header::CONTENT_TYPE, a.content_type)], a.bytes).into_response(),
        None => not_found(),
    }
}

fn not_found() -> HttpResponse {
    error_response(ApiError {
        status: 404,
        error: "no such page or endpoint (see docs/explore.md)".into(),
        field: None,
        allowed: None,
        retry_after_s: None,
    })
}

/// The answer of a prediction or a solve; a calibrated prediction adds each index's interval
/// and verdict, the combined verdict, `coverage`, `extrapolated` and the bands of the channels
/// `bands` names (every banded channel when `None`). With [`Encoding::F32`] each curve is a
/// compact float32 text and each band its half-width (`{"half"}`, [`encoding::BAND_BITS`]
/// significant bits), else arrays of numbers and each band's `lo` and `hi`.
fn response_json(
    ex: &Explorer,
    r: &Response,
    bands_of: Option<&[String]>,
    encoding: Encoding,
) -> Value {
    let f32 = encoding == Encoding::F32;
    let curve = |v: &[f64]| {
        if f32 {
            json!(encoding::f32_base64(v))
        } else {
            json!(v)
        }
    };
    let channels: serde_json::Map<String, Value> = ex
        .channels()
        .iter()
        .zip(&r.channels)
        .map(|(c, v)| (c.name.clone(), curve(v)))
        .collect();
    let cal = r.calibrated.as_ref();
    let indices: Vec<Value> = ex
        .index_names()
        .iter()
        .zip(&r.indices)
        .zip(ex.index_limits())
        .enumerate()
        .map(|(k, ((name, v), limit))| {
            let interval = cal.and_then(|c| c.indices.get(k));
            let verdict = cal.and_then(|c| c.verdicts.get(k).copied().flatten());
            json!({
                "name": name,
                "value": v,
                "pass": limit.map(|l| *v <= l),
                "lo": interval.map(|i| i.lo),
                "hi": interval.map(|i| i.hi),
                "verdict": verdict.map(|v| v.as_str()),
            })
        })
        .collect();
    let mut bands = serde_json::Map::new();
    if let Some(c) = cal.filter(|c| !c.bands.is_empty()) {
        for (k, ch) in ex.channels().iter().enumerate() {
            let Some(h) = ex.band_index(k).and_then(|b| c.bands.get(b)) else {
                continue;
            };
            if bands_of.is_some_and(|names| !names.contains(&ch.name)) {
                continue;
            }
            let band = if f32 {
                json!({"half": encoding::band_base64(h)})
            } else {
                let x = &r.channels[k];
                let lo: Vec<f64> = x.iter().zip(h).map(|(x, h)| x - h).collect();
                let hi: Vec<f64> = x.iter().zip(h).map(|(x, h)| x + h).collect();
                json!({"lo": lo, "hi": hi})
            };
            bands.insert(ch.name.clone(), band);
        }
    }
    json!({
        "t": r.t,
        "channels": channels,
        "indices": indices,
        "pass": r.failed.is_empty(),
        "failed": r.failed,
        "coverage": cal.map(|c| c.coverage),
        "extrapolated": cal.map(|c| c.extrapolated),
        "relative_residual": cal.and_then(|c| c.relative_residual),
        "verdict": cal.and_then(|c| c.verdict).map(|v| v.as_str()),
        "bands": bands,
        "no_intervals": ex.calibration_note(),
        "encoding": if f32 { "f32" } else { "json" },
    })
}

/// Where the solver's answer `exact` lies against the calibrated prediction `pred`: per
/// banded channel whether the whole curve is inside the band and the fraction of rows inside,
/// per index whether the solver's value is inside the interval (`{}` without intervals).
fn inside_json(ex: &Explorer, pred: &Response, exact: &Response) -> (Value, Value) {
    let Some(cal) = pred.calibrated.as_ref() else {
        return (json!({}), json!({}));
    };
    let mut channels = serde_json::Map::new();
    for (k, ch) in ex.channels().iter().enumerate() {
        let Some(h) = ex.band_index(k).and_then(|b| cal.bands.get(b)) else {
            continue;
        };
        let (p, x) = (&pred.channels[k], &exact.channels[k]);
        let rows = p.len().min(x.len()).min(h.len());
        let n_in = (0..rows)
            .filter(|&n| p[n] - h[n] <= x[n] && x[n] <= p[n] + h[n])
            .count();
        channels.insert(
            ch.name.clone(),
            json!({
                "inside": n_in == rows,
                "fraction_inside": if rows == 0 { 1.0 } else { n_in as f64 / rows as f64 },
            }),
        );
    }
    let indices: serde_json::Map<String, Value> = ex
        .index_names()
        .into_iter()
        .zip(&cal.indices)
        .zip(&exact.indices)
        .map(|((name, i), &x)| (name, json!(i.contains(x))))
        .collect();
    (Value::Object(channels), Value::Object(indices))
}

/// The answer of a prediction or a solve of `req`: the curves and indices, the full design,
/// the parameters outside the training ranges and the excitation used.
fn answer(ex: &Explorer, req: &DesignRequest, r: &Response) -> Result<Value, ApiError> {
    let mut v = response_json(ex, r, req.bands.as_deref(), req.encoding);
    v["design"] = Value::Object(ex.design_map(&req.design));
    v["outside"] = json!(ex.outside(&req.design)?);
    v["excitation"] = json!(ex.excitation_used(req.excitation));
    Ok(v)
}

/// The JSON answer `r` with the request's wall time (`elapsed_ms`), or its error.
fn timed(started: Instant, r: Result<Value, ApiError>) -> HttpResponse {
    match r {
        Ok(mut v) => {
            v["elapsed_ms"] = json!(started.elapsed().as_secs_f64() * 1e3);
            json_ok(v)
        }
        Err(e) => error_response(e),
    }
}

fn parse(app: &App, body: &Bytes) -> Result<DesignRequest, ApiError> {
    app.explorer.rules().design_request(&request::body(body)?)
}

async fn predict(State(app): State<Shared>, body: Bytes) -> HttpResponse {
    let started = Instant::now();
    let req = match parse(&app, &body) {
        Ok(r) => r,
        Err(e) => return error_response(e),
    };
    let ex = app.explorer.clone();
    let r = blocking(move || {
        let r = ex.predict(&req)?;
        answer(&ex, &req, &r)
    })
    .await;
    timed(started, r)
}

/// Runs `f` as a solve: admitted by the gate, cancelled when the client goes away.
async fn gated<T: Send + 'static>(
    app: &App,
    f: impl FnOnce(&AtomicBool) -> Result<T, ApiError> + Send + 'static,
) -> Result<T, ApiError> {
    let _place = app.solves.admit()?;
    let _permit = app
        .solves
        .running
        .acquire()
        .await
        .map_err(ApiError::internal)?;
    let flag = Arc::new(AtomicBool::new(false));
    let mut guard = CancelOnDrop {
        flag: flag.clone(),
        gate: app.solves.clone(),
        armed: true,
    };
    let r = blocking(move || f(&flag)).await;
    guard.armed = false;
    app.solves.completed.fetch_add(1, Ordering::Relaxed);
    r
}

async fn solve(State(app): State<Shared>, body: Bytes) -> HttpResponse {
    let started = Instant::now();
    let req = match parse(&app, &body) {
        Ok(r) => r,
        Err(e) => return error_response(e),
    };
    let ex = app.explorer.clone();
    let r = gated(&app, move |cancel| {
        let (pred, exact, solve_ms) = ex.solve(&req, cancel)?;
        let mut v = answer(&ex, &req, &exact)?;
        let errors: serde_json::Map<String, Value> = ex
            .channels()
            .iter()
            .enumerate()
            .map(|(k, c)| {
                (
                    c.name.clone(),
                    json!(relative_l2(&pred.channels[k], &exact.channels[k])),
                )
            })
            .collect();
        let index_errors: serde_json::Map<String, Value> = ex
            .index_names()
            .into_iter()
            .enumerate()
            .map(|(k, name)| {
                (
                    name,
                    json!(relative_error(pred.indices[k], exact.indices[k])),
                )
            })
            .collect();
        v["errors"] = Value::Object(errors);
        v["index_errors"] = Value::Object(index_errors);
        let (inside, index_inside) = inside_json(&ex, &pred, &exact);
        v["coverage"] = json!(pred.calibrated.as_ref().map(|c| c.coverage));
        v["inside"] = inside;
        v["index_inside"] = index_inside;
        v["solve_ms"] = json!(solve_ms);
        Ok(v)
    })
    .await;
    timed(started, r)
}

async fn sweep(State(app): State<Shared>, body: Bytes) -> HttpResponse {
    let started = Instant::now();
    let req = match request::body(&body).and_then(|v| app.explorer.rules().sweep_request(&v)) {
        Ok(r) => r,
        Err(e) => return error_response(e),
    };
    let ex = app.explorer.clone();
    let names = ex.index_names();
    let predicted = {
        let (ex, req) = (ex.clone(), req.clone());
        blocking(move || ex.sweep(&req)).await
    };
    let (designs, ix) = match predicted {
        Ok(x) => x,
        Err(e) => return error_response(e),
    };
    let values: Vec<f64> = designs.iter().map(|d| d[req.parameter]).collect();
    let mut solved = Vec::new();
    if req.solve_points > 0 {
        let picks: Vec<usize> = (0..req.solve_points)
            .map(|k| {
                if req.solve_points == 1 {
                    designs.len() / 2
                } else {
                    k * (designs.len() - 1) / (req.solve_points - 1)
                }
            })
            .collect();
        let (ex2, designs2, excitation) = (ex.clone(), designs.clone(), req.base.excitation);
        let r = gated(&app, move |cancel| {
            picks
                .iter()
                .map(|&k| Ok((k, ex2.solve_indices(&designs2[k], excitation, cancel)?)))
                .collect::<Result<Vec<_>, ApiError>>()
        })
        .await;
        match r {
            Ok(points) => {
                for (k, v) in points {
                    let m: serde_json::Map<String, Value> = names
                        .iter()
                        .cloned()
                        .zip(v.into_iter().map(|x| json!(x)))
                        .collect();
                    solved.push(json!({"value": values[k], "indices": m}));
                }
            }
            Err(e) => return error_response(e),
        }
    }
    let indices: serde_json::Map<String, Value> = names
        .iter()
        .enumerate()
        .map(|(k, n)| {
            (
                n.clone(),
                json!(ix.iter().map(|s| s.indices.values[k]).collect::<Vec<_>>()),
            )
        })
        .collect();
    // Each index curve's interval at every design, when calibrated.
    let calibrated: Option<Vec<_>> = ix.iter().map(|a| a.calibrated.as_ref()).collect();
    let calibrated = calibrated.filter(|c| c.iter().all(|a| a.indices.len() == names.len()));
    let intervals: serde_json::Map<String, Value> = match &calibrated {
        Some(cal) => names
            .iter()
            .enumerate()
            .map(|(k, n)| {
                let lo: Vec<f64> = cal.iter().map(|a| a.indices[k].lo).collect();
                let hi: Vec<f64> = cal.iter().map(|a| a.indices[k].hi).collect();
                let verdict: Vec<Option<&str>> = cal
                    .iter()
                    .map(|a| a.verdicts[k].map(|v| v.as_str()))
                    .collect();
                (n.clone(), json!({"lo": lo, "hi": hi, "verdict": verdict}))
            })
            .collect(),
        None => serde_json::Map::new(),
    };
    let outside: Result<Vec<bool>, ApiError> = designs
        .iter()
        .map(|d| ex.outside(d).map(|o| !o.is_empty()))
        .collect();
    let outside = match outside {
        Ok(o) => o,
        Err(e) => return error_response(e),
    };
    json_ok(json!({
        "parameter": ex.rules().names[req.parameter],
        "values": values,
        "indices": indices,
        "coverage": calibrated.as_ref().map(|_| req.base.coverage),
        "intervals": intervals,
        "verdict": calibrated.as_ref().map(|c| c.iter().map(|a| a.verdict.map(|v| v.as_str())).collect::<Vec<_>>()),
        "no_intervals": ex.calibration_note(),
        "outside": outside,
        "solved": solved,
        "elapsed_ms": started.elapsed().as_secs_f64() * 1e3,
    }))
}

async fn download_design(State(app): State<Shared>, body: Bytes) -> HttpResponse {
    match parse(&app, &body).and_then(|req| download::design_yaml(&app.explorer, &req)) {
        Ok(text) => attachment("application/yaml", "design.yaml", text.into_bytes()),
        Err(e) => error_response(e),
    }
}

#[derive(serde::Deserialize)]
struct CurvesQuery {
    format: Option<String>,
}

async fn download_curves(
    State(app): State<Shared>,
    Query(q): Query<CurvesQuery>,
    body: Bytes,
) -> HttpResponse {
    let format = q.format.unwrap_or_else(|| "csv".into());
    if format != "csv" && format != "parquet" {
        return error_response(ApiError::bad(
            "format",
            format!("unknown format `{format}`"),
            "csv or parquet",
        ));
    }
    let req = match parse(&app, &body) {
        Ok(r) => r,
        Err(e) => return error_response(e),
    };
    let ex = app.explorer.clone();
    let csv = format == "csv";
    let r = blocking(move || {
        let r = ex.predict(&req)?;
        if csv {
            download::curves_csv(&ex, &req, &r).map(String::into_bytes)
        } else {
            download::curves_parquet(&ex, &req, &r)
        }
    })
    .await;
    match (r, csv) {
        (Ok(bytes), true) => attachment("text/csv; charset=utf-8", "curves.csv", bytes),
        (Ok(bytes), false) => attachment("application/vnd.apache.parquet", "curves.parquet", bytes),
        (Err(e), _) => error_response(e),
    }
}

fn attachment(content_type: &'static str, name: &str, bytes: Vec<u8>) -> HttpResponse {
    let disposition = format!("attachment; filename=\"{name}\"");
    (
        [
            (header::CONTENT_TYPE, HeaderValue::from_static(content_type)),
            (
                header::CONTENT_DISPOSITION,
                HeaderValue::from_str(&disposition)
                    .unwrap_or(HeaderValue::from_static("attachment")),
            ),
        ],
        Body::from(bytes),
    )
        .into_response()
}

async fn pipeline_view(State(app): State<Shared>) -> HttpResponse {
    let Some(p) = app.pipeline.clone() else {
        return json_ok(json!({"file": null, "units": [], "evaluate": null}));
    };
    match blocking(move || glance::glance(&p).map_err(ApiError::internal)).await {
        Ok(g) => json_ok(json!(g)),
        Err(e) => error_response(e),
    }
}

async fn pipeline_plot(State(app): State<Shared>, Path(name): Path<String>) -> HttpResponse {
    let Some(p) = app.pipeline.clone() else {
        return not_found();
    };
    let found = blocking(move || Ok(glance::plot_path(&p, &name))).await;
    match found {
        Ok(Some(path)) => match std::fs::read(&path) {
            Ok(bytes) => ([(header::CONTENT_TYPE, "image/png")], bytes).into_response(),
            Err(e) => error_response(ApiError::internal(format!("{}: {e}", path.display()))),
        },
        Ok(None) => not_found(),
        Err(e) => error_response(e),
    }
}

/// The model's summary, with the limits of a study the sweep view may start.
async fn model_summary(State(app): State<Shared>) -> HttpResponse {
    let mut v = app.explorer.summary();
    v["studies"] = studies::limits_json();
    json_ok(v)
}

/// The Studies page's data: the pipeline's studies and those started here.
async fn studies_view(State(app): State<Shared>) -> HttpResponse {
    let answer = blocking(move || {
        let pipeline = match &app.pipeline {
            Some(p) => studies::pipeline_studies(p).map_err(ApiError::internal)?,
            None => Vec::new(),
        };
        Ok(json!({
            "file": app.pipeline.as_ref().map(|p| p.file.clone()),
            "dir": app.studies.dir().display().to_string(),
            "running": app.studies.is_running(),
            "limits": studies::limits_json(),
            "pipeline": pipeline,
            "explorer": app.studies.list(),
        }))
    })
    .await;
    match answer {
        Ok(v) => json_ok(v),
        Err(e) => error_response(e),
    }
}

/// Starts a study (`docs/explore.md`): 202 with its name and declaration.
async fn start_study(State(app): State<Shared>, body: Bytes) -> HttpResponse {
    let started = blocking(move || {
        let req = app.explorer.rules().study_request(&request::body(&body)?)?;
        app.studies.start(app.explorer.clone(), &req)
    })
    .await;
    match started {
        Ok(s) => (StatusCode::ACCEPTED, axum::Json(s)).into_response(),
        Err(e) => error_response(e),
    }
}

/// Cancels a running started study (`{"name": NAME}`): 202; it stops at its next slice of
/// designs and is then listed `cancelled`.
async fn cancel_study(State(app): State<Shared>, body: Bytes) -> HttpResponse {
    let name = match request::body(&body).and_then(|v| request::cancel_request(&v)) {
        Ok(n) => n,
        Err(e) => return error_response(e),
    };
    match app.studies.cancel(&name) {
        Ok(()) => (
            StatusCode::ACCEPTED,
            axum::Json(json!({"name": name, "state": "cancelling"})),
        )
            .into_response(),
        Err(e) => error_response(e),
    }
}

/// A file of a study's output: plots inline, every other file as a download.
async fn study_file(
    State(app): State<Shared>,
    Path((source, name, file)): Path<(String, String, String)>,
) -> HttpResponse {
    let Some(source) = Source::parse(&source) else {
        return not_found();
    };
    let found = blocking(move || {
        Ok(studies::file_path(
            app.pipeline.as_deref(),
            &app.studies,
            source,
            &name,
            &file,
        ))
    })
    .await;
    let path = match found {
        Ok(Some(path)) => path,
        Ok(None) => return not_found(),
        Err(e) => return error_response(e),
    };
    let bytes = match std::fs::read(&path) {
        Ok(b) => b,
        Err(e) => return error_response(ApiError::internal(format!("{}: {e}", path.display()))),
    };
    let content_type = studies::content_type(&path);
    if content_type.starts_with("image/") {
        return ([(header::CONTENT_TYPE, content_type)], bytes).into_response();
    }
    let file_name = path
        .file_name()
        .and_then(|n| n.to_str())
        .unwrap_or("study-file");
    attachment(content_type, file_name, bytes)
}

async fn health(State(app): State<Shared>) -> HttpResponse {
    let g = &app.solves;
    json_ok(json!({
        "ok": true,
        "solves_waiting_or_running": g.admitted.load(Ordering::SeqCst),
        "solves_completed": g.completed.load(Ordering::Relaxed),
        "solves_cancelled": g.cancelled.load(Ordering::Relaxed),
    }))
}

/// The router of `app`.
pub fn router(app: Shared) -> Router {
    Router::new()
        .route("/", get(|| async { asset("index.html") }))
        .route("/pipeline", get(|| async { asset("pipeline.html") }))
        .route("/studies", get(|| async { asset("studies.html") }))
        .route("/favicon.ico", get(|| async { asset("favicon.svg") }))
        .route(
            "/assets/{name}",
            get(|Path(name): Path<String>| async move { asset(&name) }),
        )
        .route("/api/model", get(model_summary))
        .route("/api/health", get(health))
        .route("/api/predict", post(predict))
        .route("/api/sweep", post(sweep))
        .route("/api/solve", post(solve))
        .route("/api/download/design", post(download_design))
        .route("/api/download/curves", post(download_curves))
        .route("/api/pipeline", get(pipeline_view))
        .route("/api/pipeline/plot/{name}", get(pipeline_plot))
        .route("/api/studies", get(studies_view).post(start_study))
        .route("/api/studies/cancel", post(cancel_study))
        .route("/api/studies/{source}/{name}/{file}", get(study_file))
        .fallback(|| async { not_found() })
        .layer(DefaultBodyLimit::max(BODY_LIMIT))
        .layer(middleware::from_fn_with_state(app.clone(), guard))
        .with_state(app)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_gate_admits_workers_plus_queue_and_frees_places_on_drop() {
        let gate = Arc::new(SolveGate::new(1, 1));
        let a = gate.admit().unwrap();
        let b = gate.admit().unwrap();
        let busy = gate.admit().map(|_| ()).unwrap_err();
        assert_eq!((busy.status, busy.retry_after_s), (429, Some(1)));
        drop(a);
        let _c = gate.admit().unwrap();
        drop(b);
        assert_eq!(gate.admitted.load(Ordering::SeqCst), 1);
    }
}
