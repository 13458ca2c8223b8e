//! `signorini serve`: the gRPC and HTTP listeners, the embedded zenoh peer, the store and the
//! worker pool, wired together; graceful shutdown on SIGINT/SIGTERM.

pub mod auth;
pub mod convert;
pub mod grpc;
pub mod http;
pub mod json;
mod pause;
mod remote;
pub mod results;
mod scene;
mod study;
pub mod tls;

use crate::config::ServeConfig;
use crate::engine::Engine;
use crate::engine::events::JobEvent;
use crate::error::ApiError;
use crate::proto::v1::simulation_server::SimulationServer;
use crate::status::JobView;
use crate::store::{Location, Store, StoreLock};
use crate::stream::{self, Streamer, ZenohOptions};
use anyhow::{Context, Result};
use axum::serve::ListenerExt;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::sync::broadcast;
use tokio_stream::wrappers::BroadcastStream;
use tokio_stream::wrappers::errors::BroadcastStreamRecvError;
use tokio_stream::{Stream, StreamExt};

/// What every handler shares.
#[derive(Clone)]
pub struct AppState {
    /// The job engine.
    pub engine: Engine,
    access: auth::Access,
    events: broadcast::Sender<Arc<JobEvent>>,
    /// This replica's zenoh session (frames of jobs running on other replicas come through it).
    session: zenoh::Session,
    rate: Arc<Mutex<(Instant, u64)>>,
}

impl AppState {
    /// Checks an `Authorization` header value for a mutating call ([`auth::Access`]: always
    /// fine when no token is configured).
    pub fn authorize(&self, header: Option<&str>) -> Result<(), ApiError> {
        self.access.check(header, auth::Scope::Write)
    }

    /// Checks an `Authorization` header value for a read (closed only with `--tokens`).
    pub fn authorize_read(&self, header: Option<&str>) -> Result<(), ApiError> {
        self.access.check(header, auth::Scope::Read)
    }

