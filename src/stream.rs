//! Live streams over zenoh: `signorini/v1/jobs/{id}/status`, `…/{id}/state`, `…/{id}/energy`.
//!
//! Workers hand frames to one publishing task through one FIFO channel, so a job's messages go
//! out in the order they were made. Step frames and progress statuses are *offered*: when
//! [`QUEUED_FRAMES`] offered messages are already waiting, the new one is dropped and counted in
//! `signorini_frames_dropped_total`. Control messages (a job's first and final status, its last
//! frames, the end of its publishers) are always queued; they are a handful per job. Nothing a
//! worker or a handler sends ever waits: this queue is where a slow or absent subscriber is
//! absorbed, and a job never waits on zenoh.
//!
//! zenoh QoS: status and step frames of a job share one priority. zenoh keeps messages in order
//! only within a priority; a higher-priority terminal status overtook the job's last step frames
//! on the wire and a watcher that stops at the terminal status missed them (seen in CI).
//!
//! Step frames are put with congestion control *block* on the publishing task (not on the
//! job): zenoh's *drop* policy, measured here, drops whole bursts as soon as its link queue is
//! momentarily full (a fast job emits dozens of frames per millisecond), so a subscriber on
//! loopback that keeps up would still lose steps. With *block*, a subscriber that stalls for more
//! than zenoh's `wait_before_close` (5 s) is disconnected by zenoh, and meanwhile the queue above
//! fills and drops offered frames — the job runs on at full speed either way.
//!
//! A queryable on `signorini/v1/jobs/*/status` answers the latest status of a job, for late
//! joiners (`signorini watch`) and as a barrier: once a query from a session is answered, the
//! subscribers it declared before are known here.

use crate::proto::v1::{JobStatus, StepFrame, WatchFrame, watch_frame};
use anyhow::{Context, Result, anyhow};
use prost::Message;
use std::collections::HashMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use tokio::sync::{broadcast, mpsc};
use zenoh::Session;
use zenoh::bytes::Encoding;
use zenoh::pubsub::Publisher;
use zenoh::qos::{CongestionControl, Priority};

/// Key of a job's status frames.
pub fn status_key(id: &str) -> String {
    format!("signorini/v1/jobs/{id}/status")
}

/// Key of a job's state frames (contact and probe columns).
pub fn state_key(id: &str) -> String {
    format!("signorini/v1/jobs/{id}/state")
}

/// Key of a job's energy frames (energy terms and works).
pub fn energy_key(id: &str) -> String {
    format!("signorini/v1/jobs/{id}/energy")
}

/// Subscriber-side wildcard of every job's status.
pub const STATUS_WILDCARD: &str = "signorini/v1/jobs/*/status";

/// The job id in a `signorini/v1/jobs/{id}/…` key.
pub fn id_of_key(key: &str) -> Option<&str> {
    key.strip_prefix("signorini/v1/jobs/")?.split('/').next()
}

/// How the zenoh session joins the network.
#[derive(Debug, Clone, Default)]
pub struct ZenohOptions {
    /// Endpoints to listen on (`tcp/127.0.0.1:7447`).
    pub listen: Vec<String>,
    /// Endpoints to connect to (routers or peers).
    pub connect: Vec<String>,
}

/// Opens a zenoh peer: explicit endpoints, multicast scouting off.
pub async fn open_session(opts: &ZenohOptions) -> Result<Session> {
    let mut config = zenoh::Config::default();
    let set = |config: &mut zenoh::Config, key: &str, value: String| {
        config
            .insert_json5(key, &value)
            .map_err(|e| anyhow!("zenoh config {key}: {e}"))
    };
    set(&mut config, "mode", "\"peer\"".into())?;
    set(&mut config, "scouting/multicast/enabled", "false".into())?;
    set(
        &mut config,
        "listen/endpoints",
        serde_json::to_string(&opts.listen)?,
    )?;
    set(
        &mut config,
        "connect/endpoints",
        serde_json::to_string(&opts.connect)?,
    )?;
    zenoh::open(config)
        .await
        .map_err(|e| anyhow!("opening zenoh session: {e}"))
}

/// What workers send to the publishing task.
#[derive(Debug)]
pub enum StreamMsg {
    /// A status frame.
    Status(JobStatus),
    /// Step frames of one job; `frame.last` marks the run's last ones.
    Steps {
        /// The job.
        id: String,
        /// Energy columns.
        energy: Option<StepFrame>,
        /// The other columns.
        state: Option<StepFrame>,
    },
    /// The job is over: undeclare its publishers.
    Closed(String),
}

/// A message in the channel, and whether it counts against [`QUEUED_FRAMES`].
struct Queued {
    msg: StreamMsg,
    offered: bool,
}

/// Counters of the stream.
#[derive(Debug, Default)]
pub struct StreamStats {
    /// Frames put on zenoh.
    pub frames_published: AtomicU64,
    /// Step frames dropped because the channel was full.
    pub frames_dropped: AtomicU64,
}

