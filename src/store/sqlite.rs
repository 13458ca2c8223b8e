//! The SQLite backend: one embedded SQLite file (WAL) with every job's spec, status, summary and
//! recorded series.
//!
//! A job's row is written when it is accepted, updated when it starts, and completed in one
//! transaction with its result, so a crash (SIGKILL) leaves every finished result whole and every
//! unfinished job marked `queued` or `running`; [`Store::recover`] turns the latter back into
//! `queued` at start-up. Figures (SVG text) are kept as a JSON list in `figures_json`; a
//! database made before that column existed gets it (empty lists) when it is opened.
//!
//! The recorded series of a job is a sequence of chunks (table `result_chunks`, one row per
//! chunk of about [`CHUNK_BYTES`], little-endian `u64`/`f64` blobs: what is read back is what was
//! computed, bit for bit). The engine appends chunks while the job runs, so neither the run nor a
//! reader ever holds a whole series: a reader takes the chunk index ([`Store::series_index`]) and
//! reads one chunk at a time ([`Store::read_chunk`]). A failed or cancelled run keeps the chunks
//! it wrote, marked `partial`. A database of the earlier layout (one blob per job in `results`)
//! is rewritten into chunks, one job per transaction, when it is opened.

use super::{
    Backend, ChunkMeta, ResultTexts, SeriesChunk, StoreError, StoredResult, batches_blob,
    check_index, decode_chunk, decode_f64s, decode_u64s, f64s_to_blob, split_series, u64s_to_blob,
};
use crate::lifecycle::{ENDED, Transition, in_sql, per_state};
use crate::status::{JobState, JobView, Lineage};
use rusqlite::{Connection, OptionalExtension, params};
use std::path::Path;
use std::sync::Mutex;

mod pause;
mod study;

/// The SQLite store (one connection behind a mutex: calls are short).
pub struct SqliteStore {
    conn: Mutex<Connection>,
}

const SCHEMA: &str = "
CREATE TABLE IF NOT EXISTS jobs (
    seq INTEGER PRIMARY KEY AUTOINCREMENT,
    id TEXT NOT NULL UNIQUE,
    name TEXT,
    spec_json TEXT NOT NULL,
    state TEXT NOT NULL,
    created_ms INTEGER NOT NULL,
    started_ms INTEGER NOT NULL DEFAULT 0,
    finished_ms INTEGER NOT NULL DEFAULT 0,
    error_field TEXT,
    error_reason TEXT,
    done INTEGER NOT NULL DEFAULT 0,
    total INTEGER NOT NULL DEFAULT 0,
    t REAL NOT NULL DEFAULT 0
);
CREATE TABLE IF NOT EXISTS results (
    id TEXT PRIMARY KEY REFERENCES jobs(id),
    summary_json TEXT NOT NULL,
    columns_json TEXT NOT NULL,
    steps BLOB NOT NULL,
    t BLOB NOT NULL,
    vals BLOB NOT NULL,
    tables_json TEXT NOT NULL,
    figures_json TEXT NOT NULL DEFAULT '[]',
    partial INTEGER NOT NULL DEFAULT 0
);
CREATE TABLE IF NOT EXISTS result_chunks (
    id TEXT NOT NULL,
    chunk INTEGER NOT NULL,
    first_row INTEGER NOT NULL,
    rows INTEGER NOT NULL,
    step_first INTEGER NOT NULL,
    step_last INTEGER NOT NULL,
    steps BLOB NOT NULL,
    t BLOB NOT NULL,
    vals BLOB NOT NULL,
    batches BLOB NOT NULL DEFAULT x'',
    PRIMARY KEY (id, chunk)
);
CREATE TABLE IF NOT EXISTS checkpoints (
    id TEXT PRIMARY KEY,
    attempt INTEGER NOT NULL,
    step INTEGER NOT NULL,
    bytes BLOB NOT NULL
);
CREATE TABLE IF NOT EXISTS write_probe (
    id INTEGER PRIMARY KEY,
    bytes BLOB NOT NULL
);
";

