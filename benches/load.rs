//! Load benchmark (harness = false): N concurrent clients against one `signorini serve`, each
//! submitting small jobs, following each to its end and downloading its result; half of them
//! over HTTP (`POST /v1/jobs`, the SSE feed `/v1/jobs/{id}/events`, `GET …/result`), half over
//! gRPC (`SubmitJob`, `WatchJob`, `GetResult`), each client on connections of its own.
//!
//!   cargo bench --bench load                       # N = 10, 100, 500; 2 jobs per client
//!   SIGNORINI_LOAD_CLIENTS=10,100 SIGNORINI_LOAD_ROUNDS=3 cargo bench --bench load
//!
//! A job is the bouncing ball, 2 000 steps recorded every 10th (201 rows). A submission the
//! server refuses because its queue is full (HTTP 429, gRPC RESOURCE_EXHAUSTED: the limit the
//! server promises, `--queue-limit`, 256 by default) is retried after a pause and counted; any
//! other failure is an error. Per N it prints the jobs done, the refusals, the errors (with the
//! first one), the wall time and throughput (jobs/s), the p50/p99 latency of a submission, of a
//! job from its submission to the final status its client saw, and of a result download, and the
//! server's resident memory (VmRSS: before, highest while the clients ran, after). The load
//! average at the start of each N is printed too: on a shared machine it says what the figures
//! are worth. docs/load.md has the figures and what they showed.

#[path = "../tests/common/mod.rs"]
mod common;

use common::{Options, TestServer, ball_json};
use http_body_util::{BodyExt, Full};
use hyper::body::Bytes;
use hyper_util::client::legacy::Client;
use hyper_util::rt::TokioExecutor;
use signorini::proto::v1 as pb;
use signorini::proto::v1::simulation_client::SimulationClient;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

type Http = Client<hyper_util::client::legacy::connect::HttpConnector, Full<Bytes>>;

/// What one client measured.
#[derive(Default)]
struct Tally {
    submit: Vec<Duration>,
    job: Vec<Duration>,
    download: Vec<Duration>,
    refused: u64,
    errors: Vec<String>,
}

/// Why a call did not succeed: the server's queue was full (retried), or anything else.
enum Failure {
    QueueFull,
    Other(String),
}

fn other(e: impl std::fmt::Display) -> Failure {
    Failure::Other(e.to_string())
}

/// One HTTP request: status and body.
async fn http(
    client: &Http,
    method: &str,
    url: String,
    body: String,
) -> Result<(u16, Bytes), Failure> {
    let req = hyper::Request::builder()
        .method(method)
        .uri(url)
        .header("content-type", "application/json")
        .body(Full::new(Bytes::from(body)))
        .map_err(other)?;
    let resp = client.request(req).await.map_err(other)?;
    let status = resp.status().as_u16();
    let body = resp.into_body().collect().await.map_err(other)?.to_bytes();
    Ok((status, body))
}

/// A job over HTTP: (submission, submission to final status, download) times.
async fn http_job(
    client: &Http,
    base: &str,
    spec: &str,
) -> Result<(Duration, Duration, Duration), Failure> {
    let started = Instant::now();
    let (code, body) = http(client, "POST", format!("{base}/v1/jobs"), spec.into()).await?;
    match code {
        201 => {}
        429 => return Err(Failure::QueueFull),
        _ => return Err(Failure::Other(format!("POST /v1/jobs: {code}"))),
    }
    let submitted = started.elapsed();
    let id: serde_json::Value = serde_json::from_slice(&body).map_err(other)?;
    let id = id["id"].as_str().unwrap_or_default().to_string();
    // The SSE feed until its final status (the server ends the stream after it).
    let req = hyper::Request::get(format!("{base}/v1/jobs/{id}/events"))
        .header("accept", "text/event-stream")
        .body(Full::new(Bytes::new()))
        .map_err(other)?;
    let resp = client.request(req).await.map_err(other)?;
    if resp.status() != 200 {
        return Err(Failure::Other(format!("events: {}", resp.status())));
    }
    let mut body = resp.into_body();
    let mut text = Vec::new();
    while let Some(frame) = body.frame().await {
        if let Ok(data) = frame.map_err(other)?.into_data() {
            text.extend_from_slice(&data);
        }
    }
    let ended = started.elapsed();
    let text = String::from_utf8_lossy(&text);
    if !text.contains("\"succeeded\"") {
        return Err(Failure::Other(format!("job {id} did not succeed")));
    }
    let asked = Instant::now();
    let (code, result) = http(
        client,
        "GET",
        format!("{base}/v1/jobs/{id}/result"),
        "".into(),
    )
    .await?;
    if code != 200 || result.len() < 1000 {
        return Err(Failure::Other(format!(
            "result: {code}, {} bytes",
            result.len()
        )));
    }
    Ok((submitted, ended, asked.elapsed()))
}

