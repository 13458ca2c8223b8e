//! The job engine: accepts jobs (validated once, by `Job::from_spec`), keeps them in a bounded
//! queue, runs them on dedicated std threads (never on the async executor), and records their
//! status and results in the [`Store`].
//!
//! Cancellation is an `AtomicBool` the run's observer reads after every step, so a running job
//! stops within one step of the call. Progress (step, t, fraction) lives in atomics read by
//! `GetJob` and is published on the job's status key about every 200 ms.

use crate::config::Limits;
use crate::error::ApiError;
use crate::proto::v1::StepFrame;
use crate::store::{JobRow, JobState, Store, StoredResult};
use crate::stream::{StreamMsg, StreamSink};
use signorini_core::energy::{CUMULATIVE_COLUMNS, ENERGY_COLUMNS};
use signorini_core::job::{self, Job};
use signorini_core::observer::{Columns, Observer, Progress, StepRecord};
use signorini_core::outcome::RunError;
use signorini_core::spec::{JobSpec, SpecError};
use std::collections::{HashMap, VecDeque};
use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};
use tokio::sync::watch;

/// Milliseconds since the Unix epoch.
pub fn now_ms() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as u64)
}

fn now_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

/// What `GetJob` reports.
#[derive(Debug, Clone, PartialEq)]
pub struct JobView {
    /// Id.
    pub id: String,
    /// Label.
    pub name: Option<String>,
    /// State.
    pub state: JobState,
    /// Steps done.
    pub done: u64,
    /// Steps in all.
    pub total: u64,
    /// Time reached.
    pub t: f64,
    /// Error field and reason of a failed job.
    pub error: Option<(String, String)>,
    /// Acceptance time, ms.
    pub created_ms: u64,
    /// Start time, ms (0 before).
    pub started_ms: u64,
    /// End time, ms (0 before).
    pub finished_ms: u64,
}

impl JobView {
    /// Fraction done in [0, 1].
    pub fn fraction(&self) -> f64 {
        Progress {
            done: self.done,
            total: self.total,
            t: self.t,
        }
        .fraction()
    }

    fn from_row(r: &JobRow) -> JobView {
        JobView {
            id: r.id.clone(),
            name: r.name.clone(),
            state: r.state,
            done: r.done,
            total: r.total,
            t: r.t,
            error: r.error.clone(),
            created_ms: r.created_ms,
            started_ms: r.started_ms,
            finished_ms: r.finished_ms,
        }
    }
}

/// A queued or running job.
struct LiveJob {
    id: String,
    name: Option<String>,
    job: Job,
    created_ms: u64,
    cancel: AtomicBool,
    running: AtomicBool,
    started_ms: AtomicU64,
    done: AtomicU64,
    total: AtomicU64,
    t_bits: AtomicU64,
    ended: watch::Sender<bool>,
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
}

/// Service counters for `/metrics`.
#[derive(Debug, Default)]
pub struct Counters {
    /// Steps computed by all workers.
    pub steps_total: AtomicU64,
}

