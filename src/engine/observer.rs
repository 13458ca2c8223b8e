//! The engine's [`Observer`] of a run: records every step for the store, batches them into
//! [`StepBatch`] events, tracks progress and checks for cancellation after every step.
//!
//! Recorded rows are held until they fill a chunk of the store ([`crate::store::chunk_rows`],
//! about 1 MiB) and then appended to the store, so a run of any length holds at most one chunk
//! of its series in memory, and a run that fails or is cancelled leaves the rows it recorded.

use super::events::{ColumnGroup, JobEvent, StepBatch};
use super::ids::now_ns;
use super::{Inner, LiveJob};
use crate::store::{SeriesChunk, StoreError, chunk_rows};
use signorini_core::energy::{CUMULATIVE_COLUMNS, ENERGY_COLUMNS};
use signorini_core::observer::{Columns, Observer, Progress, StepRecord};
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
    /// Column names (set by `start`).
    columns: Vec<String>,
    /// Recorded rows not yet in the store.
    rec: SeriesChunk,
    /// Rows per stored chunk.
    chunk_rows: usize,
    /// Chunks stored, and rows in them.
    chunks: u64,
    stored_rows: u64,
    /// Why storing a chunk failed (the run is stopped).
    store_error: Option<StoreError>,
    energy_idx: Vec<usize>,
    state_idx: Vec<usize>,
    batch_from: usize,
    batch_stamps: Vec<u64>,
    seq: u64,
    last_status: Instant,
    uncounted: u64,
}

impl<'a> ServiceObserver<'a> {
    pub(super) fn new(inner: &'a Inner, live: &'a LiveJob) -> Self {
        Self {
            inner,
            live,
            columns: Vec::new(),
            rec: SeriesChunk::default(),
            chunk_rows: chunk_rows(0),
            chunks: 0,
            stored_rows: 0,
            store_error: None,
            energy_idx: Vec::new(),
            state_idx: Vec::new(),
            batch_from: 0,
            batch_stamps: Vec::with_capacity(FRAME_STEPS),
            seq: 0,
            last_status: Instant::now(),
            uncounted: 0,
        }
    }

    /// The columns `idx` of the pending steps.
    fn group(&self, idx: &[usize]) -> ColumnGroup {
        let n = self.columns.len();
        let mut values = Vec::with_capacity((self.rec.steps.len() - self.batch_from) * idx.len());
        for row in self.rec.values[self.batch_from * n..].chunks_exact(n.max(1)) {
            values.extend(idx.iter().map(|&c| row[c]));
        }
        ColumnGroup {
            columns: idx.iter().map(|&c| self.columns[c].clone()).collect(),
            values,
        }
    }

    /// The pending steps as one batch.
    fn batch(&self, last: bool) -> JobEvent {
        let rows = self.batch_from..self.rec.steps.len();
        JobEvent::Steps(StepBatch {
            id: self.live.id.clone(),
            seq: self.seq,
            step: self.rec.steps[rows.clone()].to_vec(),
            t: self.rec.t[rows].to_vec(),
            computed_unix_ns: self.batch_stamps.clone(),
            energy: self.group(&self.energy_idx),
            state: self.group(&self.state_idx),
            last,
        })
    }

    /// The pending steps as the run's last batch (to send with a blocking send).
    pub(super) fn last_batch(&self) -> JobEvent {
        self.batch(true)
    }

    /// Offers the pending steps as one batch (dropped if the stream lags).
    fn flush(&mut self) {
        if self.rec.steps.len() == self.batch_from {
            return;
        }
        self.inner.sink.offer(self.batch(false));
        self.seq += 1;
        self.batch_from = self.rec.steps.len();
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

    /// Appends the recorded rows not yet stored as the series' next chunk.
    fn store_chunk(&mut self) -> Result<(), StoreError> {
        if self.rec.steps.is_empty() {
            return Ok(());
        }
        self.inner
            .store
            .append_chunk(&self.live.id, self.chunks, self.stored_rows, &self.rec)?;
        self.chunks += 1;
        self.stored_rows += self.rec.steps.len() as u64;
        self.rec.steps.clear();
        self.rec.t.clear();
        self.rec.values.clear();
        self.batch_from = 0;
        Ok(())
    }

    /// Stores the last recorded rows and returns the column names (empty for a run that
    /// recorded no series), or why the series could not be stored.
    pub(super) fn finish_series(&mut self) -> Result<Vec<String>, StoreError> {
        if let Some(e) = self.store_error.take() {
            return Err(e);
        }
        self.store_chunk()?;
        Ok(std::mem::take(&mut self.columns))
    }
}

impl Observer for ServiceObserver<'_> {
    fn start(&mut self, columns: &Columns) {
        self.columns = columns.names().to_vec();
        self.chunk_rows = chunk_rows(self.columns.len());
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
        self.rec.steps.push(record.step);
        self.rec.t.push(record.t);
        self.rec.values.extend_from_slice(record.values);
        self.batch_stamps.push(stamp);
        let pending = self.rec.steps.len() - self.batch_from;
        if pending >= FRAME_STEPS || stamp.saturating_sub(self.batch_stamps[0]) >= FRAME_NS {
            self.flush();
        }
        if self.rec.steps.len() >= self.chunk_rows {
            // The pending frame goes out first: frames are cut from the rows held here.
            self.flush();
            if let Err(e) = self.store_chunk() {
                self.store_error = Some(e);
                return ControlFlow::Break(());
            }
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
            self.inner.sink.offer(JobEvent::Status(self.live.view()));
        }
        if self.live.cancel.load(Ordering::Relaxed) || self.inner.shutdown.load(Ordering::Relaxed) {
            return ControlFlow::Break(());
        }
        ControlFlow::Continue(())
    }
}