/// Brings a database made by an older schema up to [`SCHEMA`]: `results.figures_json` and
/// `results.partial` came later, and series stored as one blob per job (in `results.steps`,
/// `t`, `vals`) move to `result_chunks`, one job per transaction (the old blob is emptied in the
/// same transaction, so an interrupted migration resumes at the next open).
fn migrate(conn: &mut Connection) -> Result<(), StoreError> {
    let have: Vec<String> = conn
        .prepare("SELECT name FROM pragma_table_info('results')")?
        .query_map([], |r| r.get::<_, String>(0))?
        .collect::<Result<Vec<_>, _>>()?;
    if !have.iter().any(|c| c == "figures_json") {
        conn.execute_batch(
            "ALTER TABLE results ADD COLUMN figures_json TEXT NOT NULL DEFAULT '[]'",
        )?;
    }
    if !have.iter().any(|c| c == "partial") {
        conn.execute_batch("ALTER TABLE results ADD COLUMN partial INTEGER NOT NULL DEFAULT 0")?;
    }
    let chunk_columns: Vec<String> = conn
        .prepare("SELECT name FROM pragma_table_info('result_chunks')")?
        .query_map([], |r| r.get::<_, String>(0))?
        .collect::<Result<Vec<_>, _>>()?;
    study::migrate(conn)?;
    if !chunk_columns.iter().any(|c| c == "batches") {
        conn.execute_batch(
            "ALTER TABLE result_chunks ADD COLUMN batches BLOB NOT NULL DEFAULT x''",
        )?;
    }
    let old: Vec<String> = conn
        .prepare("SELECT id FROM results WHERE length(steps) > 0 OR length(vals) > 0")?
        .query_map([], |r| r.get::<_, String>(0))?
        .collect::<Result<Vec<_>, _>>()?;
    for id in old {
        let tx = conn.transaction()?;
        let (columns, steps, t, vals) = tx.query_row(
            "SELECT columns_json, steps, t, vals FROM results WHERE id = ?1",
            [&id],
            |r| {
                Ok((
                    r.get::<_, String>(0)?,
                    r.get::<_, Vec<u8>>(1)?,
                    r.get::<_, Vec<u8>>(2)?,
                    r.get::<_, Vec<u8>>(3)?,
                ))
            },
        )?;
        let corrupt = |what| StoreError::Corrupt {
            what,
            id: id.clone(),
        };
        let columns: Vec<String> =
            serde_json::from_str(&columns).map_err(|_| corrupt("columns"))?;
        let steps = decode_u64s(&steps).ok_or_else(|| corrupt("steps"))?;
        let t = decode_f64s(&t).ok_or_else(|| corrupt("t"))?;
        let values = decode_f64s(&vals).ok_or_else(|| corrupt("values"))?;
        if t.len() != steps.len() || values.len() != steps.len() * columns.len() {
            return Err(corrupt("series"));
        }
        tx.execute("DELETE FROM result_chunks WHERE id = ?1", [&id])?;
        append_series(&tx, &id, 0, 0, columns.len(), &steps, &t, &values)?;
        tx.execute(
            "UPDATE results SET steps = x'', t = x'', vals = x'' WHERE id = ?1",
            [&id],
        )?;
        tx.commit()?;
        tracing::info!(%id, rows = steps.len(), "store: series moved to chunks");
    }
    Ok(())
}

/// Writes `steps`/`t`/`values` (row-major, `n` columns) as chunks of [`super::chunk_rows`]
/// rows, numbered from `chunk`, the first row being row `first_row` of the series.
#[allow(clippy::too_many_arguments)]
fn append_series(
    conn: &Connection,
    id: &str,
    chunk: u64,
    first_row: u64,
    n: usize,
    steps: &[u64],
    t: &[f64],
    values: &[f64],
) -> Result<(), StoreError> {
    for (k, (start, rows)) in split_series(n, steps, t, values).into_iter().enumerate() {
        insert_chunk(conn, id, chunk + k as u64, first_row + start, &rows)?;
    }
    Ok(())
}

fn insert_chunk(
    conn: &Connection,
    id: &str,
    chunk: u64,
    first_row: u64,
    rows: &SeriesChunk,
) -> Result<(), StoreError> {
    let (Some(&first), Some(&last)) = (rows.steps.first(), rows.steps.last()) else {
        return Ok(());
    };
    conn.execute(
        "INSERT OR REPLACE INTO result_chunks (id, chunk, first_row, rows, step_first, step_last, steps, t, vals, batches)
         VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10)",
        params![
            id,
            chunk as i64,
            first_row as i64,
            rows.steps.len() as i64,
            first as i64,
            last as i64,
            u64s_to_blob(&rows.steps),
            f64s_to_blob(&rows.t),
            f64s_to_blob(&rows.values),
            batches_blob(rows),
        ],
    )?;
    Ok(())
}

const JOB_COLUMNS: &str = "id, name, spec_json, state, created_ms, started_ms, finished_ms, error_field, error_reason, done, total, t";