/// A job over gRPC: (submission, submission to final status, download) times.
async fn grpc_job(
    client: &mut SimulationClient<tonic::transport::Channel>,
    spec: &str,
) -> Result<(Duration, Duration, Duration), Failure> {
    let started = Instant::now();
    let id = match client
        .submit_job(pb::SubmitJobRequest {
            spec: Some(pb::submit_job_request::Spec::Json(spec.into())),
            id: None,
        })
        .await
    {
        Ok(r) => r.into_inner().id,
        Err(s) if s.code() == tonic::Code::ResourceExhausted => return Err(Failure::QueueFull),
        Err(s) => return Err(Failure::Other(format!("SubmitJob: {s}"))),
    };
    let submitted = started.elapsed();
    let mut frames = client
        .watch_job(pb::WatchJobRequest {
            id: id.clone(),
            from_seq: None,
        })
        .await
        .map_err(other)?
        .into_inner();
    let mut last = None;
    while let Some(frame) = frames.message().await.map_err(other)? {
        if let Some(pb::watch_frame::Frame::Status(s)) = frame.frame {
            last = Some(s.state);
        }
    }
    let ended = started.elapsed();
    if last != Some(pb::JobState::Succeeded as i32) {
        return Err(Failure::Other(format!("job {id} ended {last:?}")));
    }
    let asked = Instant::now();
    let result = client
        .get_result(pb::GetResultRequest {
            id,
            ..Default::default()
        })
        .await
        .map_err(other)?
        .into_inner();
    if result.step.len() != 201 {
        return Err(Failure::Other(format!("{} rows", result.step.len())));
    }
    Ok((submitted, ended, asked.elapsed()))
}

/// One client: `rounds` jobs one after another, over gRPC when `grpc`, else HTTP.
async fn client(server: Arc<(String, String)>, grpc: bool, rounds: usize) -> Tally {
    let mut tally = Tally::default();
    let spec = ball_json(1e-3, 2000, 10);
    let http_client: Http = Client::builder(TokioExecutor::new()).build_http();
    let mut grpc_client = if grpc {
        match SimulationClient::connect(server.0.clone()).await {
            Ok(c) => Some(c.max_decoding_message_size(1 << 30)),
            Err(e) => {
                tally.errors.push(format!("gRPC connect: {e}"));
                return tally;
            }
        }
    } else {
        None
    };
    let mut done = 0;
    let mut tries = 0u32;
    while done < rounds {
        let outcome = match &mut grpc_client {
            Some(c) => grpc_job(c, &spec).await,
            None => http_job(&http_client, &server.1, &spec).await,
        };
        match outcome {
            Ok((s, j, d)) => {
                tally.submit.push(s);
                tally.job.push(j);
                tally.download.push(d);
                done += 1;
                tries = 0;
            }
            Err(Failure::QueueFull) if tries < 200 => {
                tally.refused += 1;
                tries += 1;
                tokio::time::sleep(Duration::from_millis(100 + 20 * u64::from(tries))).await;
            }
            Err(Failure::QueueFull) => {
                tally.errors.push("the queue stayed full".into());
                return tally;
            }
            Err(Failure::Other(e)) => {
                tally.errors.push(e);
                done += 1;
            }
        }
    }
    tally
}

