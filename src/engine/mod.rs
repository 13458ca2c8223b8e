//! The job engine: accepts jobs (validated once, by `Job::from_spec`), keeps them in a bounded
//! queue, runs them on dedicated std threads (never on the async executor), and records their
//! status and results in the [`Store`]. It speaks no wire format: what happens to a job leaves as
//! [`JobEvent`]s, which the adapters (`crate::stream`, `crate::server`) encode.
//!
//! Jobs wait in a [`queue::Queue`]: this process's own (SQLite store) or, with a shared store
//! (PostgreSQL), the store's, from which workers claim jobs under a lease that a heartbeat
//! thread renews (with the progress of the jobs this replica runs, and the cancel requests made
//! on other replicas); idle workers wait for the store's notification of a new job or
//! [`CLAIM_POLL`], whichever comes first. The engine asks the queue, never which one it is.
//!
//! Cancellation is an `AtomicBool` the run's observer reads after every step, so a running job
//! stops within one step of the call. Progress (step, t, fraction) lives in atomics read by
//! `GetJob` and is sent as a status event about every 200 ms.

mod error;
pub mod events;
mod history;
pub mod ids;
pub(crate) mod memory;
mod observer;
mod pause;
mod queue;
mod stop;
mod study;

use crate::config::Limits;
use crate::output::finish_run;
use crate::status::{JobState, JobView, Lineage};
use crate::store::{ChunkMeta, Claim, JobEnd, SeriesChunk, Store, StoreError, StoredResult};
use events::{EventSink, JobEvent, StreamStats};
use ids::{new_id, now_ms};
use observer::ServiceObserver;
use signorini_core::job::{self, Job};
use signorini_core::outcome::RunError;
use signorini_core::spec::{JobSpec, SpecError};
use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::Instant;
use stop::{StopReason, StopRequest};
use tokio::sync::watch;

pub use error::EngineError;
pub use history::History;
pub use ids::check_id;
pub use queue::CLAIM_POLL;

/// The rows of a running job not yet in the store, and the batches they went out in: filled by
/// the job's observer, copied by readers of the job's history under the same lock (a chunk is
/// stored and cleared from here in one step, so a reader sees every row exactly once).
#[derive(Debug, Default)]
struct Recent {
    /// The run's columns (known once it starts).
    columns: Vec<String>,
    /// Chunks stored so far.
    chunks: u64,
    /// Index in the series of the first row held here (the rows stored so far).
    first_row: u64,
    /// The rows, with the batches (seq, start, end) sent from them.
    rows: SeriesChunk,
}

impl Recent {
    /// The rows held here are now the series' next stored chunk.
    fn stored(&mut self) {
        self.chunks += 1;
        self.first_row += self.rows.steps.len() as u64;
        self.rows.steps.clear();
        self.rows.t.clear();
        self.rows.values.clear();
        self.rows.batches.clear();
    }
}

/// A queued or running job.
struct LiveJob {
    id: String,
    name: Option<String>,
    job: Job,
    created_ms: u64,
    /// The stop asked of its run (cancel, pause, lost lease), read by its observer.
    stop: StopRequest,
    running: AtomicBool,
    started_ms: AtomicU64,
    done: AtomicU64,
    total: AtomicU64,
    t_bits: AtomicU64,
    ended: watch::Sender<bool>,
    recent: Mutex<Recent>,
    /// A study's child, or maybe one: its end updates the parent's progress. False only when
    /// the job is known to have no parent (a submission, an extension, a claim that says so),
    /// which spares ordinary jobs that store statement.
    study_child: bool,
    /// What the claim of a job from a shared queue already read of its stored past (so its
    /// run does not ask again); `None` for a job of this process's own queue.
    claimed: Option<Claimed>,
}

/// A checkpoint as the store keeps it: (attempt, step, bytes).
type StoredCheckpoint = (u64, u64, Vec<u8>);

/// What a claim read with the job ([`Claim::checkpoint`], [`Claim::extends`]).
#[derive(Debug)]
struct Claimed {
    /// The job's checkpoint, if any: (attempt, step, bytes). Without one, the claim dropped
    /// the rows of earlier attempts.
    checkpoint: Option<StoredCheckpoint>,
    /// The job it extends.
    extends: Option<String>,
}

impl LiveJob {
    fn view(&self) -> JobView {
        JobView {
            id: self.id.clone(),
            name: self.name.clone(),
            state: if self.running.load(Ordering::Acquire) {
                JobState::Running
            } else {
                JobState::Queued
            },
            done: self.done.load(Ordering::Relaxed),
            total: self.total.load(Ordering::Relaxed),
            t: f64::from_bits(self.t_bits.load(Ordering::Relaxed)),
            error: None,
            created_ms: self.created_ms,
            started_ms: self.started_ms.load(Ordering::Relaxed),
            finished_ms: 0,
        }
    }

    /// The status of the job as it ends now in `state`.
    fn ended_view(&self, state: JobState) -> JobView {
        JobView {
            state,
            finished_ms: now_ms(),
            ..self.view()
        }
    }
}

/// Service counters for `/metrics`.
#[derive(Debug, Default)]
pub struct Counters {
    /// Steps computed by all workers.
    pub steps_total: AtomicU64,
}

/// What the engine's handle and its worker threads share.
struct Inner {
    store: Store,
    limits: Limits,
    queue_limit: usize,
    /// Where jobs wait for a worker.
    queue: Box<dyn queue::Queue>,
    live: Mutex<HashMap<String, Arc<LiveJob>>>,
    sink: EventSink,
    shutdown: AtomicBool,
    counters: Counters,
    workers: usize,
    /// Results being streamed, with their number of readers: a purge waits until none is left
    /// (it answers [`EngineError::BeingRead`]), so no stream is cut mid-body.
    readers: Mutex<HashMap<String, usize>>,
    /// Ends of jobs the store refused (it was full or read-only): their status is answered
    /// from here, and they are stored when a probe finds the store writable again.
    unstored_ends: Mutex<HashMap<String, JobView>>,
}