/// [`JOB_COLUMNS`] without the spec (an empty string in its place): a list never reads specs,
/// which may be megabytes each.
const LIST_COLUMNS: &str = "id, name, '', state, created_ms, started_ms, finished_ms, error_field, error_reason, done, total, t";

/// A job's status and its spec (JSON) from a `SELECT {JOB_COLUMNS}` row.
fn row_to_job(r: &rusqlite::Row<'_>) -> rusqlite::Result<((JobView, String), String)> {
    let state: String = r.get(3)?;
    let field: Option<String> = r.get(7)?;
    let reason: Option<String> = r.get(8)?;
    Ok((
        (
            JobView {
                id: r.get(0)?,
                name: r.get(1)?,
                state: JobState::Queued,
                created_ms: r.get::<_, i64>(4)? as u64,
                started_ms: r.get::<_, i64>(5)? as u64,
                finished_ms: r.get::<_, i64>(6)? as u64,
                error: match (field, reason) {
                    (Some(f), Some(r)) => Some((f, r)),
                    _ => None,
                },
                done: r.get::<_, i64>(9)? as u64,
                total: r.get::<_, i64>(10)? as u64,
                t: r.get(11)?,
            },
            r.get(2)?,
        ),
        state,
    ))
}

fn finish_row(
    ((mut view, spec_json), state): ((JobView, String), String),
) -> Result<(JobView, String), StoreError> {
    view.state = JobState::parse(&state).ok_or_else(|| StoreError::Corrupt {
        what: "state",
        id: view.id.clone(),
    })?;
    Ok((view, spec_json))
}

/// The OS lock a server holds on its store file for as long as it runs (an exclusive
/// `flock`, released by the OS when the process ends, even by SIGKILL), so two servers never
/// run the same store's jobs. SQLite's own locks are per transaction and do not prevent that.
#[derive(Debug)]
pub struct StoreLock {
    _file: std::fs::File,
}

impl StoreLock {
    /// Takes the lock of the store at `path` (creating the file if it does not exist); an error
    /// naming the file when another process holds it. `:memory:` needs no lock (`None`).
    pub fn take(path: &Path) -> Result<Option<StoreLock>, StoreError> {
        if path.as_os_str() == ":memory:" {
            return Ok(None);
        }
        let shown = path.display().to_string();
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(path)
            .map_err(|e| StoreError::Lock {
                path: shown.clone(),
                reason: e.to_string(),
            })?;
        match file.try_lock() {
            Ok(()) => Ok(Some(StoreLock { _file: file })),
            Err(std::fs::TryLockError::WouldBlock) => Err(StoreError::Locked { path: shown }),
            Err(std::fs::TryLockError::Error(e)) => Err(StoreError::Lock {
                path: shown,
                reason: e.to_string(),
            }),
        }
    }
}

impl SqliteStore {
    /// Opens (or creates) the store at `path` in WAL mode. `:memory:` gives a throwaway store.
    pub fn open(path: &Path) -> Result<SqliteStore, StoreError> {
        let mut conn = Connection::open(path)?;
        // WAL + synchronous=NORMAL: a committed transaction survives a process crash.
        conn.pragma_update(None, "journal_mode", "WAL")?;
        conn.pragma_update(None, "synchronous", "NORMAL")?;
        conn.busy_timeout(std::time::Duration::from_secs(5))?;
        conn.execute_batch(SCHEMA)?;
        migrate(&mut conn)?;
        pause::create_tables(&conn)?;
        Ok(SqliteStore {
            conn: Mutex::new(conn),
        })
    }

    /// Limits the database to `max_bytes` (whole pages, at least one): SQLite then refuses a
    /// write past it with `SQLITE_FULL`, as on a full disk.
    pub fn limit_size(&self, max_bytes: u64) -> Result<(), StoreError> {
        let conn = self.conn();
        let page: i64 = conn.query_row("PRAGMA page_size", [], |r| r.get(0))?;
        let pages = (max_bytes / page.max(1) as u64).max(1);
        conn.pragma_update(None, "max_page_count", pages as i64)?;
        Ok(())
    }

    fn conn(&self) -> std::sync::MutexGuard<'_, Connection> {
        // A panic while holding the lock leaves SQLite consistent (transactions roll back).
        self.conn.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Every job's status and spec (JSON), oldest first.
    fn list_with_specs(&self) -> Result<Vec<(JobView, String)>, StoreError> {
        let conn = self.conn();
        let mut stmt = conn.prepare(&format!("SELECT {JOB_COLUMNS} FROM jobs ORDER BY seq"))?;
        let rows = stmt
            .query_map([], row_to_job)?
            .collect::<Result<Vec<_>, _>>()?;
        rows.into_iter().map(finish_row).collect()
    }
}