/// The sending side, cloned into workers and handlers.
#[derive(Clone)]
pub struct StreamSink {
    tx: mpsc::UnboundedSender<Queued>,
    /// Offered messages in the channel.
    offered: Arc<AtomicUsize>,
    stats: Arc<StreamStats>,
}

impl StreamSink {
    /// A sink and the receiving end of its channel.
    fn channel() -> (StreamSink, mpsc::UnboundedReceiver<Queued>) {
        let (tx, rx) = mpsc::unbounded_channel();
        let sink = StreamSink {
            tx,
            offered: Arc::new(AtomicUsize::new(0)),
            stats: Arc::new(StreamStats::default()),
        };
        (sink, rx)
    }

    /// Queues a step frame or a progress status if fewer than [`QUEUED_FRAMES`] offered
    /// messages are waiting, else drops it (counted).
    pub fn offer(&self, msg: StreamMsg) {
        if self.offered.fetch_add(1, Ordering::AcqRel) >= QUEUED_FRAMES {
            self.offered.fetch_sub(1, Ordering::AcqRel);
            self.stats.frames_dropped.fetch_add(1, Ordering::Relaxed);
            return;
        }
        if self.tx.send(Queued { msg, offered: true }).is_err() {
            self.offered.fetch_sub(1, Ordering::AcqRel);
        }
    }

    /// Queues a control message (never dropped, never waits).
    pub fn send(&self, msg: StreamMsg) {
        // Err only when the publishing task is gone (shutdown): nothing left to tell.
        let _ = self.tx.send(Queued {
            msg,
            offered: false,
        });
    }

    /// Counters.
    pub fn stats(&self) -> &StreamStats {
        &self.stats
    }
}

/// The publishing side: the zenoh session and the task that owns the publishers.
pub struct Streamer {
    session: Session,
    task: tokio::task::JoinHandle<()>,
    watch: broadcast::Sender<Arc<WatchFrame>>,
}

struct JobPublishers {
    status: Publisher<'static>,
    state: Publisher<'static>,
    energy: Publisher<'static>,
}

/// Offered messages (step frames, progress statuses) waiting between the workers and zenoh at
/// most; each step frame carries up to a few hundred steps.
pub const QUEUED_FRAMES: usize = 4096;

impl Streamer {
    /// Starts the publishing task on `session`.
    pub fn start(session: Session) -> (Streamer, StreamSink) {
        let (sink, rx) = StreamSink::channel();
        let (offered, stats) = (sink.offered.clone(), sink.stats.clone());
        let (watch, _) = broadcast::channel(1024);
        let task = tokio::spawn(publish_loop(
            session.clone(),
            rx,
            offered.clone(),
            watch.clone(),
            stats.clone(),
        ));
        (
            Streamer {
                session,
                task,
                watch,
            },
            sink,
        )
    }

    /// The zenoh session (for the status queryable).
    pub fn session(&self) -> &Session {
        &self.session
    }

    /// The broadcast of every frame, as published (for gRPC `WatchJob` and SSE).
    pub fn sender(&self) -> broadcast::Sender<Arc<WatchFrame>> {
        self.watch.clone()
    }

    /// Waits for queued messages to go out (the workers' senders must be gone), then closes the
    /// session.
    pub async fn close(self) {
        let _ = tokio::time::timeout(std::time::Duration::from_secs(5), self.task).await;
        if let Err(e) = self.session.close().await {
            tracing::warn!("closing zenoh session: {e}");
        }
    }
}

async fn declare(session: &Session, key: String) -> Result<Publisher<'static>> {
    session
        .declare_publisher(key)
        .encoding(Encoding::APPLICATION_PROTOBUF)
        .congestion_control(CongestionControl::Block)
        .priority(Priority::Data)
        .await
        .map_err(|e| anyhow!("declaring publisher: {e}"))
}

async fn publishers(session: &Session, id: &str) -> Result<JobPublishers> {
    Ok(JobPublishers {
        status: declare(session, status_key(id)).await?,
        state: declare(session, state_key(id)).await?,
        energy: declare(session, energy_key(id)).await?,
    })
}

async fn publish_loop(
    session: Session,
    mut rx: mpsc::UnboundedReceiver<Queued>,
    offered: Arc<AtomicUsize>,
    watch: broadcast::Sender<Arc<WatchFrame>>,
    stats: Arc<StreamStats>,
) {
    let mut pubs: HashMap<String, JobPublishers> = HashMap::new();
    while let Some(Queued { msg, offered: o }) = rx.recv().await {
        if o {
            offered.fetch_sub(1, Ordering::AcqRel);
        }
        if let Err(e) = handle(&session, &mut pubs, msg, &watch, &stats).await {
            tracing::warn!("zenoh publish: {e:#}");
        }
    }
    for (_, p) in pubs.drain() {
        let _ = p.status.undeclare().await;
        let _ = p.state.undeclare().await;
        let _ = p.energy.undeclare().await;
    }
}

