//! Service benchmark (harness = false): one job through `signorini serve` with zenoh streaming of
//! every step, against `signorini run` (CSV, no streaming) on the same spec.
//!
//!   cargo bench --bench service            # STEPS=1000000 by default; SIGNORINI_BENCH_STEPS=N
//!
//! Reports steps/s of both (from each run's summary.json: the time inside the integration loop,
//! observers included), their ratio, frames/s received by a zenoh subscriber on loopback, and the
//! median latency from a step's computation (`computed_unix_ns` in the frame) to its arrival.

#[path = "../tests/common/mod.rs"]
mod common;

use common::{Options, TestServer, zenoh_barrier};
use prost::Message;
use signorini::proto::v1 as pb;
use std::time::{SystemTime, UNIX_EPOCH};

fn now_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

fn main() {
    let steps: u64 = std::env::var("SIGNORINI_BENCH_STEPS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1_000_000);
    let dir = tempfile::tempdir().expect("tempdir");
    let spec_json = common::ball_json(1e-5, steps, 1);
    let spec_path = dir.path().join("ball.json");
    std::fs::write(&spec_path, &spec_json).expect("writing spec");

    // 1. In-process run, CSV only.
    let out = dir.path().join("run");
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_signorini"))
        .args([
            "run",
            &spec_path.display().to_string(),
            "--out",
            &out.display().to_string(),
            "-q",
        ])
        .status()
        .expect("signorini run");
    assert!(status.success());
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).expect("summary"))
            .expect("json");
    let run_sps = summary["steps_per_s"].as_f64().expect("steps_per_s");

    // 2. Through the service, one subscriber on the energy key.
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("tokio");
    let (service_sps, frames, frames_per_s, median_ms, p90_ms, received) =
        runtime.block_on(async {
            let server = TestServer::start(
                &dir.path().join("store.db"),
                &Options {
                    workers: 1,
                    ..Options::default()
                },
            );
            let session = server.zenoh_session().await;
            let id = "bench-1";
            let sub = session
                .declare_subscriber(signorini::stream::energy_key(id))
                .await
                .expect("subscribe");
            zenoh_barrier(&session, id).await;
            let mut client = server.grpc().await;
            common::submit_json(&mut client, spec_json.clone(), Some(id))
                .await
                .expect("submit");
            let mut latencies = Vec::with_capacity(steps as usize + 1);
            let (mut frames, mut received) = (0u64, 0u64);
            let mut first = 0u64;
            let last;
            loop {
                let sample = sub.recv_async().await.expect("frame");
                let arrived = now_ns();
                let f = pb::StepFrame::decode(&*sample.payload().to_bytes()).expect("frame");
                if frames == 0 {
                    first = arrived;
                }
                frames += 1;
                received += f.step.len() as u64;
                latencies.extend(
                    f.computed_unix_ns
                        .iter()
                        .map(|&c| arrived.saturating_sub(c)),
                );
                if f.last {
                    last = arrived;
                    break;
                }
            }
            let r = client
                .get_result(pb::GetResultRequest {
                    id: id.into(),
                    ..Default::default()
                })
                .await
                .expect("result")
                .into_inner();
            let summary: serde_json::Value =
                serde_json::from_str(&r.summary_json).expect("summary");
            latencies.sort_unstable();
            let pct = |q: f64| latencies[((latencies.len() - 1) as f64 * q) as usize] as f64 / 1e6;
            let span = (last.saturating_sub(first)) as f64 / 1e9;
            drop(sub);
            let _ = session.close().await;
            (
                summary["steps_per_s"].as_f64().expect("steps_per_s"),
                frames,
                if span > 0.0 {
                    frames as f64 / span
                } else {
                    f64::NAN
                },
                pct(0.5),
                pct(0.9),
                received,
            )
        });
    println!("spec: bouncing_ball, h = 1e-5, {steps} steps, output.every = 1");
    println!("signorini run (CSV, no streaming): {run_sps:>12.0} steps/s");
    println!("service + zenoh every step:        {service_sps:>12.0} steps/s");
    println!(
        "ratio service / run:               {:>12.3}",
        service_sps / run_sps
    );
    println!("frames received: {frames} ({received} steps), {frames_per_s:.0} frames/s");
    println!("step computed → arrival at subscriber: median {median_ms:.3} ms, p90 {p90_ms:.3} ms");
}