impl Backend for SqliteStore {
    /// Records a new queued job with its spec (JSON). False when the id is taken.
    fn insert(&self, row: &JobView, spec_json: &str) -> Result<bool, StoreError> {
        let n = self.conn().execute(
            "INSERT OR IGNORE INTO jobs (id, name, spec_json, state, created_ms, total) VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
            params![row.id, row.name, spec_json, row.state.as_str(), row.created_ms as i64, row.total as i64],
        )?;
        Ok(n == 1)
    }

    /// Marks a job running.
    fn set_running(&self, id: &str, started_ms: u64) -> Result<(), StoreError> {
        self.conn().execute(
            &Transition::Claim.update_sql("started_ms = ?2", "id = ?1"),
            params![id, started_ms as i64],
        )?;
        Ok(())
    }

    /// Forgets the recorded series of a job (a job about to run again after a restart).
    fn clear_series(&self, id: &str) -> Result<(), StoreError> {
        self.conn()
            .execute("DELETE FROM result_chunks WHERE id = ?1", [id])?;
        Ok(())
    }

    /// Stores chunk number `chunk` of a running job's series, whose first row is row
    /// `first_row` of the series.
    fn append_chunk(
        &self,
        id: &str,
        chunk: u64,
        first_row: u64,
        rows: &SeriesChunk,
    ) -> Result<(), StoreError> {
        insert_chunk(&self.conn(), id, chunk, first_row, rows)
    }

    /// Ends a job: its final state, error, progress and (for a success, or the partial series
    /// of a failed or cancelled run) its result, in one transaction. The series chunks the run
    /// appended stay; rows in `result` itself, if any, are appended after them.
    fn finish(&self, row: &JobView, result: Option<&StoredResult>) -> Result<(), StoreError> {
        let mut conn = self.conn();
        let tx = conn.transaction()?;
        if let Some(r) = result {
            let texts = ResultTexts::of(r);
            tx.execute(
                "INSERT OR REPLACE INTO results (id, summary_json, columns_json, steps, t, vals, tables_json, figures_json, partial)
                 VALUES (?1, ?2, ?3, x'', x'', x'', ?4, ?5, ?6)",
                params![
                    row.id,
                    texts.summary,
                    texts.columns,
                    texts.tables,
                    texts.figures,
                    r.partial,
                ],
            )?;
            if !r.steps.is_empty() {
                let (chunk, first_row) = tx.query_row(
                    "SELECT COUNT(*), COALESCE(SUM(rows), 0) FROM result_chunks WHERE id = ?1",
                    [&row.id],
                    |q| Ok((q.get::<_, i64>(0)? as u64, q.get::<_, i64>(1)? as u64)),
                )?;
                append_series(
                    &tx,
                    &row.id,
                    chunk,
                    first_row,
                    r.columns.len(),
                    &r.steps,
                    &r.t,
                    &r.values,
                )?;
            }
        }
        let (field, reason) = row.error_parts();
        tx.execute(
            "UPDATE jobs SET state = ?2, finished_ms = ?3, error_field = ?4, error_reason = ?5, done = ?6, total = ?7, t = ?8
             WHERE id = ?1",
            params![
                row.id,
                row.state.as_str(),
                row.finished_ms as i64,
                field,
                reason,
                row.done as i64,
                row.total as i64,
                row.t
            ],
        )?;
        tx.commit()?;
        Ok(())
    }

    /// One job's status.
    fn get(&self, id: &str) -> Result<Option<JobView>, StoreError> {
        let conn = self.conn();
        let row = conn
            .query_row(
                &format!("SELECT {JOB_COLUMNS} FROM jobs WHERE id = ?1"),
                [id],
                row_to_job,
            )
            .optional()?;
        Ok(row.map(finish_row).transpose()?.map(|(view, _)| view))
    }

    fn lineage(&self, id: &str) -> Result<Lineage, StoreError> {
        let row = self
            .conn()
            .query_row(
                "SELECT j.parent, e.extends FROM jobs j LEFT JOIN extensions e ON e.id = j.id
                 WHERE j.id = ?1",
                [id],
                |r| {
                    Ok(Lineage {
                        parent: r.get(0)?,
                        extends: r.get(1)?,
                    })
                },
            )
            .optional()?;
        Ok(row.unwrap_or_default())
    }