struct Inner {
    store: Store,
    limits: Limits,
    queue_limit: usize,
    queue: Mutex<VecDeque<Arc<LiveJob>>>,
    wake: Condvar,
    live: Mutex<HashMap<String, Arc<LiveJob>>>,
    sink: StreamSink,
    shutdown: AtomicBool,
    counters: Counters,
    workers: usize,
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

/// Checks a client-chosen id: 1–64 of `[A-Za-z0-9_-]` (safe in a zenoh key and a URL).
pub fn check_id(id: &str) -> Result<(), ApiError> {
    if id.is_empty()
        || id.len() > 64
        || !id
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-')
    {
        return Err(ApiError::Invalid(SpecError::new(
            "id",
            "1 to 64 characters among A-Z a-z 0-9 _ -",
        )));
    }
    Ok(())
}

fn new_id() -> String {
    use std::hash::{BuildHasher, Hasher};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u64(now_ns());
    h.write_u64(COUNTER.fetch_add(1, Ordering::Relaxed));
    format!("j{:011x}{:08x}", now_ms(), h.finish() as u32)
}

/// Checks a job against the server's limits; the error names the field to change.
fn check_limits(job: &Job, limits: &Limits) -> Result<(), SpecError> {
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

impl Engine {
    /// Opens the engine on `store`: re-queues the jobs a previous process left unfinished and
    /// starts `workers` threads.
    pub fn start(
        store: Store,
        limits: Limits,
        queue_limit: usize,
        workers: usize,
        sink: StreamSink,
    ) -> Result<Engine, ApiError> {
        let recovered = store.recover()?;
        let inner = Arc::new(Inner {
            store,
            limits,
            queue_limit,
            queue: Mutex::new(VecDeque::new()),
            wake: Condvar::new(),
            live: Mutex::new(HashMap::new()),
            sink,
            shutdown: AtomicBool::new(false),
            counters: Counters::default(),
            workers,
        });
        for row in recovered {
            let built = crate::spec_file::parse(&row.spec_json, crate::spec_file::Format::Json)
                .and_then(|spec| Job::from_spec(&spec));
            match built {
                Ok(job) => {
                    tracing::info!(id = %row.id, "re-queued after restart");
                    let live = Arc::new(new_live(
                        row.id.clone(),
                        row.name.clone(),
                        job,
                        row.created_ms,
                    ));
                    lock(&inner.live).insert(row.id.clone(), live.clone());
                    lock(&inner.queue).push_back(live);
                }
                Err(e) => {
                    let mut r = row.clone();
                    r.state = JobState::Failed;
                    r.finished_ms = now_ms();
                    r.error = Some((
                        e.field,
                        format!("no longer valid after restart: {}", e.reason),
                    ));
                    inner.store.finish(&r, None)?;
                }
            }
        }
        let engine = Engine {
            inner,
            threads: Arc::new(Mutex::new(Vec::new())),
        };
        for k in 0..workers {
            let inner = engine.inner.clone();
            let handle = std::thread::Builder::new()
                .name(format!("signorini-worker-{k}"))
                .spawn(move || worker_loop(&inner))
                .map_err(|e| ApiError::Internal(format!("spawning worker: {e}")))?;
            lock(&engine.threads).push(handle);
        }
        Ok(engine)
    }

    /// Validates, checks limits and queues a job. Returns its id.
    pub fn submit(&self, spec: &JobSpec, id: Option<String>) -> Result<String, ApiError> {
        if self.inner.shutdown.load(Ordering::Acquire) {
            return Err(ApiError::Unavailable);
        }
        if let Some(id) = &id {
            check_id(id)?;
        }
        let job = Job::from_spec(spec)?;
        check_limits(&job, &self.inner.limits)?;
        let spec_json =
            serde_json::to_string(spec).map_err(|e| ApiError::Internal(e.to_string()))?;
        let id = id.unwrap_or_else(new_id);
        let created_ms = now_ms();
        let live = Arc::new(new_live(id.clone(), spec.name.clone(), job, created_ms));
        let total = live.total.load(Ordering::Relaxed);
        {
            let mut queue = lock(&self.inner.queue);
            if queue.len() >= self.inner.queue_limit {
                return Err(ApiError::QueueFull {
                    limit: self.inner.queue_limit,
                });
            }
            let row = JobRow {
                id: id.clone(),
                name: spec.name.clone(),
                spec_json,
                state: JobState::Queued,
                created_ms,
                started_ms: 0,
                finished_ms: 0,
                error: None,
                done: 0,
                total,
                t: 0.0,
            };
            if !self.inner.store.insert(&row)? {
                return Err(ApiError::AlreadyExists { id });
            }
            lock(&self.inner.live).insert(id.clone(), live.clone());
            // Queued before a worker can take the job (it takes jobs under this lock), so the
            // `queued` status cannot go out after `running`.
            self.inner
                .sink
                .send(StreamMsg::Status(crate::server::convert::status_to_proto(
                    &live.view(),
                )));
            queue.push_back(live.clone());
        }
        self.inner.wake.notify_one();
        Ok(id)
    }

    /// A job's status.
    pub fn status(&self, id: &str) -> Result<JobView, ApiError> {
        if let Some(live) = lock(&self.inner.live).get(id) {
            return Ok(live.view());
        }
        match self.inner.store.get(id)? {
            Some(row) => Ok(JobView::from_row(&row)),
            None => Err(ApiError::NotFound { id: id.into() }),
        }
    }

    /// The status if the job exists (for the zenoh status queryable).
    pub fn find(&self, id: &str) -> Option<JobView> {
        self.status(id).ok()
    }

    /// Every job, oldest first, with live progress.
    pub fn list(&self) -> Result<Vec<JobView>, ApiError> {
        let rows = self.inner.store.list()?;
        let live = lock(&self.inner.live);
        Ok(rows
            .iter()
            .map(|r| match live.get(&r.id) {
                Some(l) => l.view(),
                None => JobView::from_row(r),
            })
            .collect())
    }

    /// Cancels a job. A queued job ends at once; a running one stops at the end of its current
    /// step: await [`Engine::ended`] for that. Finished jobs are left as they are.
    pub fn cancel(&self, id: &str) -> Result<JobView, ApiError> {
        let live = lock(&self.inner.live).get(id).cloned();
        let Some(live) = live else {
            return self.status(id);
        };
        live.cancel.store(true, Ordering::Release);
        let was_queued = {
            let mut queue = lock(&self.inner.queue);
            let before = queue.len();
            queue.retain(|j| j.id != id);
            queue.len() != before
        };
        if was_queued {
            let mut row = live_row(&live, JobState::Cancelled);
            row.finished_ms = now_ms();
            self.inner.store.finish(&row, None)?;
            lock(&self.inner.live).remove(id);
            let view = JobView::from_row(&row);
            self.inner
                .sink
                .send(StreamMsg::Status(crate::server::convert::status_to_proto(
                    &view,
                )));
            self.inner.sink.send(StreamMsg::Closed(id.to_string()));
            live.ended.send_replace(true);
            return Ok(view);
        }
        Ok(live.view())
    }

    /// A receiver that turns `true` when a live job has ended (`None` if not live).
    pub fn ended(&self, id: &str) -> Option<watch::Receiver<bool>> {
        lock(&self.inner.live).get(id).map(|l| l.ended.subscribe())
    }

    /// The result of a succeeded job.
    pub fn result(&self, id: &str) -> Result<(JobView, StoredResult), ApiError> {
        let view = self.status(id)?;
        if view.state != JobState::Succeeded {
            return Err(ApiError::NoResult {
                id: id.into(),
                state: view.state.as_str(),
            });
        }
        let result = self
            .inner
            .store
            .result(id)?
            .ok_or_else(|| ApiError::Internal(format!("result of {id} missing")))?;
        Ok((view, result))
    }

    /// Jobs per state (from the store).
    pub fn counts(&self) -> Result<Vec<(JobState, u64)>, ApiError> {
        Ok(self.inner.store.counts()?)
    }

    /// Jobs waiting for a worker.
    pub fn queue_depth(&self) -> usize {
        lock(&self.inner.queue).len()
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
    pub fn stream_stats(&self) -> &crate::stream::StreamStats {
        self.inner.sink.stats()
    }

    /// Stops taking jobs, stops running ones (they stay `running` in the store and run again at
    /// the next start) and joins the worker threads. Blocking: call from a blocking context.
    pub fn shutdown(&self) {
        self.inner.shutdown.store(true, Ordering::Release);
        self.inner.wake.notify_all();
        let threads: Vec<_> = lock(&self.threads).drain(..).collect();
        for t in threads {
            let _ = t.join();
        }
    }
}

fn new_live(id: String, name: Option<String>, job: Job, created_ms: u64) -> LiveJob {
    let total = job.size().steps;
    LiveJob {
        id,
        name,
        job,
        created_ms,
        cancel: AtomicBool::new(false),
        running: AtomicBool::new(false),
        started_ms: AtomicU64::new(0),
        done: AtomicU64::new(0),
        total: AtomicU64::new(total),
        t_bits: AtomicU64::new(0),
        ended: watch::channel(false).0,
    }
}

fn live_row(live: &LiveJob, state: JobState) -> JobRow {
    let v = live.view();
    JobRow {
        id: v.id,
        name: v.name,
        spec_json: String::new(),
        state,
        created_ms: v.created_ms,
        started_ms: v.started_ms,
        finished_ms: 0,
        error: None,
        done: v.done,
        total: v.total,
        t: v.t,
    }
}

fn next_job(inner: &Inner) -> Option<Arc<LiveJob>> {
    let mut queue = lock(&inner.queue);
    loop {
        if inner.shutdown.load(Ordering::Acquire) {
            return None;
        }
        if let Some(j) = queue.pop_front() {
            return Some(j);
        }
        queue = inner.wake.wait(queue).unwrap_or_else(|p| p.into_inner());
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
    while let Some(live) = next_job(inner) {
        run_one(inner, &live);
    }
}

fn status_msg(view: &JobView) -> StreamMsg {
    StreamMsg::Status(crate::server::convert::status_to_proto(view))
}

fn run_one(inner: &Inner, live: &Arc<LiveJob>) {
    let started = now_ms();
    live.started_ms.store(started, Ordering::Relaxed);
    live.running.store(true, Ordering::Release);
    if let Err(e) = inner.store.set_running(&live.id, started) {
        tracing::error!(id = %live.id, "store: {e}");
    }
    inner.sink.send(status_msg(&live.view()));
    tracing::info!(id = %live.id, "running");

    let mut observer = ServiceObserver::new(inner, live);
    let clock = Instant::now();
    // A panic in the numerics (a bug) fails this job and keeps the worker and the server alive.
    let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        job::run(&live.job, threads_per_job(inner.workers), &mut observer)
    }))
    .map_err(|panic| panic_message(panic.as_ref()));
    let wall = clock.elapsed();
    // The last frames go out after the result is stored: whoever saw them can fetch it.
    let last_frames = observer.last_frames();
    observer.count_steps();

    let mut row = live_row(live, JobState::Succeeded);
    let mut result = None;
    match outcome {
        Ok(Ok(output)) => {
            result = Some(StoredResult {
                summary: output.summary.with_timing(wall).to_map(),
                columns: observer.columns.clone(),
                steps: std::mem::take(&mut observer.rec_steps),
                t: std::mem::take(&mut observer.rec_t),
                values: std::mem::take(&mut observer.rec_values),
                tables: output.tables,
                figures: signorini_figures::render(&output.charts),
            });
        }
        Ok(Err(RunError::Stopped { .. })) if !live.cancel.load(Ordering::Acquire) => {
            // Server shutdown: leave the job `running` in the store; the next start re-runs it.
            tracing::info!(id = %live.id, "interrupted by shutdown");
            return;
        }
        Ok(Err(RunError::Stopped { .. })) => row.state = JobState::Cancelled,
        Ok(Err(e)) => {
            row.state = JobState::Failed;
            row.error = Some(("run".into(), e.to_string()));
        }
        Err(panic) => {
            tracing::error!(id = %live.id, "the run panicked: {panic}");
            row.state = JobState::Failed;
            row.error = Some((
                "run".into(),
                format!("internal error (a bug: please report it with the spec): {panic}"),
            ));
        }
    }
    row.finished_ms = now_ms();
    if let Err(e) = inner.store.finish(&row, result.as_ref()) {
        tracing::error!(id = %live.id, "store: {e}");
        row.state = JobState::Failed;
        row.error = Some(("store".into(), e.to_string()));
    }
    lock(&inner.live).remove(&live.id);
    inner.sink.send(last_frames);
    tracing::info!(id = %live.id, state = row.state.as_str(), wall_s = wall.as_secs_f64(), "finished");
    inner.sink.send(status_msg(&JobView::from_row(&row)));
    inner.sink.send(StreamMsg::Closed(live.id.clone()));
    live.ended.send_replace(true);
}

/// Largest number of steps per frame.
const FRAME_STEPS: usize = 256;
/// Longest time a computed step waits for its frame to leave.
const FRAME_NS: u64 = 20_000_000;
/// Interval of progress status frames.
const STATUS_EVERY: Duration = Duration::from_millis(200);

/// Records steps for the store, batches them into zenoh frames, tracks progress, checks for
/// cancellation after every step.
struct ServiceObserver<'a> {
    inner: &'a Inner,
    live: &'a LiveJob,
    columns: Vec<String>,
    energy_idx: Vec<usize>,
    state_idx: Vec<usize>,
    rec_steps: Vec<u64>,
    rec_t: Vec<f64>,
    rec_values: Vec<f64>,
    batch_from: usize,
    batch_stamps: Vec<u64>,
    seq: u64,
    last_status: Instant,
    uncounted: u64,
}

