//! The PostgreSQL backend: jobs, results, series and the queue in one database shared by any
//! number of `serve` replicas (`--store postgres://…`).
//!
//! The queue is the `jobs` table: a worker claims the oldest job that is queued, or running
//! under a lease that ran out, with `SELECT … FOR UPDATE SKIP LOCKED` (so two replicas never
//! claim the same job and never wait on each other), raising its `attempt` and taking a lease
//! until `now() + lease` (the database's clock, the same for every replica). The replica renews
//! its leases with a heartbeat ([`SharedQueue::heartbeat`]), which also records progress and
//! carries cancel requests. A replica killed with SIGKILL renews nothing: its jobs are claimed
//! again once their leases run out. Everything a run stores (series chunks, its end and result)
//! is written only while its replica still owns the job, in the same statement or transaction
//! that checks it, so a slow replica that lost its lease (a zombie) cannot overwrite the run
//! that replaced it; results are keyed by (job, attempt) and read for the job's current attempt.
//!
//! A job that checkpoints (`output.checkpoint_seconds`/`checkpoint_steps`) keeps its latest
//! checkpoint in `checkpoints`, written under the same ownership check; a replica that claims
//! it again continues from there ([`Backend::truncate_series`] hands the rows stored up to the
//! checkpoint over to the new attempt) instead of from step 0.
//!
//! New jobs are announced with `NOTIFY signorini_jobs`; each replica LISTENs on one connection
//! and wakes its idle workers, which also poll at a short bound (a lease that ran out is
//! noticed that way).
//!
//! The schema is created and upgraded by the SQL files of `migrations/postgres/`, applied in
//! order, each once, under an advisory lock.
//!
//! The calls are blocking (like the SQLite backend's): each runs on the store's own small tokio
//! runtime and the caller waits for its answer on a channel, so they may be made from any
//! thread, including the server's async handlers, without nesting runtimes.

use super::{
    Backend, Beat, BeatReply, CancelOutcome, ChunkMeta, Claim, Enqueued, JobEnd, ResultTexts,
    SeriesChunk, SharedQueue, StoreError, StoredResult, batches_blob, check_index, decode_chunk,
    end_by_calls, f64s_to_blob, split_series, u64s_to_blob,
};
use crate::lifecycle::{ENDED, Transition, in_sql, is_sql, literal, per_state};
use crate::status::{JobState, JobView, Lineage};
use deadpool_postgres::{Manager, ManagerConfig, Pool, RecyclingMethod, Transaction};
use std::future::Future;
use std::sync::{Arc, Condvar, LazyLock, Mutex};
use std::time::Duration;
use tokio_postgres::{AsyncMessage, NoTls, Row};

mod pause;
mod study;

/// The migrations, in order: (version, name, SQL).
const MIGRATIONS: &[(i64, &str, &str)] = &[
    (
        1,
        "0001_init",
        include_str!("../../migrations/postgres/0001_init.sql"),
    ),
    (
        2,
        "0002_checkpoints",
        include_str!("../../migrations/postgres/0002_checkpoints.sql"),
    ),
    (
        3,
        "0003_studies",
        include_str!("../../migrations/postgres/0003_studies.sql"),
    ),
    (
        4,
        "0004_pause",
        include_str!("../../migrations/postgres/0004_pause.sql"),
    ),
    (
        5,
        "0005_uncompressed_series",
        include_str!("../../migrations/postgres/0005_uncompressed_series.sql"),
    ),
    (
        6,
        "0006_write_probe",
        include_str!("../../migrations/postgres/0006_write_probe.sql"),
    ),
];

/// Advisory lock key held while migrating ("sgnrn" in ASCII).
const MIGRATION_LOCK: i64 = 0x73_67_6e_72_6e;

/// How long a call waits for an unreachable PostgreSQL (restarting, recovering from a crash)
/// before it fails with [`StoreError::PostgresUnreachable`].
const RECONNECT_FOR: Duration = Duration::from_secs(30);

/// The channel new jobs are announced on.
const CHANNEL: &str = "signorini_jobs";

/// The status columns of `jobs`, in the order [`view`] reads them.
const JOB_COLUMNS: &str = "id, name, state, created_ms, started_ms, finished_ms, error_field, error_reason, done, total, t";

/// The SQL condition that replica `owner` (a statement parameter, `$5`) holds the job: it runs
/// it under its lease.
fn held_by(owner: &str) -> String {
    format!("owner = {owner} AND {}", is_sql("state", JobState::Running))
}

/// Raises flag `column` (`cancel_requested`, `pause_requested`) of job `id` if it is running,
/// for the replica running it to read at its next heartbeat: true when it was.
async fn ask_running(
    c: &deadpool_postgres::Object,
    column: &str,
    id: &str,
) -> Result<bool, StoreError> {
    let st = c
        .prepare_cached(&format!(
            "UPDATE jobs SET {column} = TRUE WHERE id = $1 AND {}",
            is_sql("state", JobState::Running)
        ))
        .await
        .map_err(pg)?;
    Ok(c.execute(&st, &[&id]).await.map_err(pg)? == 1)
}

fn pg(e: tokio_postgres::Error) -> StoreError {
    if let Some(db) = e.as_db_error() {
        let sqlstate = db.code().code();
        // Out of room (class 53), read-only (25006), an I/O error of the server (class 58).
        if sqlstate.starts_with("53") || sqlstate == "25006" || sqlstate.starts_with("58") {
            return StoreError::PostgresRefused {
                reason: db.message().to_string(),
                sqlstate: sqlstate.to_string(),
            };
        }
        // A connection exception (class 08), or the server shutting down, crashed or not yet
        // accepting connections (57P01 admin_shutdown, 57P02 crash_shutdown, 57P03
        // cannot_connect_now: "the database system is starting up / in recovery mode").
        if sqlstate.starts_with("08") || matches!(sqlstate, "57P01" | "57P02" | "57P03") {
            return StoreError::PostgresUnreachable(format!("{} ({sqlstate})", db.message()));
        }
    } else if e.is_closed()
        || std::error::Error::source(&e).is_some_and(|s| s.is::<std::io::Error>())
    {
        // The connection is gone, or could not be made (refused, reset).
        return StoreError::PostgresUnreachable(match std::error::Error::source(&e) {
            Some(cause) => format!("{e}: {cause}"),
            None => e.to_string(),
        });
    }
    StoreError::Postgres(match e.as_db_error() {
        Some(db) => format!("{} ({})", db.message(), db.code().code()),
        None => match std::error::Error::source(&e) {
            Some(cause) => format!("{e}: {cause}"),
            None => e.to_string(),
        },
    })
}

