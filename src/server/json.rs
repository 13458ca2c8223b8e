//! The one JSON encoding of a job's status and of its step frames, used by every HTTP route
//! (`GET /v1/jobs/{id}`, the list, cancel, SSE) and by the CLI (`status`, `cancel`, `watch`,
//! `pause`, `resume`, `children`).

use crate::status::{JobView, Lineage};
use serde::Serialize;
use serde_json::{Value, json};

/// A status: `{"id", "name", "state", "progress": {"step", "total", "t", "fraction"}, "error":
/// {"field", "reason"} or null, "created_ms", "started_ms", "finished_ms"}`.
#[derive(Debug, Serialize)]
pub struct StatusJson<'a> {
    id: &'a str,
    name: Option<&'a str>,
    state: &'static str,
    progress: ProgressJson,
    error: Option<ErrorJson<'a>>,
    created_ms: u64,
    started_ms: u64,
    finished_ms: u64,
}

#[derive(Debug, Serialize)]
struct ProgressJson {
    step: u64,
    total: u64,
    t: f64,
    fraction: f64,
}

#[derive(Debug, Serialize)]
struct ErrorJson<'a> {
    field: &'a str,
    reason: &'a str,
}

impl<'a> From<&'a JobView> for StatusJson<'a> {
    fn from(v: &'a JobView) -> Self {
        StatusJson {
            id: &v.id,
            name: v.name.as_deref(),
            state: v.state.as_str(),
            progress: ProgressJson {
                step: v.done,
                total: v.total,
                t: v.t,
                fraction: v.fraction(),
            },
            error: v
                .error
                .as_ref()
                .map(|(field, reason)| ErrorJson { field, reason }),
            created_ms: v.created_ms,
            started_ms: v.started_ms,
            finished_ms: v.finished_ms,
        }
    }
}

/// A status with where the job comes from (`GET /v1/jobs/{id}`): [`StatusJson`] plus `parent`
/// (the study it is a run of) and `extends` (the job it continues), each when there is one.
pub fn status_with_lineage(v: &JobView, lineage: Lineage) -> Value {
    let mut body = json!(StatusJson::from(v));
    let Lineage { parent, extends } = lineage;
    for (key, value) in [("parent", parent), ("extends", extends)] {
        if let Some(v) = value {
            body[key] = Value::String(v);
        }
    }
    body
}

/// Consecutive steps of some columns of a run: `{"kind", "id", "seq", "columns", "step", "t",
/// "rows": [[value per column] per step], "last"}`; `kind` is `energy` or `state`.
#[derive(Debug, Serialize)]
pub struct FrameJson<'a> {
    /// `energy` or `state`.
    pub kind: &'a str,
    /// The job.
    pub id: &'a str,
    /// Batch number within the run.
    pub seq: u64,
    /// Column names.
    pub columns: &'a [String],
    /// Step numbers.
    pub step: &'a [u64],
    /// Times.
    pub t: &'a [f64],
    /// One row of values per step ([`FrameJson::rows`]).
    pub rows: Vec<&'a [f64]>,
    /// The run's last frame.
    pub last: bool,
}

impl FrameJson<'_> {
    /// Row-major `values` cut into rows of `columns` values.
    pub fn rows(values: &[f64], columns: usize) -> Vec<&[f64]> {
        values.chunks(columns.max(1)).collect()
    }
}
