//! The API's edges (issue 13, parts 3 and 4), against the real server: `model` with `analysis`
//! is refused naming both; every HTTP error — a bad query, a wrong method, malformed JSON — has
//! the JSON error shape, malformed JSON located by line and column; the bearer scheme is
//! case-insensitive; a second server on the same store is refused, and a server that cannot
//! bind its port creates no store.

mod common;

use common::{Options, PATIENCE, TestServer, ball_json, free_port, submit_json, wait_terminal};
use serde_json::Value;
use signorini::proto::v1 as pb;
use std::net::TcpListener;
use std::process::{Command, Stdio};
use std::time::Instant;

fn json(bytes: &[u8]) -> Value {
    serde_json::from_slice(bytes).unwrap_or(Value::Null)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_http_error_is_json_and_names_its_field() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("s.db"), &Options::default());
    let mut client = server.grpc().await;
    let id = submit_json(&mut client, ball_json(1e-3, 100, 1), None)
        .await
        .expect("submit");
    wait_terminal(&mut client, &id).await;

    // A model next to an analysis used to run the analysis and ignore the model.
    let both = r#"{"model":{"scene":"bouncing_ball"},"time":{"h":0.001,"steps":10},
                   "analysis":{"kind":"forced_response","excitation":"force","cells":10}}"#;
    let (code, body) = server.http("POST", "/v1/jobs", Some(both), None).await;
    assert_eq!(
        (code, body["error"]["field"].as_str()),
        (400, Some("analysis")),
        "{body}"
    );
    let reason = body["error"]["reason"].as_str().unwrap_or_default();
    assert!(
        reason.contains("`model`") && reason.contains("`analysis`"),
        "{reason}"
    );

    let cases: [(&str, &str, &str, u16, &str); 6] = [
        (
            "GET",
            &format!("/v1/jobs/{id}/result?every=-1"),
            "",
            400,
            "every",
        ),
        (
            "GET",
            &format!("/v1/jobs/{id}/result?format=xml"),
            "",
            400,
            "format",
        ),
        (
            "GET",
            &format!("/v1/jobs/{id}/result?from=9&to=3"),
            "",
            400,
            "from",
        ),
        ("GET", "/v1/jobs?limit=many", "", 400, "limit"),
        ("PUT", "/v1/jobs", "{}", 405, "method"),
        ("POST", &format!("/v1/jobs/{id}/result"), "", 405, "method"),
    ];
    for (method, path, body, want, field) in cases {
        let (code, head, bytes) = server
            .request(method, path, body, &[("content-type", "application/json")])
            .await;
        let body = json(&bytes);
        assert_eq!(
            (code, body["error"]["field"].as_str()),
            (want, Some(field)),
            "{method} {path}: {}",
            String::from_utf8_lossy(&bytes)
        );
        assert_eq!(head["content-type"], "application/json", "{method} {path}");
        assert!(body["error"]["reason"].is_string(), "{method} {path}");
    }

    // Malformed JSON: where it breaks, not the field serde happened to be in (`model.?`).
    let (code, body) = server
        .http(
            "POST",
            "/v1/jobs",
            Some("{\"model\": {\"scene\": \"bouncing_ball\",\n \"mass\": }}"),
            None,
        )
        .await;
    assert_eq!(
        (code, body["error"]["field"].as_str()),
        (400, Some("spec")),
        "{body}"
    );
    let reason = body["error"]["reason"].as_str().unwrap_or_default();
    assert!(
        reason.starts_with("malformed JSON at line 2, column "),
        "{reason}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_bearer_scheme_is_case_insensitive() {
    let dir = tempfile::tempdir().expect("tempdir");
    let token = "Tok3n";
    let server = TestServer::start(
        &dir.path().join("s.db"),
        &Options {
            token: Some(token.into()),
            ..Options::default()
        },
    );
    let spec = ball_json(1e-3, 10, 1);
    for scheme in ["Bearer", "bearer", "BEARER"] {
        let auth = format!("{scheme} {token}");
        let (code, _, bytes) = server
            .request(
                "POST",
                "/v1/jobs",
                &spec,
                &[
                    ("content-type", "application/json"),
                    ("authorization", &auth),
                ],
            )
            .await;
        assert_eq!(code, 201, "{scheme}: {}", String::from_utf8_lossy(&bytes));
    }
    let mut client = server.grpc().await;
    let mut req = tonic::Request::new(pb::SubmitJobRequest {
        spec: Some(pb::submit_job_request::Spec::Json(spec.clone())),
        id: None,
    });
    req.metadata_mut().insert(
        "authorization",
        format!("bearer {token}").parse().expect("header"),
    );
    client
        .submit_job(req)
        .await
        .expect("lowercase bearer over gRPC");
    for auth in ["Basic Tok3n", "Bearer tok3n", "BearerTok3n"] {
        let (code, _, bytes) = server
            .request(
                "POST",
                "/v1/jobs",
                &spec,
                &[
                    ("content-type", "application/json"),
                    ("authorization", auth),
                ],
            )
            .await;
        assert_eq!(
            (code, json(&bytes)["error"]["field"].as_str()),
            (401, Some("authorization")),
            "{auth}"
        );
    }
}

