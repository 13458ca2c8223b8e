//! The engine's [`Observer`] of a run: records every step for the store, batches them into
//! [`StepBatch`] events, tracks progress and checks for cancellation after every step.
//!
//! Recorded rows are held in the job's [`Recent`] buffer until they fill a chunk of the store
//! ([`crate::store::chunk_rows`], about 1 MiB) and are then appended to the store, with where
//! each batch sent over the wire begins and ends, so a run of any length holds at most one chunk
//! of its series in memory, a run that fails or is cancelled leaves the rows it recorded, and the
//! history of a job (stored chunks, then the buffer) replays exactly the batches that went live.

use super::events::{ColumnGroup, JobEvent, StepBatch, split_columns};
use super::ids::now_ns;
use super::memory::{Paused, RunMemory};
use super::stop::StopReason;
use super::{Inner, LiveJob, Recent, StoredCheckpoint, lock};
use crate::store::{ChunkMeta, StoreError, chunk_rows};
use signorini_core::checkpoint::Checkpoint;
use signorini_core::observer::{Columns, Observer, Progress, StepRecord};
use signorini_core::spec::CheckpointPeriod;
use std::ops::ControlFlow;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

/// Largest number of steps per batch.
const FRAME_STEPS: usize = 256;
/// Longest time a computed step waits for its batch to leave.
const FRAME_NS: u64 = 20_000_000;
/// Interval of progress statuses.
const STATUS_EVERY: Duration = Duration::from_millis(200);

/// Records steps, sends them in batches, reports progress, stops on cancel or shutdown.
pub(super) struct ServiceObserver<'a> {
    inner: &'a Inner,
    live: &'a LiveJob,
    /// Rows per stored chunk.
    chunk_rows: usize,
    /// Why storing a chunk failed (the run is stopped).
    store_error: Option<StoreError>,
    energy_idx: Vec<usize>,
    state_idx: Vec<usize>,
    /// First row of the batch being filled, in the recent rows.
    batch_from: usize,
    batch_stamps: Vec<u64>,
    seq: u64,
    last_status: Instant,
    uncounted: u64,
    /// Checkpoints of a time integration (none for an analysis).
    checkpoints: Option<Checkpoints>,
    /// A resumed run: the last chunk of the series stored before, whose last batch number the
    /// next batch follows (read once the columns are known).
    resumed_after: Option<ChunkMeta>,
    /// The checkpoint written after the run's last step, kept back to be stored with the
    /// job's end in one store call (with the rows recorded since the last stored chunk):
    /// (attempt, step, bytes).
    final_state: Option<StoredCheckpoint>,
    /// Why this observer stopped the run, recorded when it broke it (`None` while it runs, and
    /// after a store failure, which [`ServiceObserver::end_parts`] reports).
    stopped: Option<StopReason>,
    /// When this run (this attempt) started: the server's `max_wall_seconds` counts from here.
    started: Instant,
    /// The bytes the run held when it went past the server's `max_memory_mb`.
    memory_held: u64,
}

/// When and as which attempt a run checkpoints.
struct Checkpoints {
    period: CheckpointPeriod,
    last: Instant,
    /// The run's attempt number (0 for the first run, one more per resume).
    attempt: u64,
    /// A checkpoint was written after the server began to shut down, or after a pause was
    /// asked (which of the two): the run stops before its next record or progress.
    final_written: Option<StopReason>,
    /// The checkpoint due is the one after the run's last step.
    at_end: bool,
}

/// The columns `idx` of `rows` (row-major, `n` columns) from row `from` on.
fn group(recent: &Recent, idx: &[usize], from: usize) -> ColumnGroup {
    let n = recent.columns.len();
    let rows = &recent.rows;
    let mut values = Vec::with_capacity((rows.steps.len() - from) * idx.len());
    for row in rows.values[from * n..].chunks_exact(n.max(1)) {
        values.extend(idx.iter().map(|&c| row[c]));
    }
    ColumnGroup {
        columns: idx.iter().map(|&c| recent.columns[c].clone()).collect(),
        values,
    }
}