/// Resident memory of `pid`, bytes.
fn rss(pid: u32) -> u64 {
    std::fs::read_to_string(format!("/proc/{pid}/status"))
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("VmRSS:"))
                .and_then(|v| v.split_whitespace().next())
                .and_then(|v| v.parse::<u64>().ok())
        })
        .map_or(0, |kib| kib << 10)
}

fn percentile(sorted: &[Duration], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let k = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[k].as_secs_f64() * 1e3
}

fn main() {
    let clients: Vec<usize> = std::env::var("SIGNORINI_LOAD_CLIENTS")
        .unwrap_or_else(|_| "10,100,500".into())
        .split(',')
        .filter_map(|s| s.trim().parse().ok())
        .collect();
    let rounds: usize = std::env::var("SIGNORINI_LOAD_ROUNDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(2);
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("tokio");
    println!(
        "| N | load avg | jobs ok | refused (queue full) | errors | wall s | jobs/s | submit p50 / p99 ms | job p50 / p99 ms | download p50 / p99 ms | RSS MiB before / peak / after |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for n in clients {
        let dir = tempfile::tempdir().expect("tempdir");
        let server = TestServer::start(
            &dir.path().join("store.db"),
            &Options {
                workers: 2,
                queue_limit: 256,
                ..Options::default()
            },
        );
        let load = std::fs::read_to_string("/proc/loadavg")
            .map(|s| s.split_whitespace().next().unwrap_or("?").to_string())
            .unwrap_or_default();
        let pid = server.pid();
        let before = rss(pid);
        let peak = Arc::new(AtomicU64::new(before));
        let running = Arc::new(AtomicBool::new(true));
        let sampler = {
            let (peak, running) = (peak.clone(), running.clone());
            std::thread::spawn(move || {
                while running.load(Ordering::Relaxed) {
                    peak.fetch_max(rss(pid), Ordering::Relaxed);
                    std::thread::sleep(Duration::from_millis(50));
                }
            })
        };
        let addr = Arc::new((server.grpc_url.clone(), format!("http://{}", server.http)));
        let tallies = Arc::new(Mutex::new(Vec::new()));
        let started = Instant::now();
        runtime.block_on(async {
            let tasks: Vec<_> = (0..n)
                .map(|k| tokio::spawn(client(addr.clone(), k % 2 == 1, rounds)))
                .collect();
            for t in tasks {
                match t.await {
                    Ok(tally) => tallies.lock().expect("tallies").push(tally),
                    Err(e) => tallies.lock().expect("tallies").push(Tally {
                        errors: vec![format!("client task: {e}")],
                        ..Tally::default()
                    }),
                }
            }
        });
        let wall = started.elapsed().as_secs_f64();
        running.store(false, Ordering::Relaxed);
        let _ = sampler.join();
        std::thread::sleep(Duration::from_secs(1));
        let after = rss(pid);
        let tallies = std::mem::take(&mut *tallies.lock().expect("tallies"));
        let mut all = Tally::default();
        for t in tallies {
            all.submit.extend(t.submit);
            all.job.extend(t.job);
            all.download.extend(t.download);
            all.refused += t.refused;
            all.errors.extend(t.errors);
        }
        for v in [&mut all.submit, &mut all.job, &mut all.download] {
            v.sort();
        }
        let ok = all.job.len();
        let mib = |b: u64| b as f64 / f64::from(1 << 20);
        println!(
            "| {n} | {load} | {ok} | {} | {} | {wall:.1} | {:.1} | {:.1} / {:.1} | {:.0} / {:.0} | {:.1} / {:.1} | {:.0} / {:.0} / {:.0} |",
            all.refused,
            all.errors.len(),
            ok as f64 / wall,
            percentile(&all.submit, 0.5),
            percentile(&all.submit, 0.99),
            percentile(&all.job, 0.5),
            percentile(&all.job, 0.99),
            percentile(&all.download, 0.5),
            percentile(&all.download, 0.99),
            mib(before),
            mib(peak.load(Ordering::Relaxed)),
            mib(after),
        );
        if let Some(e) = all.errors.first() {
            println!("  first error of {}: {e}", all.errors.len());
        }
        drop(server);
    }
}