/// A store write's outcome, noted in the store's health (a refusal for want of room or a
/// read-only store degrades it).
fn noted<T>(inner: &Inner, outcome: Result<T, StoreError>) -> Result<T, StoreError> {
    inner.store.health().noted(outcome)
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// The engine: cheap to clone, shared by the gRPC and HTTP handlers.
#[derive(Clone)]
pub struct Engine {
    inner: Arc<Inner>,
    threads: Arc<Mutex<Vec<JoinHandle<()>>>>,
}

/// Checks a job against the server's limits; the error names the field to change.
pub fn check_limits(job: &Job, limits: &Limits) -> Result<(), SpecError> {
    let size = job.size();
    if size.dofs > limits.max_dofs {
        return Err(SpecError::new(
            "model",
            format!(
                "{} degrees of freedom exceed this server's limit of {}",
                size.dofs, limits.max_dofs
            ),
        ));
    }
    if size.steps > limits.max_steps {
        return Err(SpecError::new(
            "time",
            format!(
                "{} steps exceed this server's limit of {}",
                size.steps, limits.max_steps
            ),
        ));
    }
    if size.output_bytes > limits.max_output_bytes {
        return Err(SpecError::new(
            "output.every",
            format!(
                "the recorded output (≈ {} MiB) exceeds this server's limit of {} MiB: record fewer steps",
                size.output_bytes >> 20,
                limits.max_output_bytes >> 20
            ),
        ));
    }
    Ok(())
}

/// Bytes per entry of an n×n table that a `lagrangian` model of n coordinates holds while it
/// is parsed, compiled and run: the spec's dense mass rows, M(q) (its expressions, its tape's
/// outputs and values), ∂F/∂q and ∂F/∂q̇ (2 entries: expressions, tape outputs, values), the
/// symmetry and Cholesky checks of M(q0) at validation, the run's iteration matrix and its
/// factors. Measured on an identity-mass model with a spring per coordinate and one contact
/// (tests/service_faults.rs): n = 1200 submitted to `serve`, 521 MB peak resident (362 B per
/// entry); n = 800 under `signorini run`, 197 MB (307 B per entry). Rounded up.
const LAGRANGIAN_BYTES_PER_ENTRY: u64 = 384;

/// The memory a `lagrangian` model of `n` coordinates will need, estimated before anything is
/// parsed further or compiled: it holds dense n×n tables ([`LAGRANGIAN_BYTES_PER_ENTRY`] bytes
/// per entry). Other models are bounded by the server's `max_dofs` and their banded or dense
/// storage, and are not estimated.
fn lagrangian_memory(n: usize) -> u64 {
    let n = n as u64;
    n.saturating_mul(n)
        .saturating_mul(LAGRANGIAN_BYTES_PER_ENTRY)
}

/// Refuses a job whose estimated memory ([`lagrangian_memory`]) exceeds the server's
/// `max_memory_mb`, naming the field and the limit.
fn check_memory(spec: &JobSpec, limits: &Limits) -> Result<(), SpecError> {
    match &spec.model {
        Some(signorini_core::spec::ModelSpec::Lagrangian(m)) => {
            check_coordinates(m.coordinates.len(), limits)
        }
        _ => Ok(()),
    }
}

/// What a JSON spec's outline says of its size: its model's scene and its number of
/// coordinates, read without building the spec (every other value is skipped as text).
#[derive(serde::Deserialize)]
struct Outline {
    model: Option<ModelOutline>,
}

#[derive(serde::Deserialize)]
struct ModelOutline {
    scene: Option<String>,
    coordinates: Option<Vec<serde::de::IgnoredAny>>,
}

/// [`Engine::precheck_json`] against `limits`.
fn precheck_json(text: &str, limits: &Limits) -> Result<(), EngineError> {
    let Ok(Outline {
        model:
            Some(ModelOutline {
                scene: Some(scene),
                coordinates: Some(coordinates),
            }),
    }) = serde_json::from_str::<Outline>(text)
    else {
        return Ok(());
    };
    if scene != "lagrangian" {
        return Ok(());
    }
    Ok(check_coordinates(coordinates.len(), limits)?)
}

/// Refuses a `lagrangian` model of `n` coordinates whose estimated memory exceeds the server's
/// `max_memory_mb`, naming the field and the limit.
fn check_coordinates(n: usize, limits: &Limits) -> Result<(), SpecError> {
    let need = lagrangian_memory(n);
    if need > limits.max_memory_bytes {
        return Err(SpecError::new(
            "model.coordinates",
            format!(
                "the model would need about {} MiB of memory (its dense n×n tables), more than this server's limit of {} MiB (max_memory_mb): use fewer coordinates",
                need >> 20,
                limits.max_memory_bytes >> 20
            ),
        ));
    }
    Ok(())
}

/// How often a submission waiting for its model's compilation looks at the clock and at a
/// shutdown.
const COMPILE_POLL: std::time::Duration = std::time::Duration::from_millis(50);

/// Longest job `name`, and longest key of a map in a spec (a parameter's name), in bytes.
pub const MAX_NAME_BYTES: usize = 256;
/// Longest other text of a spec (an expression, a coordinate's name), in bytes.
pub const MAX_TEXT_BYTES: usize = 16 << 10;

/// Checks every text of a spec (its JSON tree) against [`MAX_NAME_BYTES`] and
/// [`MAX_TEXT_BYTES`]; the error names the field (`name`, `model.potential`, …).
fn check_text(value: &serde_json::Value, path: &str) -> Result<(), SpecError> {
    use serde_json::Value;
    let join = |key: &str| {
        if path.is_empty() {
            key.to_string()
        } else {
            format!("{path}.{key}")
        }
    };
    match value {
        Value::String(text) => {
            let limit = if path == "name" {
                MAX_NAME_BYTES
            } else {
                MAX_TEXT_BYTES
            };
            if text.len() > limit {
                return Err(SpecError::new(
                    path,
                    format!(
                        "{} bytes of text, more than the {limit} this server takes",
                        text.len()
                    ),
                ));
            }
        }
        Value::Array(items) => {
            for (i, item) in items.iter().enumerate() {
                check_text(item, &format!("{path}[{i}]"))?;
            }
        }
        Value::Object(map) => {
            for (key, item) in map {
                if key.len() > MAX_NAME_BYTES {
                    return Err(SpecError::new(
                        path,
                        format!(
                            "a key of {} bytes, more than the {MAX_NAME_BYTES} this server takes",
                            key.len()
                        ),
                    ));
                }
                check_text(item, &join(key))?;
            }
        }
        Value::Null | Value::Bool(_) | Value::Number(_) => {}
    }
    Ok(())
}

/// Jobs in a page of the list when the client names no limit, and the most it may ask for.
pub const DEFAULT_PAGE: usize = 100;
/// The most jobs in one page (a larger `limit` is taken as this).
pub const MAX_PAGE: usize = 1000;

/// One page of the job list, newest first.
#[derive(Debug, Clone, PartialEq)]
pub struct JobPage {
    /// The jobs.
    pub jobs: Vec<JobView>,
    /// The token of the next page, when there are older jobs.
    pub next_page_token: Option<String>,
}

impl Engine {
    /// Opens the engine on `store`: re-queues the jobs a previous process left unfinished and
    /// starts `workers` threads.
    pub fn start(
        store: Store,
        limits: Limits,
        queue_limit: usize,
        workers: usize,
        sink: EventSink,
    ) -> Result<Engine, EngineError> {
        let mut recovered = Vec::new();
        for (view, spec_json) in store.recover()? {
            let built = crate::spec_file::parse(&spec_json, crate::spec_file::Format::Json)
                .and_then(|spec| Job::from_spec(&spec));
            match built {
                Ok(job) => {
                    tracing::info!(id = %view.id, "re-queued after restart");
                    recovered.push(Arc::new(new_live(
                        view.id.clone(),
                        view.name.clone(),
                        job,
                        view.created_ms,
                        true,
                    )));
                }
                Err(e) => {
                    store.finish(&failed_spec(view, e, "no longer valid after restart"), None)?;
                }
            }
        }
        let live = recovered
            .iter()
            .map(|l| (l.id.clone(), l.clone()))
            .collect();
        let inner = Arc::new(Inner {
            queue: queue::for_store(&store, recovered),
            store,
            limits,
            queue_limit,
            live: Mutex::new(live),
            sink,
            shutdown: AtomicBool::new(false),
            counters: Counters::default(),
            workers,
            readers: Mutex::new(HashMap::new()),
            unstored_ends: Mutex::new(HashMap::new()),
        });
        let engine = Engine {
            inner,
            threads: Arc::new(Mutex::new(Vec::new())),
        };
        let upkeep = engine
            .inner
            .queue
            .spawn_upkeep(engine.inner.clone())
            .map_err(|e| EngineError::Internal(format!("spawning the heartbeat: {e}")))?;
        lock(&engine.threads).extend(upkeep);
        for k in 0..workers {
            let inner = engine.inner.clone();
            let handle = std::thread::Builder::new()
                .name(format!("signorini-worker-{k}"))
                .spawn(move || worker_loop(&inner))
                .map_err(|e| EngineError::Internal(format!("spawning worker: {e}")))?;
            lock(&engine.threads).push(handle);
        }
        let sweeper = study::spawn_sweeper(&engine)?;
        lock(&engine.threads).push(sweeper);
        Ok(engine)
    }

    /// Validates, checks limits and queues a job. Returns its id.
    pub fn submit(&self, spec: &JobSpec, id: Option<String>) -> Result<String, EngineError> {
        if self.inner.shutdown.load(Ordering::Acquire) {
            return Err(EngineError::Unavailable);
        }
        if let Some(id) = &id {
            check_id(id)?;
        }
        self.writable()?;
        // Before any pass over the spec's tree: a model too large is refused at once.
        check_memory(spec, &self.inner.limits)?;
        let spec_value =
            serde_json::to_value(spec).map_err(|e| EngineError::Internal(e.to_string()))?;
        check_text(&spec_value, "")?;
        if spec.study.is_some() {
            return study::submit(self, spec, spec_value.to_string(), id);
        }
        let job = self.build(spec)?;
        check_limits(&job, &self.inner.limits)?;
        let spec_json = spec_value.to_string();
        let id = id.unwrap_or_else(new_id);
        let created_ms = now_ms();
        let live = Arc::new(new_live(
            id.clone(),
            spec.name.clone(),
            job,
            created_ms,
            false,
        ));
        self.inner
            .queue
            .submit(&self.inner, live, &spec_json)
            .map_err(|e| self.refusal(e))?;
        Ok(id)
    }

    /// Refuses a JSON spec whose `lagrangian` model has more coordinates than the server's
    /// `max_memory_mb` allows ([`lagrangian_memory`]), from its outline (the scene and the
    /// coordinates, every other value skipped as text) before the spec is parsed: building the
    /// spec of a dense n×n mass matrix costs memory and time of its own. A text whose outline
    /// does not read is left to the parser, which names what is wrong.
    pub fn precheck_json(&self, text: &str) -> Result<(), EngineError> {
        precheck_json(text, &self.inner.limits)
    }

    /// Builds a job from its spec (validation, and for a `lagrangian` model the compilation of
    /// its symbolic derivatives and tapes) on a thread of its own, waiting at most the server's
    /// `max_compile_seconds` and no longer than until the engine begins to shut down. A build
    /// past the limit is refused naming it; its thread finishes on its own (its memory bounded
    /// by [`check_memory`], done before) and its job is dropped.
    fn build(&self, spec: &JobSpec) -> Result<Job, EngineError> {
        use std::sync::mpsc::RecvTimeoutError;
        let (tx, rx) = std::sync::mpsc::sync_channel(1);
        let owned = spec.clone();
        std::thread::Builder::new()
            .name("signorini-compile".into())
            .spawn(move || {
                let _ = tx.send(Job::from_spec(&owned));
            })
            .map_err(|e| EngineError::Internal(format!("spawning the compiler: {e}")))?;
        let max = self.inner.limits.max_compile;
        let started = Instant::now();
        loop {
            match rx.recv_timeout(COMPILE_POLL) {
                Ok(built) => return Ok(built?),
                Err(RecvTimeoutError::Disconnected) => {
                    return Err(EngineError::Internal(
                        "compiling the model panicked (a bug: please report it with the spec)"
                            .into(),
                    ));
                }
                Err(RecvTimeoutError::Timeout) => {
                    if self.inner.shutdown.load(Ordering::Acquire) {
                        return Err(EngineError::Unavailable);
                    }
                    if started.elapsed() >= max {
                        return Err(EngineError::Invalid(SpecError::new(
                            "model",
                            format!(
                                "compiling the model took longer than this server's limit of {} s (max_compile_seconds): use fewer coordinates or simpler expressions",
                                max.as_secs_f64()
                            ),
                        )));
                    }
                }
            }
        }
    }

    /// Stops taking jobs and stops the running ones at their next step (they stay `running`
    /// in the store, as at [`Engine::shutdown`]), without waiting: a submission waiting for its
    /// model's compilation returns at once, so the listeners can close promptly.
    pub fn begin_shutdown(&self) {
        self.inner.shutdown.store(true, Ordering::Release);
        self.inner.queue.wake_all();
    }

    /// Why the store does not take writes now (`/healthz`'s degraded reason), if it does not.
    pub fn store_refusal(&self) -> Option<String> {
        self.inner.store.health().refused()
    }

    /// Probes a degraded store (blocking: it writes one chunk) and, when it writes again, stores
    /// the job ends it refused meanwhile. `None` when the store takes writes, else why not.
    pub fn probe_store(&self) -> Option<String> {
        // Healthy: nothing to probe.
        self.store_refusal()?;
        if let Some(reason) = self.inner.store.probe() {
            return Some(reason);
        }
        tracing::info!("the store takes writes again");
        let ends: Vec<JobView> = lock(&self.inner.unstored_ends).values().cloned().collect();
        for view in ends {
            match noted(&self.inner, self.inner.store.finish(&view, None)) {
                Ok(()) => {
                    lock(&self.inner.unstored_ends).remove(&view.id);
                }
                Err(e) => {
                    tracing::error!(id = %view.id, "store: {e}");
                    return self.store_refusal();
                }
            }
        }
        None
    }

    /// Refuses new work while the store does not take writes: a degraded store is probed first,
    /// and takes the job if it writes again.
    fn writable(&self) -> Result<(), EngineError> {
        match self.probe_store() {
            None => Ok(()),
            Some(reason) => Err(EngineError::StoreRefused { reason }),
        }
    }

    /// A store error that refuses writes as [`EngineError::StoreRefused`] (noted in the store's
    /// health); any other error as it is.
    fn refusal(&self, e: EngineError) -> EngineError {
        match e {
            EngineError::Store(e) if e.refuses_writes() => {
                let reason = e.to_string();
                let _ = noted::<()>(&self.inner, Err(e));
                EngineError::StoreRefused { reason }
            }
            e => e,
        }
    }

    /// A job's status.
    pub fn status(&self, id: &str) -> Result<JobView, EngineError> {
        if let Some(live) = lock(&self.inner.live).get(id) {
            return Ok(live.view());
        }
        if let Some(end) = lock(&self.inner.unstored_ends).get(id) {
            return Ok(end.clone());
        }
        self.inner
            .store
            .get(id)?
            .ok_or_else(|| EngineError::NotFound { id: id.into() })
    }

    /// The study job `id` is a run of and the job it extends (`GetJob`'s `parent` and `extends`).
    pub fn lineage(&self, id: &str) -> Result<Lineage, EngineError> {
        Ok(self.inner.store.lineage(id)?)
    }

    /// True for a job this replica does not hold while its store's queue is shared: queued for
    /// any replica, or running on another one (its events go out there).
    pub fn runs_elsewhere(&self, id: &str) -> bool {
        self.inner.queue.others_run_jobs() && !lock(&self.inner.live).contains_key(id)
    }

    /// The status if the job exists (for the zenoh status queryable).
    pub fn find(&self, id: &str) -> Option<JobView> {
        self.status(id).ok()
    }

    /// One page of jobs, newest first, with live progress: at most `limit` (0: [`DEFAULT_PAGE`];
    /// more than [`MAX_PAGE`]: that many), only those in `state` if given, after the page whose
    /// `next_page_token` is `page_token` (empty: the first page).
    pub fn list(
        &self,
        state: Option<JobState>,
        page_token: &str,
        limit: usize,
    ) -> Result<JobPage, EngineError> {
        let before = if page_token.is_empty() {
            None
        } else {
            Some(
                page_token
                    .parse::<i64>()
                    .ok()
                    .filter(|&seq| seq > 0)
                    .ok_or_else(|| {
                        SpecError::new("page_token", "not a token this server gave out")
                    })?,
            )
        };
        let limit = match limit {
            0 => DEFAULT_PAGE,
            n => n.min(MAX_PAGE),
        };
        let mut rows = self.inner.store.list_page(state, before, limit + 1)?;
        let more = rows.len() > limit;
        rows.truncate(limit);
        let next_page_token = more
            .then(|| rows.last().map(|(seq, _)| seq.to_string()))
            .flatten();
        let live = lock(&self.inner.live);
        Ok(JobPage {
            // A live job's view has its latest progress; but a stored end is final (a job is
            // stored as ended a moment before it leaves the live jobs, and a page listed by
            // state must not show it as running then).
            jobs: rows
                .into_iter()
                .map(|(_, v)| match live.get(&v.id) {
                    Some(l) if !v.state.is_terminal() => l.view(),
                    _ => v,
                })
                .collect(),
            next_page_token,
        })
    }

    /// Removes the finished jobs that ended more than `retain` ago, with their results
    /// (blocking); the number removed.
    pub fn expire(&self, retain: std::time::Duration) -> Result<usize, EngineError> {
        let cutoff = now_ms().saturating_sub(retain.as_millis() as u64);
        let ids = self.inner.store.finished_before(cutoff)?;
        let mut removed = 0;
        for id in &ids {
            match self.delete(id) {
                Ok(()) => removed += 1,
                // Purged meanwhile by a client; or being read: removed at a later sweep.
                Err(EngineError::NotFound { .. } | EngineError::BeingRead { .. }) => {}
                Err(e) => return Err(e),
            }
        }
        Ok(removed)
    }

    /// Removes a finished job and its result from the store; a queued or running job must be
    /// cancelled first, and a result being streamed must be read to its end.
    pub fn delete(&self, id: &str) -> Result<(), EngineError> {
        if let Some(live) = lock(&self.inner.live).get(id) {
            return Err(EngineError::Unfinished {
                id: id.into(),
                state: live.view().state.as_str(),
            });
        }
        self.refuse_paused_delete(id)?;
        // A study's children go with it.
        self.delete_children(id)?;
        // Held over the removal: no reader opens the result in between.
        let readers = lock(&self.inner.readers);
        if let Some(&n) = readers.get(id) {
            return Err(EngineError::BeingRead {
                id: id.into(),
                readers: n,
            });
        }
        if !self.inner.store.delete(id)? {
            // A shared store keeps a job another replica still runs.
            return Err(match self.inner.store.get(id)? {
                Some(v) if !v.state.is_terminal() => EngineError::Unfinished {
                    id: id.into(),
                    state: v.state.as_str(),
                },
                _ => EngineError::NotFound { id: id.into() },
            });
        }
        tracing::info!(%id, "purged");
        Ok(())
    }

    /// Cancels a job. A queued job ends at once; a running one stops at the end of its current
    /// step: await [`Engine::ended`] for that. Finished jobs are left as they are.
    pub fn cancel(&self, id: &str) -> Result<JobView, EngineError> {
        let live = lock(&self.inner.live).get(id).cloned();
        let Some(live) = live else {
            if let Some(view) = self.cancel_study(id)? {
                return Ok(view);
            }
            if let Some(view) = self.cancel_paused(id)? {
                return Ok(view);
            }
            // Queued for another replica, or running on one (stopped at its next heartbeat).
            if let Some(view) = self.inner.queue.cancel_elsewhere(id)? {
                self.inner.sink.send(JobEvent::Status(view.clone()));
                self.inner.sink.send(JobEvent::Closed(id.to_string()));
                study::child_ended(&self.inner, id);
                return Ok(view);
            }
            return self.status(id);
        };
        live.stop.ask(StopReason::Cancel);
        let was_queued = self.inner.queue.withdraw(id);
        if was_queued {
            let view = live.ended_view(JobState::Cancelled);
            self.inner.store.finish(&view, None)?;
            lock(&self.inner.live).remove(id);
            self.inner.sink.send(JobEvent::Status(view.clone()));
            self.inner.sink.send(JobEvent::Closed(id.to_string()));
            live.ended.send_replace(true);
            if live.study_child {
                study::child_ended(&self.inner, id);
            }
            return Ok(view);
        }
        Ok(live.view())
    }

    /// A receiver that turns `true` when a live job has ended (`None` if not live).
    pub fn ended(&self, id: &str) -> Option<watch::Receiver<bool>> {
        lock(&self.inner.live).get(id).map(|l| l.ended.subscribe())
    }

    /// The result of a finished job without its series: a succeeded job's, or the partial one
    /// a failed or cancelled run left (`partial` set). The series is read with
    /// [`Engine::series`], chunk by chunk.
    pub fn result_head(&self, id: &str) -> Result<(JobView, StoredResult), EngineError> {
        let view = self.status(id)?;
        let no_result = || EngineError::NoResult {
            id: id.into(),
            state: view.state.as_str(),
        };
        if !view.state.is_terminal() {
            return Err(no_result());
        }
        match self.inner.store.result_head(id)? {
            Some(head) => Ok((view, head)),
            None if view.state == JobState::Succeeded => {
                Err(EngineError::Internal(format!("result of {id} missing")))
            }
            None => Err(no_result()),
        }
    }

    /// A finished job's result, as [`Engine::result_head`], with its stored series opened for
    /// reading: until the [`Series`] is dropped the job cannot be purged, so a stream of it is
    /// never cut by a concurrent `DELETE …?purge=true` or the retention sweep.
    pub fn open_result(&self, id: &str) -> Result<(JobView, StoredResult, Series), EngineError> {
        // Registered before the reads: a purge from here on waits for the drop.
        let mut series = self.reader(id);
        let (view, head) = self.result_head(id)?;
        series.columns = head.columns.len();
        series.chunks = self.inner.store.series_index(id)?;
        Ok((view, head, series))
    }

    /// An empty [`Series`] of job `id`, registered as a reader (only the count is taken under
    /// the lock; the store is read after it, outside).
    fn reader(&self, id: &str) -> Series {
        *lock(&self.inner.readers).entry(id.to_string()).or_default() += 1;
        Series {
            inner: self.inner.clone(),
            id: id.to_string(),
            columns: 0,
            chunks: Vec::new(),
        }
    }

    /// Jobs per state (from the store).
    pub fn counts(&self) -> Result<Vec<(JobState, u64)>, EngineError> {
        Ok(self.inner.store.counts()?)
    }

    /// Jobs waiting for a worker (of any replica, with a shared store).
    pub fn queue_depth(&self) -> Result<usize, EngineError> {
        Ok(self.inner.queue.depth()?)
    }

    /// Worker threads.
    pub fn workers(&self) -> usize {
        self.inner.workers
    }

    /// Steps computed since start.
    pub fn steps_total(&self) -> u64 {
        self.inner.counters.steps_total.load(Ordering::Relaxed)
    }

    /// Stream counters.
    pub fn stream_stats(&self) -> &StreamStats {
        self.inner.sink.stats()
    }

    /// Stops taking jobs, stops running ones (they stay `running` in the store and run again at
    /// the next start; a shared store gives them back to its queue at once) and joins the
    /// worker threads. Blocking: call from a blocking context.
    pub fn shutdown(&self) {
        self.inner.shutdown.store(true, Ordering::Release);
        self.inner.queue.wake_all();
        let threads: Vec<_> = lock(&self.threads).drain(..).collect();
        for t in threads {
            let _ = t.join();
        }
    }
}

/// A job's stored series: its chunk index, and its chunks read one at a time (blocking: call
/// from a blocking context). The job is not purged while it lives.
pub struct Series {
    inner: Arc<Inner>,
    id: String,
    columns: usize,
    chunks: Vec<ChunkMeta>,
}

impl Series {
    /// The chunks, in order.
    pub fn chunks(&self) -> &[ChunkMeta] {
        &self.chunks
    }

    /// Rows in all.
    pub fn rows(&self) -> u64 {
        self.chunks.last().map_or(0, |c| c.first_row + c.rows)
    }

    /// One chunk's rows.
    pub fn read(&self, meta: &ChunkMeta) -> Result<SeriesChunk, EngineError> {
        Ok(self.inner.store.read_chunk(&self.id, meta, self.columns)?)
    }
}

impl Drop for Series {
    fn drop(&mut self) {
        let mut readers = lock(&self.inner.readers);
        if let Some(n) = readers.get_mut(&self.id) {
            *n -= 1;
            if *n == 0 {
                readers.remove(&self.id);
            }
        }
    }
}

fn new_live(
    id: String,
    name: Option<String>,
    job: Job,
    created_ms: u64,
    study_child: bool,
) -> LiveJob {
    let total = job.size().steps;
    LiveJob {
        id,
        name,
        job,
        created_ms,
        stop: StopRequest::default(),
        running: AtomicBool::new(false),
        started_ms: AtomicU64::new(0),
        done: AtomicU64::new(0),
        total: AtomicU64::new(total),
        t_bits: AtomicU64::new(0),
        ended: watch::channel(false).0,
        recent: Mutex::new(Recent::default()),
        study_child,
        claimed: None,
    }
}

/// Threads a job may use for its parallel tasks (an analysis): the machine's cores shared among
/// the workers, 1 with the default of one worker per core, so the pool never runs more busy
/// threads than cores.
fn threads_per_job(workers: usize) -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    (cores / workers.max(1)).max(1)
}

