//! HTTP/JSON API (axum). Each handler: validate → convert → dispatch to the [`crate::engine::Engine`] → respond,
//! encoding statuses and frames with [`super::json`].
//! Errors are `{"error": {"field", "reason"}}` with a status code per [`ApiError`] kind.

use super::AppState;
use super::json::{FrameJson, StatusJson};
use crate::engine::events::JobEvent;
use crate::error::ApiError;
use crate::spec_file::{self, Format};
use crate::status::JobView;
use crate::store::StoredResult;
use axum::extract::rejection::StringRejection;
use axum::extract::{DefaultBodyLimit, Path, Query, State};
use axum::http::{HeaderMap, Method, StatusCode, Uri, header};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{Html, IntoResponse, Response};
use axum::routing::get;
use axum::{Json, Router};
use serde::Deserialize;
use serde_json::{Map, Value, json};
use std::convert::Infallible;
use std::fmt::Write as _;
use std::time::Duration;
use tokio_stream::StreamExt;

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let code = match &self {
            ApiError::Invalid(_) => StatusCode::BAD_REQUEST,
            ApiError::NotFound { .. } | ApiError::NoFigure { .. } | ApiError::NoRoute { .. } => {
                StatusCode::NOT_FOUND
            }
            ApiError::Body {
                too_large: true, ..
            } => StatusCode::PAYLOAD_TOO_LARGE,
            ApiError::Body { .. } => StatusCode::BAD_REQUEST,
            ApiError::AlreadyExists { .. } | ApiError::NoResult { .. } => StatusCode::CONFLICT,
            ApiError::QueueFull { .. } => StatusCode::TOO_MANY_REQUESTS,
            ApiError::Unauthenticated => StatusCode::UNAUTHORIZED,
            ApiError::Unavailable => StatusCode::SERVICE_UNAVAILABLE,
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
        .route("/v1/capabilities", get(capabilities))
        .route("/healthz", get(healthz))
        .route("/metrics", get(metrics))
        .route("/jobs/{id}", get(live_page))
        .fallback(no_route)
        .layer(DefaultBodyLimit::max(MAX_BODY_BYTES))
        .with_state(state)
}

