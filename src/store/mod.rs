//! The result store: every job's spec, status, summary and recorded series, behind one
//! interface ([`Backend`]) with two implementations:
//!
//! * [`sqlite`]: one embedded SQLite file (the default; one `serve` process at a time);
//! * [`postgres`]: a PostgreSQL database shared by any number of `serve` replicas, which also
//!   holds the queue ([`SharedQueue`]: claims under a lease with a heartbeat), `--store
//!   postgres://…`.
//!
//! Both keep a job's recorded series as a sequence of chunks of about [`CHUNK_BYTES`]
//! (little-endian `u64`/`f64` blobs: what is read back is what was computed, bit for bit),
//! appended while the job runs, read back one chunk at a time.

mod health;
pub mod pause;
pub mod postgres;
pub mod sqlite;
mod study;

use crate::status::{JobState, JobView, Lineage};
use serde_json::{Map, Value};
use signorini_core::outcome::Table;
use signorini_figures::Figure;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;
use thiserror::Error;

pub use health::Health;
pub use sqlite::StoreLock;
pub use study::StudyStore;

/// A store failure.
#[derive(Debug, Error)]
pub enum StoreError {
    /// SQLite said no.
    #[error("store: {0}")]
    Sql(#[from] rusqlite::Error),
    /// Another process holds the store's lock.
    #[error(
        "store {path} is in use by another signorini serve (it holds the file's lock): stop that server or give another --store"
    )]
    Locked {
        /// The store file.
        path: String,
    },
    /// The lock file could not be opened or locked.
    #[error("store {path}: {reason}")]
    Lock {
        /// The store file.
        path: String,
        /// Why.
        reason: String,
    },
    /// PostgreSQL (or its connection pool) said no.
    #[error("store (PostgreSQL): {0}")]
    Postgres(String),
    /// PostgreSQL could not be reached, or dropped the connection (it stopped, crashed or is
    /// still recovering: SQLSTATE class 08, 57P01–57P03, or an I/O error of the connection).
    /// The PostgreSQL backend tries again for a while before it reports this.
    #[error("store (PostgreSQL): unreachable: {0}")]
    PostgresUnreachable(String),
    /// PostgreSQL refused a write for want of room or because it is read-only (SQLSTATE class
    /// 53 "insufficient resources", 25006 `read_only_sql_transaction`, class 58 "system
    /// error", e.g. 58030 `io_error`).
    #[error("store (PostgreSQL): {reason} (SQLSTATE {sqlstate})")]
    PostgresRefused {
        /// PostgreSQL's message.
        reason: String,
        /// Its SQLSTATE code.
        sqlstate: String,
    },
    /// This replica no longer holds the job's lease: another replica claimed it again (this
    /// one was too slow to renew it), so what this run would store is dropped.
    #[error("store: job {id} was claimed again by another replica (this replica lost its lease)")]
    LeaseLost {
        /// Which job.
        id: String,
    },
    /// A stored value does not decode.
    #[error("store: corrupt {what} of job {id}")]
    Corrupt {
        /// Which column.
        what: &'static str,
        /// Which job.
        id: String,
    },
}

impl StoreError {
    /// True when the store refused a write for want of room or because it is read-only (or its
    /// file cannot be written): the store is then degraded ([`Health`]) until it can write
    /// again.
    pub fn refuses_writes(&self) -> bool {
        use rusqlite::ErrorCode;
        match self {
            StoreError::Sql(rusqlite::Error::SqliteFailure(e, _)) => matches!(
                e.code,
                ErrorCode::DiskFull | ErrorCode::ReadOnly | ErrorCode::SystemIoFailure
            ),
            StoreError::PostgresRefused { .. } => true,
            _ => false,
        }
    }
}

/// A finished job's result.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StoredResult {
    /// True for the steps a failed or cancelled run recorded before it stopped (no summary).
    pub partial: bool,
    /// summary.json.
    pub summary: Map<String, Value>,
    /// Columns besides `step` and `t`.
    pub columns: Vec<String>,
    /// Step numbers of the records.
    pub steps: Vec<u64>,
    /// Times of the records.
    pub t: Vec<f64>,
    /// Values, row-major (`values[i * columns.len() + c]`).
    pub values: Vec<f64>,
    /// Extra tables (analyses).
    pub tables: Vec<Table>,
    /// Figures (SVG text), in the order the job made them.
    pub figures: Vec<Figure>,
}

