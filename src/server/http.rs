//! HTTP/JSON API (axum). Each handler: validate → convert → dispatch to the [`crate::engine::Engine`] → respond,
//! encoding statuses and frames with [`super::json`].
//! Errors are `{"error": {"field", "reason"}}` with a status code per [`ApiError`] kind.

use super::AppState;
use super::json::{FrameJson, StatusJson, status_with_lineage};
use super::results::{self, Cut, CutRequest, write_csv, write_json, write_npz};
use crate::engine::EngineError;
use crate::engine::events::JobEvent;
use crate::error::ApiError;
use crate::spec_file::{self, Format};
use crate::status::{JobState, JobView};
use crate::store::StoredResult;
use axum::body::{Body, Bytes};
use axum::extract::rejection::{QueryRejection, StringRejection};
use axum::extract::{DefaultBodyLimit, Path, Query, State};
use axum::http::{HeaderMap, Method, StatusCode, Uri, header};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{Html, IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use serde::Deserialize;
use serde_json::{Value, json};
use std::convert::Infallible;
use std::fmt::Write as _;
use std::io::{self, Write};
use std::time::Duration;
use tokio_stream::StreamExt;

/// [`EngineError`] → HTTP status: the one place the engine's errors meet HTTP.
fn engine_status(e: &EngineError) -> StatusCode {
    match e {
        EngineError::Invalid(_) => StatusCode::BAD_REQUEST,
        EngineError::NotFound { .. } => StatusCode::NOT_FOUND,
        EngineError::AlreadyExists { .. }
        | EngineError::NoResult { .. }
        | EngineError::Unfinished { .. }
        | EngineError::WrongState { .. }
        | EngineError::BeingRead { .. } => StatusCode::CONFLICT,
        EngineError::QueueFull { .. } => StatusCode::TOO_MANY_REQUESTS,
        EngineError::Unavailable | EngineError::StoreRefused { .. } => {
            StatusCode::SERVICE_UNAVAILABLE
        }
        EngineError::Store(_) | EngineError::Internal(_) => StatusCode::INTERNAL_SERVER_ERROR,
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let code = match &self {
            ApiError::Engine(e) => engine_status(e),
            ApiError::Invalid(_) => StatusCode::BAD_REQUEST,
            ApiError::NoFigure { .. } | ApiError::NoRoute { .. } => StatusCode::NOT_FOUND,
            ApiError::MethodNotAllowed { .. } => StatusCode::METHOD_NOT_ALLOWED,
            ApiError::Body {
                too_large: true, ..
            } => StatusCode::PAYLOAD_TOO_LARGE,
            ApiError::Body { .. } => StatusCode::BAD_REQUEST,
            ApiError::TooLarge { .. } => StatusCode::PAYLOAD_TOO_LARGE,
            ApiError::Unauthenticated => StatusCode::UNAUTHORIZED,
            ApiError::Forbidden { .. } => StatusCode::FORBIDDEN,
            ApiError::Internal(_) => StatusCode::INTERNAL_SERVER_ERROR,
        };
        if code.is_server_error() {
            tracing::error!("{self}");
        }
        let (field, reason) = self.field_reason();
        let mut resp = (
            code,
            Json(json!({ "error": { "field": field, "reason": reason } })),
        )
            .into_response();
        if code == StatusCode::UNAUTHORIZED {
            resp.headers_mut().insert(
                header::WWW_AUTHENTICATE,
                header::HeaderValue::from_static("Bearer"),
            );
        }
        resp
    }
}

/// The routes.
pub fn router(state: AppState) -> Router {
    Router::new()
        .route("/v1/jobs", get(list_jobs).post(submit_job))
        .route("/v1/jobs/{id}", get(get_job).delete(cancel_job))
        .route("/v1/jobs/{id}/result", get(get_result))
        .route("/v1/jobs/{id}/figures", get(list_figures))
        .route("/v1/jobs/{id}/figures/{name}", get(get_figure))
        .route("/v1/jobs/{id}/events", get(job_events))
        .route("/v1/jobs/{id}/scene", get(super::scene::job_scene))
        .route("/v1/jobs/{id}/pause", post(super::pause::pause_job))
        .route("/v1/jobs/{id}/resume", post(super::pause::resume_job))
        .route("/v1/jobs/{id}/extend", post(super::pause::extend_job))
        .route("/v1/jobs/{id}/children", get(super::study::list_children))
        .route("/v1/capabilities", get(capabilities))
        .route("/healthz", get(healthz))
        .route("/metrics", get(metrics))
        .route("/jobs/{id}", get(live_page))
        .route("/", get(index_page))
        .route("/auth.js", get(auth_script))
        .fallback(no_route)
        .method_not_allowed_fallback(no_method)
        .layer(axum::middleware::from_fn_with_state(
            state.clone(),
            read_gate,
        ))
        .layer(DefaultBodyLimit::max(MAX_BODY_BYTES))
        .with_state(state)
}

/// Paths any caller may GET: health, and the pages themselves (static HTML and script, no
/// job's data: the data they fetch is read-gated like any other).
fn open_path(path: &str) -> bool {
    matches!(path, "/healthz" | "/" | "/auth.js") || path.starts_with("/jobs/")
}

/// Reads (GET, HEAD) need a read token when the server has scoped tokens (`--tokens`), all
/// but [`open_path`]s; mutating routes check their write scope themselves ([`authorize`]).
async fn read_gate(
    State(state): State<AppState>,
    req: axum::extract::Request,
    next: axum::middleware::Next,
) -> Response {
    if !open_path(req.uri().path()) && matches!(*req.method(), Method::GET | Method::HEAD) {
        let given = read_credential(req.headers());
        if let Err(e) = state.authorize_read(given.as_deref()) {
            return e.into_response();
        }
    }
    next.run(req).await
}

/// The cookie in which the pages keep a read token (`auth.js`).
const READ_COOKIE: &str = "signorini_read";

/// What a read presents: its `Authorization` header, or else the read token of the cookie
/// [`READ_COOKIE`] (percent-encoded), which a browser's page sends with its fetches and its
/// EventSource (neither can set a header). Only reads take the cookie: a write needs the header,
/// so that no other site can make a browser write with it.
fn read_credential(headers: &HeaderMap) -> Option<String> {
    if let Some(h) = headers
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
    {
        return Some(h.to_string());
    }
    headers
        .get_all(header::COOKIE)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(';'))
        .find_map(|pair| {
            let (name, value) = pair.trim().split_once('=')?;
            (name == READ_COOKIE).then(|| percent_decode(value))?
        })
        .map(|token| format!("Bearer {token}"))
}