    /// A job's current status and, unless it is already over, the status and step events
    /// published for it up to and including its final status, each encoded by `encode` into
    /// what the client receives (gRPC `WatchJob`, SSE). The subscription is taken before the
    /// status is read, so no event falls between the two.
    pub fn follow<T: Send + 'static>(
        &self,
        id: &str,
        encode: impl Fn(&JobEvent) -> Vec<T> + Send + 'static,
    ) -> Result<(JobView, Option<impl Stream<Item = T> + Send + 'static>), ApiError> {
        let rx = self.events.subscribe();
        let current = self.engine.status(id)?;
        if current.state.is_terminal() {
            return Ok((current, None));
        }
        let events = self.live_events(id, rx, &current);
        Ok((current, Some(until_terminal(events, encode))))
    }

    /// The live events of job `id`: this replica's (from `rx`, subscribed before `current`
    /// was read) and, for a job queued or running on another replica (a shared store), what
    /// that replica publishes on zenoh, received when the replicas share a zenoh network, with
    /// its status read from the store until it ends (a final status read there waits a moment
    /// for the last frames, which the other replica publishes before its final status). When
    /// `rx` lags (events dropped for a slow reader), the job's status is read so that its end
    /// is not lost.
    fn live_events(
        &self,
        id: &str,
        rx: broadcast::Receiver<Arc<JobEvent>>,
        current: &JobView,
    ) -> EventStream {
        let (only, engine) = (id.to_string(), self.engine.clone());
        let local = BroadcastStream::new(rx).filter_map(move |msg| match msg {
            Ok(event) => (event.job_id() == only).then_some(event),
            Err(BroadcastStreamRecvError::Lagged(_)) => engine
                .status(&only)
                .ok()
                .filter(|v| v.state.is_terminal())
                .map(|v| Arc::new(JobEvent::Status(v))),
        });
        if !self.engine.runs_elsewhere(id) {
            return Box::pin(local);
        }
        let polled = poll_status(self.engine.clone(), id.to_string(), current.clone()).then(
            |event| async move {
                if matches!(&*event, JobEvent::Status(s) if s.state.is_terminal()) {
                    tokio::time::sleep(LAST_FRAMES_GRACE).await;
                }
                event
            },
        );
        let remote = remote::events(self.session.clone(), id.to_string());
        Box::pin(local.merge(remote).merge(polled))
    }

    /// A job's history from batch `from_seq` on, then its live events, each encoded by
    /// `encode`: the current status (unless the job is over), the stored batches (read one
    /// chunk at a time), then the live status and step events, skipping batches already
    /// replayed, up to and including the final status. The subscription is taken before the
    /// history, so nothing falls between the two.
    pub fn replay<T: Send + 'static>(
        &self,
        id: &str,
        from_seq: u64,
        encode: impl Fn(&JobEvent) -> Vec<T> + Send + 'static,
    ) -> Result<impl Stream<Item = T> + Send + 'static, ApiError> {
        let rx = self.events.subscribe();
        let (view, history) = self.engine.history(id)?;
        let mut live = self.live_events(id, rx, &view);
        let id = id.to_string();
        let (tx, out) = tokio::sync::mpsc::channel(16);
        tokio::spawn(async move {
            let send_all = |items: Vec<T>| {
                let tx = tx.clone();
                async move {
                    for item in items {
                        tx.send(item).await.map_err(drop)?;
                    }
                    Ok::<_, ()>(())
                }
            };
            let ended = history.ended();
            if !ended
                && send_all(encode(&JobEvent::Status(view.clone())))
                    .await
                    .is_err()
            {
                return;
            }
            let (btx, mut brx) = tokio::sync::mpsc::channel(4);
            let reading = tokio::task::spawn_blocking(move || {
                history.replay(from_seq, |b| btx.blocking_send(b).is_ok())
            });
            let mut last_seq = None;
            while let Some(batch) = brx.recv().await {
                last_seq = Some(batch.seq);
                if send_all(encode(&JobEvent::Steps(batch))).await.is_err() {
                    return;
                }
            }
            if let Ok(Err(e)) = reading.await {
                tracing::error!(%id, "replaying history: {e}");
                return;
            }
            if ended {
                let _ = send_all(encode(&JobEvent::Status(view))).await;
                return;
            }
            loop {
                let event = tokio::select! {
                    e = live.next() => e,
                    () = tx.closed() => return,
                };
                let Some(event) = event else { return };
                if let JobEvent::Steps(b) = &*event
                    && last_seq.is_some_and(|l| b.seq <= l)
                {
                    continue;
                }
                let done = matches!(&*event, JobEvent::Status(s) if s.state.is_terminal());
                if send_all(encode(&event)).await.is_err() || done {
                    return;
                }
            }
        });
        Ok(tokio_stream::wrappers::ReceiverStream::new(out))
    }

    /// Cancels a job and waits (up to 5 s) until a running one has stopped.
    pub async fn cancel_and_wait(&self, id: &str) -> Result<JobView, ApiError> {
        let ended = self.engine.ended(id);
        let view = self.engine.cancel(id)?;
        if view.state.is_terminal() {
            return Ok(view);
        }
        if let Some(mut rx) = ended {
            let _ = tokio::time::timeout(Duration::from_secs(5), rx.wait_for(|ended| *ended)).await;
        }
        Ok(self.engine.status(id)?)
    }

    /// Steps per second since the previous call.
    pub fn steps_rate(&self, total: u64) -> f64 {
        let mut last = self.rate.lock().unwrap_or_else(|p| p.into_inner());
        let dt = last.0.elapsed().as_secs_f64();
        let rate = if dt > 0.0 {
            total.saturating_sub(last.1) as f64 / dt
        } else {
            0.0
        };
        *last = (Instant::now(), total);
        rate
    }
}

async fn shutdown_signal() {
    let ctrl_c = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    #[cfg(unix)]
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let term = std::future::pending::<()>();
    tokio::select! {
        () = ctrl_c => {}
        () = term => {}
    }
}