impl StoredResult {
    /// The figure called `name` (`NAME` or `NAME.svg`), if the job made one.
    pub fn figure(&self, name: &str) -> Option<&Figure> {
        let stem = name.strip_suffix(".svg").unwrap_or(name);
        let by = |n: &str| self.figures.iter().find(|f| f.name == n);
        by(name).or_else(|| by(stem))
    }

    /// The values of column `c`.
    pub fn column(&self, c: usize) -> Vec<f64> {
        let n = self.columns.len();
        self.values
            .iter()
            .skip(c)
            .step_by(n.max(1))
            .copied()
            .collect()
    }
}

/// Target size of one stored chunk of a series (its rows are [`chunk_rows`]).
pub const CHUNK_BYTES: usize = 1 << 20;

/// Rows per stored chunk for `columns` value columns (besides `step` and `t`): about
/// [`CHUNK_BYTES`], at least one.
pub fn chunk_rows(columns: usize) -> usize {
    (CHUNK_BYTES / (8 * (columns + 2))).max(1)
}

/// Where one stored chunk sits in its series.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChunkMeta {
    /// Chunk number (0, 1, …).
    pub chunk: u64,
    /// Index of its first row in the series.
    pub first_row: u64,
    /// Its rows.
    pub rows: u64,
    /// Step number of its first and last rows.
    pub step_first: u64,
    /// Step number of its last row.
    pub step_last: u64,
}

/// Consecutive rows of a series, as stored.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SeriesChunk {
    /// Step numbers.
    pub steps: Vec<u64>,
    /// Times.
    pub t: Vec<f64>,
    /// Values, row-major, one row of the result's columns per step.
    pub values: Vec<f64>,
    /// The live batches these rows went out in: (seq, first row, end row) in the series (empty
    /// for a series stored before batches were recorded).
    pub batches: Vec<(u64, u64, u64)>,
}

pub(crate) fn decode_u64s(b: &[u8]) -> Option<Vec<u64>> {
    Some(blob_to_8(b)?.map(u64::from_le_bytes).collect())
}

pub(crate) fn decode_f64s(b: &[u8]) -> Option<Vec<f64>> {
    Some(blob_to_8(b)?.map(f64::from_le_bytes).collect())
}

