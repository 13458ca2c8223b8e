//! The study routes: a study's parent job lists its children (`GET /v1/jobs/{id}/children`,
//! gRPC `ListChildren`). Submitting, status, cancel, purge and the result of a study go through
//! the ordinary job routes.

use super::AppState;
use super::json::StatusJson;
use crate::error::ApiError;
use crate::status::JobView;
use axum::Json;
use axum::extract::{Path, State};
use serde_json::{Value, json};

/// The children of `id`, read off the async executor.
pub(super) async fn children(state: &AppState, id: String) -> Result<Vec<JobView>, ApiError> {
    let engine = state.engine.clone();
    Ok(tokio::task::spawn_blocking(move || engine.children(&id))
        .await
        .map_err(|e| ApiError::Internal(e.to_string()))??)
}

/// `GET /v1/jobs/{id}/children`: `{"jobs": [status…]}`, in study order (the reference run
/// first, if any); empty for a job that is no study.
pub(super) async fn list_children(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Json<Value>, ApiError> {
    let jobs = children(&state, id).await?;
    let jobs: Vec<StatusJson> = jobs.iter().map(StatusJson::from).collect();
    Ok(Json(json!({ "jobs": jobs })))
}