/// Sets `TCP_NODELAY` on an accepted connection. A response written in several small pieces (an
/// HTTP/2 frame after another, a body after its headers) otherwise waits, under Nagle's
/// algorithm, for the peer's delayed acknowledgement (40 ms): the load bench measured a 45 ms
/// median download at every load before this (docs/load.md). A socket that refuses the option
/// is served anyway.
pub(crate) fn no_delay(tcp: &tokio::net::TcpStream) {
    if let Err(e) = tcp.set_nodelay(true) {
        tracing::debug!("setting TCP_NODELAY on a connection: {e}");
    }
}

/// Runs the service until SIGINT/SIGTERM.
pub async fn serve(cfg: ServeConfig) -> Result<()> {
    let access = match (&cfg.tokens, &cfg.token) {
        (Some(_), Some(_)) => anyhow::bail!("give --token or --tokens, not both"),
        (Some(file), None) => auth::Access::from_file(file)?,
        (None, Some(token)) => auth::Access::Shared(Arc::from(token.as_str())),
        (None, None) => auth::Access::Open,
    };
    let tls = match &cfg.tls {
        Some(files) => Some(tls::ServerTls::load(&files.cert, &files.key)?),
        None => None,
    };
    // What can fail without leaving anything behind comes first: the ports, then the zenoh
    // peer, then the store's lock (which creates the file of a new store), then the store.
    let grpc_listener = tokio::net::TcpListener::bind(cfg.grpc_addr)
        .await
        .with_context(|| format!("binding {}", cfg.grpc_addr))?;
    let http_listener = tokio::net::TcpListener::bind(cfg.http_addr)
        .await
        .with_context(|| format!("binding {}", cfg.http_addr))?;
    let grpc_addr = grpc_listener.local_addr()?;
    let http_addr = http_listener.local_addr()?;
    let session = stream::open_session(&ZenohOptions {
        listen: cfg.zenoh_listen.clone(),
        connect: cfg.zenoh_connect.clone(),
        config: cfg.zenoh_config.clone(),
    })
    .await?;
    let location = Location::of(&cfg.store);
    let opened = match location {
        Location::Sqlite(path) => StoreLock::take(path)
            .and_then(|lock| Ok((lock, Store::open_limited(path, cfg.store_max_bytes)?))),
        // Replicas share it: no lock. A connection per worker, one for the heartbeat, a few
        // for the API.
        Location::Postgres(url) => {
            Store::connect(url, &cfg.replica, cfg.workers + 4, cfg.lease).map(|s| (None, s))
        }
    };
    let (_lock, store) = match opened {
        Ok(o) => o,
        Err(e) => {
            let _ = session.close().await;
            return Err(e).with_context(|| format!("opening store {}", location.shown()));
        }
    };
    let (streamer, sink) = Streamer::start(session.clone());
    let engine = Engine::start(store, cfg.limits, cfg.queue_limit, cfg.workers, sink)
        .map_err(anyhow::Error::from)?;
    // Tasks that hold the engine (and through it the event sink): aborted at shutdown, before
    // the streamer waits for every sink to go.
    let mut background = Vec::new();
    {
        let engine = engine.clone();
        background.push(
            stream::serve_status_queryable(session.clone(), move |id| engine.find(id)).await?,
        );
    }
    {
        let engine = engine.clone();
        background.extend(
            stream::serve_history_queryable(session.clone(), move |id| {
                engine.history(id).ok().map(|(_, h)| h)
            })
            .await?,
        );
    }
    if let Some(retain) = cfg.retain {
        // Old finished jobs go at start and then every tenth of the retention (at most hourly).
        let engine = engine.clone();
        let every = (retain / 10).clamp(Duration::from_millis(200), Duration::from_secs(3600));
        background.push(tokio::spawn(async move {
            loop {
                let e = engine.clone();
                match tokio::task::spawn_blocking(move || e.expire(retain)).await {
                    Ok(Ok(n)) if n > 0 => tracing::info!(removed = n, "retention"),
                    Ok(Err(e)) => tracing::error!("retention: {e}"),
                    _ => {}
                }
                tokio::time::sleep(every).await;
            }
        }));
    }
    let state = AppState {
        engine: engine.clone(),
        access,
        events: streamer.sender(),
        session: session.clone(),
        rate: Arc::new(Mutex::new((Instant::now(), 0))),
    };

    let (health, health_service) = tonic_health::server::health_reporter();
    health
        .set_serving::<SimulationServer<grpc::SimulationService>>()
        .await;
    background.push(tokio::spawn(watch_store(engine.clone(), health)));

    let (stop_tx, stop_rx) = tokio::sync::watch::channel(false);
    let stopped = |mut rx: tokio::sync::watch::Receiver<bool>| async move {
        let _ = rx.wait_for(|s| *s).await;
    };
    // Server reflection, v1 and v1alpha (grpcurl asks v1 first; Python's grpcio-reflection
    // client speaks v1alpha): tools discover the services and their messages.
    let reflection = || {
        tonic_reflection::server::Builder::configure()
            .register_encoded_file_descriptor_set(crate::proto::FILE_DESCRIPTOR_SET)
            .register_encoded_file_descriptor_set(tonic_health::pb::FILE_DESCRIPTOR_SET)
    };
    let reflection_v1 = reflection()
        .build_v1()
        .context("building the gRPC reflection service")?;
    let reflection_v1alpha = reflection()
        .build_v1alpha()
        .context("building the gRPC reflection service (v1alpha)")?;
    let mut grpc = tonic::transport::Server::builder();
    if let Some(tls) = &tls {
        grpc = grpc
            .tls_config(tls.grpc())
            .context("the gRPC listener's TLS")?;
    }
    let grpc = grpc
        .add_service(health_service)
        .add_service(reflection_v1)
        .add_service(reflection_v1alpha)
        .add_service(
            SimulationServer::new(grpc::SimulationService::new(state.clone()))
                .max_encoding_message_size(crate::cli::client::MAX_MESSAGE)
                .max_decoding_message_size(64 << 20),
        )
        .serve_with_incoming_shutdown(
            tokio_stream::wrappers::TcpListenerStream::new(grpc_listener)
                .map(|accepted| accepted.inspect(no_delay)),
            stopped(stop_rx.clone()),
        );
    let grpc_task = tokio::spawn(grpc);
    let router = http::router(state.clone());
    let http_task = match &tls {
        Some(tls) => {
            let http = axum::serve(tls.listener(http_listener)?, router)
                .with_graceful_shutdown(stopped(stop_rx));
            tokio::spawn(async move { http.await })
        }
        None => {
            let http = axum::serve(http_listener.tap_io(|tcp| no_delay(tcp)), router)
                .with_graceful_shutdown(stopped(stop_rx));
            tokio::spawn(async move { http.await })
        }
    };
    tracing::info!(%grpc_addr, %http_addr, store = %location.shown(), workers = cfg.workers, tls = tls.is_some(), "serving");
    println!("signorini serving gRPC on {grpc_addr}, HTTP on {http_addr}");

    shutdown_signal().await;
    tracing::info!("shutting down");
    // Jobs stop and compilations are abandoned now: in-flight requests end promptly.
    engine.begin_shutdown();
    let _ = stop_tx.send(true);
    let _ = tokio::time::timeout(Duration::from_secs(10), grpc_task).await;
    let _ = tokio::time::timeout(Duration::from_secs(10), http_task).await;
    let e = engine.clone();
    tokio::task::spawn_blocking(move || e.shutdown()).await?;
    for task in background {
        task.abort();
        let _ = task.await;
    }
    drop(state);
    drop(engine);
    streamer.close().await;
    Ok(())
}

