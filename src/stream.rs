//! Live streams over zenoh: `signorini/v1/jobs/{id}/status`, `…/{id}/state`, `…/{id}/energy`.
//!
//! The engine hands its [`JobEvent`]s to one publishing task through one FIFO channel
//! ([`crate::engine::events`]: step batches and progress statuses are offered and dropped when
//! the channel is full, control events never), so a job's messages go out in the order they were
//! made and a job never waits on zenoh. The task encodes each event as protobuf
//! ([`crate::proto::encode`]) and puts it, then forwards the event, as published, to gRPC
//! `WatchJob` and SSE, which encode it for their clients.
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
//!
//! Late joiners get the frames they missed from the store: queryables on
//! `signorini/v1/jobs/*/energy/*` and `…/state/*` answer a `get` of `…/{id}/energy/*` with the
//! job's recorded frames, one reply per frame keyed `…/{id}/energy/{seq}` (distinct keys, so
//! zenoh's default consolidation keeps them all, in no set order: sort by `seq`; `…/energy/7`
//! gets frame 7 only), from
//! `?from_seq=N` on and at most [`HISTORY_FRAMES`] per query (ask again from the last `seq` + 1):
//! the very frames that went live (same `seq`, same rows). Chosen over zenoh-ext's advanced
//! publisher cache, which keeps a window of recent samples in memory per publisher: the store
//! already holds every frame of every job, finished ones included, at no memory cost.

use crate::engine::events::{self, EventQueue, EventSink, JobEvent, StreamStats};
use crate::proto::encode::{status_to_proto, step_frames};
use crate::status::JobView;
use anyhow::{Context, Result, anyhow};
use prost::Message;
use std::collections::HashMap;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use tokio::sync::broadcast;
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
    /// A zenoh configuration file (JSON5) to start from instead of the built-in peer on
    /// loopback: its mode, authentication (`transport.auth.usrpwd`, TLS) and access control
    /// apply; `listen`/`connect`, when not empty, replace its endpoints.
    pub config: Option<std::path::PathBuf>,
}

/// Opens a zenoh session: a peer with multicast scouting off on the given endpoints, or the
/// configuration file of `opts.config` with the endpoints given.
pub async fn open_session(opts: &ZenohOptions) -> Result<Session> {
    let set = |config: &mut zenoh::Config, key: &str, value: String| {
        config
            .insert_json5(key, &value)
            .map_err(|e| anyhow!("zenoh config {key}: {e}"))
    };
    let mut config = match &opts.config {
        Some(path) => zenoh::Config::from_file(path)
            .map_err(|e| anyhow!("zenoh config {}: {e}", path.display()))?,
        None => {
            let mut config = zenoh::Config::default();
            set(&mut config, "mode", "\"peer\"".into())?;
            set(&mut config, "scouting/multicast/enabled", "false".into())?;
            config
        }
    };
    let from_file = opts.config.is_some();
    if !from_file || !opts.listen.is_empty() {
        set(
            &mut config,
            "listen/endpoints",
            serde_json::to_string(&opts.listen)?,
        )?;
    }
    if !from_file || !opts.connect.is_empty() {
        set(
            &mut config,
            "connect/endpoints",
            serde_json::to_string(&opts.connect)?,
        )?;
    }
    zenoh::open(config)
        .await
        .map_err(|e| anyhow!("opening zenoh session: {e}"))
}

/// The publishing side: the zenoh session and the task that owns the publishers.
pub struct Streamer {
    session: Session,
    task: tokio::task::JoinHandle<()>,
    watch: broadcast::Sender<Arc<JobEvent>>,
}

struct JobPublishers {
    status: Publisher<'static>,
    state: Publisher<'static>,
    energy: Publisher<'static>,
}