impl<'a> ServiceObserver<'a> {
    pub(super) fn new(inner: &'a Inner, live: &'a LiveJob) -> Self {
        let period = live.job.spec().output.checkpoint_period();
        let checkpoints = match period {
            Ok(period) if live.job.checkpoints() => Some(Checkpoints {
                period,
                last: Instant::now(),
                attempt: 0,
                final_written: None,
                at_end: false,
            }),
            _ => None,
        };
        Self {
            inner,
            live,
            chunk_rows: chunk_rows(0),
            store_error: None,
            energy_idx: Vec::new(),
            state_idx: Vec::new(),
            batch_from: 0,
            batch_stamps: Vec::with_capacity(FRAME_STEPS),
            seq: 0,
            last_status: Instant::now(),
            uncounted: 0,
            checkpoints,
            resumed_after: None,
            final_state: None,
            stopped: None,
            started: Instant::now(),
            memory_held: 0,
        }
    }

    /// Continues a run resumed by its `attempt`-th attempt, whose series was stored up to its
    /// checkpoint, ending with chunk `last_chunk`: the next batch is numbered after the last
    /// one stored.
    pub(super) fn resumed(mut self, attempt: u64, last_chunk: Option<ChunkMeta>) -> Self {
        if let Some(c) = &mut self.checkpoints {
            c.attempt = attempt;
        }
        self.resumed_after = last_chunk;
        self
    }

    /// The pending steps as one batch, its rows recorded in the history as batch `seq`.
    fn batch(&self, recent: &mut Recent, last: bool) -> JobEvent {
        let rows = self.batch_from..recent.rows.steps.len();
        let start = recent.first_row + rows.start as u64;
        let end = recent.first_row + rows.end as u64;
        if end > start {
            recent.rows.batches.push((self.seq, start, end));
        }
        JobEvent::Steps(StepBatch {
            id: self.live.id.clone(),
            seq: self.seq,
            step: recent.rows.steps[rows.clone()].to_vec(),
            t: recent.rows.t[rows].to_vec(),
            computed_unix_ns: self.batch_stamps.clone(),
            energy: group(recent, &self.energy_idx, self.batch_from),
            state: group(recent, &self.state_idx, self.batch_from),
            last,
        })
    }

    /// The pending steps as the run's last batch (to send with a blocking send).
    pub(super) fn last_batch(&mut self) -> JobEvent {
        let mut recent = lock(&self.live.recent);
        let batch = self.batch(&mut recent, true);
        self.batch_from = recent.rows.steps.len();
        batch
    }

    /// Offers the pending steps as one batch (dropped if the stream lags).
    fn flush(&mut self, recent: &mut Recent) {
        if recent.rows.steps.len() == self.batch_from {
            return;
        }
        self.inner.sink.offer(self.batch(recent, false));
        self.seq += 1;
        self.batch_from = recent.rows.steps.len();
        self.batch_stamps.clear();
    }

    /// Adds the steps done since the last call to the service's counter.
    pub(super) fn count_steps(&mut self) {
        self.inner
            .counters
            .steps_total
            .fetch_add(self.uncounted, Ordering::Relaxed);
        self.uncounted = 0;
    }

    /// Appends the recorded rows not yet stored (all in sent batches) as the series' next
    /// chunk. Under the buffer's lock, so a reader of the history sees each row once.
    fn store_chunk(&mut self, recent: &mut Recent) -> Result<(), StoreError> {
        if recent.rows.steps.is_empty() {
            return Ok(());
        }
        super::noted(
            self.inner,
            self.inner.store.append_chunk(
                &self.live.id,
                recent.chunks,
                recent.first_row,
                &recent.rows,
            ),
        )?;
        recent.stored();
        self.batch_from = 0;
        Ok(())
    }

    /// Why the run stops after the checkpoint it has just written: a shutdown began or a pause
    /// was asked before it.
    fn after_checkpoint(&self) -> Option<StopReason> {
        self.checkpoints.as_ref().and_then(|c| c.final_written)
    }