/// The text of a panic payload (`panic!` with a message gives a `&str` or a `String`).
fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic without a message".into())
}

fn worker_loop(inner: &Inner) {
    // The job the queue claimed together with the end of the one before.
    let mut claimed: Option<Arc<LiveJob>> = None;
    loop {
        let next = match claimed.take() {
            Some(live) if inner.shutdown.load(Ordering::Acquire) => {
                // Not started: back to the queue, for any replica.
                if let Err(e) = inner.queue.release(&live.id) {
                    tracing::error!(id = %live.id, "store: {e}");
                }
                lock(&inner.live).remove(&live.id);
                None
            }
            Some(live) => Some(live),
            None => inner.queue.next(inner),
        };
        let Some(live) = next else {
            return;
        };
        claimed = run_one(inner, &live);
    }
}

/// A claimed job made live on this replica; `None` when its spec no longer builds (it is
/// failed, naming the field).
fn adopt(inner: &Inner, claim: Claim) -> Option<Arc<LiveJob>> {
    let Claim {
        view,
        spec_json,
        attempt,
        cancel_requested,
        study_child,
        checkpoint,
        extends,
    } = claim;
    let built = crate::spec_file::parse(&spec_json, crate::spec_file::Format::Json)
        .and_then(|spec| Job::from_spec(&spec));
    let job = match built {
        Ok(job) => job,
        Err(e) => {
            let failed = failed_spec(view, e, "not valid on this replica");
            if let Err(e) = inner.store.finish(&failed, None) {
                tracing::error!(id = %failed.id, "store: {e}");
            }
            inner.sink.send(JobEvent::Status(failed.clone()));
            if study_child {
                study::child_ended(inner, &failed.id);
            }
            inner.sink.send(JobEvent::Closed(failed.id));
            return None;
        }
    };
    tracing::info!(id = %view.id, attempt, "claimed");
    let live = Arc::new(LiveJob {
        claimed: Some(Claimed {
            checkpoint,
            extends,
        }),
        ..new_live(
            view.id.clone(),
            view.name.clone(),
            job,
            view.created_ms,
            study_child,
        )
    });
    if cancel_requested {
        live.stop.ask(StopReason::Cancel);
    }
    lock(&inner.live).insert(view.id.clone(), live.clone());
    Some(live)
}