/// `%XX` escapes decoded (what `encodeURIComponent` wrote); `None` for a bad escape or bytes
/// that are not UTF-8.
fn percent_decode(text: &str) -> Option<String> {
    let bytes = text.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = text.get(i + 1..i + 3)?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

/// Checks the `Authorization` header of an HTTP request ([`AppState::authorize`]): every
/// mutating route, this module's and `super::pause`'s, calls it.
pub(super) fn authorize(state: &AppState, headers: &HeaderMap) -> Result<(), ApiError> {
    let given = headers
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok());
    state.authorize(given)
}

#[derive(Debug, Deserialize)]
struct SubmitQuery {
    id: Option<String>,
}

/// Largest request body: 64 MiB, as for gRPC messages (a spec with dense matrices of a few
/// hundred dofs is a few MB).
pub const MAX_BODY_BYTES: usize = 64 << 20;

impl From<StringRejection> for ApiError {
    fn from(r: StringRejection) -> Self {
        ApiError::Body {
            too_large: r.status() == StatusCode::PAYLOAD_TOO_LARGE,
            reason: if r.status() == StatusCode::PAYLOAD_TOO_LARGE {
                format!("larger than {} MiB", MAX_BODY_BYTES >> 20)
            } else {
                r.body_text()
            },
        }
    }
}

async fn no_route(method: Method, uri: Uri) -> ApiError {
    ApiError::NoRoute {
        method: method.to_string(),
        path: uri.path().to_string(),
    }
}