    /// A pause asked, or else the server shutting down: what makes a run stop at its next
    /// checkpoint (at once, for a run that writes none).
    fn stopping(&self) -> Option<StopReason> {
        match self.live.stop.asked() {
            Some(StopReason::Pause) => Some(StopReason::Pause),
            _ => self
                .inner
                .shutdown
                .load(Ordering::Relaxed)
                .then_some(StopReason::Shutdown),
        }
    }

    /// Stops the run for `reason`, or for a stronger one asked meanwhile (a cancel, a lost
    /// lease), and records which.
    fn stop(&mut self, reason: StopReason) -> ControlFlow<()> {
        let asked = self.live.stop.asked().filter(|&a| a > reason);
        self.stopped = Some(asked.unwrap_or(reason));
        ControlFlow::Break(())
    }

    /// Why this observer stopped the run (`None` if it did not, or for a store failure).
    pub(super) fn stop_reason(&self) -> Option<StopReason> {
        self.stopped
    }

    /// The bytes the run held when it was stopped for the server's `max_memory_mb`.
    pub(super) fn memory_held(&self) -> u64 {
        self.memory_held
    }

    /// What the job's end stores besides its status, once the run is over: the column names
    /// (empty for a run that recorded no series) and the checkpoint kept back after the last
    /// step; or why the series could not be stored. The rows not yet stored stay in the job's
    /// buffer, which the end stores.
    pub(super) fn end_parts(
        &mut self,
    ) -> Result<(Vec<String>, Option<StoredCheckpoint>), StoreError> {
        if let Some(e) = self.store_error.take() {
            return Err(e);
        }
        let columns = lock(&self.live.recent).columns.clone();
        Ok((columns, self.final_state.take()))
    }

    /// Stores the last recorded rows and returns the column names (empty for a run that
    /// recorded no series), or why the series could not be stored.
    pub(super) fn finish_series(&mut self) -> Result<Vec<String>, StoreError> {
        if let Some(e) = self.store_error.take() {
            return Err(e);
        }
        let mut recent = lock(&self.live.recent);
        self.store_chunk(&mut recent)?;
        Ok(recent.columns.clone())
    }
}

