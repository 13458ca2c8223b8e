//! Shared harness of the service end-to-end tests: a [`TestServer`] that starts the real
//! `signorini serve` binary on 127.0.0.1 ports chosen free, with a temporary store, and kills it
//! on drop; a zenoh peer on loopback (multicast scouting off) connected to it; small gRPC and HTTP
//! clients (hyper-util).
#![allow(dead_code)]

pub mod browser;
pub mod fingerprint;
pub mod pg;
pub mod refusals;

use http_body_util::{BodyExt, Full};
use hyper::body::Bytes;
use hyper_util::client::legacy::Client;
use hyper_util::rt::TokioExecutor;
use prost::Message;
use serde_json::Value;
use signorini::proto::v1 as pb;
use signorini::proto::v1::simulation_client::SimulationClient;
use std::io::{BufRead, BufReader};
use std::net::{SocketAddr, TcpListener};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;
use tonic::transport::Channel;

/// Generous bound for anything a loaded 2-core machine should finish.
pub const PATIENCE: Duration = Duration::from_secs(180);

/// A port nobody listens on right now.
pub fn free_port() -> u16 {
    let l = TcpListener::bind("127.0.0.1:0").expect("binding an ephemeral port");
    l.local_addr().expect("local addr").port()
}

/// Options of a test server.
#[derive(Debug, Clone)]
pub struct Options {
    pub workers: usize,
    pub queue_limit: usize,
    pub token: Option<String>,
    pub max_steps: Option<u64>,
    /// A zenoh configuration file for the server's session (`--zenoh-config`).
    pub zenoh_config: Option<PathBuf>,
    /// `--retain-days`.
    pub retain_days: Option<f64>,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            workers: 2,
            queue_limit: 64,
            token: None,
            max_steps: None,
            zenoh_config: None,
            retain_days: None,
        }
    }
}

/// A running `signorini serve`.
pub struct TestServer {
    child: Child,
    pub grpc_url: String,
    pub http: SocketAddr,
    pub zenoh: String,
    pub store: PathBuf,
}

impl TestServer {
    /// Starts the binary on `store` and waits for its "serving" line.
    ///
    /// gRPC and HTTP bind port 0 and the server reports the ports it got (two ports picked here
    /// once came out equal). zenoh has no such report, so its port is picked here and can, rarely,
    /// be taken by another test's server before this one binds it: a server that exits before
    /// serving is started again on a new port (at most five times).
    pub fn start(store: &Path, opts: &Options) -> TestServer {
        Self::start_with(store, opts, &[])
    }

    /// [`TestServer::start`] with more flags (`--replica`, `--lease-secs`, `--zenoh-connect`).
    pub fn start_with(store: &Path, opts: &Options, extra: &[&str]) -> TestServer {
        for _ in 0..5 {
            if let Some(server) = Self::try_start(store, opts, extra) {
                return server;
            }
        }
        panic!("signorini serve exited before serving, five times");
    }

