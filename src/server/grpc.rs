//! gRPC API (`signorini.v1.Simulation`, tonic). Each method: validate → convert → dispatch to the
//! [`Engine`](crate::engine::Engine) → respond, encoding with [`crate::proto::encode`]; [`ApiError`]
//! becomes a `Status` here and nowhere else.

use super::AppState;
use super::convert;
use crate::engine::events::JobEvent;
use crate::error::ApiError;
use crate::proto::encode::{result_to_proto, status_to_proto, step_frames};
use crate::proto::v1 as pb;
use crate::proto::v1::simulation_server::Simulation;
use crate::spec_file::{self, Format};
use std::pin::Pin;
use tokio_stream::{Stream, StreamExt};
use tonic::{Code, Request, Response, Status};

/// The gRPC service.
pub struct SimulationService {
    state: AppState,
}

impl SimulationService {
    /// A service over the shared state.
    pub fn new(state: AppState) -> Self {
        Self { state }
    }

    fn authorize<T>(&self, req: &Request<T>) -> Result<(), Status> {
        let given = req
            .metadata()
            .get("authorization")
            .and_then(|v| v.to_str().ok());
        self.state.authorize(given).map_err(to_status)
    }
}

/// [`ApiError`] → gRPC status; the message is `field: reason`, the field also in metadata
/// `x-error-field`.
pub fn to_status(e: ApiError) -> Status {
    let code = match &e {
        ApiError::Invalid(_) => Code::InvalidArgument,
        ApiError::NotFound { .. } | ApiError::NoFigure { .. } | ApiError::NoRoute { .. } => {
            Code::NotFound
        }
        ApiError::Body {
            too_large: true, ..
        } => Code::ResourceExhausted,
        ApiError::Body { .. } => Code::InvalidArgument,
        ApiError::AlreadyExists { .. } => Code::AlreadyExists,
        ApiError::QueueFull { .. } => Code::ResourceExhausted,
        ApiError::NoResult { .. } => Code::FailedPrecondition,
        ApiError::Unauthenticated => Code::Unauthenticated,
        ApiError::Unavailable => Code::Unavailable,
        ApiError::Internal(_) => Code::Internal,
    };
    if code == Code::Internal {
        tracing::error!("{e}");
    }
    let (field, reason) = e.field_reason();
    let message = if field.is_empty() {
        reason
    } else {
        format!("{field}: {reason}")
    };
    let mut status = Status::new(code, message);
    if let Ok(v) = field.parse() {
        status.metadata_mut().insert("x-error-field", v);
    }
    status
}

/// An event as the frames of `WatchJob`: a status, or a step batch's energy and state frames.
fn watch_frames(event: &JobEvent) -> Vec<pb::WatchFrame> {
    use pb::watch_frame::Frame;
    let frames = match event {
        JobEvent::Status(v) => vec![Frame::Status(status_to_proto(v))],
        JobEvent::Steps(batch) => {
            let (energy, state) = step_frames(batch);
            energy
                .map(Frame::Energy)
                .into_iter()
                .chain(state.map(Frame::State))
                .collect()
        }
        JobEvent::Closed(_) => Vec::new(),
    };
    frames
        .into_iter()
        .map(|frame| pb::WatchFrame { frame: Some(frame) })
        .collect()
}

type FrameStream = Pin<Box<dyn Stream<Item = Result<pb::WatchFrame, Status>> + Send + 'static>>;

#[tonic::async_trait]
impl Simulation for SimulationService {
    async fn submit_job(
        &self,
        req: Request<pb::SubmitJobRequest>,
    ) -> Result<Response<pb::SubmitJobResponse>, Status> {
        self.authorize(&req)?;
        let pb::SubmitJobRequest { spec, id } = req.into_inner();
        // Parsing and validation (a factorisation of M and K) run off the async executor.
        let engine = self.state.engine.clone();
        let id = tokio::task::spawn_blocking(move || {
            let spec = match spec {
                Some(pb::submit_job_request::Spec::Typed(s)) => convert::job_spec(s),
                Some(pb::submit_job_request::Spec::Json(text)) => {
                    spec_file::parse(&text, Format::Json)
                }
                None => Err(signorini_core::spec::SpecError::new(
                    "spec",
                    "missing: give `typed` or `json`",
                )),
            }?;
            engine.submit(&spec, id)
        })
        .await
        .map_err(|e| Status::internal(e.to_string()))?
        .map_err(to_status)?;
        Ok(Response::new(pb::SubmitJobResponse { id }))
    }

    async fn get_job(
        &self,
        req: Request<pb::GetJobRequest>,
    ) -> Result<Response<pb::JobStatus>, Status> {
        let pb::GetJobRequest { id } = req.into_inner();
        let view = self.state.engine.status(&id).map_err(to_status)?;
        Ok(Response::new(status_to_proto(&view)))
    }

    async fn list_jobs(
        &self,
        req: Request<pb::ListJobsRequest>,
    ) -> Result<Response<pb::ListJobsResponse>, Status> {
        let pb::ListJobsRequest {} = req.into_inner();
        let jobs = self.state.engine.list().map_err(to_status)?;
        Ok(Response::new(pb::ListJobsResponse {
            jobs: jobs.iter().map(status_to_proto).collect(),
        }))
    }

    async fn cancel_job(
        &self,
        req: Request<pb::CancelJobRequest>,
    ) -> Result<Response<pb::JobStatus>, Status> {
        self.authorize(&req)?;
        let pb::CancelJobRequest { id } = req.into_inner();
        let view = self.state.cancel_and_wait(&id).await.map_err(to_status)?;
        Ok(Response::new(status_to_proto(&view)))
    }

    type WatchJobStream = FrameStream;

    async fn watch_job(
        &self,
        req: Request<pb::WatchJobRequest>,
    ) -> Result<Response<Self::WatchJobStream>, Status> {
        let pb::WatchJobRequest { id } = req.into_inner();
        let (current, frames) = self.state.follow(&id, watch_frames).map_err(to_status)?;
        let first = tokio_stream::iter([Ok(pb::WatchFrame {
            frame: Some(pb::watch_frame::Frame::Status(status_to_proto(&current))),
        })]);
        match frames {
            None => Ok(Response::new(Box::pin(first))),
            Some(frames) => Ok(Response::new(Box::pin(first.chain(frames.map(Ok))))),
        }
    }

    async fn get_result(
        &self,
        req: Request<pb::GetResultRequest>,
    ) -> Result<Response<pb::JobResult>, Status> {
        let pb::GetResultRequest { id, columns, every } = req.into_inner();
        let engine = self.state.engine.clone();
        let (view, result) = tokio::task::spawn_blocking(move || {
            let (view, result) = engine.result(&id)?;
            Ok::<_, ApiError>((view, result.select(&columns, every)?))
        })
        .await
        .map_err(|e| Status::internal(e.to_string()))?
        .map_err(to_status)?;
        Ok(Response::new(result_to_proto(&view, &result)))
    }

    async fn capabilities(
        &self,
        req: Request<pb::CapabilitiesRequest>,
    ) -> Result<Response<pb::CapabilitiesResponse>, Status> {
        let pb::CapabilitiesRequest {} = req.into_inner();
        Ok(Response::new(convert::capabilities_to_proto(
            &signorini_core::capabilities::capabilities(),
        )))
    }
}