async fn no_method(method: Method, uri: Uri) -> ApiError {
    ApiError::MethodNotAllowed {
        method: method.to_string(),
        path: uri.path().to_string(),
    }
}

/// The spelling of a submitted spec: TOML when the body is sent as `application/toml` (the
/// CLI's files as they are), JSON otherwise.
fn spec_format(headers: &HeaderMap) -> Format {
    let toml = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.split(';').next())
        .is_some_and(|mime| mime.trim().eq_ignore_ascii_case("application/toml"));
    if toml { Format::Toml } else { Format::Json }
}

async fn submit_job(
    State(state): State<AppState>,
    headers: HeaderMap,
    query: Result<Query<SubmitQuery>, QueryRejection>,
    body: Result<String, StringRejection>,
) -> Result<(StatusCode, Json<Value>), ApiError> {
    authorize(&state, &headers)?;
    let Query(q) = query?;
    let body = body?;
    // Parsing and validation (a factorisation of M and K) run off the async executor.
    let engine = state.engine.clone();
    let format = spec_format(&headers);
    let id = tokio::task::spawn_blocking(move || {
        if format == Format::Json {
            engine.precheck_json(&body)?;
        }
        let spec = spec_file::parse(&body, format)?;
        engine.submit(&spec, q.id)
    })
    .await
    .map_err(|e| ApiError::Internal(e.to_string()))??;
    Ok((StatusCode::CREATED, Json(json!({ "id": id }))))
}

/// `?limit=N&state=S&page_token=T` of `GET /v1/jobs`.
#[derive(Debug, Deserialize)]
struct ListQuery {
    #[serde(default)]
    limit: Option<usize>,
    #[serde(default)]
    state: Option<String>,
    #[serde(default)]
    page_token: Option<String>,
}

/// `{"jobs": [status…], "next_page_token": T or null}`: one page, newest first.
async fn list_jobs(
    State(state): State<AppState>,
    query: Result<Query<ListQuery>, QueryRejection>,
) -> Result<Json<Value>, ApiError> {
    let Query(q) = query?;
    let filter = match q.state.as_deref() {
        None | Some("") => None,
        Some(s) => Some(JobState::parse(s).ok_or_else(|| {
            signorini_core::spec::SpecError::new(
                "state",
                format!(
                    "{s:?} is not one of queued, running, succeeded, failed, cancelled, paused"
                ),
            )
        })?),
    };
    let page = state.engine.list(
        filter,
        q.page_token.as_deref().unwrap_or(""),
        q.limit.unwrap_or(0),
    )?;
    let jobs: Vec<StatusJson> = page.jobs.iter().map(StatusJson::from).collect();
    Ok(Json(
        json!({ "jobs": jobs, "next_page_token": page.next_page_token }),
    ))
}

/// Answers a status as [`StatusJson`].
fn status_body(v: &JobView) -> Response {
    Json(StatusJson::from(v)).into_response()
}

async fn get_job(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let view = state.engine.status(&id)?;
    let lineage = state.engine.lineage(&id)?;
    Ok(Json(status_with_lineage(&view, lineage)).into_response())
}

/// `?purge=true` of `DELETE /v1/jobs/{id}`.
#[derive(Debug, Deserialize)]
struct DeleteQuery {
    #[serde(default)]
    purge: bool,
}

/// `DELETE /v1/jobs/{id}` cancels the job (and answers its status); with `?purge=true` it
/// removes a finished job and its result instead (`{"id", "purged": true}`; 409 while the job
/// is queued or running).
async fn cancel_job(
    State(state): State<AppState>,
    headers: HeaderMap,
    Path(id): Path<String>,
    query: Result<Query<DeleteQuery>, QueryRejection>,
) -> Result<Response, ApiError> {
    authorize(&state, &headers)?;
    let Query(q) = query?;
    if q.purge {
        let engine = state.engine.clone();
        let gone = id.clone();
        tokio::task::spawn_blocking(move || engine.delete(&gone))
            .await
            .map_err(|e| ApiError::Internal(e.to_string()))??;
        return Ok(Json(json!({ "id": id, "purged": true })).into_response());
    }
    Ok(status_body(&state.cancel_and_wait(&id).await?))
}