pub(crate) fn f64s_to_blob(v: &[f64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

pub(crate) fn u64s_to_blob(v: &[u64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

pub(crate) fn blob_to_8(b: &[u8]) -> Option<impl Iterator<Item = [u8; 8]> + '_> {
    if !b.len().is_multiple_of(8) {
        return None;
    }
    Some(b.chunks_exact(8).map(|c| {
        let mut a = [0u8; 8];
        a.copy_from_slice(c);
        a
    }))
}

#[derive(serde::Serialize, serde::Deserialize)]
pub(crate) struct TableJson {
    pub name: String,
    pub columns: Vec<String>,
    /// JSON has no NaN: an empty cell (NaN, e.g. the `branch` of an orbit on no main branch)
    /// is stored as null and read back as NaN.
    #[serde(with = "nan_as_null")]
    pub rows: Vec<Vec<f64>>,
}

/// Table rows with NaN cells through JSON: NaN ↔ null.
mod nan_as_null {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer>(rows: &[Vec<f64>], s: S) -> Result<S::Ok, S::Error> {
        let cells: Vec<Vec<Option<f64>>> = rows
            .iter()
            .map(|r| r.iter().map(|&x| (!x.is_nan()).then_some(x)).collect())
            .collect();
        cells.serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<Vec<f64>>, D::Error> {
        let cells = Vec::<Vec<Option<f64>>>::deserialize(d)?;
        Ok(cells
            .into_iter()
            .map(|r| r.into_iter().map(|x| x.unwrap_or(f64::NAN)).collect())
            .collect())
    }
}

#[derive(serde::Serialize, serde::Deserialize)]
pub(crate) struct FigureJson {
    pub name: String,
    pub svg: String,
}

/// The JSON texts of a result's summary, columns, tables and figures, as both backends store
/// them (all empty for an end without a result).
#[derive(Default, Clone)]
pub(crate) struct ResultTexts {
    pub summary: String,
    pub columns: String,
    pub tables: String,
    pub figures: String,
}

impl ResultTexts {
    pub(crate) fn of(r: &StoredResult) -> ResultTexts {
        let tables: Vec<TableJson> = r
            .tables
            .iter()
            .map(|t| TableJson {
                name: t.name.clone(),
                columns: t.columns.clone(),
                rows: t.rows.clone(),
            })
            .collect();
        let figures: Vec<FigureJson> = r
            .figures
            .iter()
            .map(|f| FigureJson {
                name: f.name.clone(),
                svg: f.svg.clone(),
            })
            .collect();
        ResultTexts {
            summary: serde_json::to_string(&r.summary).unwrap_or_else(|_| "{}".into()),
            columns: serde_json::to_string(&r.columns).unwrap_or_else(|_| "[]".into()),
            tables: serde_json::to_string(&tables).unwrap_or_else(|_| "[]".into()),
            figures: serde_json::to_string(&figures).unwrap_or_else(|_| "[]".into()),
        }
    }

    /// The result head (no series) these texts describe; `Corrupt` naming the text that does
    /// not decode.
    pub(crate) fn decode(&self, id: &str, partial: bool) -> Result<StoredResult, StoreError> {
        let corrupt = |what| StoreError::Corrupt {
            what,
            id: id.to_string(),
        };
        let summary: Map<String, Value> =
            serde_json::from_str(&self.summary).map_err(|_| corrupt("summary"))?;
        let columns: Vec<String> =
            serde_json::from_str(&self.columns).map_err(|_| corrupt("columns"))?;
        let tables: Vec<TableJson> =
            serde_json::from_str(&self.tables).map_err(|_| corrupt("tables"))?;
        let figures: Vec<FigureJson> =
            serde_json::from_str(&self.figures).map_err(|_| corrupt("figures"))?;
        Ok(StoredResult {
            partial,
            summary,
            columns,
            tables: tables
                .into_iter()
                .map(|t| Table {
                    name: t.name,
                    columns: t.columns,
                    rows: t.rows,
                })
                .collect(),
            figures: figures
                .into_iter()
                .map(|f| Figure {
                    name: f.name,
                    svg: f.svg,
                })
                .collect(),
            ..StoredResult::default()
        })
    }
}

/// A stored chunk's blobs decoded and checked against its index entry (`rows` rows of
/// `columns` value columns).
pub(crate) fn decode_chunk(
    id: &str,
    rows: usize,
    columns: usize,
    blobs: (&[u8], &[u8], &[u8], &[u8]),
) -> Result<SeriesChunk, StoreError> {
    let (steps, t, vals, batches) = blobs;
    let corrupt = |what| StoreError::Corrupt {
        what,
        id: id.to_string(),
    };
    let steps = decode_u64s(steps).ok_or_else(|| corrupt("steps"))?;
    let t = decode_f64s(t).ok_or_else(|| corrupt("t"))?;
    let values = decode_f64s(vals).ok_or_else(|| corrupt("values"))?;
    let batches = decode_u64s(batches)
        .filter(|b| b.len() % 3 == 0)
        .ok_or_else(|| corrupt("batches"))?
        .chunks_exact(3)
        .map(|b| (b[0], b[1], b[2]))
        .collect();
    if steps.len() != rows || t.len() != rows || values.len() != rows * columns {
        return Err(corrupt("series"));
    }
    Ok(SeriesChunk {
        steps,
        t,
        values,
        batches,
    })
}

/// A chunk index checked for gaps: each chunk starts where the one before ended.
pub(crate) fn check_index(id: &str, chunks: Vec<ChunkMeta>) -> Result<Vec<ChunkMeta>, StoreError> {
    let mut next = 0;
    for c in &chunks {
        if c.first_row != next {
            return Err(StoreError::Corrupt {
                what: "chunk index",
                id: id.into(),
            });
        }
        next += c.rows;
    }
    Ok(chunks)
}

/// The rows of `steps`/`t`/`values` (row-major, `n` columns) cut into chunks of
/// [`chunk_rows`] rows: (offset of the first row, rows).
pub(crate) fn split_series(
    n: usize,
    steps: &[u64],
    t: &[f64],
    values: &[f64],
) -> Vec<(u64, SeriesChunk)> {
    let per = chunk_rows(n);
    (0..steps.len())
        .step_by(per)
        .map(|start| {
            let end = (start + per).min(steps.len());
            (
                start as u64,
                SeriesChunk {
                    steps: steps[start..end].to_vec(),
                    t: t[start..end].to_vec(),
                    values: values[start * n..end * n].to_vec(),
                    batches: Vec::new(),
                },
            )
        })
        .collect()
}

/// The batches of a chunk as one flat list (seq, start, end, seq, …) for its blob.
pub(crate) fn batches_blob(rows: &SeriesChunk) -> Vec<u8> {
    let flat: Vec<u64> = rows
        .batches
        .iter()
        .flat_map(|&(seq, start, end)| [seq, start, end])
        .collect();
    u64s_to_blob(&flat)
}

/// What every store does (see the module documentation). Blocking calls: the engine calls them
/// from its worker threads, the servers from blocking contexts or for short reads.
pub trait Backend: StudyStore + Send + Sync + pause::PauseStore {
    /// Records a new queued job with its spec (JSON). False when the id is taken.
    fn insert(&self, row: &JobView, spec_json: &str) -> Result<bool, StoreError>;

    /// Marks a job running.
    fn set_running(&self, id: &str, started_ms: u64) -> Result<(), StoreError>;

    /// Forgets the recorded series of a job about to run again (after a restart, or claimed
    /// again after its replica died).
    fn clear_series(&self, id: &str) -> Result<(), StoreError>;

    /// Stores chunk number `chunk` of a running job's series, whose first row is row
    /// `first_row` of the series.
    fn append_chunk(
        &self,
        id: &str,
        chunk: u64,
        first_row: u64,
        rows: &SeriesChunk,
    ) -> Result<(), StoreError>;

    /// Ends a job: its final state, error, progress and (for a success, or the partial series
    /// of a failed or cancelled run) its result, in one transaction. The series chunks the run
    /// appended stay; rows in `result` itself, if any, are appended after them.
    fn finish(&self, row: &JobView, result: Option<&StoredResult>) -> Result<(), StoreError>;

    /// One job's status.
    fn get(&self, id: &str) -> Result<Option<JobView>, StoreError>;

    /// Where job `id` comes from, in one query: the study it is a run of and the job it extends
    /// (both `None` for an unknown id).
    fn lineage(&self, id: &str) -> Result<Lineage, StoreError>;

    /// One page of jobs, newest first: at most `limit`, only those in `state` if given, only
    /// those older than the job numbered `before` if given. Each comes with its number (the
    /// store's insertion order), which the next page takes as `before`.
    fn list_page(
        &self,
        state: Option<JobState>,
        before: Option<i64>,
        limit: usize,
    ) -> Result<Vec<(i64, JobView)>, StoreError>;

    /// The finished jobs (succeeded, failed, cancelled) that ended before `cutoff_ms`.
    fn finished_before(&self, cutoff_ms: u64) -> Result<Vec<String>, StoreError>;

    /// Removes a finished job, its result and its series. False when there was no such job.
    fn delete(&self, id: &str) -> Result<bool, StoreError>;

    /// At start-up: the jobs this process is to run again, oldest first, now marked queued,
    /// with their specs (JSON). A shared store returns none: its queue is claimed, not
    /// recovered.
    fn recover(&self) -> Result<Vec<(JobView, String)>, StoreError>;

    /// Number of jobs per state.
    fn counts(&self) -> Result<Vec<(JobState, u64)>, StoreError>;

    /// A job's result without its series (`steps`, `t`, `values` empty): summary, columns,
    /// tables, figures and whether it is partial. `None` when the job has no result.
    fn result_head(&self, id: &str) -> Result<Option<StoredResult>, StoreError>;

    /// The chunks of a job's series, in order (no values read).
    fn series_index(&self, id: &str) -> Result<Vec<ChunkMeta>, StoreError>;

    /// One chunk of a job's series with `columns` value columns, checked against its index.
    fn read_chunk(
        &self,
        id: &str,
        meta: &ChunkMeta,
        columns: usize,
    ) -> Result<SeriesChunk, StoreError>;

    /// Keeps the latest checkpoint of a running job (its bytes, made by
    /// `signorini_core::checkpoint::Checkpoint::encode`), written by its run number `attempt`
    /// after step `step`; replaces the one before.
    fn save_checkpoint(
        &self,
        id: &str,
        attempt: u64,
        step: u64,
        bytes: &[u8],
    ) -> Result<(), StoreError>;

    /// The latest checkpoint of a job: (attempt, step, bytes), if any.
    fn load_checkpoint(&self, id: &str) -> Result<Option<(u64, u64, Vec<u8>)>, StoreError>;

    /// Forgets a job's checkpoint (it ended, or its checkpoint cannot be used).
    fn delete_checkpoint(&self, id: &str) -> Result<(), StoreError>;

    /// Ends a job in one call: stores the rows its run recorded and had not stored yet, the
    /// checkpoint its run wrote after its last step (if it kept it back for this call), its end
    /// and result ([`Backend::finish`]); for a success keeps that checkpoint as the final state
    /// (`extend` continues from it), and forgets the job's running checkpoint. By default the
    /// separate calls, in this order (an error storing the rows or the end is returned; one
    /// keeping the checkpoint or the final state, or deleting the checkpoint, is logged, as it
    /// costs only a later `extend` or resume); PostgreSQL makes it one statement, one round
    /// trip, all or nothing.
    fn end(&self, end: &JobEnd<'_>) -> Result<(), StoreError> {
        end_by_calls(self, end)
    }

    /// Keeps the first `rows` rows of a job's stored series (a job resumed from a checkpoint
    /// that had recorded that many) and drops the chunks after them. A checkpoint is saved
    /// right after a chunk, so its row count is a chunk boundary; a chunk across it is refused.
    fn truncate_series(&self, id: &str, rows: u64) -> Result<(), StoreError>;

    /// Writes one chunk's worth ([`CHUNK_BYTES`]) of data in a committed transaction and
    /// removes it again: whether the store can take a running job's next chunk now (a
    /// degraded store, [`Health`], is healthy again when this succeeds).
    fn probe_write(&self) -> Result<(), StoreError>;

    /// A job's whole result, its series read chunk by chunk into memory: for tests and small
    /// results only (the servers stream series with [`Backend::series_index`] and
    /// [`Backend::read_chunk`]).
    fn result(&self, id: &str) -> Result<Option<StoredResult>, StoreError> {
        let Some(mut r) = self.result_head(id)? else {
            return Ok(None);
        };
        for meta in self.series_index(id)? {
            let c = self.read_chunk(id, &meta, r.columns.len())?;
            r.steps.extend(c.steps);
            r.t.extend(c.t);
            r.values.extend(c.values);
        }
        Ok(Some(r))
    }
}

/// The end of a job, stored by [`Backend::end`].
#[derive(Debug, Clone, Copy)]
pub struct JobEnd<'a> {
    /// Its final status (a terminal state).
    pub view: &'a JobView,
    /// Its result (a success's, or the partial series of a failed or cancelled run).
    pub result: Option<&'a StoredResult>,
    /// The rows the run recorded after its last stored chunk: (chunk number, index of its
    /// first row in the series, the rows).
    pub rows: Option<(u64, u64, &'a SeriesChunk)>,
    /// The checkpoint the run wrote after its last step and kept back for this call:
    /// (attempt, step, bytes), as [`Backend::save_checkpoint`] takes them.
    pub final_state: Option<(u64, u64, &'a [u8])>,
}

/// [`Backend::end`] as the separate calls it stands for.
pub(crate) fn end_by_calls<B: Backend + ?Sized>(
    store: &B,
    end: &JobEnd<'_>,
) -> Result<(), StoreError> {
    let id = &end.view.id;
    if let Some((chunk, first_row, rows)) = end.rows {
        store.append_chunk(id, chunk, first_row, rows)?;
    }
    // A checkpoint, a final state not kept, a checkpoint not deleted cost only a later
    // `extend` or resume: logged, the end stands.
    if let Some((attempt, step, bytes)) = end.final_state
        && let Err(e) = store.save_checkpoint(id, attempt, step, bytes)
    {
        tracing::warn!(%id, step, "checkpoint not saved: {e}");
    }
    store.finish(end.view, end.result)?;
    if end.view.state == JobState::Succeeded {
        match store.keep_final_state(id, end.view.done) {
            Ok(kept) => tracing::debug!(%id, kept, "final state"),
            Err(e) => tracing::error!(%id, "store: {e}"),
        }
    }
    if let Err(e) = store.delete_checkpoint(id) {
        tracing::error!(%id, "store: {e}");
    }
    Ok(())
}

/// A job a replica has claimed from the shared queue.
#[derive(Debug, Clone)]
pub struct Claim {
    /// Its status (state `running`, this replica's start time).
    pub view: JobView,
    /// Its spec (JSON).
    pub spec_json: String,
    /// Which run of the job this is (1 for the first claim, one more each time it is claimed
    /// again after a replica lost it).
    pub attempt: u64,
    /// A client asked to cancel it (while the replica that held it before was dying).
    pub cancel_requested: bool,
    /// It is a study's child (its end updates the parent's progress).
    pub study_child: bool,
    /// Its latest checkpoint, read by the claim: (attempt, step, bytes), as
    /// [`Backend::load_checkpoint`] answers. When there is none, the claim has also dropped the
    /// rows earlier attempts stored ([`Backend::clear_series`]).
    pub checkpoint: Option<(u64, u64, Vec<u8>)>,
    /// The job it continues, when it is an extension (as [`pause::PauseStore::extends`]
    /// answers).
    pub extends: Option<String>,
}

/// The progress of a job a replica runs, sent with each heartbeat.
#[derive(Debug, Clone)]
pub struct Beat {
    /// The job.
    pub id: String,
    /// Steps done and in all.
    pub done: u64,
    /// Steps in all.
    pub total: u64,
    /// Simulated time reached.
    pub t: f64,
}

/// What a heartbeat learned of one of the jobs this replica runs.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum BeatReply {
    /// The lease was renewed.
    Held,
    /// The lease was renewed and a client asked (on any replica) to cancel the job.
    CancelRequested,
    /// The lease was renewed and a client asked (on any replica) to pause the job.
    PauseRequested,
    /// The job is no longer this replica's (its lease ran out and another replica claimed it):
    /// stop running it.
    Lost,
}

/// What [`SharedQueue::enqueue`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Enqueued {
    /// The job is queued.
    Queued,
    /// The queue holds its limit of jobs already: nothing was stored.
    Full,
    /// A job has this id already: nothing was stored.
    Taken,
}

/// How a cancel request for a job run by the shared queue ended.
#[derive(Debug, Clone, PartialEq)]
pub enum CancelOutcome {
    /// It was still queued: now cancelled, this status.
    Cancelled(JobView),
    /// It runs (on some replica), which stops it at its next heartbeat.
    Requested,
    /// It had already finished, or does not exist.
    NotLive,
}

/// The job queue a PostgreSQL store shares between replicas: a worker claims the oldest queued
/// job, or one whose lease ran out, with `SELECT … FOR UPDATE SKIP LOCKED`; the replica renews
/// its leases with a heartbeat; whatever it stores after losing a lease is refused.
pub trait SharedQueue: Send + Sync {
    /// This replica's name, the owner of its claims.
    fn replica(&self) -> &str;

    /// The lease a claim holds without a heartbeat.
    fn lease(&self) -> Duration;

    /// Claims the next job (started now, at `started_ms`), if any.
    fn claim(&self, started_ms: u64) -> Result<Option<Claim>, StoreError>;

    /// Queues a new job (its status and spec, as [`Backend::insert`] takes them), announced to
    /// every replica, unless `limit` jobs are queued already: one round trip.
    fn enqueue(&self, row: &JobView, spec_json: &str, limit: usize)
    -> Result<Enqueued, StoreError>;

    /// Ends a job ([`Backend::end`]) and claims the next one ([`SharedQueue::claim`]), in one
    /// round trip where the store can: the end's outcome and the claim's. The end is stored
    /// first; a lost lease on the ended job does not stop the claim.
    fn end_and_claim(
        &self,
        end: &JobEnd<'_>,
        started_ms: u64,
    ) -> (Result<(), StoreError>, Result<Option<Claim>, StoreError>);

    /// Renews the leases of the jobs this replica runs, recording their progress.
    fn heartbeat(&self, beats: &[Beat]) -> Result<Vec<(String, BeatReply)>, StoreError>;

    /// Gives a job this replica holds back to the queue (this replica is shutting down).
    fn release(&self, id: &str) -> Result<(), StoreError>;

    /// Cancels a queued job, or asks the replica running it to stop it.
    fn request_cancel(&self, id: &str, finished_ms: u64) -> Result<CancelOutcome, StoreError>;

    /// Jobs waiting for any replica.
    fn queued(&self) -> Result<u64, StoreError>;

    /// A number that changes whenever a job is queued anywhere (a notification arrived).
    fn ticket(&self) -> u64;

    /// Waits until the ticket differs from `seen` or `timeout` passes.
    fn wait(&self, seen: u64, timeout: Duration);

    /// Wakes every waiter (shutdown).
    fn wake(&self);
}

/// The store a server runs on: one of the backends, and the queue it shares between replicas
/// when it holds one (PostgreSQL).
pub struct Store {
    backend: Arc<dyn Backend>,
    queue: Option<Arc<dyn SharedQueue>>,
    health: Health,
}

impl std::ops::Deref for Store {
    type Target = dyn Backend;

    fn deref(&self) -> &(dyn Backend + 'static) {
        self.backend.as_ref()
    }
}

/// Where a store lives, from `--store`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Location<'a> {
    /// A SQLite file (or `:memory:`).
    Sqlite(&'a Path),
    /// A PostgreSQL connection URL (`postgres://` or `postgresql://`).
    Postgres(&'a str),
}

impl<'a> Location<'a> {
    /// What `--store` names: a `postgres://`/`postgresql://` URL, else a SQLite file.
    pub fn of(store: &'a Path) -> Location<'a> {
        match store.to_str() {
            Some(s) if s.starts_with("postgres://") || s.starts_with("postgresql://") => {
                Location::Postgres(s)
            }
            _ => Location::Sqlite(store),
        }
    }

    /// The store as it may be logged: a URL loses its user, password and query.
    pub fn shown(&self) -> String {
        match self {
            Location::Sqlite(p) => p.display().to_string(),
            Location::Postgres(url) => {
                let (scheme, rest) = url.split_once("://").unwrap_or(("postgres", url));
                let host = rest.rsplit_once('@').map_or(rest, |(_, h)| h);
                let host = host.split_once('?').map_or(host, |(h, _)| h);
                format!("{scheme}://{host}")
            }
        }
    }
}

impl Store {
    /// Opens (or creates) the SQLite store at `path` in WAL mode. `:memory:` gives a throwaway
    /// store.
    pub fn open(path: &Path) -> Result<Store, StoreError> {
        Store::open_limited(path, None)
    }

    /// [`Store::open`] with the store's size limited to `max_bytes` (SQLite's
    /// `max_page_count`): a write past it is refused as on a full disk.
    pub fn open_limited(path: &Path, max_bytes: Option<u64>) -> Result<Store, StoreError> {
        let backend = sqlite::SqliteStore::open(path)?;
        if let Some(max) = max_bytes {
            backend.limit_size(max)?;
        }
        Ok(Store {
            backend: Arc::new(backend),
            queue: None,
            health: Health::default(),
        })
    }

    /// Connects to the PostgreSQL store at `url` (applying its migrations) as replica
    /// `replica`, with a pool of `connections` connections and leases of `lease`.
    pub fn connect(
        url: &str,
        replica: &str,
        connections: usize,
        lease: Duration,
    ) -> Result<Store, StoreError> {
        let store = Arc::new(postgres::PgStore::connect(
            url,
            replica,
            connections,
            lease,
        )?);
        Ok(Store {
            backend: store.clone(),
            queue: Some(store),
            health: Health::default(),
        })
    }

    /// Whether the store takes writes ([`Health`]).
    pub fn health(&self) -> &Health {
        &self.health
    }

    /// Probes a degraded store ([`Backend::probe_write`]) and records the outcome: `None` when
    /// it takes writes again, else why not.
    pub fn probe(&self) -> Option<String> {
        self.health.probed(self.backend.probe_write())
    }

    /// The queue this store shares between replicas, if it holds one (PostgreSQL).
    pub fn shared_queue(&self) -> Option<Arc<dyn SharedQueue>> {
        self.queue.clone()
    }
}