/// How often a degraded store is probed (a submission probes it at once too).
const STORE_PROBE: Duration = Duration::from_secs(1);

/// Probes the store every [`STORE_PROBE`] while it does not take writes, so `/healthz` and the
/// gRPC health service (`NOT_SERVING` meanwhile) turn healthy again once it can, without
/// waiting for a submission.
async fn watch_store(engine: Engine, health: tonic_health::server::HealthReporter) {
    let mut serving = true;
    loop {
        tokio::time::sleep(STORE_PROBE).await;
        let refused = match engine.store_refusal() {
            None => None,
            Some(_) => {
                let e = engine.clone();
                tokio::task::spawn_blocking(move || e.probe_store())
                    .await
                    .unwrap_or_else(|e| Some(e.to_string()))
            }
        };
        match (refused, serving) {
            (Some(reason), true) => {
                tracing::warn!("the store cannot take writes: {reason}");
                health
                    .set_not_serving::<SimulationServer<grpc::SimulationService>>()
                    .await;
                serving = false;
            }
            (None, false) => {
                health
                    .set_serving::<SimulationServer<grpc::SimulationService>>()
                    .await;
                serving = true;
            }
            _ => {}
        }
    }
}

/// Encodes events and passes them through up to and including the first terminal status, and
/// ends there. (A combinator such as `map_while` would only end the stream when the *next* event
/// of the job arrives — never, once the job is over.) A forwarding task ends the stream by
/// dropping its sender right after the terminal status, or stops when the client goes away.
/// How often a watcher of a job that runs on another replica reads its status from the store.
const STATUS_POLL: Duration = Duration::from_millis(250);

