//! Where jobs wait for a worker, behind one interface ([`Queue`]) with two implementations,
//! chosen once when the engine starts ([`for_store`]):
//!
//! * [`LocalQueue`]: this process's own queue (the SQLite store, one replica): the jobs wait in
//!   memory, live from their submission, and the store records them;
//! * [`SharedQueue`](crate::store::SharedQueue) through [`StoreQueue`]: the store's queue
//!   (PostgreSQL), shared by every replica: a job is one row, a worker of any replica claims it
//!   under a lease that this replica's heartbeat renews, and the end of a job carries the claim
//!   of the worker's next one in the same round trip (docs/scale_out.md).
//!
//! The engine asks the queue and never which one it is: submissions, studies, extensions and
//! resumes are queued through it, workers take their jobs from it and store their ends through
//! it, and a cancel of a job this process does not hold goes to it.

use super::events::JobEvent;
use super::ids::now_ms;
use super::stop::StopReason;
use super::{Inner, LiveJob, adopt, failed_spec, lock, new_live};
use crate::engine::EngineError;
use crate::spec_file::{Format, parse};
use crate::status::JobView;
use crate::store::{
    Beat, BeatReply, CancelOutcome, Claim, Enqueued, JobEnd, SharedQueue, Store, StoreError,
};
use signorini_core::job::Job;
use std::collections::VecDeque;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Longest wait of an idle worker between two claims on a shared store (a notification of a
/// new job wakes it sooner; a lease that ran out is only found this way).
pub const CLAIM_POLL: Duration = Duration::from_millis(250);

/// What the engine does with its queue. Blocking calls, made from worker threads and from the
/// servers' blocking contexts.
pub(super) trait Queue: Send + Sync {
    /// Queues a new job with its spec (JSON) and announces it: `QueueFull` when the queue holds
    /// its limit, `AlreadyExists` when the id is taken (nothing stored then).
    fn submit(&self, inner: &Inner, live: Arc<LiveJob>, spec_json: &str)
    -> Result<(), EngineError>;

    /// Queues `jobs` together once `store` has recorded them (a study's runs, an extension),
    /// unless they would take the queue past its limit (`QueueFull`, and `store` is not
    /// called); announces each.
    fn enqueue(
        &self,
        inner: &Inner,
        jobs: &[Arc<LiveJob>],
        store: &mut dyn FnMut() -> Result<(), EngineError>,
    ) -> Result<(), EngineError>;

    /// Queues again a job the store has just unparked (`view`, with its spec): its status.
    fn resumed(
        &self,
        inner: &Inner,
        view: JobView,
        spec_json: &str,
    ) -> Result<JobView, EngineError>;

    /// Jobs waiting for a worker (of any replica).
    fn depth(&self) -> Result<usize, StoreError>;

    /// Takes a live job off the queue before a worker took it (cancel, pause): true if it was
    /// waiting here.
    fn withdraw(&self, id: &str) -> bool;

    /// The next job for a worker, waiting for one; `None` once the engine shuts down.
    fn next(&self, inner: &Inner) -> Option<Arc<LiveJob>>;

    /// Stores a job's end ([`crate::store::Backend::end`]) and, where the queue can, claims
    /// the worker's next job in the same round trip: the end's outcome and the claim's.
    fn end(
        &self,
        inner: &Inner,
        end: &JobEnd<'_>,
    ) -> (Result<(), StoreError>, Result<Option<Claim>, StoreError>);

    /// Gives a job this process holds back to the queue (the server shuts down): at once for a
    /// shared queue; the local queue's store keeps it `running` and the next start queues it.
    fn release(&self, id: &str) -> Result<(), StoreError>;

    /// Cancels a job this process does not hold: queued for another replica (cancelled now:
    /// its status), running on one (asked to stop at its next heartbeat: `None`), or unknown.
    fn cancel_elsewhere(&self, id: &str) -> Result<Option<JobView>, StoreError>;

    /// True when workers of other replicas take jobs from this queue too, so a job this
    /// process does not hold may be running elsewhere.
    fn others_run_jobs(&self) -> bool;

    /// Starts what keeps this process's claims alive (the heartbeat of a shared queue).
    fn spawn_upkeep(&self, inner: Arc<Inner>) -> std::io::Result<Option<JoinHandle<()>>>;

    /// Wakes every waiting worker (the engine shuts down).
    fn wake_all(&self);
}

/// The queue of an engine on `store`: the store's shared queue if it holds one, else a local
/// queue holding `recovered` (the jobs a previous process left unfinished, live already).
pub(super) fn for_store(store: &Store, recovered: Vec<Arc<LiveJob>>) -> Box<dyn Queue> {
    match store.shared_queue() {
        Some(shared) => {
            tracing::info!(
                replica = shared.replica(),
                lease_s = shared.lease().as_secs_f64(),
                "shared queue"
            );
            Box::new(StoreQueue { shared })
        }
        None => Box::new(LocalQueue {
            jobs: Mutex::new(recovered.into()),
            wake: Condvar::new(),
        }),
    }
}

/// The refusal of a job that would take the queue past its limit.
pub(super) fn full(inner: &Inner) -> EngineError {
    EngineError::QueueFull {
        limit: inner.queue_limit,
    }
}

/// This process's own queue: jobs wait in memory, live from their submission.
struct LocalQueue {
    jobs: Mutex<VecDeque<Arc<LiveJob>>>,
    wake: Condvar,
}

impl Queue for LocalQueue {
    fn submit(
        &self,
        inner: &Inner,
        live: Arc<LiveJob>,
        spec_json: &str,
    ) -> Result<(), EngineError> {
        let id = live.id.clone();
        self.enqueue(inner, std::slice::from_ref(&live), &mut || {
            if inner.store.insert(&live.view(), spec_json)? {
                Ok(())
            } else {
                Err(EngineError::AlreadyExists { id: id.clone() })
            }
        })
    }

    fn enqueue(
        &self,
        inner: &Inner,
        jobs: &[Arc<LiveJob>],
        store: &mut dyn FnMut() -> Result<(), EngineError>,
    ) -> Result<(), EngineError> {
        {
            let mut queue = lock(&self.jobs);
            if queue.len() + jobs.len() > inner.queue_limit {
                return Err(full(inner));
            }
            // Stored, live and announced before a worker can take them (workers take jobs
            // under this lock), so a `queued` status never goes out after `running`.
            store()?;
            let mut live = lock(&inner.live);
            for job in jobs {
                live.insert(job.id.clone(), job.clone());
                inner.sink.send(JobEvent::Status(job.view()));
                queue.push_back(job.clone());
            }
        }
        self.wake.notify_all();
        Ok(())
    }

    fn resumed(
        &self,
        inner: &Inner,
        view: JobView,
        spec_json: &str,
    ) -> Result<JobView, EngineError> {
        let id = view.id.clone();
        let job = match parse(spec_json, Format::Json).and_then(|spec| Job::from_spec(&spec)) {
            Ok(job) => job,
            Err(e) => {
                let failed = failed_spec(view, e, "no longer valid");
                inner.store.finish(&failed, None)?;
                inner.sink.send(JobEvent::Status(failed.clone()));
                inner.sink.send(JobEvent::Closed(id));
                return Ok(failed);
            }
        };
        let live = Arc::new(new_live(
            view.id.clone(),
            view.name.clone(),
            job,
            view.created_ms,
            true,
        ));
        live.done.store(view.done, Ordering::Relaxed);
        live.t_bits.store(view.t.to_bits(), Ordering::Relaxed);
        let status = live.view();
        {
            let mut queue = lock(&self.jobs);
            lock(&inner.live).insert(id, live.clone());
            inner.sink.send(JobEvent::Status(status.clone()));
            queue.push_back(live);
        }
        self.wake.notify_one();
        Ok(status)
    }

    fn depth(&self) -> Result<usize, StoreError> {
        Ok(lock(&self.jobs).len())
    }

    fn withdraw(&self, id: &str) -> bool {
        let mut queue = lock(&self.jobs);
        let before = queue.len();
        queue.retain(|j| j.id != id);
        queue.len() != before
    }

    fn next(&self, inner: &Inner) -> Option<Arc<LiveJob>> {
        let mut queue = lock(&self.jobs);
        loop {
            if inner.shutdown.load(Ordering::Acquire) {
                return None;
            }
            if let Some(j) = queue.pop_front() {
                return Some(j);
            }
            queue = self.wake.wait(queue).unwrap_or_else(|p| p.into_inner());
        }
    }

    fn end(
        &self,
        inner: &Inner,
        end: &JobEnd<'_>,
    ) -> (Result<(), StoreError>, Result<Option<Claim>, StoreError>) {
        (inner.store.end(end), Ok(None))
    }

    fn release(&self, _id: &str) -> Result<(), StoreError> {
        // The store keeps the job `running`; the next start of the server queues it again.
        Ok(())
    }

    fn cancel_elsewhere(&self, _id: &str) -> Result<Option<JobView>, StoreError> {
        // No other process runs this store's jobs.
        Ok(None)
    }

    fn others_run_jobs(&self) -> bool {
        false
    }

    fn spawn_upkeep(&self, _inner: Arc<Inner>) -> std::io::Result<Option<JoinHandle<()>>> {
        Ok(None)
    }

    fn wake_all(&self) {
        self.wake.notify_all();
    }
}

/// The store's queue, shared by every replica: a job lives on this replica only from its
/// claim to its end.
struct StoreQueue {
    shared: Arc<dyn SharedQueue>,
}

impl StoreQueue {
    /// Claims jobs until one builds here, or until the engine shuts down.
    fn claim(&self, inner: &Inner) -> Option<Arc<LiveJob>> {
        loop {
            if inner.shutdown.load(Ordering::Acquire) {
                return None;
            }
            let seen = self.shared.ticket();
            match self.shared.claim(now_ms()) {
                Ok(Some(claim)) => {
                    if let Some(live) = adopt(inner, claim) {
                        return Some(live);
                    }
                }
                Ok(None) => self.shared.wait(seen, CLAIM_POLL),
                Err(e) => {
                    tracing::error!("claiming a job: {e}");
                    std::thread::sleep(CLAIM_POLL);
                }
            }
        }
    }
}

impl Queue for StoreQueue {
    fn submit(
        &self,
        inner: &Inner,
        live: Arc<LiveJob>,
        spec_json: &str,
    ) -> Result<(), EngineError> {
        // The store queues it (and tells every replica) in one round trip; a worker of any
        // replica claims it.
        match self
            .shared
            .enqueue(&live.view(), spec_json, inner.queue_limit)?
        {
            Enqueued::Queued => {}
            Enqueued::Full => return Err(full(inner)),
            Enqueued::Taken => {
                return Err(EngineError::AlreadyExists {
                    id: live.id.clone(),
                });
            }
        }
        inner.sink.send(JobEvent::Status(live.view()));
        Ok(())
    }

    fn enqueue(
        &self,
        inner: &Inner,
        jobs: &[Arc<LiveJob>],
        store: &mut dyn FnMut() -> Result<(), EngineError>,
    ) -> Result<(), EngineError> {
        if self.shared.queued()? + jobs.len() as u64 > inner.queue_limit as u64 {
            return Err(full(inner));
        }
        // The store announces them to every replica.
        store()?;
        for job in jobs {
            inner.sink.send(JobEvent::Status(job.view()));
        }
        Ok(())
    }

    fn resumed(
        &self,
        inner: &Inner,
        view: JobView,
        _spec_json: &str,
    ) -> Result<JobView, EngineError> {
        // Any replica claims it (the store announced it).
        inner.sink.send(JobEvent::Status(view.clone()));
        Ok(view)
    }

    fn depth(&self) -> Result<usize, StoreError> {
        Ok(self.shared.queued()? as usize)
    }

    fn withdraw(&self, _id: &str) -> bool {
        // A job is live here only once claimed: the store's queue changes its row itself.
        false
    }

    fn next(&self, inner: &Inner) -> Option<Arc<LiveJob>> {
        self.claim(inner)
    }

    fn end(
        &self,
        inner: &Inner,
        end: &JobEnd<'_>,
    ) -> (Result<(), StoreError>, Result<Option<Claim>, StoreError>) {
        if inner.shutdown.load(Ordering::Acquire) {
            return (inner.store.end(end), Ok(None));
        }
        self.shared.end_and_claim(end, now_ms())
    }

    fn release(&self, id: &str) -> Result<(), StoreError> {
        self.shared.release(id)
    }

    fn cancel_elsewhere(&self, id: &str) -> Result<Option<JobView>, StoreError> {
        Ok(match self.shared.request_cancel(id, now_ms())? {
            CancelOutcome::Cancelled(view) => Some(view),
            CancelOutcome::Requested | CancelOutcome::NotLive => None,
        })
    }

    fn others_run_jobs(&self) -> bool {
        true
    }

    fn spawn_upkeep(&self, inner: Arc<Inner>) -> std::io::Result<Option<JoinHandle<()>>> {
        let shared = self.shared.clone();
        std::thread::Builder::new()
            .name("signorini-heartbeat".into())
            .spawn(move || heartbeat_loop(&inner, shared.as_ref()))
            .map(Some)
    }

    fn wake_all(&self) {
        self.shared.wake();
    }
}

/// Renews this replica's leases about four times per lease, with the progress of its running
/// jobs; stops a job whose cancel or pause was asked on another replica, or whose lease was
/// lost.
fn heartbeat_loop(inner: &Inner, q: &dyn SharedQueue) {
    let every = q.lease() / 4;
    let mut last = Instant::now();
    while !inner.shutdown.load(Ordering::Acquire) {
        std::thread::sleep(Duration::from_millis(20).min(every));
        if last.elapsed() < every {
            continue;
        }
        last = Instant::now();
        let running: Vec<Arc<LiveJob>> = lock(&inner.live)
            .values()
            .filter(|l| l.running.load(Ordering::Acquire))
            .cloned()
            .collect();
        let beats: Vec<Beat> = running
            .iter()
            .map(|l| Beat {
                id: l.id.clone(),
                done: l.done.load(Ordering::Relaxed),
                total: l.total.load(Ordering::Relaxed),
                t: f64::from_bits(l.t_bits.load(Ordering::Relaxed)),
            })
            .collect();
        match super::noted(inner, q.heartbeat(&beats)) {
            Ok(replies) => {
                for (id, reply) in replies {
                    let Some(live) = running.iter().find(|l| l.id == id) else {
                        continue;
                    };
                    match reply {
                        BeatReply::Held => {}
                        BeatReply::CancelRequested => live.stop.ask(StopReason::Cancel),
                        BeatReply::PauseRequested => live.stop.ask(StopReason::Pause),
                        BeatReply::Lost => live.stop.ask(StopReason::LeaseLost),
                    }
                }
            }
            Err(e) => tracing::error!("heartbeat: {e}"),
        }
    }
}
