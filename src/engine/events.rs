//! What the engine tells the world: [`JobEvent`]s, plain Rust data with no wire format in them,
//! sent through one FIFO channel to the adapter that publishes them (`crate::stream` encodes them
//! for zenoh and forwards them to gRPC `WatchJob` and SSE, which encode them for their clients).
//!
//! A job's events are queued in the order they are made. Step batches and progress statuses are
//! *offered*: when [`QUEUED_FRAMES`] offered events are already waiting, the new one is dropped
//! and counted in `signorini_frames_dropped_total`. Control events (a job's first and final
//! status, its last step batch, its end) are always queued; they are a handful per job. Nothing
//! the engine sends ever waits: this queue is where a slow or absent subscriber is absorbed, and a
//! job never waits on its subscribers.

use crate::status::JobView;
use signorini_core::energy::{CUMULATIVE_COLUMNS, ENERGY_COLUMNS};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use tokio::sync::mpsc;

/// An event of one job.
#[derive(Debug, Clone, PartialEq)]
pub enum JobEvent {
    /// The job's status changed or progressed.
    Status(JobView),
    /// Recorded steps; [`StepBatch::last`] marks the run's last batch.
    Steps(StepBatch),
    /// The job is over: nothing more comes for it.
    Closed(String),
}

impl JobEvent {
    /// The job the event is about.
    pub fn job_id(&self) -> &str {
        match self {
            JobEvent::Status(v) => &v.id,
            JobEvent::Steps(b) => &b.id,
            JobEvent::Closed(id) => id,
        }
    }
}

/// Consecutive recorded steps of one run, split into its energy columns and the rest.
#[derive(Debug, Clone, PartialEq)]
pub struct StepBatch {
    /// The job.
    pub id: String,
    /// Batch number within the run (0, 1, …; a dropped batch leaves a gap).
    pub seq: u64,
    /// Step numbers.
    pub step: Vec<u64>,
    /// Times.
    pub t: Vec<f64>,
    /// When each step was computed (ns since the Unix epoch).
    pub computed_unix_ns: Vec<u64>,
    /// Energy terms and works (`ENERGY_COLUMNS`, `CUMULATIVE_COLUMNS`).
    pub energy: ColumnGroup,
    /// Every other column (contacts, probes).
    pub state: ColumnGroup,
    /// True for the run's last batch (it may hold no step).
    pub last: bool,
}

/// Some columns of a [`StepBatch`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ColumnGroup {
    /// Column names.
    pub columns: Vec<String>,
    /// Values, row-major: `values[i * columns.len() + c]` is column `c` of step `i`.
    pub values: Vec<f64>,
}

/// The indices of the energy and work columns (`ENERGY_COLUMNS`, `CUMULATIVE_COLUMNS`, and
/// what a figure plots: a nonlinear family's potential, friction work and energy error, the
/// constraint residuals) of a run's `columns`, and of the others: how a batch is split into
/// [`StepBatch::energy`] and [`StepBatch::state`]. The live page draws the energy frames.
pub fn split_columns(columns: &[String]) -> (Vec<usize>, Vec<usize>) {
    let energy: Vec<&str> = ENERGY_COLUMNS
        .iter()
        .chain(CUMULATIVE_COLUMNS.iter())
        .chain(signorini_core::trace::ENERGY_COLUMNS.iter())
        .chain(signorini_core::trace::RESIDUAL_COLUMNS.iter())
        .chain(std::iter::once(&"work_friction"))
        .copied()
        .collect();
    (0..columns.len()).partition(|&i| energy.contains(&columns[i].as_str()))
}

/// An event in the channel, and whether it counts against [`QUEUED_FRAMES`].
struct Queued {
    event: JobEvent,
    offered: bool,
}

/// Offered events (step batches, progress statuses) waiting between the engine and the
/// publisher at most; each step batch carries up to a few hundred steps.
pub const QUEUED_FRAMES: usize = 4096;

/// Counters of the event stream.
#[derive(Debug, Default)]
pub struct StreamStats {
    /// Frames put on zenoh (counted by the publisher).
    pub frames_published: AtomicU64,
    /// Offered events dropped because the channel was full.
    pub frames_dropped: AtomicU64,
}