fn pool_err(e: deadpool_postgres::PoolError) -> StoreError {
    match e {
        deadpool_postgres::PoolError::Backend(e) => pg(e),
        other => StoreError::Postgres(other.to_string()),
    }
}

/// A job's status from a `SELECT {JOB_COLUMNS}` row.
fn view(r: &Row) -> Result<JobView, StoreError> {
    let id: String = r.try_get(0).map_err(pg)?;
    let state: String = r.try_get(2).map_err(pg)?;
    let field: Option<String> = r.try_get(6).map_err(pg)?;
    let reason: Option<String> = r.try_get(7).map_err(pg)?;
    let int =
        |k: usize| -> Result<u64, StoreError> { Ok(r.try_get::<_, i64>(k).map_err(pg)? as u64) };
    Ok(JobView {
        state: JobState::parse(&state).ok_or_else(|| StoreError::Corrupt {
            what: "state",
            id: id.clone(),
        })?,
        name: r.try_get(1).map_err(pg)?,
        created_ms: int(3)?,
        started_ms: int(4)?,
        finished_ms: int(5)?,
        error: match (field, reason) {
            (Some(f), Some(r)) => Some((f, r)),
            _ => None,
        },
        done: int(8)?,
        total: int(9)?,
        t: r.try_get(10).map_err(pg)?,
        id,
    })
}

/// A number bumped at every notification, and the condition idle workers wait on.
#[derive(Default)]
struct Ticket {
    n: Mutex<u64>,
    changed: Condvar,
}

impl Ticket {
    fn bump(&self) {
        let mut n = self.n.lock().unwrap_or_else(|p| p.into_inner());
        *n = n.wrapping_add(1);
        self.changed.notify_all();
    }
}

/// The PostgreSQL store of one replica.
pub struct PgStore {
    runtime: Option<tokio::runtime::Runtime>,
    handle: tokio::runtime::Handle,
    pool: Pool,
    replica: String,
    lease: Duration,
    ticket: Arc<Ticket>,
}

impl Drop for PgStore {
    fn drop(&mut self) {
        // Never blocks (the store may be dropped on an async thread): the listener and the
        // pool's connection tasks are simply abandoned.
        if let Some(rt) = self.runtime.take() {
            rt.shutdown_background();
        }
    }
}

/// Applies the migrations not yet recorded in `schema_migrations`, each in its own
/// transaction, under an advisory lock (replicas starting together wait for each other).
async fn migrate(pool: Pool) -> Result<(), StoreError> {
    let mut client = pool.get().await.map_err(pool_err)?;
    client
        .execute("SELECT pg_advisory_lock($1)", &[&MIGRATION_LOCK])
        .await
        .map_err(pg)?;
    let applied = async {
        client
            .batch_execute(
                "CREATE TABLE IF NOT EXISTS schema_migrations (
                    version BIGINT PRIMARY KEY,
                    name TEXT NOT NULL,
                    applied_at TIMESTAMPTZ NOT NULL DEFAULT now()
                )",
            )
            .await
            .map_err(pg)?;
        for &(version, name, sql) in MIGRATIONS {
            let tx = client.transaction().await.map_err(pg)?;
            let done = tx
                .query_opt(
                    "SELECT 1 FROM schema_migrations WHERE version = $1",
                    &[&version],
                )
                .await
                .map_err(pg)?
                .is_some();
            if done {
                continue;
            }
            tx.batch_execute(sql)
                .await
                .map_err(|e| StoreError::Postgres(format!("migration {name}: {}", pg(e))))?;
            tx.execute(
                "INSERT INTO schema_migrations (version, name) VALUES ($1, $2)",
                &[&version, &name],
            )
            .await
            .map_err(pg)?;
            tx.commit().await.map_err(pg)?;
            tracing::info!(migration = name, "store: migrated");
        }
        Ok(())
    }
    .await;
    let unlocked = client
        .execute("SELECT pg_advisory_unlock($1)", &[&MIGRATION_LOCK])
        .await
        .map_err(pg);
    applied.and(unlocked.map(|_| ()))
}

/// Listens for new jobs on a connection of its own (reconnecting after a second if it drops)
/// and bumps the ticket at each.
async fn listen(config: tokio_postgres::Config, ticket: Arc<Ticket>) {
    loop {
        match config.connect(NoTls).await {
            Ok((client, mut connection)) => {
                let bumps = ticket.clone();
                let driver = tokio::spawn(async move {
                    while let Some(message) =
                        std::future::poll_fn(|cx| connection.poll_message(cx)).await
                    {
                        match message {
                            Ok(AsyncMessage::Notification(_)) => bumps.bump(),
                            Ok(_) => {}
                            Err(_) => break,
                        }
                    }
                });
                match client.batch_execute(&format!("LISTEN {CHANNEL}")).await {
                    Ok(()) => {
                        // A job queued while this connection was down is found by polling.
                        ticket.bump();
                        let _ = driver.await;
                    }
                    Err(e) => {
                        tracing::warn!("store: LISTEN {CHANNEL}: {}", pg(e));
                        driver.abort();
                    }
                }
            }
            Err(e) => tracing::warn!("store: connecting the listener: {}", pg(e)),
        }
        tokio::time::sleep(Duration::from_secs(1)).await;
    }
}

impl PgStore {
    /// Connects to `url`, applies the migrations and starts listening for new jobs.
    pub fn connect(
        url: &str,
        replica: &str,
        connections: usize,
        lease: Duration,
    ) -> Result<PgStore, StoreError> {
        let config: tokio_postgres::Config = url
            .parse()
            .map_err(|e| StoreError::Postgres(format!("--store: not a PostgreSQL URL: {e}")))?;
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .thread_name("signorini-store")
            .enable_all()
            .build()
            .map_err(|e| StoreError::Postgres(format!("starting the store's runtime: {e}")))?;
        let manager = Manager::from_config(
            config.clone(),
            NoTls,
            ManagerConfig {
                recycling_method: RecyclingMethod::Fast,
            },
        );
        let pool = Pool::builder(manager)
            .max_size(connections.max(2))
            .build()
            .map_err(|e| StoreError::Postgres(format!("connection pool: {e}")))?;
        let store = PgStore {
            handle: runtime.handle().clone(),
            runtime: Some(runtime),
            pool: pool.clone(),
            replica: replica.to_string(),
            lease,
            ticket: Arc::new(Ticket::default()),
        };
        store.block(migrate(pool))?;
        store.handle.spawn(listen(config, store.ticket.clone()));
        Ok(store)
    }

