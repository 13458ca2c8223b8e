//! The service's typed errors at its edges: [`ApiError`], an engine error
//! ([`EngineError`]) or one of the request itself (a body, a route, a token). Handlers map them
//! to gRPC codes (`server::grpc`) and HTTP statuses (`server::http`), each in one place; nothing
//! below the edges knows either protocol.

use crate::engine::EngineError;
use signorini_core::spec::SpecError;
use thiserror::Error;

/// Why a service call failed.
#[derive(Debug, Error)]
pub enum ApiError {
    /// The engine refused the call or could not carry it out.
    #[error(transparent)]
    Engine(#[from] EngineError),
    /// A field of the request (a query parameter, a body field) is invalid: the field and why.
    #[error("invalid {}: {}", .0.field, .0.reason)]
    Invalid(SpecError),
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
    /// A known token whose scope does not allow the call (a read token on a mutating call).
    #[error("the token of {name} may only read: this call needs a write token")]
    Forbidden {
        /// The token's holder, as the tokens file names it.
        name: String,
    },
    /// An internal failure at the edge (a task that did not finish, a value that could not
    /// be encoded).
    #[error("internal error: {0}")]
    Internal(String),
}

impl ApiError {
    /// The `{field, reason}` pair of the error body.
    pub fn field_reason(&self) -> (String, String) {
        match self {
            ApiError::Engine(EngineError::Invalid(e)) | ApiError::Invalid(e) => {
                (e.field.clone(), e.reason.clone())
            }
            ApiError::Engine(e) => (e.field(), self.to_string()),
            ApiError::NoFigure { .. } => ("figure".into(), self.to_string()),
            ApiError::Body { .. } => ("body".into(), self.to_string()),
            ApiError::NoRoute { .. } => ("path".into(), self.to_string()),
            ApiError::MethodNotAllowed { .. } => ("method".into(), self.to_string()),
            ApiError::Unauthenticated | ApiError::Forbidden { .. } => {
                ("authorization".into(), self.to_string())
            }
            ApiError::TooLarge { .. } => ("columns".into(), self.to_string()),
            ApiError::Internal(_) => (String::new(), self.to_string()),
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
        ApiError::Engine(EngineError::Store(e))
    }
}
