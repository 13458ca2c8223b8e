//! The engine's domain types ⇄ protobuf messages, for the gRPC API and the zenoh stream (they
//! carry the same messages). Every domain struct is destructured field by field (no `..`), so a
//! field added to it breaks the build here until it is handled.

use super::v1 as pb;
use crate::engine::events::{ColumnGroup, StepBatch};
use crate::status::{JobState, JobView};
use crate::store::StoredResult;
use anyhow::{Result, anyhow};
use signorini_core::outcome::Table;

/// A job state → proto.
pub fn state_to_proto(s: JobState) -> pb::JobState {
    match s {
        JobState::Queued => pb::JobState::Queued,
        JobState::Running => pb::JobState::Running,
        JobState::Succeeded => pb::JobState::Succeeded,
        JobState::Failed => pb::JobState::Failed,
        JobState::Cancelled => pb::JobState::Cancelled,
        JobState::Paused => pb::JobState::Paused,
    }
}

/// A proto job state → the domain's (None for UNSPECIFIED or unknown values).
pub fn state_from_proto(s: i32) -> Option<JobState> {
    match pb::JobState::try_from(s).ok()? {
        pb::JobState::Unspecified => None,
        pb::JobState::Queued => Some(JobState::Queued),
        pb::JobState::Running => Some(JobState::Running),
        pb::JobState::Succeeded => Some(JobState::Succeeded),
        pb::JobState::Failed => Some(JobState::Failed),
        pb::JobState::Cancelled => Some(JobState::Cancelled),
        pb::JobState::Paused => Some(JobState::Paused),
    }
}

/// A status → proto (the gRPC `JobStatus` and the zenoh status frame).
pub fn status_to_proto(v: &JobView) -> pb::JobStatus {
    let JobView {
        id,
        name,
        state,
        done,
        total,
        t,
        error,
        created_ms,
        started_ms,
        finished_ms,
    } = v;
    pb::JobStatus {
        id: id.clone(),
        state: state_to_proto(*state) as i32,
        progress: Some(pb::Progress {
            step: *done,
            total: *total,
            t: *t,
            fraction: v.fraction(),
        }),
        name: name.clone(),
        error: error.as_ref().map(|(field, reason)| pb::JobError {
            field: field.clone(),
            reason: reason.clone(),
        }),
        created_ms: *created_ms,
        started_ms: *started_ms,
        finished_ms: *finished_ms,
        parent: None,
        extends: None,
    }
}

/// A proto status → the domain's (what a client of the gRPC API or the zenoh stream reads).
pub fn status_from_proto(s: pb::JobStatus) -> Result<JobView> {
    let pb::JobStatus {
        id,
        state,
        progress,
        name,
        error,
        created_ms,
        started_ms,
        finished_ms,
        parent: _,
        extends: _,
    } = s;
    let pb::Progress {
        step,
        total,
        t,
        fraction: _,
    } = progress.unwrap_or_default();
    Ok(JobView {
        state: state_from_proto(state)
            .ok_or_else(|| anyhow!("job {id}: unknown state {state} from the server"))?,
        id,
        name,
        done: step,
        total,
        t,
        error: error.map(|pb::JobError { field, reason }| (field, reason)),
        created_ms,
        started_ms,
        finished_ms,
    })
}

/// A step batch → its energy and state frames (a group without columns gives no frame).
pub fn step_frames(b: &StepBatch) -> (Option<pb::StepFrame>, Option<pb::StepFrame>) {
    let StepBatch {
        id,
        seq,
        step,
        t,
        computed_unix_ns,
        energy,
        state,
        last,
    } = b;
    let frame = |group: &ColumnGroup| {
        let ColumnGroup { columns, values } = group;
        (!columns.is_empty()).then(|| pb::StepFrame {
            id: id.clone(),
            seq: *seq,
            columns: columns.clone(),
            step: step.clone(),
            t: t.clone(),
            values: values.clone(),
            computed_unix_ns: computed_unix_ns.clone(),
            last: *last,
        })
    };
    (frame(energy), frame(state))
}

/// A step frame received from zenoh → a step batch holding its columns as the energy group
/// (`energy`) or the state group, the other group empty: the inverse of [`step_frames`] for one
/// frame.
pub fn step_batch_from_frame(f: pb::StepFrame, energy: bool) -> StepBatch {
    let pb::StepFrame {
        id,
        seq,
        columns,
        step,
        t,
        values,
        computed_unix_ns,
        last,
    } = f;
    let group = ColumnGroup { columns, values };
    let (energy, state) = if energy {
        (group, ColumnGroup::default())
    } else {
        (ColumnGroup::default(), group)
    };
    StepBatch {
        id,
        seq,
        step,
        t,
        computed_unix_ns,
        energy,
        state,
        last,
    }
}

/// Tables → proto.
pub fn tables_to_proto(tables: &[Table]) -> Vec<pb::Table> {
    tables
        .iter()
        .map(|tb| pb::Table {
            name: tb.name.clone(),
            columns: tb.columns.clone(),
            rows: tb
                .rows
                .iter()
                .map(|row| pb::Row {
                    values: row.clone(),
                })
                .collect(),
        })
        .collect()
}

/// A stored result → proto (column-major series).
pub fn result_to_proto(view: &JobView, r: &StoredResult) -> pb::JobResult {
    let StoredResult {
        partial: _,
        summary,
        columns,
        steps,
        t,
        values: _,
        tables,
        figures,
    } = r;
    pb::JobResult {
        id: view.id.clone(),
        status: Some(status_to_proto(view)),
        summary_json: serde_json::Value::Object(summary.clone()).to_string(),
        columns: columns.clone(),
        step: steps.clone(),
        t: t.clone(),
        series: columns
            .iter()
            .enumerate()
            .map(|(c, name)| pb::Series {
                column: name.clone(),
                values: r.column(c),
            })
            .collect(),
        tables: tables_to_proto(tables),
        figures: figures
            .iter()
            .map(|f| pb::Figure {
                name: f.name.clone(),
                svg: f.svg.clone(),
            })
            .collect(),
    }
}

/// Proto tables → tables.
pub fn tables_from_proto(tables: Vec<pb::Table>) -> Vec<Table> {
    tables
        .into_iter()
        .map(
            |pb::Table {
                 name,
                 columns,
                 rows,
             }| Table {
                name,
                columns,
                rows: rows.into_iter().map(|row| row.values).collect(),
            },
        )
        .collect()
}
