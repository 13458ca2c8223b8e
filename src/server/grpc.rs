//! gRPC API (`signorini.v1.Simulation`, tonic). Each method: validate → convert → dispatch to the
//! [`Engine`](crate::engine::Engine) → respond, encoding with [`crate::proto::encode`]; [`ApiError`]
//! becomes a `Status` here and nowhere else.

use super::AppState;
use super::convert;
use super::results::{Cut, CutRequest};
use crate::engine::EngineError;
use crate::engine::events::JobEvent;
use crate::error::ApiError;
use crate::proto::encode::{
    result_to_proto, state_from_proto, status_to_proto, step_frames, tables_to_proto,
};
use crate::proto::v1 as pb;
use crate::proto::v1::simulation_server::Simulation;
use crate::spec_file::{self, Format};
use crate::status::Lineage;
use crate::store::StoredResult;
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

    /// [`AppState::authorize_read`] for a read call.
    fn authorize_read<T>(&self, req: &Request<T>) -> Result<(), Status> {
        let given = req
            .metadata()
            .get("authorization")
            .and_then(|v| v.to_str().ok());
        self.state.authorize_read(given).map_err(to_status)
    }
}

/// [`EngineError`] → gRPC code: the one place the engine's errors meet gRPC.
fn engine_code(e: &EngineError) -> Code {
    match e {
        EngineError::Invalid(_) => Code::InvalidArgument,
        EngineError::NotFound { .. } => Code::NotFound,
        EngineError::AlreadyExists { .. } => Code::AlreadyExists,
        EngineError::QueueFull { .. } => Code::ResourceExhausted,
        EngineError::NoResult { .. }
        | EngineError::Unfinished { .. }
        | EngineError::BeingRead { .. }
        | EngineError::WrongState { .. } => Code::FailedPrecondition,
        EngineError::Unavailable | EngineError::StoreRefused { .. } => Code::Unavailable,
        EngineError::Store(_) | EngineError::Internal(_) => Code::Internal,
    }
}