/// A finished job's result without its series, read off the async executor.
async fn load_result(state: &AppState, id: String) -> Result<(JobView, StoredResult), ApiError> {
    let engine = state.engine.clone();
    Ok(tokio::task::spawn_blocking(move || engine.result_head(&id))
        .await
        .map_err(|e| ApiError::Internal(e.to_string()))??)
}

/// `?format=json|csv|npz&columns=a,b&every=N&from=S&to=S` of `GET /v1/jobs/{id}/result`.
#[derive(Debug, Deserialize)]
struct ResultQuery {
    /// Body format (json by default).
    #[serde(default)]
    format: Option<String>,
    /// Comma-separated column names (all when absent).
    #[serde(default)]
    columns: Option<String>,
    /// Every N-th row of the range, and its last.
    #[serde(default)]
    every: Option<u64>,
    /// First step number kept.
    #[serde(default)]
    from: Option<u64>,
    /// Last step number kept.
    #[serde(default)]
    to: Option<u64>,
}

impl From<QueryRejection> for ApiError {
    fn from(r: QueryRejection) -> Self {
        // "Failed to deserialize query string: every: invalid digit found in string"
        let text = r.body_text();
        let detail = text.split_once(": ").map_or(text.as_str(), |(_, d)| d);
        let (field, reason) = match detail.split_once(": ") {
            Some((f, reason))
                if !f.is_empty() && f.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_') =>
            {
                (f.to_string(), reason.to_string())
            }
            _ => ("query".to_string(), detail.to_string()),
        };
        ApiError::Invalid(signorini_core::spec::SpecError::new(field, reason))
    }
}

/// Whether `Accept-Encoding` admits gzip (`gzip` listed without `q=0`).
fn accepts_gzip(headers: &HeaderMap) -> bool {
    headers
        .get_all(header::ACCEPT_ENCODING)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(','))
        .any(|item| {
            let mut parts = item.split(';').map(str::trim);
            parts.next().is_some_and(|c| c.eq_ignore_ascii_case("gzip"))
                && parts.all(|p| {
                    p.strip_prefix("q=")
                        .is_none_or(|q| q.parse::<f64>().map_or(true, |q| q > 0.0))
                })
        })
}

/// Pieces of a streamed body: about this many bytes each.
const PIECE: usize = 64 << 10;

/// A writer that hands its bytes to the response body in pieces of [`PIECE`] bytes, waiting
/// while the body's small channel is full (the client reads slower than the store is read).
struct Pieces {
    tx: tokio::sync::mpsc::Sender<io::Result<Bytes>>,
    buf: Vec<u8>,
}

impl Pieces {
    fn send(&mut self) -> io::Result<()> {
        if self.buf.is_empty() {
            return Ok(());
        }
        let piece = Bytes::from(std::mem::replace(&mut self.buf, Vec::with_capacity(PIECE)));
        self.tx
            .blocking_send(Ok(piece))
            .map_err(|_| io::Error::new(io::ErrorKind::BrokenPipe, "the client went away"))
    }
}

