//! A job's status, the one domain shape of it: [`JobState`] and [`JobView`]. Each wire encodes
//! it once: protobuf `JobStatus` (gRPC and zenoh, [`crate::proto::encode`]), JSON
//! ([`crate::server::json::StatusJson`], every HTTP route and the CLI) and the store's SQL row.

use signorini_core::observer::Progress;

/// Lifecycle of a job.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum JobState {
    /// Waiting for a worker.
    Queued,
    /// On a worker.
    Running,
    /// Finished with a result.
    Succeeded,
    /// Stopped by an error (the error names the step or the field).
    Failed,
    /// Stopped by a cancel call.
    Cancelled,
    /// Parked by a pause call: not queued, not finished; its checkpoint (if it ran) and its
    /// series are kept, and a resume call queues it again to continue from that checkpoint.
    Paused,
}

impl JobState {
    /// Every state, in lifecycle order.
    pub const ALL: [JobState; 6] = [
        JobState::Queued,
        JobState::Running,
        JobState::Succeeded,
        JobState::Failed,
        JobState::Cancelled,
        JobState::Paused,
    ];

    /// The name used in HTTP bodies, the store and metrics.
    pub fn as_str(self) -> &'static str {
        match self {
            JobState::Queued => "queued",
            JobState::Running => "running",
            JobState::Succeeded => "succeeded",
            JobState::Failed => "failed",
            JobState::Cancelled => "cancelled",
            JobState::Paused => "paused",
        }
    }

    /// Parses [`JobState::as_str`].
    pub fn parse(s: &str) -> Option<JobState> {
        JobState::ALL.into_iter().find(|x| x.as_str() == s)
    }

    /// True when the job will not change any more.
    pub fn is_terminal(self) -> bool {
        crate::lifecycle::ENDED.contains(&self)
    }
}

/// Where a job comes from, as `GetJob` reports it besides its status: the study it is a run of,
/// and the succeeded job it continues.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Lineage {
    /// The study (parent job) the job is a run of.
    pub parent: Option<String>,
    /// The succeeded job the job continues (an extension).
    pub extends: Option<String>,
}

/// A job's status: what `GetJob` reports, what the store keeps besides the spec, and what a
/// status event carries.
#[derive(Debug, Clone, PartialEq)]
pub struct JobView {
    /// Id.
    pub id: String,
    /// Optional label from the spec.
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
    /// Acceptance time (ms since the epoch).
    pub created_ms: u64,
    /// Start time of the last attempt (0 if never started).
    pub started_ms: u64,
    /// End time (0 while unfinished).
    pub finished_ms: u64,
}

impl JobView {
    /// The error's field and reason as the store's two nullable columns.
    pub fn error_parts(&self) -> (Option<&str>, Option<&str>) {
        match &self.error {
            Some((f, r)) => (Some(f.as_str()), Some(r.as_str())),
            None => (None, None),
        }
    }

    /// Fraction done in [0, 1].
    pub fn fraction(&self) -> f64 {
        Progress {
            done: self.done,
            total: self.total,
            t: self.t,
        }
        .fraction()
    }
}