    /// Runs `f` on the store's runtime and waits for its answer.
    fn block<T: Send + 'static>(
        &self,
        f: impl Future<Output = Result<T, StoreError>> + Send + 'static,
    ) -> Result<T, StoreError> {
        let (tx, rx) = std::sync::mpsc::sync_channel(1);
        self.handle.spawn(async move {
            let _ = tx.send(f.await);
        });
        rx.recv()
            .map_err(|_| StoreError::Postgres("the store's runtime stopped".into()))?
    }

    /// Runs `f` with a pooled connection. While PostgreSQL cannot be reached (a restart, a
    /// crash and its recovery, a network cut) `f` is run again on a fresh connection, after
    /// pauses growing from 0.1 s to 1 s, for at most [`RECONNECT_FOR`]: a running job's writes,
    /// its heartbeat and a submission wait for the database instead of failing. A statement
    /// whose connection broke was not committed (PostgreSQL rolls back an unfinished
    /// transaction), so running it again does not apply it twice; the one exception, a
    /// connection lost between the commit and its acknowledgement, leaves a chunk already
    /// stored (inserted `ON CONFLICT DO NOTHING`) or a claim whose lease runs out.
    fn with<T, F, Fut>(&self, f: F) -> Result<T, StoreError>
    where
        T: Send + 'static,
        F: FnOnce(deadpool_postgres::Object) -> Fut + Clone + Send + 'static,
        Fut: Future<Output = Result<T, StoreError>> + Send,
    {
        let pool = self.pool.clone();
        self.block(async move {
            let started = tokio::time::Instant::now();
            let mut pause = Duration::from_millis(100);
            loop {
                let outcome = match pool.get().await.map_err(pool_err) {
                    Ok(c) => f.clone()(c).await,
                    Err(e) => Err(e),
                };
                match outcome {
                    Err(StoreError::PostgresUnreachable(reason))
                        if started.elapsed() + pause < RECONNECT_FOR =>
                    {
                        tracing::warn!("store: PostgreSQL unreachable ({reason}): trying again");
                        tokio::time::sleep(pause).await;
                        pause = (pause * 2).min(Duration::from_secs(1));
                    }
                    other => return other,
                }
            }
        })
    }

    fn lease_secs(&self) -> f64 {
        self.lease.as_secs_f64()
    }

    /// [`Backend::finish`] for a result that carries rows of its own (appended as chunks after
    /// the run's), in one transaction.
    fn finish_with_rows(
        &self,
        row: &JobView,
        result: Option<&StoredResult>,
    ) -> Result<(), StoreError> {
        let row = row.clone();
        let owner = self.replica.clone();
        let result = result.map(|r| (ResultTexts::of(r), r.clone()));
        self.with(move |mut c| async move {
            let tx = c.transaction().await.map_err(pg)?;
            let (field, reason) = row.error_parts();
            let attempt: Option<i64> = tx
                .query_opt(
                    &format!(
                        "UPDATE jobs SET state = $2, finished_ms = $3, error_field = $4, error_reason = $5,
                                done = $6, total = $7, t = $8, lease_until = NULL
                         WHERE id = $1 AND {} AND owner = $9 RETURNING attempt",
                        Transition::End.from_sql()
                    ),
                    &[
                        &row.id,
                        &row.state.as_str(),
                        &(row.finished_ms as i64),
                        &field,
                        &reason,
                        &(row.done as i64),
                        &(row.total as i64),
                        &row.t,
                        &owner,
                    ],
                )
                .await
                .map_err(pg)?
                .map(|r| r.try_get(0))
                .transpose()
                .map_err(pg)?;
            let Some(attempt) = attempt else {
                return Err(StoreError::LeaseLost { id: row.id });
            };
            if let Some((texts, r)) = result {
                tx.execute(
                    "INSERT INTO results (id, attempt, summary_json, columns_json, tables_json, figures_json, partial)
                     VALUES ($1, $2, $3, $4, $5, $6, $7) ON CONFLICT (id, attempt) DO NOTHING",
                    &[
                        &row.id,
                        &attempt,
                        &texts.summary,
                        &texts.columns,
                        &texts.tables,
                        &texts.figures,
                        &r.partial,
                    ],
                )
                .await
                .map_err(pg)?;
                if !r.steps.is_empty() {
                    let have = tx
                        .query_one(
                            "SELECT COUNT(*), COALESCE(SUM(rows), 0)::BIGINT FROM result_chunks WHERE id = $1 AND attempt = $2",
                            &[&row.id, &attempt],
                        )
                        .await
                        .map_err(pg)?;
                    let chunk = have.try_get::<_, i64>(0).map_err(pg)? as u64;
                    let first_row = have.try_get::<_, i64>(1).map_err(pg)? as u64;
                    let parts = split_series(r.columns.len(), &r.steps, &r.t, &r.values);
                    for (k, (start, rows)) in parts.into_iter().enumerate() {
                        insert_chunk(
                            &tx,
                            &row.id,
                            attempt,
                            chunk + k as u64,
                            first_row + start,
                            &rows,
                        )
                        .await?;
                    }
                }
            }
            tx.commit().await.map_err(pg)?;
            Ok(())
        })
    }
}

/// Inserts one chunk of attempt `attempt`.
async fn insert_chunk(
    c: &Transaction<'_>,
    id: &str,
    attempt: i64,
    chunk: u64,
    first_row: u64,
    rows: &SeriesChunk,
) -> Result<(), StoreError> {
    let (Some(&first), Some(&last)) = (rows.steps.first(), rows.steps.last()) else {
        return Ok(());
    };
    c.execute(
        "INSERT INTO result_chunks (id, attempt, chunk, first_row, rows, step_first, step_last, steps, t, vals, batches)
         VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11)
         ON CONFLICT (id, attempt, chunk) DO NOTHING",
        &[
            &id,
            &attempt,
            &(chunk as i64),
            &(first_row as i64),
            &(rows.steps.len() as i64),
            &(first as i64),
            &(last as i64),
            &u64s_to_blob(&rows.steps),
            &f64s_to_blob(&rows.t),
            &f64s_to_blob(&rows.values),
            &batches_blob(rows),
        ],
    )
    .await
    .map_err(pg)?;
    Ok(())
}

/// The owned arguments of the end statement (sent to the store's runtime; cloned for a
/// retry while PostgreSQL is unreachable).
#[derive(Clone)]
struct EndArgs {
    row: JobView,
    texts: Option<ResultTexts>,
    partial: bool,
    chunk: i64,
    first_row: i64,
    rows: SeriesChunk,
    kept_step: Option<i64>,
    kept_bytes: Option<Vec<u8>>,
}