impl<'a> ServiceObserver<'a> {
    fn new(inner: &'a Inner, live: &'a LiveJob) -> Self {
        Self {
            inner,
            live,
            columns: Vec::new(),
            energy_idx: Vec::new(),
            state_idx: Vec::new(),
            rec_steps: Vec::new(),
            rec_t: Vec::new(),
            rec_values: Vec::new(),
            batch_from: 0,
            batch_stamps: Vec::with_capacity(FRAME_STEPS),
            seq: 0,
            last_status: Instant::now(),
            uncounted: 0,
        }
    }

    fn frame(&self, idx: &[usize], last: bool) -> Option<StepFrame> {
        if idx.is_empty() {
            return None;
        }
        let n = self.columns.len();
        let rows = self.batch_from..self.rec_steps.len();
        let mut values = Vec::with_capacity(rows.len() * idx.len());
        for i in rows.clone() {
            let row = &self.rec_values[i * n..(i + 1) * n];
            values.extend(idx.iter().map(|&c| row[c]));
        }
        Some(StepFrame {
            id: self.live.id.clone(),
            seq: self.seq,
            columns: idx.iter().map(|&c| self.columns[c].clone()).collect(),
            step: self.rec_steps[rows.clone()].to_vec(),
            t: self.rec_t[rows].to_vec(),
            values,
            computed_unix_ns: self.batch_stamps.clone(),
            last,
        })
    }

