//! The service's typed errors. Handlers map them to gRPC codes (`server::grpc`) and HTTP
//! statuses (`server::http`) at the edges; nothing below the edges knows either protocol.

use signorini_core::spec::SpecError;
use thiserror::Error;

/// Why a service call failed.
#[derive(Debug, Error)]
pub enum ApiError {
    /// The spec (or a request field) is invalid: the field and why.
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
    /// The job is queued or running: it cannot be removed yet.
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
    /// The job succeeded but made no figure of this name.
    #[error("job {id} has no figure {name:?}")]
    NoFigure {
        /// The job.
        id: String,
        /// The name asked for.
        name: String,
    },
    /// The request body could not be read: too large, or not UTF-8.
    #[error("request body: {reason}")]
    Body {
        /// Why.
        reason: String,
        /// True when it exceeded the size limit.
        too_large: bool,
    },
    /// No such route.
    #[error("no route {method} {path}")]
    NoRoute {
        /// HTTP method.
        method: String,
        /// Path asked for.
        path: String,
    },
    /// A reply would be larger than one message may be.
    #[error("{reason}")]
    TooLarge {
        /// Why, and what to do instead.
        reason: String,
    },
    /// The route exists, the method does not.
    #[error("{method} is not allowed on {path}")]
    MethodNotAllowed {
        /// HTTP method.
        method: String,
        /// Path asked for.
        path: String,
    },
    /// Missing or wrong bearer token on a mutating call.
    #[error("missing or invalid bearer token")]
    Unauthenticated,
    /// The server is shutting down.
    #[error("shutting down")]
    Unavailable,
    /// A store or internal failure.
    #[error("internal error: {0}")]
    Internal(String),
}

impl ApiError {
    /// The `{field, reason}` pair of the error body.
    pub fn field_reason(&self) -> (String, String) {
        match self {
            ApiError::Invalid(e) => (e.field.clone(), e.reason.clone()),
            ApiError::NotFound { .. }
            | ApiError::AlreadyExists { .. }
            | ApiError::NoResult { .. }
            | ApiError::Unfinished { .. }
            | ApiError::WrongState { .. }
            | ApiError::BeingRead { .. } => ("id".into(), self.to_string()),
            ApiError::NoFigure { .. } => ("figure".into(), self.to_string()),
            ApiError::Body { .. } => ("body".into(), self.to_string()),
            ApiError::NoRoute { .. } => ("path".into(), self.to_string()),
            ApiError::MethodNotAllowed { .. } => ("method".into(), self.to_string()),
            ApiError::Unauthenticated => ("authorization".into(), self.to_string()),
            ApiError::QueueFull { .. } => ("queue".into(), self.to_string()),
            ApiError::TooLarge { .. } => ("columns".into(), self.to_string()),
            ApiError::Unavailable | ApiError::Internal(_) => (String::new(), self.to_string()),
        }
    }
}

impl From<SpecError> for ApiError {
    fn from(e: SpecError) -> Self {
        ApiError::Invalid(e)
    }
}

impl From<crate::store::StoreError> for ApiError {
    fn from(e: crate::store::StoreError) -> Self {
        ApiError::Internal(e.to_string())
    }
}
