//! Why the engine refused a call or could not carry it out: [`EngineError`], typed with its
//! fields and free of any protocol. The adapters map it to their statuses, each in one place
//! (`crate::server::http`, `crate::server::grpc`), through [`crate::error::ApiError`].

use crate::store::StoreError;
use signorini_core::spec::SpecError;
use thiserror::Error;

/// Why an engine call failed.
#[derive(Debug, Error)]
pub enum EngineError {
    /// The spec (or a field of the call) is invalid: the field and why.
    #[error("invalid {}: {}", .0.field, .0.reason)]
    Invalid(SpecError),
    /// No job with this id.
    #[error("no job {id}")]
    NotFound {
        /// The id asked for.
        id: String,
    },
    /// A client-chosen id is already taken.
    #[error("job {id} already exists")]
    AlreadyExists {
        /// The id.
        id: String,
    },
    /// The queue holds `limit` jobs already.
    #[error("queue full ({limit} jobs waiting)")]
    QueueFull {
        /// The configured queue limit.
        limit: usize,
    },
    /// The job has no result (yet, or ever).
    #[error("job {id} is {state}: no result")]
    NoResult {
        /// The job.
        id: String,
        /// Its state.
        state: &'static str,
    },
    /// The job is queued, running or paused: it cannot be removed yet.
    #[error("job {id} is {state}: cancel it before removing it")]
    Unfinished {
        /// The job.
        id: String,
        /// Its state.
        state: &'static str,
    },
    /// The job is not in a state (or of a kind) that allows the call: pause, resume, extend.
    #[error("job {id} is {state}: {reason}")]
    WrongState {
        /// The job.
        id: String,
        /// Its state.
        state: &'static str,
        /// What the call needs, or why the job cannot do it.
        reason: String,
    },
    /// The job's result is being streamed: it cannot be removed until the readers are done.
    #[error("job {id}'s result is being read by {readers} client(s): remove it when they are done")]
    BeingRead {
        /// The job.
        id: String,
        /// Streams open on its result.
        readers: usize,
    },
    /// The engine is shutting down.
    #[error("shutting down")]
    Unavailable,
    /// The store does not take writes (it is full or read-only): new jobs are refused until a
    /// probe of it writes again.
    #[error("the store cannot take writes ({reason}): new jobs are refused until it can")]
    StoreRefused {
        /// The store's reason.
        reason: String,
    },
    /// The store failed.
    #[error("internal error: {0}")]
    Store(#[from] StoreError),
    /// Another internal failure (a thread that could not start, a value that could not be
    /// encoded): what failed.
    #[error("internal error: {0}")]
    Internal(String),
}

impl EngineError {
    /// The field of the call the error names: the spec's field, `id` for the job's
    /// identity or state, `queue`; empty for an internal failure.
    pub fn field(&self) -> String {
        match self {
            EngineError::Invalid(e) => e.field.clone(),
            EngineError::NotFound { .. }
            | EngineError::AlreadyExists { .. }
            | EngineError::NoResult { .. }
            | EngineError::Unfinished { .. }
            | EngineError::WrongState { .. }
            | EngineError::BeingRead { .. } => "id".into(),
            EngineError::QueueFull { .. } => "queue".into(),
            EngineError::StoreRefused { .. } => "store".into(),
            EngineError::Unavailable | EngineError::Store(_) | EngineError::Internal(_) => {
                String::new()
            }
        }
    }
}

impl From<SpecError> for EngineError {
    fn from(e: SpecError) -> Self {
        EngineError::Invalid(e)
    }
}