/// [`ApiError`] → gRPC status; the message is `field: reason`, the field also in metadata
/// `x-error-field`.
pub fn to_status(e: impl Into<ApiError>) -> Status {
    let e = e.into();
    let code = match &e {
        ApiError::Engine(e) => engine_code(e),
        ApiError::Invalid(_) => Code::InvalidArgument,
        ApiError::NoFigure { .. } | ApiError::NoRoute { .. } => Code::NotFound,
        ApiError::MethodNotAllowed { .. } => Code::Unimplemented,
        ApiError::Body {
            too_large: true, ..
        } => Code::ResourceExhausted,
        ApiError::Body { .. } => Code::InvalidArgument,
        ApiError::TooLarge { .. } => Code::ResourceExhausted,
        ApiError::Unauthenticated => Code::Unauthenticated,
        ApiError::Forbidden { .. } => Code::PermissionDenied,
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

/// The largest series (8 bytes per value, `step` and `t` included) `GetResult` sends in its
/// one message; larger cuts go through `StreamResult`.
pub const UNARY_RESULT_BYTES: u64 = 64 << 20;

/// The request's cut.
fn cut_request(columns: Vec<String>, every: u64, from: Option<u64>, to: Option<u64>) -> CutRequest {
    CutRequest {
        columns,
        every,
        from,
        to,
    }
}

/// The messages of `StreamResult`, made on a blocking thread as the store is read and sent
/// through a channel of four: the header, the figures, the rows of each stored chunk.
fn stream_result(state: &AppState, id: String, req: CutRequest) -> ResultStream {
    use pb::result_chunk::Part;
    let (tx, rx) = tokio::sync::mpsc::channel(4);
    let engine = state.engine.clone();
    tokio::task::spawn_blocking(move || {
        let send = |part: Part| {
            tx.blocking_send(Ok(pb::ResultChunk { part: Some(part) }))
                .map_err(|_| std::io::Error::new(std::io::ErrorKind::BrokenPipe, "client gone"))
        };
        let opened =
            engine
                .open_result(&id)
                .map_err(ApiError::from)
                .and_then(|(view, head, series)| {
                    let cut = Cut::new(&head, &series, &req)?;
                    Ok((view, head, series, cut))
                });
        let (view, head, series, cut) = match opened {
            Ok(o) => o,
            Err(e) => {
                let _ = tx.blocking_send(Err(to_status(e)));
                return;
            }
        };
        let header = pb::ResultHeader {
            id: view.id.clone(),
            status: Some(status_to_proto(&view)),
            summary_json: serde_json::Value::Object(head.summary.clone()).to_string(),
            columns: cut.names.clone(),
            rows: cut.rows(),
            partial: head.partial,
            tables: tables_to_proto(&head.tables),
        };
        let sent = send(Part::Header(header))
            .and_then(|()| {
                head.figures.iter().try_for_each(|f| {
                    send(Part::Figure(pb::Figure {
                        name: f.name.clone(),
                        svg: f.svg.clone(),
                    }))
                })
            })
            .and_then(|()| {
                cut.for_each(&series, |rows| {
                    send(Part::Rows(pb::ResultRows {
                        first_row: rows.first_kept,
                        step: rows.steps.clone(),
                        t: rows.t.clone(),
                        values: rows.values.clone(),
                    }))
                })
            });
        if let Err(e) = sent
            && e.kind() != std::io::ErrorKind::BrokenPipe
        {
            let _ = tx.blocking_send(Err(Status::internal(e.to_string())));
        }
    });
    Box::pin(tokio_stream::wrappers::ReceiverStream::new(rx))
}

type ResultStream = Pin<Box<dyn Stream<Item = Result<pb::ResultChunk, Status>> + Send + 'static>>;

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
                    engine.precheck_json(&text)?;
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
        self.authorize_read(&req)?;
        let pb::GetJobRequest { id } = req.into_inner();
        let view = self.state.engine.status(&id).map_err(to_status)?;
        let Lineage { parent, extends } = self.state.engine.lineage(&id).map_err(to_status)?;
        Ok(Response::new(pb::JobStatus {
            parent,
            extends,
            ..status_to_proto(&view)
        }))
    }

    async fn list_jobs(
        &self,
        req: Request<pb::ListJobsRequest>,
    ) -> Result<Response<pb::ListJobsResponse>, Status> {
        self.authorize_read(&req)?;
        let pb::ListJobsRequest {
            limit,
            page_token,
            state,
        } = req.into_inner();
        let state = match (state, state_from_proto(state)) {
            (0, _) => None,
            (_, Some(s)) => Some(s),
            (n, None) => {
                return Err(to_status(ApiError::Invalid(
                    signorini_core::spec::SpecError::new("state", format!("unknown state {n}")),
                )));
            }
        };
        let page = self
            .state
            .engine
            .list(state, &page_token, limit as usize)
            .map_err(to_status)?;
        Ok(Response::new(pb::ListJobsResponse {
            jobs: page.jobs.iter().map(status_to_proto).collect(),
            next_page_token: page.next_page_token.unwrap_or_default(),
        }))
    }

    async fn list_children(
        &self,
        req: Request<pb::ListChildrenRequest>,
    ) -> Result<Response<pb::ListJobsResponse>, Status> {
        self.authorize_read(&req)?;
        let id = req.into_inner().id;
        let jobs = super::study::children(&self.state, id)
            .await
            .map_err(to_status)?;
        Ok(Response::new(pb::ListJobsResponse {
            jobs: jobs.iter().map(status_to_proto).collect(),
            next_page_token: String::new(),
        }))
    }

    async fn delete_job(
        &self,
        req: Request<pb::DeleteJobRequest>,
    ) -> Result<Response<pb::DeleteJobResponse>, Status> {
        self.authorize(&req)?;
        let pb::DeleteJobRequest { id } = req.into_inner();
        let engine = self.state.engine.clone();
        let gone = id.clone();
        tokio::task::spawn_blocking(move || engine.delete(&gone))
            .await
            .map_err(|e| Status::internal(e.to_string()))?
            .map_err(to_status)?;
        Ok(Response::new(pb::DeleteJobResponse { id }))
    }

    async fn pause_job(
        &self,
        req: Request<pb::PauseJobRequest>,
    ) -> Result<Response<pb::JobStatus>, Status> {
        self.authorize(&req)?;
        let pb::PauseJobRequest { id } = req.into_inner();
        let view = self.state.pause_and_wait(&id).await.map_err(to_status)?;
        Ok(Response::new(status_to_proto(&view)))
    }

    async fn resume_job(
        &self,
        req: Request<pb::ResumeJobRequest>,
    ) -> Result<Response<pb::JobStatus>, Status> {
        self.authorize(&req)?;
        let pb::ResumeJobRequest { id } = req.into_inner();
        let view = self.state.resume_job(&id).await.map_err(to_status)?;
        Ok(Response::new(status_to_proto(&view)))
    }

    async fn extend_job(
        &self,
        req: Request<pb::ExtendJobRequest>,
    ) -> Result<Response<pb::ExtendJobResponse>, Status> {
        self.authorize(&req)?;
        let pb::ExtendJobRequest { id, t_end, new_id } = req.into_inner();
        let new = self
            .state
            .extend_job(&id, t_end, new_id)
            .await
            .map_err(to_status)?;
        Ok(Response::new(pb::ExtendJobResponse {
            id: new,
            extends: id,
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
        self.authorize_read(&req)?;
        let pb::WatchJobRequest { id, from_seq } = req.into_inner();
        if let Some(from_seq) = from_seq {
            let frames = self
                .state
                .replay(&id, from_seq, watch_frames)
                .map_err(to_status)?;
            return Ok(Response::new(Box::pin(frames.map(Ok))));
        }
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
        self.authorize_read(&req)?;
        let pb::GetResultRequest {
            id,
            columns,
            every,
            from_step,
            to_step,
        } = req.into_inner();
        let req = cut_request(columns, every, from_step, to_step);
        let engine = self.state.engine.clone();
        let result = tokio::task::spawn_blocking(move || {
            let (view, head, series) = engine.open_result(&id)?;
            if head.partial {
                // A client of this call takes what it gets for the whole run: partial rows only
                // go out through StreamResult and HTTP, marked.
                return Err(EngineError::NoResult {
                    id,
                    state: view.state.as_str(),
                }
                .into());
            }
            let cut = Cut::new(&head, &series, &req)?;
            let bytes = cut.rows() * (cut.names.len() as u64 + 2) * 8;
            if bytes > UNARY_RESULT_BYTES {
                return Err(ApiError::TooLarge {
                    reason: format!(
                        "the series asked for is {} MiB, more than the {} MiB GetResult sends in one message: use StreamResult, or fewer columns / a larger every",
                        bytes >> 20,
                        UNARY_RESULT_BYTES >> 20
                    ),
                });
            }
            let mut r = StoredResult {
                columns: cut.names.clone(),
                ..head
            };
            cut.for_each(&series, |rows| {
                r.steps.extend_from_slice(&rows.steps);
                r.t.extend_from_slice(&rows.t);
                r.values.extend_from_slice(&rows.values);
                Ok(())
            })
            .map_err(|e| ApiError::Internal(e.to_string()))?;
            Ok(result_to_proto(&view, &r))
        })
        .await
        .map_err(|e| Status::internal(e.to_string()))?
        .map_err(to_status)?;
        Ok(Response::new(result))
    }

    type StreamResultStream = ResultStream;

    async fn stream_result(
        &self,
        req: Request<pb::GetResultRequest>,
    ) -> Result<Response<Self::StreamResultStream>, Status> {
        self.authorize_read(&req)?;
        let pb::GetResultRequest {
            id,
            columns,
            every,
            from_step,
            to_step,
        } = req.into_inner();
        // Errors before the first message (unknown job, no result, bad cut) end the call with
        // their status as the stream's only item.
        Ok(Response::new(stream_result(
            &self.state,
            id,
            cut_request(columns, every, from_step, to_step),
        )))
    }

    async fn capabilities(
        &self,
        req: Request<pb::CapabilitiesRequest>,
    ) -> Result<Response<pb::CapabilitiesResponse>, Status> {
        self.authorize_read(&req)?;
        let pb::CapabilitiesRequest {} = req.into_inner();
        Ok(Response::new(convert::capabilities_to_proto(
            &signorini_core::capabilities::capabilities(),
        )))
    }
}