fn authorize(state: &AppState, headers: &HeaderMap) -> Result<(), ApiError> {
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

async fn submit_job(
    State(state): State<AppState>,
    headers: HeaderMap,
    Query(q): Query<SubmitQuery>,
    body: Result<String, StringRejection>,
) -> Result<(StatusCode, Json<Value>), ApiError> {
    authorize(&state, &headers)?;
    let body = body?;
    // Parsing and validation (a factorisation of M and K) run off the async executor.
    let engine = state.engine.clone();
    let id = tokio::task::spawn_blocking(move || {
        let spec = spec_file::parse(&body, Format::Json)?;
        engine.submit(&spec, q.id)
    })
    .await
    .map_err(|e| ApiError::Internal(e.to_string()))??;
    Ok((StatusCode::CREATED, Json(json!({ "id": id }))))
}

/// `{"jobs": [status…]}`, oldest first.
async fn list_jobs(State(state): State<AppState>) -> Result<Json<Value>, ApiError> {
    let jobs = state.engine.list()?;
    let jobs: Vec<StatusJson> = jobs.iter().map(StatusJson::from).collect();
    Ok(Json(json!({ "jobs": jobs })))
}

/// Answers a status as [`StatusJson`].
fn status_body(v: &JobView) -> Response {
    Json(StatusJson::from(v)).into_response()
}

async fn get_job(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    Ok(status_body(&state.engine.status(&id)?))
}

async fn cancel_job(
    State(state): State<AppState>,
    headers: HeaderMap,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    authorize(&state, &headers)?;
    Ok(status_body(&state.cancel_and_wait(&id).await?))
}

/// `{"id", "summary", "columns", "steps": {"step": […], "t": […], column: […]}, "tables",
/// "figures": [name…]}` — figure names only; `GET /v1/jobs/{id}/figures/{name}` serves the SVG.
pub fn result_json(view: &JobView, r: &StoredResult) -> Value {
    let mut steps = Map::new();
    steps.insert("step".into(), json!(r.steps));
    steps.insert("t".into(), json!(r.t));
    for (c, name) in r.columns.iter().enumerate() {
        steps.insert(name.clone(), json!(r.column(c)));
    }
    let mut columns = vec!["step".to_string(), "t".to_string()];
    columns.extend(r.columns.iter().cloned());
    json!({
        "id": view.id,
        "state": view.state.as_str(),
        "summary": r.summary,
        "columns": columns,
        "steps": steps,
        "tables": r.tables.iter().map(|t| json!({ "name": t.name, "columns": t.columns, "rows": t.rows })).collect::<Vec<_>>(),
        "figures": r.figures.iter().map(|f| f.name.as_str()).collect::<Vec<_>>(),
    })
}

/// A finished job's stored result, read off the async executor.
async fn load_result(state: &AppState, id: String) -> Result<(JobView, StoredResult), ApiError> {
    let engine = state.engine.clone();
    tokio::task::spawn_blocking(move || engine.result(&id))
        .await
        .map_err(|e| ApiError::Internal(e.to_string()))?
}

/// `?columns=a,b&every=N` of `GET /v1/jobs/{id}/result`.
#[derive(Debug, Deserialize)]
struct ResultQuery {
    /// Comma-separated column names (all when absent).
    #[serde(default)]
    columns: Option<String>,
    /// Every N-th recorded row, and the last.
    #[serde(default)]
    every: Option<u64>,
}

async fn get_result(
    State(state): State<AppState>,
    Path(id): Path<String>,
    Query(q): Query<ResultQuery>,
) -> Result<Json<Value>, ApiError> {
    let (view, result) = load_result(&state, id).await?;
    let columns: Vec<String> = q
        .columns
        .iter()
        .flat_map(|c| c.split(','))
        .filter(|c| !c.is_empty())
        .map(str::to_string)
        .collect();
    let result = result.select(&columns, q.every.unwrap_or(1))?;
    Ok(Json(result_json(&view, &result)))
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

async fn healthz() -> Json<Value> {
    Json(json!({ "status": "ok" }))
}

/// Samples of a metric: `({labels}, value)`.
type Samples = Vec<(String, String)>;

/// Prometheus text: per metric its help and type lines, then `NAME{labels} value` per sample.
async fn metrics(State(state): State<AppState>) -> Result<Response, ApiError> {
    let counts = state.engine.counts()?;
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
            one(state.engine.queue_depth().to_string()),
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
/// of a step batch as [`FrameJson`]); the state columns are not sent.
fn sse_events(event: &JobEvent) -> Vec<Event> {
    let event = match event {
        JobEvent::Status(v) => Event::default()
            .event("status")
            .json_data(StatusJson::from(v)),
        JobEvent::Steps(b) if !b.energy.columns.is_empty() => {
            Event::default().event("energy").json_data(FrameJson {
                kind: "energy",
                id: &b.id,
                seq: b.seq,
                columns: &b.energy.columns,
                step: &b.step,
                t: &b.t,
                rows: FrameJson::rows(&b.energy.values, b.energy.columns.len()),
                last: b.last,
            })
        }
        JobEvent::Steps(_) | JobEvent::Closed(_) => return Vec::new(),
    };
    event.into_iter().collect()
}

/// Server-sent events of one job: its current status, then its status and energy events as
/// they are published; the stream ends after the job's final status.
async fn job_events(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Sse<impl tokio_stream::Stream<Item = Result<Event, Infallible>>>, ApiError> {
    let (current, events) = state.follow(&id, sse_events)?;
    let first = sse_events(&JobEvent::Status(current));
    let rest: std::pin::Pin<Box<dyn tokio_stream::Stream<Item = Event> + Send>> = match events {
        None => Box::pin(tokio_stream::empty()),
        Some(events) => Box::pin(events),
    };
    let stream = tokio_stream::iter(first).chain(rest).map(Ok);
    Ok(Sse::new(stream).keep_alive(KeepAlive::new().interval(Duration::from_secs(10))))
}

async fn live_page(Path(id): Path<String>) -> Result<Html<String>, ApiError> {
    crate::engine::check_id(&id)?;
    Ok(Html(include_str!("live.html").replace("{{JOB_ID}}", &id)))
}