impl EndArgs {
    fn of(end: &JobEnd<'_>) -> EndArgs {
        let (chunk, first_row, rows) = match end.rows {
            Some((chunk, first_row, rows)) => (chunk as i64, first_row as i64, rows.clone()),
            None => (0, 0, SeriesChunk::default()),
        };
        let (kept_step, kept_bytes) = match end.final_state {
            Some((_, step, bytes)) => (Some(step as i64), Some(bytes.to_vec())),
            None => (None, None),
        };
        EndArgs {
            row: end.view.clone(),
            texts: end.result.map(ResultTexts::of),
            partial: end.result.is_some_and(|r| r.partial),
            chunk,
            first_row,
            rows,
            kept_step,
            kept_bytes,
        }
    }
}

/// [`Backend::end`] of a result without rows of its own, as one statement: the end of the job
/// while replica `owner` still holds it (`done`), and hanging on it the result, the last rows,
/// the final state (the checkpoint after the last step, given or else the stored one at that
/// step) and the checkpoint delete, so a replica that lost its lease stores nothing (not even
/// the delete: the checkpoint is the new owner's).
async fn store_end(
    c: &deadpool_postgres::Object,
    owner: &str,
    args: EndArgs,
) -> Result<(), StoreError> {
    let EndArgs {
        row,
        texts,
        partial,
        chunk,
        first_row,
        rows,
        kept_step,
        kept_bytes,
    } = args;
    let (field, reason) = row.error_parts();
    let has_result = texts.is_some();
    let texts = texts.unwrap_or_default();
    let n_rows = rows.steps.len() as i64;
    let step_first = rows.steps.first().map_or(0, |&s| s as i64);
    let step_last = rows.steps.last().map_or(0, |&s| s as i64);
    let blobs = (
        u64s_to_blob(&rows.steps),
        f64s_to_blob(&rows.t),
        f64s_to_blob(&rows.values),
        batches_blob(&rows),
    );
    static END: LazyLock<String> = LazyLock::new(|| {
        format!(
            "WITH done AS (
                    UPDATE jobs SET state = $2, finished_ms = $3, error_field = $4, error_reason = $5,
                           done = $6, total = $7, t = $8, lease_until = NULL
                    WHERE id = $1 AND {} AND owner = $9 RETURNING attempt),
                 res AS (
                    INSERT INTO results (id, attempt, summary_json, columns_json, tables_json, figures_json, partial)
                    SELECT $1, attempt, $10, $11, $12, $13, $14 FROM done WHERE $15
                    ON CONFLICT (id, attempt) DO NOTHING),
                 chunk AS (
                    INSERT INTO result_chunks (id, attempt, chunk, first_row, rows, step_first, step_last, steps, t, vals, batches)
                    SELECT $1, attempt, $16, $17, $18, $19, $20, $21, $22, $23, $24 FROM done WHERE $18::BIGINT > 0
                    ON CONFLICT (id, attempt, chunk) DO NOTHING),
                 kept AS (
                    INSERT INTO final_states (id, step, bytes)
                    SELECT $1, s.step, s.bytes FROM done, (
                        SELECT $25::BIGINT AS step, $26::BYTEA AS bytes WHERE $25::BIGINT IS NOT NULL
                        UNION ALL
                        SELECT step, bytes FROM checkpoints
                        WHERE id = $1 AND step = $6::BIGINT AND $25::BIGINT IS NULL) s
                    WHERE $2::TEXT = {}
                    ON CONFLICT (id) DO UPDATE SET step = EXCLUDED.step, bytes = EXCLUDED.bytes),
                 dropped AS (
                    DELETE FROM checkpoints WHERE id = $1 AND EXISTS (SELECT 1 FROM done))
                 SELECT attempt FROM done",
            Transition::End.from_sql(),
            literal(JobState::Succeeded),
        )
    });
    let st = c.prepare_cached(&END).await.map_err(pg)?;
    let owned = c
        .query_opt(
            &st,
            &[
                &row.id,
                &row.state.as_str(),
                &(row.finished_ms as i64),
                &field,
                &reason,
                &(row.done as i64),
                &(row.total as i64),
                &row.t,
                &owner,
                &texts.summary,
                &texts.columns,
                &texts.tables,
                &texts.figures,
                &partial,
                &has_result,
                &chunk,
                &first_row,
                &n_rows,
                &step_first,
                &step_last,
                &blobs.0,
                &blobs.1,
                &blobs.2,
                &blobs.3,
                &kept_step,
                &kept_bytes,
            ],
        )
        .await
        .map_err(pg)?
        .is_some();
    if !owned {
        return Err(StoreError::LeaseLost { id: row.id });
    }
    Ok(())
}

/// Claims the next job for replica `owner` under a lease of `lease` seconds, started at
/// `started_ms` ([`SharedQueue::claim`]).
async fn claim_next(
    c: &deadpool_postgres::Object,
    owner: &str,
    lease: f64,
    started_ms: u64,
) -> Result<Option<Claim>, StoreError> {
    static CLAIM: LazyLock<String> = LazyLock::new(|| {
        format!(
            "WITH next AS (
                        SELECT id FROM jobs
                        WHERE {} OR ({} AND lease_until < now())
                        ORDER BY seq LIMIT 1 FOR UPDATE SKIP LOCKED),
                     claimed AS (
                     UPDATE jobs j SET state = {}, owner = $1, attempt = j.attempt + 1,
                            lease_until = now() + make_interval(secs => $2),
                            started_ms = $3, done = 0, t = 0
                     FROM next WHERE j.id = next.id
                     RETURNING {}, j.spec_json, j.attempt, j.cancel_requested,
                               j.parent IS NOT NULL),
                     cleared AS (
                     DELETE FROM result_chunks r USING claimed c
                     WHERE r.id = c.id AND r.attempt < c.attempt
                       AND NOT EXISTS (SELECT 1 FROM checkpoints k WHERE k.id = c.id))
                     SELECT c.*, k.attempt, k.step, k.bytes, e.extends
                     FROM claimed c LEFT JOIN checkpoints k ON k.id = c.id
                          LEFT JOIN extensions e ON e.id = c.id",
            Transition::Claim.from_sql(),
            Transition::Takeover.from_sql(),
            Transition::Claim.to_sql(),
            JOB_COLUMNS
                .split(", ")
                .map(|c| format!("j.{c}"))
                .collect::<Vec<_>>()
                .join(", ")
        )
    });
    let Some(r) = c
        .query_opt(
            &c.prepare_cached(&CLAIM).await.map_err(pg)?,
            &[&owner, &lease, &(started_ms as i64)],
        )
        .await
        .map_err(pg)?
    else {
        return Ok(None);
    };
    Ok(Some(Claim {
        view: view(&r)?,
        spec_json: r.try_get(11).map_err(pg)?,
        attempt: r.try_get::<_, i64>(12).map_err(pg)? as u64,
        cancel_requested: r.try_get(13).map_err(pg)?,
        study_child: r.try_get(14).map_err(pg)?,
        checkpoint: match r.try_get::<_, Option<i64>>(15).map_err(pg)? {
            Some(attempt) => Some((
                attempt as u64,
                r.try_get::<_, i64>(16).map_err(pg)? as u64,
                r.try_get(17).map_err(pg)?,
            )),
            None => None,
        },
        extends: r.try_get(18).map_err(pg)?,
    }))
}