    /// One page of jobs, newest first: at most `limit`, only those in `state` if given, only
    /// those older than the job numbered `before` if given. Each comes with its number (the
    /// store's insertion order), which the next page takes as `before`.
    fn list_page(
        &self,
        state: Option<JobState>,
        before: Option<i64>,
        limit: usize,
    ) -> Result<Vec<(i64, JobView)>, StoreError> {
        let conn = self.conn();
        let mut stmt = conn.prepare(&format!(
            "SELECT {LIST_COLUMNS}, seq FROM jobs WHERE (?1 IS NULL OR state = ?1) AND (?2 IS NULL OR seq < ?2)
             ORDER BY seq DESC LIMIT ?3"
        ))?;
        let rows = stmt
            .query_map(
                params![state.map(JobState::as_str), before, limit as i64],
                |r| Ok((r.get::<_, i64>(12)?, row_to_job(r)?)),
            )?
            .collect::<Result<Vec<_>, _>>()?;
        rows.into_iter()
            .map(|(seq, row)| Ok((seq, finish_row(row)?.0)))
            .collect()
    }

    /// The finished jobs (succeeded, failed, cancelled) that ended before `cutoff_ms`.
    fn finished_before(&self, cutoff_ms: u64) -> Result<Vec<String>, StoreError> {
        let conn = self.conn();
        let mut stmt = conn.prepare(&format!(
            "SELECT id FROM jobs WHERE state IN {} AND finished_ms < ?1",
            in_sql(&ENDED)
        ))?;
        let ids = stmt
            .query_map([cutoff_ms as i64], |r| r.get::<_, String>(0))?
            .collect::<Result<Vec<_>, _>>()?;
        Ok(ids)
    }

    /// Keeps the latest checkpoint of a running job (its bytes, made by
    /// `signorini_core::checkpoint::Checkpoint::encode`), written by its run number `attempt`
    /// after step `step`; replaces the one before.
    fn save_checkpoint(
        &self,
        id: &str,
        attempt: u64,
        step: u64,
        bytes: &[u8],
    ) -> Result<(), StoreError> {
        self.conn().execute(
            "INSERT OR REPLACE INTO checkpoints (id, attempt, step, bytes) VALUES (?1, ?2, ?3, ?4)",
            params![id, attempt as i64, step as i64, bytes],
        )?;
        Ok(())
    }

    /// The latest checkpoint of a job: (attempt, step, bytes), if any.
    fn load_checkpoint(&self, id: &str) -> Result<Option<(u64, u64, Vec<u8>)>, StoreError> {
        let row = self
            .conn()
            .query_row(
                "SELECT attempt, step, bytes FROM checkpoints WHERE id = ?1",
                [id],
                |r| {
                    Ok((
                        r.get::<_, i64>(0)? as u64,
                        r.get::<_, i64>(1)? as u64,
                        r.get::<_, Vec<u8>>(2)?,
                    ))
                },
            )
            .optional()?;
        Ok(row)
    }

    /// Forgets a job's checkpoint (the job ended, or its checkpoint cannot be used).
    fn delete_checkpoint(&self, id: &str) -> Result<(), StoreError> {
        self.conn()
            .execute("DELETE FROM checkpoints WHERE id = ?1", [id])?;
        Ok(())
    }

    /// Keeps the first `rows` rows of a job's stored series (a job resumed from a checkpoint
    /// that had recorded that many) and drops the chunks after them. A checkpoint is saved
    /// right after a chunk, so its row count is a chunk boundary; a chunk across it is refused.
    fn truncate_series(&self, id: &str, rows: u64) -> Result<(), StoreError> {
        let mut conn = self.conn();
        let tx = conn.transaction()?;
        let across: i64 = tx.query_row(
            "SELECT COUNT(*) FROM result_chunks WHERE id = ?1 AND first_row < ?2 AND first_row + rows > ?2",
            params![id, rows as i64],
            |r| r.get(0),
        )?;
        if across > 0 {
            return Err(StoreError::Corrupt {
                what: "series (a chunk across the checkpoint)",
                id: id.to_string(),
            });
        }
        tx.execute(
            "DELETE FROM result_chunks WHERE id = ?1 AND first_row >= ?2",
            params![id, rows as i64],
        )?;
        tx.commit()?;
        Ok(())
    }