/// A job's events, from whichever sources.
type EventStream = std::pin::Pin<Box<dyn Stream<Item = Arc<JobEvent>> + Send>>;

/// How long a final status read from the store waits for the frames another replica published
/// before it (they come through zenoh, the status through the store).
const LAST_FRAMES_GRACE: Duration = Duration::from_millis(500);

/// A job's status read from the store every [`STATUS_POLL`], as a status event each time it
/// changed from `last`, until it ends (or the receiver goes).
fn poll_status(
    engine: Engine,
    id: String,
    mut last: JobView,
) -> tokio_stream::wrappers::ReceiverStream<Arc<JobEvent>> {
    let (tx, rx) = tokio::sync::mpsc::channel(4);
    tokio::spawn(async move {
        while !last.state.is_terminal() {
            tokio::select! {
                () = tokio::time::sleep(STATUS_POLL) => {}
                () = tx.closed() => return,
            }
            let (e, i) = (engine.clone(), id.clone());
            let view = match tokio::task::spawn_blocking(move || e.status(&i)).await {
                Ok(Ok(view)) => view,
                Ok(Err(e)) => {
                    tracing::warn!(%id, "watching: {e}");
                    return;
                }
                Err(_) => return,
            };
            if view != last {
                last = view.clone();
                if tx.send(Arc::new(JobEvent::Status(view))).await.is_err() {
                    return;
                }
            }
        }
    });
    tokio_stream::wrappers::ReceiverStream::new(rx)
}

fn until_terminal<T: Send + 'static>(
    events: impl Stream<Item = Arc<JobEvent>> + Send + 'static,
    encode: impl Fn(&JobEvent) -> Vec<T> + Send + 'static,
) -> impl Stream<Item = T> + Send + 'static {
    let (tx, rx) = tokio::sync::mpsc::channel(64);
    tokio::spawn(async move {
        let mut events = std::pin::pin!(events);
        loop {
            let event = tokio::select! {
                e = events.next() => e,
                () = tx.closed() => None,
            };
            let Some(event) = event else { return };
            let ended = matches!(&*event, JobEvent::Status(s) if s.state.is_terminal());
            for item in encode(&event) {
                if tx.send(item).await.is_err() {
                    return;
                }
            }
            if ended {
                return;
            }
        }
    });
    tokio_stream::wrappers::ReceiverStream::new(rx)
}
