//! The live events of a job that runs on another replica (a shared PostgreSQL store): the
//! status and step frames that replica publishes on the job's zenoh keys, received by this
//! replica's session, so that `WatchJob` and the SSE route on any replica stream the frames of
//! any job when the replicas share a zenoh network (`--zenoh-connect` to one router).

use crate::engine::events::JobEvent;
use crate::proto::encode::{status_from_proto, step_batch_from_frame};
use crate::proto::v1 as pb;
use prost::Message;
use std::sync::Arc;
use tokio::sync::mpsc;
use tokio_stream::wrappers::ReceiverStream;
use zenoh::Session;
use zenoh::sample::{Locality, Sample};

/// Step frames waiting for a slow watcher at most; more are dropped (a gap in `seq`), as the
/// publishing replica drops frames for a slow link.
const BUFFERED_FRAMES: usize = 64;

/// The events of job `id` published by other sessions (this replica's own publications come
/// through its event channel): its statuses, and its step batches, each holding one frame's
/// group (energy or state). Frames published before the subscription is in place are not
/// seen (the stored history has them). The stream ends when its receiver is dropped or
/// after the job's final status.
pub fn events(session: Session, id: String) -> ReceiverStream<Arc<JobEvent>> {
    let (tx, rx) = mpsc::channel(BUFFERED_FRAMES);
    tokio::spawn(async move {
        let subscriber = match session
            .declare_subscriber(format!("signorini/v1/jobs/{id}/*"))
            .allowed_origin(Locality::Remote)
            .await
        {
            Ok(s) => s,
            Err(e) => {
                tracing::warn!(%id, "subscribing to another replica's frames: {e}");
                return;
            }
        };
        loop {
            let sample = tokio::select! {
                s = subscriber.recv_async() => s,
                () = tx.closed() => break,
            };
            let Ok(sample) = sample else { break };
            let event = match event_of(&sample) {
                Ok(event) => event,
                Err(e) => {
                    tracing::warn!(%id, key = %sample.key_expr(), "a frame from another replica: {e}");
                    continue;
                }
            };
            let Some(event) = event else { continue };
            let ended = matches!(&event, JobEvent::Status(s) if s.state.is_terminal());
            let event = Arc::new(event);
            // A status always goes through (the last one ends the watch); a frame waits for
            // no one.
            let sent = match &*event {
                JobEvent::Status(_) => tx.send(event).await.is_ok(),
                _ => !matches!(
                    tx.try_send(event),
                    Err(mpsc::error::TrySendError::Closed(_))
                ),
            };
            if !sent || ended {
                break;
            }
        }
        if let Err(e) = subscriber.undeclare().await {
            tracing::debug!(%id, "undeclaring: {e}");
        }
    });
    ReceiverStream::new(rx)
}

/// The event a sample on `signorini/v1/jobs/{id}/{status,energy,state}` carries (`None` for
/// another key).
fn event_of(sample: &Sample) -> anyhow::Result<Option<JobEvent>> {
    let key = sample.key_expr().as_str();
    let bytes = sample.payload().to_bytes();
    Ok(match key.rsplit('/').next() {
        Some("status") => Some(JobEvent::Status(status_from_proto(pb::JobStatus::decode(
            &*bytes,
        )?)?)),
        Some(kind @ ("energy" | "state")) => Some(JobEvent::Steps(step_batch_from_frame(
            pb::StepFrame::decode(&*bytes)?,
            kind == "energy",
        ))),
        _ => None,
    })
}