    /// The pending steps as the run's last energy and state frames (to send with a blocking send).
    fn last_frames(&mut self) -> StreamMsg {
        StreamMsg::Steps {
            id: self.live.id.clone(),
            energy: self.frame(&self.energy_idx, true),
            state: self.frame(&self.state_idx, true),
        }
    }

    /// Offers the pending steps as one energy and one state frame (dropped if the stream lags).
    fn flush(&mut self) {
        if self.rec_steps.len() == self.batch_from {
            return;
        }
        let msg = StreamMsg::Steps {
            id: self.live.id.clone(),
            energy: self.frame(&self.energy_idx, false),
            state: self.frame(&self.state_idx, false),
        };
        self.inner.sink.offer(msg);
        self.seq += 1;
        self.batch_from = self.rec_steps.len();
        self.batch_stamps.clear();
    }

    fn count_steps(&mut self) {
        self.inner
            .counters
            .steps_total
            .fetch_add(self.uncounted, Ordering::Relaxed);
        self.uncounted = 0;
    }
}

impl Observer for ServiceObserver<'_> {
    fn start(&mut self, columns: &Columns) {
        self.columns = columns.names().to_vec();
        let energy: Vec<&str> = ENERGY_COLUMNS
            .iter()
            .chain(CUMULATIVE_COLUMNS.iter())
            .copied()
            .collect();
        for (i, c) in self.columns.iter().enumerate() {
            if energy.contains(&c.as_str()) {
                self.energy_idx.push(i)
            } else {
                self.state_idx.push(i)
            }
        }
    }

    fn observe(&mut self, record: &StepRecord<'_>) -> ControlFlow<()> {
        let stamp = now_ns();
        self.rec_steps.push(record.step);
        self.rec_t.push(record.t);
        self.rec_values.extend_from_slice(record.values);
        self.batch_stamps.push(stamp);
        let pending = self.rec_steps.len() - self.batch_from;
        if pending >= FRAME_STEPS || stamp.saturating_sub(self.batch_stamps[0]) >= FRAME_NS {
            self.flush();
        }
        ControlFlow::Continue(())
    }

    fn progress(&mut self, p: Progress) -> ControlFlow<()> {
        self.live.done.store(p.done, Ordering::Relaxed);
        self.live.total.store(p.total, Ordering::Relaxed);
        self.live.t_bits.store(p.t.to_bits(), Ordering::Relaxed);
        self.uncounted += 1;
        if self.uncounted.is_multiple_of(16) && self.last_status.elapsed() >= STATUS_EVERY {
            self.count_steps();
            self.last_status = Instant::now();
            self.inner.sink.offer(status_msg(&self.live.view()));
        }
        if self.live.cancel.load(Ordering::Relaxed) || self.inner.shutdown.load(Ordering::Relaxed) {
            return ControlFlow::Break(());
        }
        ControlFlow::Continue(())
    }
}
