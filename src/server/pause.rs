//! The pause, resume and extend calls at the edges (`crate::engine::pause` does the work):
//! `POST /v1/jobs/{id}/pause`, `…/resume`, `…/extend` with `{"t_end": T}`, and the gRPC
//! `PauseJob`, `ResumeJob`, `ExtendJob` (which forward here).

use super::AppState;
use super::http::authorize;
use super::json::StatusJson;
use crate::error::ApiError;
use crate::status::JobView;
use axum::Json;
use axum::extract::rejection::StringRejection;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use serde_json::{Map, Value, json};
use signorini_core::spec::SpecError;
use std::time::Duration;

/// Longest wait of a pause call for a running job to reach its checkpoint and stop.
const PAUSE_WAIT: Duration = Duration::from_secs(5);

impl AppState {
    /// Pauses a job and waits (up to [`PAUSE_WAIT`]) until a running one has stopped at its
    /// checkpoint; its status then (`paused`; `running` if it is slower, or runs on another
    /// replica, which parks it at its next heartbeat).
    pub async fn pause_and_wait(&self, id: &str) -> Result<JobView, ApiError> {
        let ended = self.engine.ended(id);
        let engine = self.engine.clone();
        let job = id.to_string();
        let view = tokio::task::spawn_blocking(move || engine.pause(&job))
            .await
            .map_err(|e| ApiError::Internal(e.to_string()))??;
        if view.state != crate::status::JobState::Running {
            return Ok(view);
        }
        if let Some(mut rx) = ended {
            let _ = tokio::time::timeout(PAUSE_WAIT, rx.wait_for(|ended| *ended)).await;
        }
        Ok(self.engine.status(id)?)
    }

    /// Queues a paused job again: its status.
    pub async fn resume_job(&self, id: &str) -> Result<JobView, ApiError> {
        let engine = self.engine.clone();
        let job = id.to_string();
        Ok(tokio::task::spawn_blocking(move || engine.resume(&job))
            .await
            .map_err(|e| ApiError::Internal(e.to_string()))??)
    }

    /// Extends a succeeded job to `t_end`: the new job's id.
    pub async fn extend_job(
        &self,
        id: &str,
        t_end: f64,
        new_id: Option<String>,
    ) -> Result<String, ApiError> {
        let engine = self.engine.clone();
        let job = id.to_string();
        Ok(
            tokio::task::spawn_blocking(move || engine.extend(&job, t_end, new_id))
                .await
                .map_err(|e| ApiError::Internal(e.to_string()))??,
        )
    }
}

/// `POST /v1/jobs/{id}/pause`: the job's status (`paused`, or `running` until a slow step
/// ends); 409 naming the state for a job that is not queued or running, or writes no
/// checkpoints.
pub(super) async fn pause_job(
    State(state): State<AppState>,
    headers: HeaderMap,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    authorize(&state, &headers)?;
    let view = state.pause_and_wait(&id).await?;
    Ok(Json(StatusJson::from(&view)).into_response())
}

/// `POST /v1/jobs/{id}/resume`: the job's status (`queued`); 409 naming the state for a job
/// that is not paused.
pub(super) async fn resume_job(
    State(state): State<AppState>,
    headers: HeaderMap,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    authorize(&state, &headers)?;
    let view = state.resume_job(&id).await?;
    Ok(Json(StatusJson::from(&view)).into_response())
}

/// The body of `POST /v1/jobs/{id}/extend`: `{"t_end": T}`, optionally with `"id"`.
#[derive(Debug, PartialEq)]
struct ExtendBody {
    /// The new final time.
    t_end: f64,
    /// Optional client-chosen id of the new job.
    id: Option<String>,
}

impl ExtendBody {
    /// Reads the body field by field, so the error names the field that is wrong (`t_end`,
    /// `id`, an unknown key), or `body` when the text is no JSON object.
    fn parse(body: &str) -> Result<ExtendBody, SpecError> {
        let fields: Map<String, Value> =
            serde_json::from_str(body).map_err(|e| SpecError::new("body", e.to_string()))?;
        let (mut t_end, mut id) = (None, None);
        for (key, value) in fields {
            match (key.as_str(), value) {
                ("t_end", Value::Number(n)) => t_end = n.as_f64(),
                ("t_end", other) => {
                    return Err(SpecError::new("t_end", format!("a number, got {other}")));
                }
                ("id", Value::String(s)) => id = Some(s),
                ("id", Value::Null) => id = None,
                ("id", other) => {
                    return Err(SpecError::new("id", format!("a string, got {other}")));
                }
                (other, _) => {
                    return Err(SpecError::new(
                        other,
                        "unknown field: the body takes t_end and id",
                    ));
                }
            }
        }
        let t_end = t_end.ok_or_else(|| SpecError::new("t_end", "missing"))?;
        Ok(ExtendBody { t_end, id })
    }
}

/// `POST /v1/jobs/{id}/extend` with `{"t_end": T}` (and optionally `"id"`): 201 with `{"id":
/// NEW, "extends": ID}`; 400 naming `t_end` when it is not after the job's end; 409 naming the
/// state for a job that has not succeeded.
pub(super) async fn extend_job(
    State(state): State<AppState>,
    headers: HeaderMap,
    Path(id): Path<String>,
    body: Result<String, StringRejection>,
) -> Result<(StatusCode, Json<Value>), ApiError> {
    authorize(&state, &headers)?;
    let body = body?;
    let ExtendBody { t_end, id: new_id } = ExtendBody::parse(&body)?;
    let new = state.extend_job(&id, t_end, new_id).await?;
    Ok((
        StatusCode::CREATED,
        Json(json!({ "id": new, "extends": id })),
    ))
}

#[cfg(test)]
mod tests {
    use super::ExtendBody;

    #[test]
    fn the_extend_body_names_the_wrong_field() {
        let ok = ExtendBody::parse(r#"{"t_end": 8.5, "id": "next"}"#).expect("valid");
        assert_eq!(
            ok,
            ExtendBody {
                t_end: 8.5,
                id: Some("next".into())
            }
        );
        let field = |body: &str| ExtendBody::parse(body).expect_err(body).field;
        assert_eq!(field(r#"{"t_end": "late"}"#), "t_end");
        assert_eq!(field(r#"{"id": "next"}"#), "t_end");
        assert_eq!(field(r#"{"t_end": 2, "id": 7}"#), "id");
        assert_eq!(field(r#"{"t_end": 2, "t_stop": 3}"#), "t_stop");
        assert_eq!(field("[2]"), "body");
        assert_eq!(field("not json"), "body");
    }
}