impl Backend for PgStore {
    fn insert(&self, row: &JobView, spec_json: &str) -> Result<bool, StoreError> {
        let (id, name, spec) = (row.id.clone(), row.name.clone(), spec_json.to_string());
        let (state, created, total) = (row.state.as_str(), row.created_ms as i64, row.total as i64);
        self.with(move |c| async move {
            // Inserted and announced in one statement: the notification goes at commit.
            let n = c
                .query(
                    &c.prepare_cached(&format!(
                        "WITH ins AS (
                            INSERT INTO jobs (id, name, spec_json, state, created_ms, total)
                            VALUES ($1, $2, $3, $4, $5, $6) ON CONFLICT (id) DO NOTHING RETURNING id)
                         SELECT pg_notify('{CHANNEL}', id) FROM ins"
                    )).await.map_err(pg)?,
                    &[&id, &name, &spec, &state, &created, &total],
                )
                .await
                .map_err(pg)?
                .len();
            Ok(n == 1)
        })
    }

    fn set_running(&self, _id: &str, _started_ms: u64) -> Result<(), StoreError> {
        // Done by the claim (state, owner, lease, start time), in the same statement.
        Ok(())
    }

    fn clear_series(&self, id: &str) -> Result<(), StoreError> {
        // The chunks of earlier attempts (a replica that died mid-run, with no checkpoint to
        // continue from); the current attempt's are written under its own key.
        let id = id.to_string();
        self.with(move |c| async move {
            let st = c
                .prepare_cached(
                    "DELETE FROM result_chunks WHERE id = $1 AND attempt < (SELECT attempt FROM jobs WHERE id = $1)",
                )
                .await
                .map_err(pg)?;
            c.execute(&st, &[&id]).await.map_err(pg)?;
            Ok(())
        })
    }

    /// One chunk of bytes that do not compress (stored EXTERNAL anyway), under this replica's
    /// name, committed, then removed.
    fn probe_write(&self) -> Result<(), StoreError> {
        let replica = self.replica.clone();
        // xorshift64: bytes that take their full size on disk.
        let mut x = 0x9e37_79b9_7f4a_7c15_u64;
        let bytes: Vec<u8> = (0..super::CHUNK_BYTES / 8)
            .flat_map(|_| {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                x.to_le_bytes()
            })
            .collect();
        self.with(move |c| async move {
            c.execute(
                "INSERT INTO write_probe (replica, bytes) VALUES ($1, $2)
                 ON CONFLICT (replica) DO UPDATE SET bytes = EXCLUDED.bytes",
                &[&replica, &bytes],
            )
            .await
            .map_err(pg)?;
            c.execute("DELETE FROM write_probe WHERE replica = $1", &[&replica])
                .await
                .map_err(pg)?;
            Ok(())
        })
    }

    fn save_checkpoint(
        &self,
        id: &str,
        attempt: u64,
        step: u64,
        bytes: &[u8],
    ) -> Result<(), StoreError> {
        let (id, owner, bytes) = (id.to_string(), self.replica.clone(), bytes.to_vec());
        self.with(move |c| async move {
            // Only while this replica holds the job (a zombie's checkpoint would replace the
            // one the new owner continues from).
            static SAVE: LazyLock<String> = LazyLock::new(|| {
                format!(
                    "INSERT INTO checkpoints (id, attempt, step, bytes)
                     SELECT id, $2, $3, $4 FROM jobs WHERE id = $1 AND {} FOR SHARE
                     ON CONFLICT (id) DO UPDATE SET attempt = EXCLUDED.attempt, step = EXCLUDED.step, bytes = EXCLUDED.bytes",
                    held_by("$5")
                )
            });
            let st = c.prepare_cached(&SAVE).await.map_err(pg)?;
            let n = c
                .execute(&st, &[&id, &(attempt as i64), &(step as i64), &bytes, &owner])
                .await
                .map_err(pg)?;
            if n == 0 {
                return Err(StoreError::LeaseLost { id });
            }
            Ok(())
        })
    }

    fn load_checkpoint(&self, id: &str) -> Result<Option<(u64, u64, Vec<u8>)>, StoreError> {
        let id = id.to_string();
        self.with(move |c| async move {
            let st = c
                .prepare_cached("SELECT attempt, step, bytes FROM checkpoints WHERE id = $1")
                .await
                .map_err(pg)?;
            let Some(r) = c.query_opt(&st, &[&id]).await.map_err(pg)? else {
                return Ok(None);
            };
            Ok(Some((
                r.try_get::<_, i64>(0).map_err(pg)? as u64,
                r.try_get::<_, i64>(1).map_err(pg)? as u64,
                r.try_get(2).map_err(pg)?,
            )))
        })
    }

    fn delete_checkpoint(&self, id: &str) -> Result<(), StoreError> {
        let id = id.to_string();
        self.with(move |c| async move {
            let st = c
                .prepare_cached("DELETE FROM checkpoints WHERE id = $1")
                .await
                .map_err(pg)?;
            c.execute(&st, &[&id]).await.map_err(pg)?;
            Ok(())
        })
    }

    fn truncate_series(&self, id: &str, rows: u64) -> Result<(), StoreError> {
        // Resuming on a new attempt: the rows the checkpoint counts were stored by earlier
        // attempts; those after it go, and the rest become this attempt's (the series is read
        // for the job's current attempt), in one transaction, while this replica holds the job.
        let (id, owner) = (id.to_string(), self.replica.clone());
        self.with(move |mut c| async move {
            let tx = c.transaction().await.map_err(pg)?;
            let attempt: i64 = match tx
                .query_opt(
                    &format!(
                        "SELECT attempt FROM jobs WHERE id = $1 AND {} FOR SHARE",
                        held_by("$2")
                    ),
                    &[&id, &owner],
                )
                .await
                .map_err(pg)?
            {
                Some(r) => r.try_get(0).map_err(pg)?,
                None => return Err(StoreError::LeaseLost { id }),
            };
            let rows = rows as i64;
            let across: i64 = tx
                .query_one(
                    "SELECT COUNT(*) FROM result_chunks WHERE id = $1 AND first_row < $2 AND first_row + rows > $2",
                    &[&id, &rows],
                )
                .await
                .map_err(pg)?
                .try_get(0)
                .map_err(pg)?;
            if across > 0 {
                return Err(StoreError::Corrupt {
                    what: "series (a chunk across the checkpoint)",
                    id,
                });
            }
            tx.execute(
                "DELETE FROM result_chunks WHERE id = $1 AND first_row >= $2",
                &[&id, &rows],
            )
            .await
            .map_err(pg)?;
            tx.execute(
                "UPDATE result_chunks SET attempt = $2 WHERE id = $1 AND attempt < $2",
                &[&id, &attempt],
            )
            .await
            .map_err(pg)?;
            tx.commit().await.map_err(pg)?;
            Ok(())
        })
    }

    fn append_chunk(
        &self,
        id: &str,
        chunk: u64,
        first_row: u64,
        rows: &SeriesChunk,
    ) -> Result<(), StoreError> {
        let (Some(&first), Some(&last)) = (rows.steps.first(), rows.steps.last()) else {
            return Ok(());
        };
        let (id, owner) = (id.to_string(), self.replica.clone());
        let blobs = (
            u64s_to_blob(&rows.steps),
            f64s_to_blob(&rows.t),
            f64s_to_blob(&rows.values),
            batches_blob(rows),
        );
        let n_rows = rows.steps.len() as i64;
        static APPEND: LazyLock<String> = LazyLock::new(|| {
            format!(
                "INSERT INTO result_chunks (id, attempt, chunk, first_row, rows, step_first, step_last, steps, t, vals, batches)
                 SELECT id, attempt, $2, $3, $4, $5, $6, $7, $8, $9, $10 FROM jobs
                 WHERE id = $1 AND {} FOR SHARE
                 ON CONFLICT (id, attempt, chunk) DO NOTHING",
                held_by("$11")
            )
        });
        self.with(move |c| async move {
            // Written only while this replica holds the job (FOR SHARE waits for a claim in
            // progress and sees its outcome).
            let n = c
                .execute(
                    &c.prepare_cached(&APPEND).await.map_err(pg)?,
                    &[
                        &id,
                        &(chunk as i64),
                        &(first_row as i64),
                        &n_rows,
                        &(first as i64),
                        &(last as i64),
                        &blobs.0,
                        &blobs.1,
                        &blobs.2,
                        &blobs.3,
                        &owner,
                    ],
                )
                .await
                .map_err(pg)?;
            if n == 0 {
                return Err(StoreError::LeaseLost { id });
            }
            Ok(())
        })
    }

    fn finish(&self, row: &JobView, result: Option<&StoredResult>) -> Result<(), StoreError> {
        if result.is_some_and(|r| !r.steps.is_empty()) {
            return self.finish_with_rows(row, result);
        }
        // The usual end (the series is already in chunks): one statement, so one round trip.
        let row = row.clone();
        let owner = self.replica.clone();
        let texts = result.map(ResultTexts::of);
        let partial = result.is_some_and(|r| r.partial);
        self.with(move |c| async move {
            let (field, reason) = row.error_parts();
            let has_result = texts.is_some();
            let texts = texts.unwrap_or_default();
            static FINISH: LazyLock<String> = LazyLock::new(|| {
                format!(
                    "WITH done AS (
                        UPDATE jobs SET state = $2, finished_ms = $3, error_field = $4, error_reason = $5,
                               done = $6, total = $7, t = $8, lease_until = NULL
                        WHERE id = $1 AND {} AND owner = $9 RETURNING attempt),
                     ins AS (
                        INSERT INTO results (id, attempt, summary_json, columns_json, tables_json, figures_json, partial)
                        SELECT $1, attempt, $10, $11, $12, $13, $14 FROM done WHERE $15
                        ON CONFLICT (id, attempt) DO NOTHING)
                     SELECT attempt FROM done",
                    Transition::End.from_sql()
                )
            });
            let st = c.prepare_cached(&FINISH).await.map_err(pg)?;
            let owned = c
                .query_opt(
                    &st,
                    &[
                        &row.id,
                        &row.state.as_str(),
                        &(row.finished_ms as i64),
                        &field,
                        &reason,
                        &(row.done as i64),
                        &(row.total as i64),
                        &row.t,
                        &owner,
                        &texts.summary,
                        &texts.columns,
                        &texts.tables,
                        &texts.figures,
                        &partial,
                        &has_result,
                    ],
                )
                .await
                .map_err(pg)?
                .is_some();
            if !owned {
                return Err(StoreError::LeaseLost { id: row.id });
            }
            Ok(())
        })
    }

    fn end(&self, end: &JobEnd<'_>) -> Result<(), StoreError> {
        if end.result.is_some_and(|r| !r.steps.is_empty()) {
            return end_by_calls(self, end);
        }
        let (args, owner) = (EndArgs::of(end), self.replica.clone());
        self.with(move |c| async move { store_end(&c, &owner, args).await })
    }

    fn get(&self, id: &str) -> Result<Option<JobView>, StoreError> {
        let id = id.to_string();
        self.with(move |c| async move {
            c.query_opt(
                &c.prepare_cached(&format!("SELECT {JOB_COLUMNS} FROM jobs WHERE id = $1"))
                    .await
                    .map_err(pg)?,
                &[&id],
            )
            .await
            .map_err(pg)?
            .map(|r| view(&r))
            .transpose()
        })
    }

    fn lineage(&self, id: &str) -> Result<Lineage, StoreError> {
        let id = id.to_string();
        self.with(move |c| async move {
            let row = c
                .query_opt(
                    &c.prepare_cached(
                        "SELECT j.parent, e.extends FROM jobs j LEFT JOIN extensions e ON e.id = j.id
                         WHERE j.id = $1",
                    )
                    .await
                    .map_err(pg)?,
                    &[&id],
                )
                .await
                .map_err(pg)?;
            Ok(match row {
                Some(r) => Lineage {
                    parent: r.try_get(0).map_err(pg)?,
                    extends: r.try_get(1).map_err(pg)?,
                },
                None => Lineage::default(),
            })
        })
    }

    fn list_page(
        &self,
        state: Option<JobState>,
        before: Option<i64>,
        limit: usize,
    ) -> Result<Vec<(i64, JobView)>, StoreError> {
        let state = state.map(JobState::as_str);
        self.with(move |c| async move {
            let rows = c
                .query(
                    &c.prepare_cached(&format!(
                        "SELECT {JOB_COLUMNS}, seq FROM jobs
                         WHERE ($1::TEXT IS NULL OR state = $1) AND ($2::BIGINT IS NULL OR seq < $2)
                         ORDER BY seq DESC LIMIT $3"
                    ))
                    .await
                    .map_err(pg)?,
                    &[&state, &before, &(limit as i64)],
                )
                .await
                .map_err(pg)?;
            rows.iter()
                .map(|r| Ok((r.try_get::<_, i64>(11).map_err(pg)?, view(r)?)))
                .collect()
        })
    }

    fn finished_before(&self, cutoff_ms: u64) -> Result<Vec<String>, StoreError> {
        self.with(move |c| async move {
            c.query(
                &c.prepare_cached(&format!(
                    "SELECT id FROM jobs WHERE state IN {} AND finished_ms < $1",
                    in_sql(&ENDED)
                ))
                .await
                .map_err(pg)?,
                &[&(cutoff_ms as i64)],
            )
            .await
            .map_err(pg)?
            .iter()
            .map(|r| r.try_get(0).map_err(pg))
            .collect()
        })
    }

    fn delete(&self, id: &str) -> Result<bool, StoreError> {
        // Results and chunks go with the job (ON DELETE CASCADE); a job another replica runs
        // is not finished, so not removed.
        let id = id.to_string();
        self.with(move |c| async move {
            let n = c
                .execute(
                    &c.prepare_cached(&format!(
                        "DELETE FROM jobs WHERE id = $1 AND state IN {}",
                        in_sql(&ENDED)
                    ))
                    .await
                    .map_err(pg)?,
                    &[&id],
                )
                .await
                .map_err(pg)?;
            Ok(n == 1)
        })
    }

    fn recover(&self) -> Result<Vec<(JobView, String)>, StoreError> {
        // Nothing to take back: unfinished jobs are claimed from the queue, those of a replica
        // that died once their leases run out.
        Ok(Vec::new())
    }

    fn counts(&self) -> Result<Vec<(JobState, u64)>, StoreError> {
        let rows: Vec<(String, u64)> = self.with(move |c| async move {
            c.query(
                &c.prepare_cached("SELECT state, COUNT(*) FROM jobs GROUP BY state")
                    .await
                    .map_err(pg)?,
                &[],
            )
            .await
            .map_err(pg)?
            .iter()
            .map(|r| {
                Ok((
                    r.try_get(0).map_err(pg)?,
                    r.try_get::<_, i64>(1).map_err(pg)? as u64,
                ))
            })
            .collect()
        })?;
        Ok(per_state(&rows))
    }

    fn result_head(&self, id: &str) -> Result<Option<StoredResult>, StoreError> {
        let id = id.to_string();
        self.with(move |c| async move {
            let Some(r) = c
                .query_opt(
                    &c.prepare_cached("SELECT r.summary_json, r.columns_json, r.tables_json, r.figures_json, r.partial
                     FROM results r JOIN jobs j ON j.id = r.id AND j.attempt = r.attempt WHERE r.id = $1").await.map_err(pg)?,
                    &[&id],
                )
                .await
                .map_err(pg)?
            else {
                return Ok(None);
            };
            let texts = ResultTexts {
                summary: r.try_get(0).map_err(pg)?,
                columns: r.try_get(1).map_err(pg)?,
                tables: r.try_get(2).map_err(pg)?,
                figures: r.try_get(3).map_err(pg)?,
            };
            Ok(Some(texts.decode(&id, r.try_get(4).map_err(pg)?)?))
        })
    }

    fn series_index(&self, id: &str) -> Result<Vec<ChunkMeta>, StoreError> {
        let id = id.to_string();
        self.with(move |c| async move {
            let rows = c
                .query(
                    &c.prepare_cached(
                        "SELECT c.chunk, c.first_row, c.rows, c.step_first, c.step_last
                     FROM result_chunks c JOIN jobs j ON j.id = c.id AND j.attempt = c.attempt
                     WHERE c.id = $1 ORDER BY c.chunk",
                    )
                    .await
                    .map_err(pg)?,
                    &[&id],
                )
                .await
                .map_err(pg)?;
            let int = |r: &Row, k: usize| -> Result<u64, StoreError> {
                Ok(r.try_get::<_, i64>(k).map_err(pg)? as u64)
            };
            let chunks = rows
                .iter()
                .map(|r| {
                    Ok(ChunkMeta {
                        chunk: int(r, 0)?,
                        first_row: int(r, 1)?,
                        rows: int(r, 2)?,
                        step_first: int(r, 3)?,
                        step_last: int(r, 4)?,
                    })
                })
                .collect::<Result<Vec<_>, StoreError>>()?;
            check_index(&id, chunks)
        })
    }

    fn read_chunk(
        &self,
        id: &str,
        meta: &ChunkMeta,
        columns: usize,
    ) -> Result<SeriesChunk, StoreError> {
        let (id, meta) = (id.to_string(), *meta);
        self.with(move |c| async move {
            let r = c
                .query_one(
                    &c.prepare_cached(
                        "SELECT c.steps, c.t, c.vals, c.batches
                     FROM result_chunks c JOIN jobs j ON j.id = c.id AND j.attempt = c.attempt
                     WHERE c.id = $1 AND c.chunk = $2",
                    )
                    .await
                    .map_err(pg)?,
                    &[&id, &(meta.chunk as i64)],
                )
                .await
                .map_err(pg)?;
            let blob = |k: usize| -> Result<Vec<u8>, StoreError> { r.try_get(k).map_err(pg) };
            let (steps, t, vals, batches) = (blob(0)?, blob(1)?, blob(2)?, blob(3)?);
            decode_chunk(
                &id,
                meta.rows as usize,
                columns,
                (&steps, &t, &vals, &batches),
            )
        })
    }
}