/// The sending side, held by the engine.
#[derive(Clone)]
pub struct EventSink {
    tx: mpsc::UnboundedSender<Queued>,
    /// Offered events in the channel.
    offered: Arc<AtomicUsize>,
    stats: Arc<StreamStats>,
}

/// The receiving side, held by the publisher.
pub struct EventQueue {
    rx: mpsc::UnboundedReceiver<Queued>,
    offered: Arc<AtomicUsize>,
    stats: Arc<StreamStats>,
}

/// A sink and the queue it feeds.
pub fn channel() -> (EventSink, EventQueue) {
    let (tx, rx) = mpsc::unbounded_channel();
    let offered = Arc::new(AtomicUsize::new(0));
    let stats = Arc::new(StreamStats::default());
    let sink = EventSink {
        tx,
        offered: offered.clone(),
        stats: stats.clone(),
    };
    (sink, EventQueue { rx, offered, stats })
}

impl EventSink {
    /// Queues a step batch or a progress status if fewer than [`QUEUED_FRAMES`] offered events
    /// are waiting, else drops it (counted).
    pub fn offer(&self, event: JobEvent) {
        if self.offered.fetch_add(1, Ordering::AcqRel) >= QUEUED_FRAMES {
            self.offered.fetch_sub(1, Ordering::AcqRel);
            self.stats.frames_dropped.fetch_add(1, Ordering::Relaxed);
            return;
        }
        if self
            .tx
            .send(Queued {
                event,
                offered: true,
            })
            .is_err()
        {
            self.offered.fetch_sub(1, Ordering::AcqRel);
        }
    }

    /// Queues a control event (never dropped, never waits).
    pub fn send(&self, event: JobEvent) {
        // Err only when the publisher is gone (shutdown): nothing left to tell.
        let _ = self.tx.send(Queued {
            event,
            offered: false,
        });
    }

    /// Counters.
    pub fn stats(&self) -> &StreamStats {
        &self.stats
    }
}

impl EventQueue {
    /// The next event, in the order they were queued; `None` once every sink is gone.
    pub async fn recv(&mut self) -> Option<JobEvent> {
        let Queued { event, offered } = self.rx.recv().await?;
        if offered {
            self.offered.fetch_sub(1, Ordering::AcqRel);
        }
        Some(event)
    }

    /// Counters (shared with the sinks).
    pub fn stats(&self) -> Arc<StreamStats> {
        self.stats.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn status(id: &str) -> JobEvent {
        JobEvent::Status(JobView {
            id: id.into(),
            name: None,
            state: crate::status::JobState::Queued,
            done: 0,
            total: 0,
            t: 0.0,
            error: None,
            created_ms: 0,
            started_ms: 0,
            finished_ms: 0,
        })
    }

    /// With nobody reading (a publisher stuck on a stalled subscriber), offered events stop at
    /// [`QUEUED_FRAMES`] and the rest are dropped and counted, while control events are still
    /// queued at once and in order: nothing the engine sends waits.
    #[test]
    fn a_stuck_publisher_drops_offered_frames_and_never_blocks_control_messages() {
        let (sink, mut queue) = channel();
        for _ in 0..QUEUED_FRAMES + 904 {
            sink.offer(status("frame"));
        }
        assert_eq!(sink.offered.load(Ordering::Acquire), QUEUED_FRAMES);
        assert_eq!(sink.stats().frames_dropped.load(Ordering::Relaxed), 904);
        sink.send(status("final"));
        sink.send(JobEvent::Closed("final".into()));
        let mut got = Vec::new();
        while let Ok(q) = queue.rx.try_recv() {
            got.push(q);
        }
        assert_eq!(got.len(), QUEUED_FRAMES + 2);
        assert!(got[..QUEUED_FRAMES].iter().all(|q| q.offered));
        assert!(matches!(&got[QUEUED_FRAMES].event, JobEvent::Status(s) if s.id == "final"));
        assert!(matches!(&got[QUEUED_FRAMES + 1].event, JobEvent::Closed(id) if id == "final"));
        assert!(!got[QUEUED_FRAMES].offered && !got[QUEUED_FRAMES + 1].offered);
    }
}