impl Write for Pieces {
    fn write(&mut self, bytes: &[u8]) -> io::Result<usize> {
        self.buf.extend_from_slice(bytes);
        if self.buf.len() >= PIECE {
            self.send()?;
        }
        Ok(bytes.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        self.send()
    }
}

/// A response body that `write` makes on a blocking thread (it reads the store), sent as it is
/// made through a channel of four pieces, gzip-compressed when `gzip`: whatever the body's size,
/// the server holds a few pieces of it. An error after the first bytes aborts the body (the
/// client sees a truncated transfer, never a silently short one).
fn streamed_body(
    gzip: bool,
    write: impl FnOnce(&mut dyn Write) -> io::Result<()> + Send + 'static,
) -> Body {
    let (tx, rx) = tokio::sync::mpsc::channel(4);
    let errors = tx.clone();
    tokio::task::spawn_blocking(move || {
        let mut out = Pieces {
            tx,
            buf: Vec::with_capacity(PIECE),
        };
        let done = if gzip {
            let gz = flate2::write::GzEncoder::new(&mut out, flate2::Compression::fast());
            let mut w = io::BufWriter::with_capacity(PIECE, gz);
            write(&mut w)
                .and_then(|()| w.into_inner().map_err(|e| e.into_error()))
                .and_then(|gz| gz.finish().map(drop))
        } else {
            write(&mut out)
        };
        match done.and_then(|()| out.flush()) {
            Ok(()) => {}
            Err(e) if e.kind() == io::ErrorKind::BrokenPipe => {}
            Err(e) => {
                tracing::error!("streaming a result: {e}");
                let _ = errors.blocking_send(Err(e));
            }
        }
    });
    Body::from_stream(tokio_stream::wrappers::ReceiverStream::new(rx))
}

/// `GET /v1/jobs/{id}/result`: the stored result, streamed from the store as JSON (default), CSV
/// or NPZ, cut to `columns`, the steps `from..=to` and every `every`-th row of them (plus the
/// last), gzip-compressed when the client accepts it. A failed or cancelled job's rows are
/// served too, with `"partial": true` (header `x-signorini-partial: true`). The CSV of a job
/// that records no steps (a study, an analysis) is its first table (`study`, `backbone`, …).
async fn get_result(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
    query: Result<Query<ResultQuery>, QueryRejection>,
) -> Result<Response, ApiError> {
    let Query(q) = query?;
    let format = results::Format::parse(q.format.as_deref().unwrap_or("json"))?;
    let req = CutRequest {
        columns: q
            .columns
            .iter()
            .flat_map(|c| c.split(','))
            .filter(|c| !c.is_empty())
            .map(str::to_string)
            .collect(),
        every: q.every.unwrap_or(1),
        from: q.from,
        to: q.to,
    };
    let engine = state.engine.clone();
    let (view, head, series, cut) = tokio::task::spawn_blocking(move || {
        let (view, head, series) = engine.open_result(&id)?;
        let cut = Cut::new(&head, &series, &req)?;
        Ok::<_, ApiError>((view, head, series, cut))
    })
    .await
    .map_err(|e| ApiError::Internal(e.to_string()))??;
    let gzip = accepts_gzip(&headers);
    let (partial, rows, file) = (head.partial, cut.rows(), format!("{}.npz", view.id));
    let body = streamed_body(gzip, move |w| match format {
        results::Format::Json => write_json(w, &view, &head, &cut, &series),
        // A job that records no steps (a study, an analysis): its first table as CSV.
        results::Format::Csv if head.columns.is_empty() && !head.tables.is_empty() => {
            results::write_table_csv(w, &head.tables[0])
        }
        results::Format::Csv => write_csv(w, &cut, &series),
        results::Format::Npz => write_npz(w, &cut, &series),
    });
    let mut resp = Response::new(body);
    let h = resp.headers_mut();
    h.insert(
        header::CONTENT_TYPE,
        header::HeaderValue::from_static(format.content_type()),
    );
    h.insert(
        header::VARY,
        header::HeaderValue::from_static("accept-encoding"),
    );
    if gzip {
        h.insert(
            header::CONTENT_ENCODING,
            header::HeaderValue::from_static("gzip"),
        );
    }
    h.insert(
        "x-signorini-partial",
        header::HeaderValue::from_static(if partial { "true" } else { "false" }),
    );
    h.insert("x-signorini-rows", header::HeaderValue::from(rows));
    if format == results::Format::Npz
        && let Ok(v) = header::HeaderValue::from_str(&format!("attachment; filename=\"{file}\""))
    {
        h.insert(header::CONTENT_DISPOSITION, v);
    }
    Ok(resp)
}

/// `{"id", "figures": [name…]}`: the figures of a succeeded job, without its step series.
async fn list_figures(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Json<Value>, ApiError> {
    let (view, result) = load_result(&state, id).await?;
    Ok(Json(json!({
        "id": view.id,
        "figures": result.figures.iter().map(|f| f.name.as_str()).collect::<Vec<_>>(),
    })))
}

/// One figure of a succeeded job as `image/svg+xml`; `name` may carry the `.svg` suffix. The name
/// is only compared with the stored names.
async fn get_figure(
    State(state): State<AppState>,
    Path((id, name)): Path<(String, String)>,
) -> Result<Response, ApiError> {
    let (_, result) = load_result(&state, id.clone()).await?;
    let figure = result.figure(&name).ok_or_else(|| ApiError::NoFigure {
        id,
        name: name.clone(),
    })?;
    Ok((
        [(header::CONTENT_TYPE, "image/svg+xml")],
        figure.svg.clone(),
    )
        .into_response())
}

async fn capabilities() -> Json<Value> {
    Json(serde_json::to_value(signorini_core::capabilities::capabilities()).unwrap_or(Value::Null))
}

/// `{"status": "ok"}`, or 503 `{"status": "degraded", "reason": …}` while the store does not
/// take writes (the store's own words; new submissions are refused meanwhile).
async fn healthz(State(state): State<AppState>) -> Response {
    match state.engine.store_refusal() {
        None => Json(json!({ "status": "ok" })).into_response(),
        Some(reason) => (
            StatusCode::SERVICE_UNAVAILABLE,
            Json(json!({ "status": "degraded", "reason": reason })),
        )
            .into_response(),
    }
}

/// Samples of a metric: `({labels}, value)`.
type Samples = Vec<(String, String)>;

/// Prometheus text: per metric its help and type lines, then `NAME{labels} value` per sample.
async fn metrics(State(state): State<AppState>) -> Result<Response, ApiError> {
    let counts = state.engine.counts()?;
    let queue_depth = state.engine.queue_depth()?;
    let steps = state.engine.steps_total();
    let rate = state.steps_rate(steps);
    let stats = state.engine.stream_stats();
    let one = |value: String| -> Samples { vec![(String::new(), value)] };
    let load = |c: &std::sync::atomic::AtomicU64| {
        one(c.load(std::sync::atomic::Ordering::Relaxed).to_string())
    };
    let jobs: Samples = counts
        .into_iter()
        .map(|(st, n)| (format!("{{state=\"{}\"}}", st.as_str()), n.to_string()))
        .collect();
    let metrics = [
        ("signorini_jobs", "gauge", "Jobs by state.", jobs),
        (
            "signorini_queue_depth",
            "gauge",
            "Jobs waiting for a worker.",
            one(queue_depth.to_string()),
        ),
        (
            "signorini_workers",
            "gauge",
            "Worker threads.",
            one(state.engine.workers().to_string()),
        ),
        (
            "signorini_steps_total",
            "counter",
            "Time steps computed.",
            one(steps.to_string()),
        ),
        (
            "signorini_steps_per_second",
            "gauge",
            "Steps per second since the previous scrape.",
            one(rate.to_string()),
        ),
        (
            "signorini_frames_published_total",
            "counter",
            "zenoh frames put.",
            load(&stats.frames_published),
        ),
        (
            "signorini_frames_dropped_total",
            "counter",
            "Step frames dropped for a slow link.",
            load(&stats.frames_dropped),
        ),
    ];
    let mut s = String::new();
    for (name, kind, help, samples) in metrics {
        let _ = writeln!(s, "# HELP {name} {help}\n# TYPE {name} {kind}");
        for (labels, value) in samples {
            let _ = writeln!(s, "{name}{labels} {value}");
        }
    }
    Ok(([(header::CONTENT_TYPE, "text/plain; version=0.0.4")], s).into_response())
}

/// A job event as server-sent events: `status` ([`StatusJson`]) or `energy` (the energy columns
/// of a step batch as [`FrameJson`]), and with `state` also a `state` event of the batch's
/// other columns (a rigid job's poses for the live page's 3D view; the same frame shape).
fn sse_events(event: &JobEvent, state: bool) -> Vec<Event> {
    let mut events = sse_energy_events(event);
    if let (true, JobEvent::Steps(b)) = (state, event)
        && !b.state.columns.is_empty()
    {
        events.extend(
            Event::default()
                .event("state")
                .id(b.seq.to_string())
                .json_data(FrameJson {
                    kind: "state",
                    id: &b.id,
                    seq: b.seq,
                    columns: &b.state.columns,
                    step: &b.step,
                    t: &b.t,
                    rows: FrameJson::rows(&b.state.values, b.state.columns.len()),
                    last: b.last,
                }),
        );
    }
    events
}

/// The status and energy events of [`sse_events`].
fn sse_energy_events(event: &JobEvent) -> Vec<Event> {
    let event = match event {
        JobEvent::Status(v) => Event::default()
            .event("status")
            .json_data(StatusJson::from(v)),
        JobEvent::Steps(b) if !b.energy.columns.is_empty() => Event::default()
            .event("energy")
            .id(b.seq.to_string())
            .json_data(FrameJson {
                kind: "energy",
                id: &b.id,
                seq: b.seq,
                columns: &b.energy.columns,
                step: &b.step,
                t: &b.t,
                rows: FrameJson::rows(&b.energy.values, b.energy.columns.len()),
                last: b.last,
            }),
        JobEvent::Steps(_) | JobEvent::Closed(_) => return Vec::new(),
    };
    event.into_iter().collect()
}

/// `?from_seq=N` of `GET /v1/jobs/{id}/events`.
#[derive(Debug, Deserialize)]
struct EventsQuery {
    #[serde(default)]
    from_seq: Option<u64>,
    /// Also send `state` events (the columns that are not energy terms).
    #[serde(default)]
    state: bool,
}

/// Server-sent events of one job: its current status, then its status and energy events as
/// they are published; the stream ends after the job's final status. Energy events carry
/// `id:` = their `seq`. With `?from_seq=N`, or a `Last-Event-ID: N` header (a reconnecting
/// `EventSource`: from N + 1), the job's stored energy frames from that seq come first, then
/// the live ones, none twice.
async fn job_events(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
    query: Result<Query<EventsQuery>, QueryRejection>,
) -> Result<Sse<impl tokio_stream::Stream<Item = Result<Event, Infallible>>>, ApiError> {
    let Query(q) = query?;
    let resume = headers
        .get("last-event-id")
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.trim().parse::<u64>().ok())
        .map(|seq| seq + 1);
    let with_state = q.state;
    let encode = move |e: &JobEvent| sse_events(e, with_state);
    let stream: std::pin::Pin<Box<dyn tokio_stream::Stream<Item = Event> + Send>> =
        match resume.or(q.from_seq) {
            Some(from_seq) => Box::pin(state.replay(&id, from_seq, encode)?),
            None => {
                let (current, events) = state.follow(&id, encode)?;
                let first = encode(&JobEvent::Status(current));
                match events {
                    None => Box::pin(tokio_stream::iter(first)),
                    Some(events) => Box::pin(tokio_stream::iter(first).chain(events)),
                }
            }
        };
    Ok(Sse::new(stream.map(Ok)).keep_alive(KeepAlive::new().interval(Duration::from_secs(10))))
}

/// The live page of a job (404 for an unknown one).
async fn live_page(
    State(state): State<AppState>,
    headers: HeaderMap,
    Path(id): Path<String>,
) -> Result<Html<String>, ApiError> {
    crate::engine::check_id(&id)?;
    // Whether the job exists is a read: told only to a caller who may read (the page itself
    // is open, `auth.js`).
    if state
        .authorize_read(read_credential(&headers).as_deref())
        .is_ok()
    {
        state.engine.status(&id)?;
    }
    Ok(Html(include_str!("live.html").replace("{{JOB_ID}}", &id)))
}

/// The pages' read access on a server with `--tokens`: a read token from the page's address
/// (`#token=…`) into the cookie [`READ_COOKIE`], or a note saying how to give one.
async fn auth_script() -> impl IntoResponse {
    (
        [(header::CONTENT_TYPE, "text/javascript; charset=utf-8")],
        include_str!("auth.js"),
    )
}

/// The index page: the newest jobs, linked to their live pages.
async fn index_page() -> Html<&'static str> {
    Html(include_str!("index.html"))
}