    /// One chunk of zeros (SQLite stores a `zeroblob` in full) committed, removed, and
    /// checkpointed into the database file with the WAL truncated.
    fn probe_write(&self) -> Result<(), StoreError> {
        let conn = self.conn();
        conn.execute(
            "INSERT OR REPLACE INTO write_probe (id, bytes) VALUES (1, zeroblob(?1))",
            [super::CHUNK_BYTES as i64],
        )?;
        conn.execute("DELETE FROM write_probe", [])?;
        // Through to the database file and the WAL emptied: the room found is the file
        // system's (or the page limit's), not space the WAL held from earlier writes.
        conn.query_row("PRAGMA wal_checkpoint(TRUNCATE)", [], |_| Ok(()))?;
        Ok(())
    }

    /// Removes a job, its result and its series. False when there was no such job.
    fn delete(&self, id: &str) -> Result<bool, StoreError> {
        let mut conn = self.conn();
        let tx = conn.transaction()?;
        tx.execute("DELETE FROM checkpoints WHERE id = ?1", [id])?;
        tx.execute("DELETE FROM result_chunks WHERE id = ?1", [id])?;
        tx.execute("DELETE FROM results WHERE id = ?1", [id])?;
        pause::delete_job(&tx, id)?;
        let n = tx.execute("DELETE FROM jobs WHERE id = ?1", [id])?;
        tx.commit()?;
        Ok(n == 1)
    }

    /// At start-up: every job that was queued or running when the last process stopped, oldest
    /// first, now marked queued again, with its spec (JSON).
    fn recover(&self) -> Result<Vec<(JobView, String)>, StoreError> {
        self.conn().execute(
            // A study's parent stays `running`: its children are re-queued, and the engine
            // completes it once they have all ended.
            &Transition::Release.update_sql("started_ms = 0", "children = 0"),
            [],
        )?;
        Ok(self
            .list_with_specs()?
            .into_iter()
            .filter(|(r, _)| r.state == JobState::Queued)
            .collect())
    }

    /// Number of jobs per state.
    fn counts(&self) -> Result<Vec<(JobState, u64)>, StoreError> {
        let conn = self.conn();
        let mut stmt = conn.prepare("SELECT state, COUNT(*) FROM jobs GROUP BY state")?;
        let rows = stmt
            .query_map([], |r| {
                Ok((r.get::<_, String>(0)?, r.get::<_, i64>(1)? as u64))
            })?
            .collect::<Result<Vec<_>, _>>()?;
        Ok(per_state(&rows))
    }

    /// A job's result without its series (`steps`, `t`, `values` empty): summary, columns,
    /// tables, figures and whether it is partial. `None` when the job has no result.
    fn result_head(&self, id: &str) -> Result<Option<StoredResult>, StoreError> {
        let conn = self.conn();
        let raw = conn
            .query_row(
                "SELECT summary_json, columns_json, tables_json, figures_json, partial FROM results WHERE id = ?1",
                [id],
                |r| {
                    Ok((
                        r.get::<_, String>(0)?,
                        r.get::<_, String>(1)?,
                        r.get::<_, String>(2)?,
                        r.get::<_, String>(3)?,
                        r.get::<_, bool>(4)?,
                    ))
                },
            )
            .optional()?;
        let Some((summary, columns, tables, figures, partial)) = raw else {
            return Ok(None);
        };
        let texts = ResultTexts {
            summary,
            columns,
            tables,
            figures,
        };
        Ok(Some(texts.decode(id, partial)?))
    }

    /// The chunks of a job's series, in order (no values read).
    fn series_index(&self, id: &str) -> Result<Vec<ChunkMeta>, StoreError> {
        let conn = self.conn();
        let mut stmt = conn.prepare(
            "SELECT chunk, first_row, rows, step_first, step_last FROM result_chunks WHERE id = ?1 ORDER BY chunk",
        )?;
        let rows = stmt
            .query_map([id], |r| {
                Ok(ChunkMeta {
                    chunk: r.get::<_, i64>(0)? as u64,
                    first_row: r.get::<_, i64>(1)? as u64,
                    rows: r.get::<_, i64>(2)? as u64,
                    step_first: r.get::<_, i64>(3)? as u64,
                    step_last: r.get::<_, i64>(4)? as u64,
                })
            })?
            .collect::<Result<Vec<_>, _>>()?;
        check_index(id, rows)
    }