    /// One attempt: `None` when the server exited before reporting where it serves.
    fn try_start(store: &Path, opts: &Options, extra: &[&str]) -> Option<TestServer> {
        let zenoh = format!("tcp/127.0.0.1:{}", free_port());
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_signorini"));
        cmd.arg("serve")
            .args(["--grpc-addr", "127.0.0.1:0", "--http-addr", "127.0.0.1:0"])
            .args([
                "--store",
                &store.display().to_string(),
                "--zenoh-listen",
                &zenoh,
            ])
            .args([
                "--workers",
                &opts.workers.to_string(),
                "--queue-limit",
                &opts.queue_limit.to_string(),
            ])
            .env_remove("SIGNORINI_TOKEN")
            .env_remove("SIGNORINI_CONFIG")
            .env_remove("SIGNORINI_ZENOH_CONFIG")
            .env_remove("SIGNORINI_RETAIN_DAYS")
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit());
        if let Some(t) = &opts.token {
            cmd.args(["--token", t]);
        }
        if let Some(s) = opts.max_steps {
            cmd.args(["--max-steps", &s.to_string()]);
        }
        if let Some(c) = &opts.zenoh_config {
            cmd.arg("--zenoh-config").arg(c);
        }
        if let Some(d) = opts.retain_days {
            cmd.args(["--retain-days", &d.to_string()]);
        }
        cmd.args(extra)
            .env_remove("SIGNORINI_REPLICA")
            .env_remove("SIGNORINI_LEASE_SECS");
        let mut child = cmd.spawn().expect("starting signorini serve");
        let stdout = child.stdout.take().expect("piped stdout");
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                // "signorini serving gRPC on ADDR, HTTP on ADDR"
                if let Some(rest) = line.strip_prefix("signorini serving gRPC on ")
                    && let Some((grpc, http)) = rest.split_once(", HTTP on ")
                {
                    let _ = tx.send((grpc.parse::<SocketAddr>(), http.parse::<SocketAddr>()));
                }
            }
        });
        let (grpc, http) = match rx.recv_timeout(PATIENCE) {
            Ok((Ok(g), Ok(h))) => (g, h),
            Err(mpsc::RecvTimeoutError::Disconnected) => {
                let _ = child.wait();
                return None;
            }
            other => {
                let _ = child.kill();
                let _ = child.wait();
                panic!("server did not report where it serves: {other:?}");
            }
        };
        Some(TestServer {
            child,
            grpc_url: format!("http://{grpc}"),
            http,
            zenoh,
            store: store.to_path_buf(),
        })
    }

    /// SIGTERM (what a container engine sends to stop), then waits for the process to exit:
    /// its exit status and how long it took (`None` after `within` without exiting: then it is
    /// killed).
    pub fn terminate(
        &mut self,
        within: std::time::Duration,
    ) -> Option<(std::process::ExitStatus, std::time::Duration)> {
        let started = std::time::Instant::now();
        let _ = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status();
        while started.elapsed() < within {
            if let Ok(Some(status)) = self.child.try_wait() {
                return Some((status, started.elapsed()));
            }
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        self.kill9();
        None
    }

    /// SIGKILL, no cleanup (crash test).
    pub fn kill9(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }

    /// A gRPC client.
    pub async fn grpc(&self) -> SimulationClient<Channel> {
        SimulationClient::connect(self.grpc_url.clone())
            .await
            .expect("gRPC connect")
            .max_decoding_message_size(1 << 30)
    }

    /// An HTTP call: status and JSON body (Null when the body is not JSON).
    pub async fn http(
        &self,
        method: &str,
        path: &str,
        body: Option<&str>,
        token: Option<&str>,
    ) -> (u16, Value) {
        let (status, bytes) = self.http_raw(method, path, body, token).await;
        (
            status,
            serde_json::from_slice(&bytes).unwrap_or(Value::Null),
        )
    }

    /// An HTTP call: status and raw body.
    pub async fn http_raw(
        &self,
        method: &str,
        path: &str,
        body: Option<&str>,
        token: Option<&str>,
    ) -> (u16, Vec<u8>) {
        let client: Client<_, Full<Bytes>> = Client::builder(TokioExecutor::new()).build_http();
        let mut req = hyper::Request::builder()
            .method(method)
            .uri(format!("http://{}{path}", self.http))
            .header("content-type", "application/json");
        if let Some(t) = token {
            req = req.header("authorization", format!("Bearer {t}"));
        }
        let req = req
            .body(Full::new(Bytes::from(body.unwrap_or("").to_string())))
            .expect("request");
        let resp = client.request(req).await.expect("HTTP request");
        let status = resp.status().as_u16();
        let bytes = resp
            .into_body()
            .collect()
            .await
            .expect("HTTP body")
            .to_bytes();
        (status, bytes.to_vec())
    }

    /// The server's process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// `GET path` with extra request headers: status, response headers and raw body.
    pub async fn http_get_with(
        &self,
        path: &str,
        headers: &[(&str, &str)],
    ) -> (u16, hyper::HeaderMap, Vec<u8>) {
        self.request("GET", path, "", headers).await
    }

    /// Any request with exactly these headers: status, response headers and raw body.
    pub async fn request(
        &self,
        method: &str,
        path: &str,
        body: &str,
        headers: &[(&str, &str)],
    ) -> (u16, hyper::HeaderMap, Vec<u8>) {
        let client: Client<_, Full<Bytes>> = Client::builder(TokioExecutor::new()).build_http();
        let mut req = hyper::Request::builder()
            .method(method)
            .uri(format!("http://{}{path}", self.http));
        for (k, v) in headers {
            req = req.header(*k, *v);
        }
        let req = req
            .body(Full::new(Bytes::from(body.to_string())))
            .expect("request");
        let resp = client.request(req).await.expect("HTTP request");
        let status = resp.status().as_u16();
        let head = resp.headers().clone();
        let bytes = resp
            .into_body()
            .collect()
            .await
            .expect("HTTP body")
            .to_bytes();
        (status, head, bytes.to_vec())
    }

    /// `GET path`: status, `content-type` and raw body.
    pub async fn http_get_typed(&self, path: &str) -> (u16, String, Vec<u8>) {
        let client: Client<_, Full<Bytes>> = Client::builder(TokioExecutor::new()).build_http();
        let req = hyper::Request::builder()
            .method("GET")
            .uri(format!("http://{}{path}", self.http))
            .body(Full::new(Bytes::new()))
            .expect("request");
        let resp = client.request(req).await.expect("HTTP request");
        let status = resp.status().as_u16();
        let ctype = resp
            .headers()
            .get("content-type")
            .and_then(|v| v.to_str().ok())
            .unwrap_or_default()
            .to_string();
        let bytes = resp
            .into_body()
            .collect()
            .await
            .expect("HTTP body")
            .to_bytes();
        (status, ctype, bytes.to_vec())
    }

    /// A zenoh peer connected to the server's (loopback, multicast scouting off).
    pub async fn zenoh_session(&self) -> zenoh::Session {
        signorini::stream::open_session(&signorini::stream::ZenohOptions {
            listen: Vec::new(),
            connect: vec![self.zenoh.clone()],
            ..Default::default()
        })
        .await
        .expect("zenoh session")
    }
}