async fn handle(
    session: &Session,
    pubs: &mut HashMap<String, JobPublishers>,
    msg: StreamMsg,
    watch: &broadcast::Sender<Arc<WatchFrame>>,
    stats: &StreamStats,
) -> Result<()> {
    let id = match &msg {
        StreamMsg::Status(s) => s.id.clone(),
        StreamMsg::Steps { id, .. } => id.clone(),
        StreamMsg::Closed(id) => {
            if let Some(p) = pubs.remove(id) {
                let _ = p.status.undeclare().await;
                let _ = p.state.undeclare().await;
                let _ = p.energy.undeclare().await;
            }
            return Ok(());
        }
    };
    if !pubs.contains_key(&id) {
        let p = publishers(session, &id).await?;
        pubs.insert(id.clone(), p);
    }
    let p = pubs.get(&id).context("publisher just declared")?;
    match msg {
        StreamMsg::Status(s) => {
            p.status
                .put(s.encode_to_vec())
                .await
                .map_err(|e| anyhow!("{e}"))?;
            stats.frames_published.fetch_add(1, Ordering::Relaxed);
            let _ = watch.send(Arc::new(WatchFrame {
                frame: Some(watch_frame::Frame::Status(s)),
            }));
        }
        StreamMsg::Steps { id, energy, state } => {
            let _ = id;
            for (frame, publisher, is_energy) in
                [(energy, &p.energy, true), (state, &p.state, false)]
            {
                let Some(frame) = frame else { continue };
                publisher
                    .put(frame.encode_to_vec())
                    .await
                    .map_err(|e| anyhow!("{e}"))?;
                stats.frames_published.fetch_add(1, Ordering::Relaxed);
                if watch.receiver_count() > 0 {
                    let f = if is_energy {
                        watch_frame::Frame::Energy(frame)
                    } else {
                        watch_frame::Frame::State(frame)
                    };
                    let _ = watch.send(Arc::new(WatchFrame { frame: Some(f) }));
                }
            }
        }
        StreamMsg::Closed(_) => {}
    }
    Ok(())
}

/// Answers `signorini/v1/jobs/{id}/status` queries with `lookup(id)` (an error reply when the
/// job is unknown), until the session closes.
pub async fn serve_status_queryable<F>(session: Session, lookup: F) -> Result<()>
where
    F: Fn(&str) -> Option<JobStatus> + Send + Sync + 'static,
{
    let queryable = session
        .declare_queryable(STATUS_WILDCARD)
        .await
        .map_err(|e| anyhow!("declaring queryable: {e}"))?;
    tokio::spawn(async move {
        while let Ok(query) = queryable.recv_async().await {
            let key = query.key_expr().as_str().to_string();
            let reply = match id_of_key(&key).and_then(&lookup) {
                Some(status) => {
                    query
                        .reply(key.as_str(), status.encode_to_vec())
                        .encoding(Encoding::APPLICATION_PROTOBUF)
                        .await
                }
                None => query.reply_err(format!("no job at {key}")).await,
            };
            if let Err(e) = reply {
                tracing::debug!("status query reply: {e}");
            }
        }
    });
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn status(id: &str) -> StreamMsg {
        StreamMsg::Status(JobStatus {
            id: id.into(),
            ..Default::default()
        })
    }

    /// With nobody reading (a publisher stuck on a stalled subscriber), offered messages stop
    /// at [`QUEUED_FRAMES`] and the rest are dropped and counted, while control messages are
    /// still queued at once and in order: nothing a worker sends waits.
    #[test]
    fn a_stuck_publisher_drops_offered_frames_and_never_blocks_control_messages() {
        let (sink, mut rx) = StreamSink::channel();
        for _ in 0..QUEUED_FRAMES + 904 {
            sink.offer(status("frame"));
        }
        assert_eq!(sink.offered.load(Ordering::Acquire), QUEUED_FRAMES);
        assert_eq!(sink.stats().frames_dropped.load(Ordering::Relaxed), 904);
        sink.send(status("final"));
        sink.send(StreamMsg::Closed("final".into()));
        let mut got = Vec::new();
        while let Ok(q) = rx.try_recv() {
            got.push(q);
        }
        assert_eq!(got.len(), QUEUED_FRAMES + 2);
        assert!(got[..QUEUED_FRAMES].iter().all(|q| q.offered));
        assert!(matches!(&got[QUEUED_FRAMES].msg, StreamMsg::Status(s) if s.id == "final"));
        assert!(matches!(&got[QUEUED_FRAMES + 1].msg, StreamMsg::Closed(id) if id == "final"));
        assert!(!got[QUEUED_FRAMES].offered && !got[QUEUED_FRAMES + 1].offered);
    }
}