/// Runs a job to its end; with a shared store, returns the next job, claimed with the end.
fn run_one(inner: &Inner, live: &Arc<LiveJob>) -> Option<Arc<LiveJob>> {
    let started = now_ms();
    live.started_ms.store(started, Ordering::Relaxed);
    live.running.store(true, Ordering::Release);
    if let Err(e) = noted(inner, inner.store.set_running(&live.id, started)) {
        return fail_for_store(inner, live, &e);
    }
    // A job run again after a restart continues from its last checkpoint, or else starts its
    // series afresh.
    let resume = resume_point(inner, live);
    // A claim that found no checkpoint has dropped the earlier attempts' rows itself.
    let cleared = live
        .claimed
        .as_ref()
        .is_some_and(|c| c.checkpoint.is_none());
    if resume.is_none()
        && !cleared
        && let Err(e) = noted(inner, inner.store.clear_series(&live.id))
    {
        return fail_for_store(inner, live, &e);
    }
    inner.sink.send(JobEvent::Status(live.view()));
    tracing::info!(id = %live.id, "running");

    let mut observer = ServiceObserver::new(inner, live);
    if let Some(r) = &resume {
        observer = observer.resumed(r.attempt, r.last_chunk);
    }
    let clock = Instant::now();
    // CPU seconds of this worker thread (a study's children report theirs as `cpu_s`).
    let cpu = cpu_time::ThreadTime::now();
    // What the run holds is counted while it runs, against `max_memory_mb`.
    let counted = memory::RunMemory::start();
    // A panic in the numerics (a bug) fails this job and keeps the worker and the server alive.
    let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        let threads = threads_per_job(inner.workers);
        let checkpoint = resume.as_ref().map(|r| &r.checkpoint);
        job::run_with_detectors(
            &live.job,
            threads,
            &mut observer,
            checkpoint,
            &signorini_collision::ParryDetectors,
        )
    }))
    .map_err(|panic| panic_message(panic.as_ref()));
    drop(counted);
    let wall = clock.elapsed();
    let cpu_s = cpu.elapsed().as_secs_f64();
    // The last batch goes out after the result is stored: whoever saw it can fetch the result.
    let last_batch = observer.last_batch();
    observer.count_steps();
    // The rows recorded since the last stored chunk, and the checkpoint after the last step,
    // are stored with the job's end, in one store call.
    let (columns, final_state) = match observer.end_parts() {
        Ok(parts) => parts,
        Err(e) => {
            tracing::error!(id = %live.id, "store: {e}");
            let view = JobView {
                error: Some(("store".into(), e.to_string())),
                ..live.ended_view(JobState::Failed)
            };
            return end_job(inner, live, view, Ending::bare(), Some(last_batch));
        }
    };
    // What a failed or cancelled run recorded is kept, marked partial.
    let partial = || {
        (!columns.is_empty()).then(|| StoredResult {
            partial: true,
            columns: columns.clone(),
            ..StoredResult::default()
        })
    };
    let (state, error, result) = match outcome {
        Ok(Ok(output)) => {
            let mut run = finish_run(output, wall);
            run.summary.insert("cpu_s".into(), cpu_s.into());
            pause::mark_extension(inner, live, &mut run.summary);
            let result = StoredResult {
                summary: run.summary,
                columns: columns.clone(),
                tables: run.tables,
                figures: run.figures,
                ..StoredResult::default()
            };
            (JobState::Succeeded, None, Some(result))
        }
        Ok(Err(RunError::Stopped { step })) => match observer.stop_reason() {
            Some(StopReason::Pause) => {
                store_rest(live, &mut observer);
                return pause::park(inner, live);
            }
            Some(StopReason::Shutdown) => {
                // Leave the job `running` in the store; the next start re-runs it (a shared
                // store's queue takes it back now, for any replica).
                store_rest(live, &mut observer);
                tracing::info!(id = %live.id, "interrupted by shutdown");
                if let Err(e) = inner.queue.release(&live.id) {
                    tracing::error!(id = %live.id, "store: {e}");
                }
                return None;
            }
            Some(StopReason::LeaseLost) => {
                // Another replica runs the job now: nothing of this run is stored.
                let lost = StoreError::LeaseLost {
                    id: live.id.clone(),
                };
                drop_lost(inner, live, &lost);
                return None;
            }
            Some(StopReason::Cancel) => (JobState::Cancelled, None, partial()),
            Some(limit @ (StopReason::WallLimit | StopReason::MemoryLimit)) => (
                JobState::Failed,
                Some(past_limit(inner, limit, step, observer.memory_held())),
                partial(),
            ),
            None => {
                let reason = format!(
                    "internal error (a bug: please report it with the spec): the run stopped at step {step} without being asked to"
                );
                (JobState::Failed, Some(("run".into(), reason)), partial())
            }
        },
        Ok(Err(e)) => (
            JobState::Failed,
            Some(("run".into(), e.to_string())),
            partial(),
        ),
        Err(panic) => {
            tracing::error!(id = %live.id, "the run panicked: {panic}");
            let reason = format!("internal error (a bug: please report it with the spec): {panic}");
            (JobState::Failed, Some(("run".into(), reason)), partial())
        }
    };
    tracing::info!(id = %live.id, wall_s = wall.as_secs_f64(), "run over");
    let view = JobView {
        error,
        ..live.ended_view(state)
    };
    let ending = Ending {
        result,
        rows: true,
        final_state,
    };
    end_job(inner, live, view, ending, Some(last_batch))
}

