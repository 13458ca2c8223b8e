//! (3) 20 jobs on 2 workers all finish; a full queue refuses with RESOURCE_EXHAUSTED / 429;
//! cancel stops a long job quickly and its status says cancelled.
//! (4) invalid specs give INVALID_ARGUMENT / 400 naming the field; the server keeps serving.
//! (6) with a token, mutating calls without it are refused (UNAUTHENTICATED / 401), health
//! and reads stay open.

mod common;

use common::{
    Options, TestServer, ball_json, ball_typed, submit_json, wait_running, wait_terminal,
};
use signorini::proto::v1 as pb;
use std::time::{Duration, Instant};
use tonic::Code;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn twenty_jobs_on_two_workers_all_finish() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(
        &dir.path().join("store.db"),
        &Options {
            workers: 2,
            ..Options::default()
        },
    );
    let mut submits = Vec::new();
    for k in 0..20u64 {
        let mut client = server.grpc().await;
        submits.push(tokio::spawn(async move {
            submit_json(&mut client, ball_json(1e-3, 2000 + 100 * k, 10), None)
                .await
                .expect("SubmitJob")
        }));
    }
    let mut ids = Vec::new();
    for s in submits {
        ids.push(s.await.expect("submit task"));
    }
    let mut client = server.grpc().await;
    for id in &ids {
        let s = wait_terminal(&mut client, id).await;
        assert_eq!(s.state, pb::JobState::Succeeded as i32, "{s:?}");
    }
    let listed = client
        .list_jobs(pb::ListJobsRequest::default())
        .await
        .expect("ListJobs")
        .into_inner()
        .jobs;
    assert_eq!(listed.len(), 20);
    assert!(
        listed
            .iter()
            .all(|j| j.state == pb::JobState::Succeeded as i32)
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn full_queue_is_refused_and_cancel_stops_a_long_job_quickly() {
    let dir = tempfile::tempdir().expect("tempdir");
    let opts = Options {
        workers: 1,
        queue_limit: 2,
        max_steps: Some(1_000_000_000),
        ..Options::default()
    };
    let server = TestServer::start(&dir.path().join("store.db"), &opts);
    let mut client = server.grpc().await;
    // About a minute or more of work, recording little.
    let long = ball_json(1e-6, 500_000_000, 1_000_000);
    let a = submit_json(&mut client, long.clone(), Some("long-a"))
        .await
        .expect("submit a");
    wait_running(&mut client, &a, 1).await;
    submit_json(&mut client, long.clone(), Some("long-b"))
        .await
        .expect("submit b (queued)");
    submit_json(&mut client, long.clone(), Some("long-c"))
        .await
        .expect("submit c (queued)");
    let err = submit_json(&mut client, long.clone(), Some("long-d"))
        .await
        .expect_err("queue full");
    assert_eq!(err.code(), Code::ResourceExhausted, "{err:?}");
    let (code, body) = server.http("POST", "/v1/jobs", Some(&long), None).await;
    assert_eq!(code, 429, "{body}");
    assert_eq!(body["error"]["field"], "queue");

    let started = Instant::now();
    let s = client
        .cancel_job(pb::CancelJobRequest { id: a.clone() })
        .await
        .expect("CancelJob")
        .into_inner();
    let took = started.elapsed();
    assert_eq!(s.state, pb::JobState::Cancelled as i32, "{s:?}");
    // The worker stops within a step; the rest is two RPC hops on a loaded machine.
    assert!(took < Duration::from_secs(2), "cancel took {took:?}");
    let (code, st) = server.http("GET", "/v1/jobs/long-a", None, None).await;
    assert_eq!(code, 200);
    assert_eq!(st["state"], "cancelled");

    // A queued job cancels at once (over HTTP); the other one then runs and is cancelled too.
    let (code, st) = server.http("DELETE", "/v1/jobs/long-c", None, None).await;
    assert_eq!(
        (code, st["state"].as_str()),
        (200, Some("cancelled")),
        "{st}"
    );
    wait_running(&mut client, "long-b", 1).await;
    let s = client
        .cancel_job(pb::CancelJobRequest {
            id: "long-b".into(),
        })
        .await
        .expect("cancel b")
        .into_inner();
    assert_eq!(s.state, pb::JobState::Cancelled as i32);
    let err = client
        .get_result(pb::GetResultRequest {
            id: "long-b".into(),
            ..Default::default()
        })
        .await
        .expect_err("no result");
    assert_eq!(err.code(), Code::FailedPrecondition);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn invalid_specs_name_the_field_and_the_server_keeps_serving() {
    let dir = tempfile::tempdir().expect("tempdir");
    let opts = Options {
        max_steps: Some(100_000),
        ..Options::default()
    };
    let server = TestServer::start(&dir.path().join("store.db"), &opts);
    let cases: &[(&str, &str)] = &[
        (
            r#"{"model":{"scene":"bouncing_ball"},"time":{"h":-0.1,"steps":10}}"#,
            "time.h",
        ),
        (
            r#"{"model":{"scene":"bouncing_ball","mass":-1},"time":{"h":0.01,"steps":10}}"#,
            "model.mass",
        ),
        (
            r#"{"model":{"scene":"bouncing_ball","mas":1},"time":{"h":0.01,"steps":10}}"#,
            "model.mas",
        ),
        (
            r#"{"model":{"scene":"no_such_scene"},"time":{"h":0.01,"steps":10}}"#,
            "model.scene",
        ),
        (r#"{"time":{"h":0.01,"steps":10}}"#, "model"),
        (
            r#"{"model":{"scene":"bouncing_ball"},"time":{"h":0.001,"steps":1000000}}"#,
            "time",
        ),
    ];
    let mut client = server.grpc().await;
    for (spec, field) in cases {
        let (code, body) = server.http("POST", "/v1/jobs", Some(spec), None).await;
        assert_eq!(code, 400, "{spec}: {body}");
        assert_eq!(body["error"]["field"], *field, "{spec}: {body}");
        assert!(
            body["error"]["reason"]
                .as_str()
                .is_some_and(|r| !r.is_empty())
        );
        let err = submit_json(&mut client, spec.to_string(), None)
            .await
            .expect_err("invalid");
        assert_eq!(err.code(), Code::InvalidArgument, "{spec}");
        assert!(
            err.message().starts_with(&format!("{field}:")),
            "{spec}: {}",
            err.message()
        );
        assert_eq!(
            err.metadata()
                .get("x-error-field")
                .and_then(|v| v.to_str().ok()),
            Some(*field)
        );
    }
    // Typed spec without time.h; NaN restitution.
    let mut typed = ball_typed(1e-3, 10, 1);
    typed.time = Some(pb::TimeSpec {
        steps: Some(10),
        ..Default::default()
    });
    let req = pb::SubmitJobRequest {
        spec: Some(pb::submit_job_request::Spec::Typed(typed)),
        id: None,
    };
    let err = client.submit_job(req).await.expect_err("missing h");
    assert_eq!(
        (
            err.code(),
            err.metadata()
                .get("x-error-field")
                .and_then(|v| v.to_str().ok())
        ),
        (Code::InvalidArgument, Some("time.h"))
    );
    let (code, body) = server
        .http("POST", "/v1/jobs", Some("{not json"), None)
        .await;
    assert_eq!(code, 400, "{body}");
    let (code, body) = server
        .http(
            "POST",
            "/v1/jobs?id=bad%20id",
            Some(&ball_json(1e-3, 10, 1)),
            None,
        )
        .await;
    assert_eq!(
        (code, body["error"]["field"].as_str()),
        (400, Some("id")),
        "{body}"
    );
    let (code, _) = server.http("GET", "/v1/jobs/nope", None, None).await;
    assert_eq!(code, 404);
    // Every HTTP error has the JSON shape: an unknown route, and a body over the 64 MiB limit
    // (axum answered both in plain text, or with no body at all).
    let (code, body) = server.http("GET", "/v1/nope", None, None).await;
    assert_eq!(
        (code, body["error"]["field"].as_str()),
        (404, Some("path")),
        "{body}"
    );
    let huge = format!("{{\"name\": \"{}\"}}", "x".repeat(64 << 20));
    let (code, body) = server.http("POST", "/v1/jobs", Some(&huge), None).await;
    assert_eq!(
        (code, body["error"]["field"].as_str()),
        (413, Some("body")),
        "{body}"
    );

    // Still serving, and nothing invalid was stored.
    let id = submit_json(&mut client, ball_json(1e-3, 100, 1), None)
        .await
        .expect("valid job");
    assert_eq!(
        wait_terminal(&mut client, &id).await.state,
        pb::JobState::Succeeded as i32
    );
    let listed = client
        .list_jobs(pb::ListJobsRequest::default())
        .await
        .expect("ListJobs")
        .into_inner()
        .jobs;
    assert_eq!(listed.len(), 1);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn token_guards_mutating_calls_and_health_stays_open() {
    let dir = tempfile::tempdir().expect("tempdir");
    let token = "s3cret-token";
    let server = TestServer::start(
        &dir.path().join("store.db"),
        &Options {
            token: Some(token.into()),
            ..Options::default()
        },
    );
    let spec = ball_json(1e-3, 100, 1);

    let (code, body) = server.http("POST", "/v1/jobs", Some(&spec), None).await;
    assert_eq!(code, 401, "{body}");
    let (code, _) = server
        .http("POST", "/v1/jobs", Some(&spec), Some("wrong"))
        .await;
    assert_eq!(code, 401);
    let (code, body) = server
        .http("POST", "/v1/jobs", Some(&spec), Some(token))
        .await;
    assert_eq!(code, 201, "{body}");
    let id = body["id"].as_str().expect("id").to_string();
    let (code, _) = server
        .http("DELETE", &format!("/v1/jobs/{id}"), None, None)
        .await;
    assert_eq!(code, 401);

    let mut client = server.grpc().await;
    let err = submit_json(&mut client, spec.clone(), None)
        .await
        .expect_err("no token");
    assert_eq!(err.code(), Code::Unauthenticated);
    let err = client
        .cancel_job(pb::CancelJobRequest { id: id.clone() })
        .await
        .expect_err("no token");
    assert_eq!(err.code(), Code::Unauthenticated);
    let mut req = tonic::Request::new(pb::SubmitJobRequest {
        spec: Some(pb::submit_job_request::Spec::Json(spec.clone())),
        id: None,
    });
    req.metadata_mut().insert(
        "authorization",
        format!("Bearer {token}").parse().expect("header"),
    );
    client.submit_job(req).await.expect("with token");

    // Health and reads stay open.
    let (code, body) = server.http("GET", "/healthz", None, None).await;
    assert_eq!((code, body["status"].as_str()), (200, Some("ok")));
    let (code, _) = server
        .http("GET", &format!("/v1/jobs/{id}"), None, None)
        .await;
    assert_eq!(code, 200);
    let (code, _) = server.http_raw("GET", "/metrics", None, None).await;
    assert_eq!(code, 200);
    let channel = tonic::transport::Endpoint::from_shared(server.grpc_url.clone())
        .expect("url")
        .connect()
        .await
        .expect("connect");
    let mut health = tonic_health::pb::health_client::HealthClient::new(channel);
    let resp = health
        .check(tonic_health::pb::HealthCheckRequest {
            service: "signorini.v1.Simulation".into(),
        })
        .await
        .expect("health check")
        .into_inner();
    assert_eq!(
        resp.status,
        tonic_health::pb::health_check_response::ServingStatus::Serving as i32
    );
    assert_eq!(
        wait_terminal(&mut client, &id).await.state,
        pb::JobState::Succeeded as i32
    );
}