impl SharedQueue for PgStore {
    fn replica(&self) -> &str {
        &self.replica
    }

    fn lease(&self) -> Duration {
        self.lease
    }

    /// The claim also answers what the run would ask next: the job's checkpoint and the job it
    /// extends; without a checkpoint it drops the rows earlier attempts stored (the run starts
    /// from step 0), in the same statement.
    fn claim(&self, started_ms: u64) -> Result<Option<Claim>, StoreError> {
        let (owner, lease) = (self.replica.clone(), self.lease_secs());
        self.with(move |c| async move { claim_next(&c, &owner, lease, started_ms).await })
    }

    /// The end and the claim go out together on one connection (pipelined: one round trip),
    /// each its own statement and transaction, the end first.
    fn end_and_claim(
        &self,
        end: &JobEnd<'_>,
        started_ms: u64,
    ) -> (Result<(), StoreError>, Result<Option<Claim>, StoreError>) {
        if end.result.is_some_and(|r| !r.steps.is_empty()) {
            return (end_by_calls(self, end), self.claim(started_ms));
        }
        let (args, owner, lease) = (EndArgs::of(end), self.replica.clone(), self.lease_secs());
        let both = self.with(move |c| async move {
            // Prepared (once per connection) before, so the two executions are sent back to
            // back without waiting for each other.
            let (ended, claimed) = tokio::join!(
                store_end(&c, &owner, args),
                claim_next(&c, &owner, lease, started_ms)
            );
            Ok((ended, claimed))
        });
        match both {
            Ok(both) => both,
            Err(e) => (Err(e), Ok(None)),
        }
    }