/// Why a run stopped at `step` for a limit of the server failed: the field to change, and the
/// limit named (`max_wall_seconds`; `max_memory_mb`, the run then holding `held` bytes).
fn past_limit(inner: &Inner, limit: StopReason, step: u64, held: u64) -> (String, String) {
    if limit == StopReason::MemoryLimit {
        let reason = format!(
            "the run held {} MiB of memory, more than this server's limit of {} MiB (max_memory_mb), stopped at step {step}: use a smaller model",
            held >> 20,
            inner.limits.max_memory_bytes >> 20
        );
        return ("model".into(), reason);
    }
    let max = inner.limits.max_wall.unwrap_or_default().as_secs_f64();
    let reason = format!(
        "the run took longer than this server's limit of {max} s of wall time (max_wall_seconds), stopped at step {step}: ask for fewer steps"
    );
    ("time".into(), reason)
}

/// Ends a job a store write outside its run failed for (marking it running, dropping an
/// earlier attempt's rows, parking it paused): failed, with the store's reason.
fn fail_for_store(inner: &Inner, live: &Arc<LiveJob>, e: &StoreError) -> Option<Arc<LiveJob>> {
    tracing::error!(id = %live.id, "store: {e}");
    let view = JobView {
        error: Some(("store".into(), e.to_string())),
        ..live.ended_view(JobState::Failed)
    };
    end_job(inner, live, view, Ending::bare(), None)
}