impl Observer for ServiceObserver<'_> {
    fn start(&mut self, columns: &Columns) {
        let _paused = Paused::new();
        let mut recent = lock(&self.live.recent);
        recent.columns = columns.names().to_vec();
        self.chunk_rows = chunk_rows(recent.columns.len());
        (self.energy_idx, self.state_idx) = split_columns(&recent.columns);
        if let Some(last) = self.resumed_after.take() {
            let stored = self
                .inner
                .store
                .read_chunk(&self.live.id, &last, recent.columns.len());
            match stored {
                Ok(chunk) => {
                    self.seq = chunk
                        .batches
                        .iter()
                        .map(|&(s, _, _)| s + 1)
                        .max()
                        .unwrap_or(0);
                }
                Err(e) => self.store_error = Some(e),
            }
        }
    }

    fn observe(&mut self, record: &StepRecord<'_>) -> ControlFlow<()> {
        let _paused = Paused::new();
        if let Some(reason) = self.after_checkpoint() {
            // Nothing after the last checkpoint is recorded: the run continues from it.
            return self.stop(reason);
        }
        let stamp = now_ns();
        let mut recent = lock(&self.live.recent);
        recent.rows.steps.push(record.step);
        recent.rows.t.push(record.t);
        recent.rows.values.extend_from_slice(record.values);
        self.batch_stamps.push(stamp);
        let pending = recent.rows.steps.len() - self.batch_from;
        if pending >= FRAME_STEPS || stamp.saturating_sub(self.batch_stamps[0]) >= FRAME_NS {
            self.flush(&mut recent);
        }
        if recent.rows.steps.len() >= self.chunk_rows {
            // The pending frame goes out first: a chunk holds whole batches.
            self.flush(&mut recent);
            if let Err(e) = self.store_chunk(&mut recent) {
                self.store_error = Some(e);
                return ControlFlow::Break(());
            }
        }
        ControlFlow::Continue(())
    }

    fn progress(&mut self, p: Progress) -> ControlFlow<()> {
        let _paused = Paused::new();
        if let Some(reason) = self.after_checkpoint() {
            // The progress stays at the checkpoint's step, where the run continues.
            return self.stop(reason);
        }
        self.live.done.store(p.done, Ordering::Relaxed);
        self.live.total.store(p.total, Ordering::Relaxed);
        self.live.t_bits.store(p.t.to_bits(), Ordering::Relaxed);
        self.uncounted += 1;
        if self.uncounted.is_multiple_of(16) && self.last_status.elapsed() >= STATUS_EVERY {
            self.count_steps();
            self.last_status = Instant::now();
            self.inner.sink.offer(JobEvent::Status(self.live.view()));
        }
        if let Some(reason @ (StopReason::Cancel | StopReason::LeaseLost)) = self.live.stop.asked()
        {
            return self.stop(reason);
        }
        if self
            .inner
            .limits
            .max_wall
            .is_some_and(|max| self.started.elapsed() > max)
        {
            return self.stop(StopReason::WallLimit);
        }
        let held = RunMemory::held();
        if held > self.inner.limits.max_memory_bytes {
            self.memory_held = held;
            return self.stop(StopReason::MemoryLimit);
        }
        // At shutdown or at a pause, a run that checkpoints stops after its next checkpoint
        // (above); one that does not stops now.
        if self.checkpoints.is_none()
            && let Some(reason) = self.stopping()
        {
            return self.stop(reason);
        }
        if self.store_error.is_some() {
            return ControlFlow::Break(());
        }
        ControlFlow::Continue(())
    }

    fn checkpoint_due(&mut self, p: Progress) -> bool {
        let _paused = Paused::new();
        let stopping = self.stopping().is_some();
        let Some(c) = &mut self.checkpoints else {
            return false;
        };
        c.at_end = p.done == p.total;
        stopping
            // After the last step: the final state a succeeded job keeps (for `extend`).
            || p.done == p.total
            || c.period.steps.is_some_and(|n| p.done.is_multiple_of(n))
            || (p.done.is_multiple_of(16) && c.last.elapsed().as_secs_f64() >= c.period.seconds)
    }

    /// Stores the rows recorded so far (sending the pending batch first), then the checkpoint
    /// that counts them: a resumed run finds its series exactly up to its checkpoint.
    ///
    /// The checkpoint after the last step (unless a shutdown or a pause asked for it) is kept
    /// back instead: the job's end stores it with the last rows, in the same store call.
    fn checkpoint(&mut self, checkpoint: &mut Checkpoint) {
        let _paused = Paused::new();
        let stopping = self.stopping();
        if let Some(c) = &self.checkpoints
            && c.at_end
            && stopping.is_none()
        {
            match checkpoint.encode() {
                Ok(bytes) => self.final_state = Some((c.attempt, checkpoint.step(), bytes)),
                Err(e) => {
                    tracing::warn!(id = %self.live.id, step = checkpoint.step(), "checkpoint not saved: {e}")
                }
            }
            return;
        }
        let saved = {
            let mut recent = lock(&self.live.recent);
            self.flush(&mut recent);
            self.store_chunk(&mut recent)
        }
        .map_err(|e| e.to_string())
        .and_then(|()| checkpoint.encode().map_err(|e| e.to_string()))
        .and_then(|bytes| {
            let attempt = self.checkpoints.as_ref().map_or(0, |c| c.attempt);
            let saved =
                self.inner
                    .store
                    .save_checkpoint(&self.live.id, attempt, checkpoint.step(), &bytes);
            super::noted(self.inner, saved).map_err(|e| e.to_string())
        });
        match saved {
            Ok(()) => {
                if let Some(c) = &mut self.checkpoints {
                    c.last = Instant::now();
                    c.final_written = stopping;
                }
            }
            Err(e) => {
                tracing::warn!(id = %self.live.id, step = checkpoint.step(), "checkpoint not saved: {e}")
            }
        }
    }
}