impl Streamer {
    /// Starts the publishing task on `session`; the engine sends its events to the sink.
    pub fn start(session: Session) -> (Streamer, EventSink) {
        let (sink, queue) = events::channel();
        let (watch, _) = broadcast::channel(1024);
        let task = tokio::spawn(publish_loop(session.clone(), queue, watch.clone()));
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

    /// The broadcast of every status and step event, as published (for gRPC `WatchJob` and
    /// SSE).
    pub fn sender(&self) -> broadcast::Sender<Arc<JobEvent>> {
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
    mut queue: EventQueue,
    watch: broadcast::Sender<Arc<JobEvent>>,
) {
    let stats = queue.stats();
    let mut pubs: HashMap<String, JobPublishers> = HashMap::new();
    while let Some(event) = queue.recv().await {
        if let Err(e) = handle(&session, &mut pubs, event, &watch, &stats).await {
            tracing::warn!("zenoh publish: {e:#}");
        }
    }
    for (_, p) in pubs.drain() {
        p.undeclare().await;
    }
}

impl JobPublishers {
    async fn undeclare(self) {
        let _ = self.status.undeclare().await;
        let _ = self.state.undeclare().await;
        let _ = self.energy.undeclare().await;
    }
}

/// Puts one event on the job's keys and forwards it to the watchers.
async fn handle(
    session: &Session,
    pubs: &mut HashMap<String, JobPublishers>,
    event: JobEvent,
    watch: &broadcast::Sender<Arc<JobEvent>>,
    stats: &StreamStats,
) -> Result<()> {
    if let JobEvent::Closed(id) = &event {
        if let Some(p) = pubs.remove(id) {
            p.undeclare().await;
        }
        return Ok(());
    }
    let id = event.job_id().to_string();
    if !pubs.contains_key(&id) {
        let p = publishers(session, &id).await?;
        pubs.insert(id.clone(), p);
    }
    let p = pubs.get(&id).context("publisher just declared")?;
    match &event {
        JobEvent::Status(v) => put(&p.status, status_to_proto(v).encode_to_vec(), stats).await?,
        JobEvent::Steps(batch) => {
            let (energy, state) = step_frames(batch);
            for (frame, publisher) in [(energy, &p.energy), (state, &p.state)] {
                if let Some(frame) = frame {
                    put(publisher, frame.encode_to_vec(), stats).await?;
                }
            }
            if watch.receiver_count() == 0 {
                return Ok(());
            }
        }
        JobEvent::Closed(_) => return Ok(()),
    }
    let _ = watch.send(Arc::new(event));
    Ok(())
}

/// Puts one encoded frame.
async fn put(publisher: &Publisher<'static>, bytes: Vec<u8>, stats: &StreamStats) -> Result<()> {
    publisher.put(bytes).await.map_err(|e| anyhow!("{e}"))?;
    stats.frames_published.fetch_add(1, Ordering::Relaxed);
    Ok(())
}

/// Most frames one history query answers.
pub const HISTORY_FRAMES: usize = 512;

/// Answers `signorini/v1/jobs/{id}/energy` and `…/state` queries (`?from_seq=N`, default 0)
/// with up to [`HISTORY_FRAMES`] recorded frames of that key from seq N on, read from
/// `history(id)` (blocking) as the frames are sent; an error reply for an unknown job. Returns
/// the serving tasks (aborted at shutdown: they hold `history`).
pub async fn serve_history_queryable<F>(
    session: Session,
    history: F,
) -> Result<Vec<tokio::task::JoinHandle<()>>>
where
    F: Fn(&str) -> Option<crate::engine::History> + Send + Sync + 'static,
{
    let history = Arc::new(history);
    let mut tasks = Vec::new();
    for kind in ["energy", "state"] {
        let queryable = session
            .declare_queryable(format!("signorini/v1/jobs/*/{kind}/*"))
            .await
            .map_err(|e| anyhow!("declaring queryable: {e}"))?;
        let history = history.clone();
        tasks.push(tokio::spawn(async move {
            while let Ok(query) = queryable.recv_async().await {
                let history = history.clone();
                tokio::spawn(async move {
                    let started = std::time::Instant::now();
                    let asked = query.key_expr().clone();
                    let from_seq = query
                        .parameters()
                        .get("from_seq")
                        .and_then(|v| v.parse::<u64>().ok())
                        .unwrap_or(0);
                    let Some(id) = id_of_key(asked.as_str()).map(str::to_string) else {
                        return;
                    };
                    let base = format!("signorini/v1/jobs/{id}/{kind}");
                    let (tx, mut rx) = tokio::sync::mpsc::channel(4);
                    let reader = tokio::task::spawn_blocking(move || {
                        let Some(h) = history(&id) else {
                            return false;
                        };
                        let mut left = HISTORY_FRAMES;
                        let _ = h.replay(from_seq, |b| {
                            left -= 1;
                            tx.blocking_send(b).is_ok() && left > 0
                        });
                        true
                    });
                    while let Some(batch) = rx.recv().await {
                        let (energy, state) = step_frames(&batch);
                        let frame = if kind == "energy" { energy } else { state };
                        let Some(frame) = frame else { continue };
                        let Ok(key) =
                            zenoh::key_expr::KeyExpr::try_from(format!("{base}/{}", frame.seq))
                        else {
                            continue;
                        };
                        if !asked.intersects(&key) {
                            continue;
                        }
                        let sent = query
                            .reply(key, frame.encode_to_vec())
                            .encoding(Encoding::APPLICATION_PROTOBUF)
                            .await;
                        if let Err(e) = sent {
                            tracing::debug!("history query reply: {e}");
                            return;
                        }
                    }
                    if let Ok(false) = reader.await {
                        let _ = query.reply_err(format!("no job at {asked}")).await;
                    }
                    let took = started.elapsed();
                    if took > std::time::Duration::from_secs(1) {
                        tracing::warn!("history query {asked} from seq {from_seq} took {took:?}");
                    } else {
                        tracing::debug!("history query {asked} from seq {from_seq} in {took:?}");
                    }
                });
            }
        }));
    }
    Ok(tasks)
}

/// Answers `signorini/v1/jobs/{id}/status` queries with `lookup(id)` (an error reply when the
/// job is unknown), until the session closes. Returns the serving task (aborted at shutdown:
/// it holds `lookup`).
pub async fn serve_status_queryable<F>(
    session: Session,
    lookup: F,
) -> Result<tokio::task::JoinHandle<()>>
where
    F: Fn(&str) -> Option<JobView> + Send + Sync + 'static,
{
    let queryable = session
        .declare_queryable(STATUS_WILDCARD)
        .await
        .map_err(|e| anyhow!("declaring queryable: {e}"))?;
    Ok(tokio::spawn(async move {
        while let Ok(query) = queryable.recv_async().await {
            let key = query.key_expr().as_str().to_string();
            let reply = match id_of_key(&key).and_then(&lookup) {
                Some(status) => {
                    query
                        .reply(key.as_str(), status_to_proto(&status).encode_to_vec())
                        .encoding(Encoding::APPLICATION_PROTOBUF)
                        .await
                }
                None => query.reply_err(format!("no job at {key}")).await,
            };
            if let Err(e) = reply {
                tracing::debug!("status query reply: {e}");
            }
        }
    }))
}