/// Stores the rows a stopped run recorded after its last stored chunk (a run that stops to be
/// continued: its series stays in the store).
fn store_rest(live: &LiveJob, observer: &mut ServiceObserver<'_>) {
    if let Err(e) = observer.finish_series() {
        tracing::error!(id = %live.id, "store: {e}");
    }
}

/// What a job's end stores besides its status.
struct Ending {
    /// Its result.
    result: Option<StoredResult>,
    /// Whether the rows recorded after the last stored chunk are stored (not after a store
    /// error, whose series stays as stored).
    rows: bool,
    /// The checkpoint the run wrote after its last step: (attempt, step, bytes).
    final_state: Option<StoredCheckpoint>,
}

impl Ending {
    /// An end with nothing but the status.
    fn bare() -> Ending {
        Ending {
            result: None,
            rows: false,
            final_state: None,
        }
    }
}

/// Where an interrupted job continues: its checkpoint, the attempt that continues it, and the
/// last chunk of its stored series (whose last batch the next live batch follows).
struct ResumePoint {
    checkpoint: signorini_core::checkpoint::Checkpoint,
    attempt: u64,
    last_chunk: Option<ChunkMeta>,
}

/// The checkpoint a job continues from, its stored series cut back to the rows the checkpoint
/// counts and the job's buffer set after them; `None` for a job without one. A checkpoint that
/// cannot be used (damaged, of another format or spec) is logged, dropped, and the job runs
/// again from step 0.
fn resume_point(inner: &Inner, live: &LiveJob) -> Option<ResumePoint> {
    let stored = match &live.claimed {
        Some(c) => Ok(c.checkpoint.clone()),
        None => inner.store.load_checkpoint(&live.id),
    };
    let (attempt, step, bytes) = match stored {
        Ok(Some(found)) => found,
        Ok(None) => return None,
        Err(e) => {
            tracing::error!(id = %live.id, "store: {e}");
            return None;
        }
    };
    let usable = live
        .job
        .read_checkpoint(&bytes)
        .map_err(|e| e.to_string())
        .and_then(|c| {
            inner
                .store
                .truncate_series(&live.id, c.records())
                .and_then(|()| inner.store.series_index(&live.id))
                .map(|index| (c, index))
                .map_err(|e| e.to_string())
        });
    let (checkpoint, index) = match usable {
        Ok(found) => found,
        Err(e) => {
            tracing::warn!(
                id = %live.id,
                step,
                "the checkpoint cannot be used ({e}): the job reruns from step 0"
            );
            if let Err(e) = inner.store.delete_checkpoint(&live.id) {
                tracing::error!(id = %live.id, "store: {e}");
            }
            return None;
        }
    };
    {
        let mut recent = lock(&live.recent);
        recent.chunks = index.last().map_or(0, |m| m.chunk + 1);
        recent.first_row = index.iter().map(|m| m.rows).sum();
    }
    live.done.store(checkpoint.step(), Ordering::Relaxed);
    tracing::info!(
        id = %live.id,
        step = checkpoint.step(),
        attempt = attempt + 1,
        "resuming from its checkpoint"
    );
    Some(ResumePoint {
        checkpoint,
        attempt: attempt + 1,
        last_chunk: index.last().copied(),
    })
}