/// `signorini serve` on `store` with free ports; its exit status and stderr once it ends.
fn serve_once(store: &std::path::Path, http: &str) -> (bool, String) {
    let child = Command::new(env!("CARGO_BIN_EXE_signorini"))
        .arg("serve")
        .args(["--grpc-addr", "127.0.0.1:0", "--http-addr", http])
        .arg("--store")
        .arg(store)
        .args(["--zenoh-listen", &format!("tcp/127.0.0.1:{}", free_port())])
        .env_remove("SIGNORINI_CONFIG")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("starting serve");
    let started = Instant::now();
    let out = child.wait_with_output().expect("serve output");
    assert!(started.elapsed() < PATIENCE);
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_store_serves_one_server_and_a_failed_start_creates_nothing() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("s.db");
    let server = TestServer::start(&store, &Options::default());
    // The second server on the same file stops at once, saying why, and runs nothing.
    let (ok, stderr) = serve_once(&store, "127.0.0.1:0");
    assert!(!ok);
    assert!(
        stderr.contains("is in use by another signorini serve"),
        "{stderr}"
    );
    let mut client = server.grpc().await;
    let id = submit_json(&mut client, ball_json(1e-3, 10, 1), None)
        .await
        .expect("the first server still serves");
    assert_eq!(
        wait_terminal(&mut client, &id).await.state,
        pb::JobState::Succeeded as i32
    );
    drop(server);

    // A taken port: the server ends with the reason, and no store file appears.
    let taken = TcpListener::bind("127.0.0.1:0").expect("a port");
    let addr = taken.local_addr().expect("addr").to_string();
    let fresh = dir.path().join("fresh.db");
    let (ok, stderr) = serve_once(&fresh, &addr);
    assert!(!ok);
    assert!(stderr.contains(&format!("binding {addr}")), "{stderr}");
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .expect("dir")
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with("fresh"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

/// A container engine stops the service with SIGTERM and kills it 5 s later (podman, docker):
/// the graceful shutdown must finish well inside that, with the zenoh queryables (which hold the
/// engine) served during the run. It once waited the streamer's whole 5 s timeout for them.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigterm_stops_the_service_promptly_and_cleanly() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut server = TestServer::start(&dir.path().join("s.db"), &Options::default());
    let mut client = server.grpc().await;
    let id = submit_json(&mut client, ball_json(1e-3, 1000, 1), Some("before-stop"))
        .await
        .expect("submit");
    wait_terminal(&mut client, &id).await;
    let session = server.zenoh_session().await;
    let replies = session
        .get("signorini/v1/jobs/before-stop/status")
        .await
        .expect("status query");
    assert!(
        replies.recv_async().await.is_ok(),
        "the status queryable answers"
    );
    drop(replies);
    let _ = session.close().await;
    drop(client);
    let (status, took) = server
        .terminate(std::time::Duration::from_secs(10))
        .expect("serve exits after SIGTERM");
    assert!(status.success(), "clean exit: {status:?}");
    assert!(
        took < std::time::Duration::from_secs(3),
        "shutdown took {took:?}"
    );
}