impl Drop for TestServer {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Waits until the server's zenoh peer answers a status query for `id` (an error reply when the
/// job does not exist yet): from then on, subscribers this session declared earlier are known to
/// the server, so no frame of the job can be missed.
pub async fn zenoh_barrier(session: &zenoh::Session, id: &str) {
    let deadline = tokio::time::Instant::now() + PATIENCE;
    loop {
        let replies = session
            .get(signorini::stream::status_key(id))
            .await
            .expect("zenoh get");
        if replies.recv_async().await.is_ok() {
            return;
        }
        assert!(
            tokio::time::Instant::now() < deadline,
            "server's zenoh peer never answered"
        );
        // No route yet: the peers are still connecting.
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

/// Collected step frames of one key.
#[derive(Debug, Default)]
pub struct Collected {
    pub columns: Vec<String>,
    pub steps: Vec<u64>,
    pub t: Vec<f64>,
    pub rows: Vec<Vec<f64>>,
    pub frames: usize,
}

/// Receives frames from `sub` until the one marked `last`.
pub async fn collect_until_last(
    sub: &zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>,
) -> Collected {
    let mut c = Collected::default();
    loop {
        let sample = tokio::time::timeout(PATIENCE, sub.recv_async())
            .await
            .expect("no frame in time")
            .expect("subscriber closed");
        let f = pb::StepFrame::decode(&*sample.payload().to_bytes()).expect("a StepFrame");
        let n = f.columns.len();
        c.columns = f.columns.clone();
        c.steps.extend(&f.step);
        c.t.extend(&f.t);
        c.rows.extend(f.values.chunks(n).map(<[f64]>::to_vec));
        c.frames += 1;
        if f.last {
            return c;
        }
    }
}

/// True for a status that will not change any more: succeeded, failed or cancelled. Not for a
/// paused job, whose enum value (`JOB_STATE_PAUSED = 6`) comes after theirs.
pub fn has_ended(s: &pb::JobStatus) -> bool {
    matches!(
        pb::JobState::try_from(s.state),
        Ok(pb::JobState::Succeeded | pb::JobState::Failed | pb::JobState::Cancelled)
    )
}

/// Polls gRPC `GetJob` (which any replica answers from the store) until `done` holds.
pub async fn poll_job(
    client: &mut SimulationClient<Channel>,
    id: &str,
    done: impl Fn(&pb::JobStatus) -> bool,
) -> pb::JobStatus {
    let fut = async {
        loop {
            let s = client
                .get_job(pb::GetJobRequest { id: id.to_string() })
                .await
                .expect("GetJob")
                .into_inner();
            if done(&s) {
                return s;
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    };
    tokio::time::timeout(PATIENCE, fut)
        .await
        .unwrap_or_else(|_| panic!("job {id}: not done in time"))
}

/// Follows gRPC `WatchJob` until the job's terminal status; returns it.
pub async fn wait_terminal(client: &mut SimulationClient<Channel>, id: &str) -> pb::JobStatus {
    let fut = async {
        let mut stream = client
            .watch_job(pb::WatchJobRequest {
                id: id.to_string(),
                ..Default::default()
            })
            .await
            .expect("WatchJob")
            .into_inner();
        while let Some(frame) = stream.message().await.expect("WatchJob stream") {
            if let Some(pb::watch_frame::Frame::Status(s)) = frame.frame
                && has_ended(&s)
            {
                return s;
            }
        }
        panic!("WatchJob ended before a terminal status");
    };
    tokio::time::timeout(PATIENCE, fut)
        .await
        .expect("job did not end in time")
}

/// Follows gRPC `WatchJob` until the job is running and has done at least `steps` steps.
pub async fn wait_running(client: &mut SimulationClient<Channel>, id: &str, steps: u64) {
    let fut = async {
        let mut stream = client
            .watch_job(pb::WatchJobRequest {
                id: id.to_string(),
                ..Default::default()
            })
            .await
            .expect("WatchJob")
            .into_inner();
        while let Some(frame) = stream.message().await.expect("WatchJob stream") {
            if let Some(pb::watch_frame::Frame::Status(s)) = frame.frame {
                let running = s.state == pb::JobState::Running as i32;
                if running && s.progress.as_ref().is_some_and(|p| p.step >= steps) {
                    return;
                }
                assert!(
                    s.state <= pb::JobState::Running as i32,
                    "job ended early: {s:?}"
                );
            }
        }
        panic!("WatchJob ended before the job ran");
    };
    tokio::time::timeout(PATIENCE, fut)
        .await
        .expect("job did not start in time");
}

/// A study of four long bouncing-ball runs (10⁸ and 2·10⁸ steps, two schemes) against the exact
/// solution: its children are still running or queued when a test acts on them.
pub const LONG_BALL_STUDY: &str = r#"{"study": {
    "reference": "exact",
    "base": {"model": {"scene": "bouncing_ball"}, "time": {"h": 1e-6, "t_end": 100.0},
             "output": {"every": 1000000}},
    "schemes": [{"scheme": "moreau_jean", "theta": 0.5}, {"scheme": "moreau_jean", "theta": 1.0}],
    "grid": {"time.h": [1e-6, 5e-7]}}}"#;

/// A bouncing-ball spec in JSON.
pub fn ball_json(h: f64, steps: u64, every: u64) -> String {
    format!(
        r#"{{"name":"ball","model":{{"scene":"bouncing_ball","restitution":0.8}},"time":{{"h":{h:?},"steps":{steps}}},"output":{{"every":{every}}}}}"#
    )
}

/// The same as a typed proto spec.
pub fn ball_typed(h: f64, steps: u64, every: u64) -> pb::JobSpec {
    pb::JobSpec {
        name: Some("ball".into()),
        model: Some(pb::ModelSpec {
            scene: Some(pb::model_spec::Scene::BouncingBall(pb::BouncingBall {
                restitution: Some(0.8),
                ..Default::default()
            })),
        }),
        integrator: None,
        time: Some(pb::TimeSpec {
            h: Some(h),
            steps: Some(steps),
            ..Default::default()
        }),
        contact_solver: None,
        output: Some(pb::OutputSpec {
            every: Some(every),
            probes: vec![],
            ..Default::default()
        }),
        analysis: None,
    }
}

/// The messages of gRPC `StreamResult` for a job's whole result.
pub async fn result_stream(
    client: &mut SimulationClient<Channel>,
    id: &str,
) -> tonic::Streaming<pb::ResultChunk> {
    client
        .stream_result(pb::GetResultRequest {
            id: id.to_string(),
            ..Default::default()
        })
        .await
        .expect("StreamResult")
        .into_inner()
}

/// Submits a JSON spec over gRPC.
pub async fn submit_json(
    client: &mut SimulationClient<Channel>,
    spec: String,
    id: Option<&str>,
) -> Result<String, tonic::Status> {
    let req = pb::SubmitJobRequest {
        spec: Some(pb::submit_job_request::Spec::Json(spec)),
        id: id.map(str::to_string),
    };
    client.submit_job(req).await.map(|r| r.into_inner().id)
}

/// A long job that keeps the only worker of a `workers: 1` server busy (records little), so the
/// next job waits in the queue while a watcher subscribes; cancel it to let that job run.
/// Needs `max_steps` ≥ 5·10⁸.
pub async fn occupy_the_worker(client: &mut SimulationClient<Channel>, id: &str) {
    submit_json(client, ball_json(1e-6, 500_000_000, 1_000_000), Some(id))
        .await
        .expect("submitting the blocker");
    wait_running(client, id, 1).await;
}

/// A child process killed (and reaped) on drop.
pub struct ChildGuard(pub Child);

impl Drop for ChildGuard {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Lines of a child's stdout, read on a thread; `None` at end of file.
pub fn stdout_lines(child: &mut Child) -> mpsc::Receiver<Option<String>> {
    let stdout = child.stdout.take().expect("piped stdout");
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if tx.send(Some(line)).is_err() {
                return;
            }
        }
        let _ = tx.send(None);
    });
    rx
}

/// One server-sent event.
#[derive(Debug, Clone)]
pub struct SseEvent {
    pub event: String,
    pub data: Value,
    /// The `id:` field, when the event has one.
    pub id: Option<String>,
}

/// Reads `GET path` as server-sent events, handing each parsed event to `on_event` until it
/// returns false; then the stream must end (the server closes it after a final status).
pub async fn read_sse(addr: SocketAddr, path: &str, on_event: impl FnMut(SseEvent) -> bool) {
    read_sse_with(addr, path, &[], on_event).await
}

/// [`read_sse`] with extra request headers (`Last-Event-ID`).
pub async fn read_sse_with(
    addr: SocketAddr,
    path: &str,
    headers: &[(&str, &str)],
    mut on_event: impl FnMut(SseEvent) -> bool,
) {
    let client: Client<_, Full<Bytes>> = Client::builder(TokioExecutor::new()).build_http();
    let mut req = hyper::Request::builder()
        .method("GET")
        .uri(format!("http://{addr}{path}"))
        .header("accept", "text/event-stream");
    for (k, v) in headers {
        req = req.header(*k, *v);
    }
    let req = req.body(Full::new(Bytes::new())).expect("request");
    let resp = client.request(req).await.expect("SSE request");
    assert_eq!(resp.status().as_u16(), 200, "SSE status");
    let ctype = resp
        .headers()
        .get("content-type")
        .and_then(|v| v.to_str().ok())
        .unwrap_or_default()
        .to_string();
    assert!(ctype.starts_with("text/event-stream"), "{ctype}");
    let mut body = resp.into_body();
    let mut buf = String::new();
    loop {
        let frame = body
            .frame()
            .await
            .expect("SSE stream ended early")
            .expect("SSE body");
        let Ok(chunk) = frame.into_data() else {
            continue;
        };
        buf.push_str(std::str::from_utf8(&chunk).expect("UTF-8 events"));
        while let Some(end) = buf.find("\n\n") {
            let block: String = buf.drain(..end + 2).collect();
            let mut event = String::from("message");
            let mut data = String::new();
            let mut id = None;
            for line in block.lines() {
                if let Some(e) = line.strip_prefix("event:") {
                    event = e.trim().to_string();
                } else if let Some(i) = line.strip_prefix("id:") {
                    id = Some(i.trim().to_string());
                } else if let Some(d) = line.strip_prefix("data:") {
                    data.push_str(d.trim_start());
                }
            }
            if data.is_empty() {
                continue; // keep-alive comment
            }
            let data = serde_json::from_str(&data).expect("JSON event data");
            if !on_event(SseEvent { event, data, id }) {
                // The server ends the stream after a job's final status: nothing but the end
                // (or a keep-alive comment) may follow.
                loop {
                    let next = tokio::time::timeout(PATIENCE, body.frame())
                        .await
                        .expect("the SSE stream did not end after the final status");
                    match next {
                        None => return,
                        Some(frame) => {
                            let frame = frame.expect("SSE body");
                            let text = frame.into_data().unwrap_or_default();
                            let text = String::from_utf8_lossy(&text);
                            assert!(
                                text.lines().all(|l| l.is_empty() || l.starts_with(':')),
                                "an event after the final status: {text}"
                            );
                        }
                    }
                }
            }
        }
    }
}