    fn heartbeat(&self, beats: &[Beat]) -> Result<Vec<(String, BeatReply)>, StoreError> {
        if beats.is_empty() {
            return Ok(Vec::new());
        }
        let (owner, lease) = (self.replica.clone(), self.lease_secs());
        let ids: Vec<String> = beats.iter().map(|b| b.id.clone()).collect();
        let done: Vec<i64> = beats.iter().map(|b| b.done as i64).collect();
        let total: Vec<i64> = beats.iter().map(|b| b.total as i64).collect();
        let t: Vec<f64> = beats.iter().map(|b| b.t).collect();
        static BEAT: LazyLock<String> = LazyLock::new(|| {
            format!(
                "UPDATE jobs j SET lease_until = now() + make_interval(secs => $2),
                        done = u.done, total = u.total, t = u.t
                 FROM unnest($3::TEXT[], $4::BIGINT[], $5::BIGINT[], $6::FLOAT8[]) AS u(id, done, total, t)
                 WHERE j.id = u.id AND j.owner = $1 AND {}
                 RETURNING j.id, j.cancel_requested, j.pause_requested",
                is_sql("j.state", JobState::Running)
            )
        });
        self.with(move |c| async move {
            let rows = c
                .query(
                    &c.prepare_cached(&BEAT).await.map_err(pg)?,
                    &[&owner, &lease, &ids, &done, &total, &t],
                )
                .await
                .map_err(pg)?;
            let mut held = Vec::with_capacity(rows.len());
            for r in &rows {
                let id: String = r.try_get(0).map_err(pg)?;
                let cancel: bool = r.try_get(1).map_err(pg)?;
                let pause: bool = r.try_get(2).map_err(pg)?;
                held.push((id, cancel, pause));
            }
            Ok(ids
                .into_iter()
                .map(|id| {
                    let reply = match held.iter().find(|(h, _, _)| *h == id) {
                        Some((_, true, _)) => BeatReply::CancelRequested,
                        Some((_, false, true)) => BeatReply::PauseRequested,
                        Some((_, false, false)) => BeatReply::Held,
                        None => BeatReply::Lost,
                    };
                    (id, reply)
                })
                .collect())
        })
    }