    /// One chunk of a job's series with `columns` value columns, checked against its index.
    fn read_chunk(
        &self,
        id: &str,
        meta: &ChunkMeta,
        columns: usize,
    ) -> Result<SeriesChunk, StoreError> {
        let (steps, t, vals, batches) = self.conn().query_row(
            "SELECT steps, t, vals, batches FROM result_chunks WHERE id = ?1 AND chunk = ?2",
            params![id, meta.chunk as i64],
            |r| {
                Ok((
                    r.get::<_, Vec<u8>>(0)?,
                    r.get::<_, Vec<u8>>(1)?,
                    r.get::<_, Vec<u8>>(2)?,
                    r.get::<_, Vec<u8>>(3)?,
                ))
            },
        )?;
        decode_chunk(
            id,
            meta.rows as usize,
            columns,
            (&steps, &t, &vals, &batches),
        )
    }
}
#[cfg(test)]
mod tests {
    use super::*;
    use signorini_figures::Figure;

    fn row(id: &str) -> JobView {
        JobView {
            id: id.into(),
            name: None,
            state: JobState::Queued,
            created_ms: 1,
            started_ms: 0,
            finished_ms: 0,
            error: None,
            done: 0,
            total: 10,
            t: 0.0,
        }
    }

    #[test]
    fn result_round_trips_bit_for_bit_and_running_jobs_recover_as_queued() -> Result<(), StoreError>
    {
        let dir = tempfile::tempdir().map_err(|_| StoreError::Corrupt {
            what: "tmp",
            id: String::new(),
        })?;
        let path = dir.path().join("s.db");
        {
            let s = SqliteStore::open(&path)?;
            assert!(s.insert(&row("a"), "{}")?);
            assert!(!s.insert(&row("a"), "{}")?);
            assert!(s.insert(&row("b"), "{}")?);
            s.set_running("b", 5)?;
            let r = StoredResult {
                columns: vec!["x".into(), "y".into()],
                steps: vec![0, 1],
                t: vec![0.0, 0.1],
                values: vec![1.0 / 3.0, f64::MIN_POSITIVE, -0.0, 1e300],
                ..Default::default()
            };
            let mut done = row("a");
            done.state = JobState::Succeeded;
            s.finish(&done, Some(&r))?;
            let back = s.result("a")?.ok_or(StoreError::Corrupt {
                what: "missing",
                id: "a".into(),
            })?;
            assert_eq!(
                back.values.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                r.values.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
            );
            assert_eq!(back.column(1), vec![f64::MIN_POSITIVE, 1e300]);
        }
        let s = SqliteStore::open(&path)?;
        let again = s.recover()?;
        assert_eq!(
            again.iter().map(|(r, _)| r.id.as_str()).collect::<Vec<_>>(),
            vec!["b"]
        );
        assert_eq!(s.get("a")?.map(|r| r.state), Some(JobState::Succeeded));
        Ok(())
    }

    fn tmp() -> Result<tempfile::TempDir, StoreError> {
        tempfile::tempdir().map_err(|_| StoreError::Corrupt {
            what: "tmp",
            id: String::new(),
        })
    }

    fn missing(id: &str) -> StoreError {
        StoreError::Corrupt {
            what: "missing",
            id: id.into(),
        }
    }

    /// A second lock on the same store file is refused while the first is held, and granted
    /// once it is released.
    #[test]
    fn a_store_is_locked_by_one_holder_at_a_time() -> Result<(), StoreError> {
        let dir = tmp()?;
        let path = dir.path().join("s.db");
        let first = StoreLock::take(&path)?;
        assert!(first.is_some());
        match StoreLock::take(&path) {
            Err(StoreError::Locked { path: p }) => assert!(p.ends_with("s.db")),
            other => panic!("expected Locked, got {other:?}"),
        }
        drop(first);
        assert!(StoreLock::take(&path)?.is_some());
        assert!(StoreLock::take(Path::new(":memory:"))?.is_none());
        Ok(())
    }

    #[test]
    fn figures_round_trip_and_are_found_with_or_without_svg() -> Result<(), StoreError> {
        let dir = tmp()?;
        let s = SqliteStore::open(&dir.path().join("s.db"))?;
        assert!(s.insert(&row("f"), "{}")?);
        let figures = vec![
            Figure {
                name: "backbone".into(),
                svg: "<svg xmlns=\"http://www.w3.org/2000/svg\">ω ≤ \"1\"</svg>\n".into(),
            },
            Figure {
                name: "orbit_gap_0".into(),
                svg: "<svg/>".into(),
            },
        ];
        let mut done = row("f");
        done.state = JobState::Succeeded;
        s.finish(
            &done,
            Some(&StoredResult {
                figures: figures.clone(),
                ..Default::default()
            }),
        )?;
        let back = s.result("f")?.ok_or_else(|| missing("f"))?;
        assert_eq!(back.figures, figures);
        assert_eq!(back.figure("backbone"), Some(&figures[0]));
        assert_eq!(back.figure("orbit_gap_0.svg"), Some(&figures[1]));
        assert_eq!(back.figure("../backbone"), None);
        assert_eq!(back.figure("nope"), None);
        Ok(())
    }