/// Stores a job's end (its last rows, its result, its final state: one store call), then
/// tells the world: the last step batch (if the run made one), the final status, the end of
/// the job's events. An end the store refuses fails the job with the store's reason; if the
/// store refuses that too, the failure is kept in memory (its status answered from there) and
/// stored when the store writes again ([`Engine::probe_store`]). With a shared store (unless
/// shutting down), the worker's next job is claimed in the same round trip, and returned.
fn end_job(
    inner: &Inner,
    live: &Arc<LiveJob>,
    mut view: JobView,
    ending: Ending,
    last_batch: Option<JobEvent>,
) -> Option<Arc<LiveJob>> {
    // Under the buffer's lock, as a chunk is stored while a job runs: a reader of the history
    // sees each row once.
    let mut recent = lock(&live.recent);
    let rows = (ending.rows && !recent.rows.steps.is_empty()).then_some((
        recent.chunks,
        recent.first_row,
        &recent.rows,
    ));
    let end = JobEnd {
        view: &view,
        result: ending.result.as_ref(),
        rows,
        final_state: ending
            .final_state
            .as_ref()
            .map(|(attempt, step, bytes)| (*attempt, *step, bytes.as_slice())),
    };
    let (stored, claimed) = inner.queue.end(inner, &end);
    match noted(inner, stored) {
        Ok(()) => {
            if rows.is_some() {
                recent.stored();
            }
        }
        Err(e @ StoreError::LeaseLost { .. }) => {
            drop(recent);
            drop_lost(inner, live, &e);
            return take_claim(inner, claimed);
        }
        Err(e) => {
            tracing::error!(id = %live.id, "store: {e}");
            view.state = JobState::Failed;
            view.error = Some(("store".into(), e.to_string()));
            // The end as a failure, without what could not be stored; kept here until the
            // store takes it.
            if let Err(e) = noted(inner, inner.store.finish(&view, None)) {
                tracing::error!(id = %live.id, "store: {e}");
                lock(&inner.unstored_ends).insert(live.id.clone(), view.clone());
            }
            if let Err(e) = noted(inner, inner.store.delete_checkpoint(&live.id)) {
                tracing::error!(id = %live.id, "store: {e}");
            }
        }
    }
    drop(recent);
    lock(&inner.live).remove(&live.id);
    if let Some(batch) = last_batch {
        inner.sink.send(batch);
    }
    tracing::info!(id = %live.id, state = view.state.as_str(), "finished");
    inner.sink.send(JobEvent::Status(view));
    inner.sink.send(JobEvent::Closed(live.id.clone()));
    live.ended.send_replace(true);
    if live.study_child {
        study::child_ended(inner, &live.id);
    }
    take_claim(inner, claimed)
}

/// Job `view` failed now because its stored spec no longer builds into a job: the error names
/// the spec's field, its reason after `why` ("no longer valid after restart").
fn failed_spec(view: JobView, e: SpecError, why: &str) -> JobView {
    JobView {
        state: JobState::Failed,
        finished_ms: now_ms(),
        error: Some((e.field, format!("{why}: {}", e.reason))),
        ..view
    }
}

/// Lets go of a job another replica runs now (this one lost its lease): its end is that
/// replica's to tell, so only this replica's watchers are told that its events end here.
fn drop_lost(inner: &Inner, live: &LiveJob, lost: &StoreError) {
    tracing::warn!(id = %live.id, "{lost}");
    lock(&inner.live).remove(&live.id);
    inner.sink.send(JobEvent::Closed(live.id.clone()));
    live.ended.send_replace(true);
}

/// The job a claim made with a job's end took, made live (`None` when there was none).
fn take_claim(inner: &Inner, claimed: Result<Option<Claim>, StoreError>) -> Option<Arc<LiveJob>> {
    match claimed {
        Ok(Some(claim)) => adopt(inner, claim),
        Ok(None) => None,
        Err(e) => {
            tracing::error!("claiming a job: {e}");
            None
        }
    }
}