    fn release(&self, id: &str) -> Result<(), StoreError> {
        let (id, owner) = (id.to_string(), self.replica.clone());
        self.with(move |c| async move {
            c.query(
                &c.prepare_cached(&format!(
                    "WITH released AS ({} RETURNING id)
                     SELECT pg_notify('{CHANNEL}', id) FROM released",
                    Transition::Release.update_sql(
                        "owner = NULL, lease_until = NULL, started_ms = 0",
                        "id = $1 AND owner = $2"
                    ),
                ))
                .await
                .map_err(pg)?,
                &[&id, &owner],
            )
            .await
            .map_err(pg)?;
            Ok(())
        })
    }

    fn request_cancel(&self, id: &str, finished_ms: u64) -> Result<CancelOutcome, StoreError> {
        let id = id.to_string();
        self.with(move |c| async move {
            if let Some(r) = c
                .query_opt(
                    &c.prepare_cached(&format!(
                        "{} RETURNING {JOB_COLUMNS}",
                        Transition::CancelQueued.update_sql("finished_ms = $2", "id = $1"),
                    ))
                    .await
                    .map_err(pg)?,
                    &[&id, &(finished_ms as i64)],
                )
                .await
                .map_err(pg)?
            {
                return Ok(CancelOutcome::Cancelled(view(&r)?));
            }
            Ok(if ask_running(&c, "cancel_requested", &id).await? {
                CancelOutcome::Requested
            } else {
                CancelOutcome::NotLive
            })
        })
    }

    fn enqueue(
        &self,
        row: &JobView,
        spec_json: &str,
        limit: usize,
    ) -> Result<Enqueued, StoreError> {
        let (id, name, spec) = (row.id.clone(), row.name.clone(), spec_json.to_string());
        let (state, created, total) = (row.state.as_str(), row.created_ms as i64, row.total as i64);
        let limit = limit as i64;
        static ENQUEUE: LazyLock<String> = LazyLock::new(|| {
            format!(
                "WITH queue AS (
                    SELECT COUNT(*) >= $7 AS at_limit FROM jobs WHERE {}),
                 ins AS (
                    INSERT INTO jobs (id, name, spec_json, state, created_ms, total)
                    SELECT $1, $2, $3, $4, $5, $6 FROM queue WHERE NOT queue.at_limit
                    ON CONFLICT (id) DO NOTHING RETURNING id),
                 told AS (SELECT pg_notify('{CHANNEL}', id) FROM ins)
                 SELECT queue.at_limit, (SELECT COUNT(*) FROM told) FROM queue",
                is_sql("state", JobState::Queued)
            )
        });
        self.with(move |c| async move {
            // Counted, inserted and announced in one statement: the notification goes at
            // commit.
            let r = c
                .query_one(
                    &c.prepare_cached(&ENQUEUE).await.map_err(pg)?,
                    &[&id, &name, &spec, &state, &created, &total, &limit],
                )
                .await
                .map_err(pg)?;
            let full: bool = r.try_get(0).map_err(pg)?;
            let inserted: i64 = r.try_get(1).map_err(pg)?;
            Ok(match (full, inserted) {
                (true, _) => Enqueued::Full,
                (false, 0) => Enqueued::Taken,
                _ => Enqueued::Queued,
            })
        })
    }

    fn queued(&self) -> Result<u64, StoreError> {
        self.with(move |c| async move {
            let r = c
                .query_one(
                    &c.prepare_cached(&format!(
                        "SELECT COUNT(*) FROM jobs WHERE {}",
                        is_sql("state", JobState::Queued)
                    ))
                    .await
                    .map_err(pg)?,
                    &[],
                )
                .await
                .map_err(pg)?;
            Ok(r.try_get::<_, i64>(0).map_err(pg)? as u64)
        })
    }

    fn ticket(&self) -> u64 {
        *self.ticket.n.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn wait(&self, seen: u64, timeout: Duration) {
        let n = self.ticket.n.lock().unwrap_or_else(|p| p.into_inner());
        let _ = self
            .ticket
            .changed
            .wait_timeout_while(n, timeout, |n| *n == seen);
    }

    fn wake(&self) {
        self.ticket.bump();
    }
}