    #[test]
    fn corrupt_figures_are_reported_as_corrupt() -> Result<(), StoreError> {
        let dir = tmp()?;
        let s = SqliteStore::open(&dir.path().join("s.db"))?;
        assert!(s.insert(&row("c"), "{}")?);
        let mut done = row("c");
        done.state = JobState::Succeeded;
        s.finish(&done, Some(&StoredResult::default()))?;
        s.conn().execute(
            "UPDATE results SET figures_json = '{not json' WHERE id = 'c'",
            [],
        )?;
        match s.result("c") {
            Err(StoreError::Corrupt { what, id }) => {
                assert_eq!((what, id.as_str()), ("figures", "c"));
            }
            other => panic!("expected a corrupt-figures error, got {other:?}"),
        }
        Ok(())
    }

    /// A database written before figures were stored (the exact `results` table of that schema)
    /// opens, keeps its result, reads back with no figures, and takes figures afterwards.
    #[test]
    fn a_database_of_the_schema_without_figures_is_migrated() -> Result<(), StoreError> {
        let dir = tmp()?;
        let path = dir.path().join("old.db");
        {
            let conn = Connection::open(&path)?;
            conn.execute_batch(
                "
CREATE TABLE IF NOT EXISTS jobs (
    seq INTEGER PRIMARY KEY AUTOINCREMENT,
    id TEXT NOT NULL UNIQUE,
    name TEXT,
    spec_json TEXT NOT NULL,
    state TEXT NOT NULL,
    created_ms INTEGER NOT NULL,
    started_ms INTEGER NOT NULL DEFAULT 0,
    finished_ms INTEGER NOT NULL DEFAULT 0,
    error_field TEXT,
    error_reason TEXT,
    done INTEGER NOT NULL DEFAULT 0,
    total INTEGER NOT NULL DEFAULT 0,
    t REAL NOT NULL DEFAULT 0
);
CREATE TABLE IF NOT EXISTS results (
    id TEXT PRIMARY KEY REFERENCES jobs(id),
    summary_json TEXT NOT NULL,
    columns_json TEXT NOT NULL,
    steps BLOB NOT NULL,
    t BLOB NOT NULL,
    vals BLOB NOT NULL,
    tables_json TEXT NOT NULL
);
INSERT INTO jobs (id, spec_json, state, created_ms, finished_ms, done, total, t)
    VALUES ('old', '{}', 'succeeded', 1, 2, 1, 1, 0.5);
",
            )?;
            conn.execute(
                "INSERT INTO results (id, summary_json, columns_json, steps, t, vals, tables_json)
                 VALUES ('old', '{\"steps\":1}', '[\"x\"]', ?1, ?2, ?3, '[{\"name\":\"backbone\",\"columns\":[\"m\"],\"rows\":[[1.0]]}]')",
                params![
                    u64s_to_blob(&[0, 1]),
                    f64s_to_blob(&[0.0, 0.5]),
                    f64s_to_blob(&[1.5, 2.5])
                ],
            )?;
        }
        for _ in 0..2 {
            // Twice: the second open finds the column already there.
            let s = SqliteStore::open(&path)?;
            let back = s.result("old")?.ok_or_else(|| missing("old"))?;
            assert_eq!(back.summary.get("steps"), Some(&serde_json::json!(1)));
            assert_eq!(back.steps, vec![0, 1]);
            assert_eq!(back.column(0), vec![1.5, 2.5]);
            assert_eq!(back.tables.len(), 1);
            assert!(back.figures.is_empty());
            assert_eq!(s.get("old")?.map(|r| r.state), Some(JobState::Succeeded));
        }
        let s = SqliteStore::open(&path)?;
        assert!(s.insert(&row("new"), "{}")?);
        let mut done = row("new");
        done.state = JobState::Succeeded;
        let fig = Figure {
            name: "energy".into(),
            svg: "<svg/>".into(),
        };
        s.finish(
            &done,
            Some(&StoredResult {
                figures: vec![fig.clone()],
                ..Default::default()
            }),
        )?;
        assert_eq!(
            s.result("new")?.ok_or_else(|| missing("new"))?.figures,
            vec![fig]
        );
        Ok(())
    }
}
