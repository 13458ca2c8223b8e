//! Limits and housekeeping (issue 13, part 2), against the real server: a 20 MB `name` and an
//! over-long expression are refused naming their field; the job list is paged (newest first,
//! `limit`, `page_token`, `state`) over HTTP, gRPC and `signorini list`; a finished job is
//! removed with its result by `DELETE …?purge=true` and gRPC `DeleteJob`, an unfinished one is
//! not, nor one whose result is being streamed until its reader is done.

mod common;

use common::{Options, TestServer, ball_json, submit_json, wait_running, wait_terminal};
use serde_json::{Value, json};
use signorini::proto::v1 as pb;
use std::path::Path;
use std::process::Command;
use tonic::Code;

fn field(status: &tonic::Status) -> Option<&str> {
    status
        .metadata()
        .get("x-error-field")
        .and_then(|v| v.to_str().ok())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn long_texts_are_refused_naming_the_field() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("s.db"), &Options::default());
    let mut client = server.grpc().await;

    // The 20 MB name (it used to be stored, and every list carried it).
    let mut spec: Value = serde_json::from_str(&ball_json(1e-3, 10, 1)).expect("spec");
    spec["name"] = json!("x".repeat(20 << 20));
    let (code, body) = server
        .http("POST", "/v1/jobs", Some(&spec.to_string()), None)
        .await;
    assert_eq!(
        (code, body["error"]["field"].as_str()),
        (400, Some("name")),
        "{body}"
    );
    spec["name"] = json!("y".repeat(257));
    let err = submit_json(&mut client, spec.to_string(), None)
        .await
        .expect_err("a 257-byte name");
    assert_eq!(
        (err.code(), field(&err)),
        (Code::InvalidArgument, Some("name"))
    );
    spec["name"] = json!("z".repeat(256));
    submit_json(&mut client, spec.to_string(), None)
        .await
        .expect("a 256-byte name is fine");

    // Any other text: an expression of a user model, named by its path.
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/pendulum_lagrangian.toml");
    let mut pendulum: Value =
        toml::from_str(&std::fs::read_to_string(path).expect("example")).expect("TOML");
    pendulum["model"]["constraints"][1]["expr"] = json!(format!("y{}", " + 0*x".repeat(4000)));
    let (code, body) = server
        .http("POST", "/v1/jobs", Some(&pendulum.to_string()), None)
        .await;
    assert_eq!(
        (code, body["error"]["field"].as_str()),
        (400, Some("model.constraints[1].expr")),
        "{body}"
    );
    let (code, body) = server.http("GET", "/v1/jobs", None, None).await;
    assert_eq!(code, 200);
    assert_eq!(
        body["jobs"].as_array().map(Vec::len),
        Some(1),
        "only the valid job"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_job_list_is_paged_newest_first_and_filtered_by_state() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(
        &dir.path().join("s.db"),
        &Options {
            workers: 1,
            ..Options::default()
        },
    );
    let mut client = server.grpc().await;
    let mut ids = Vec::new();
    for k in 0..7 {
        let id = submit_json(
            &mut client,
            ball_json(1e-3, 100, 1),
            Some(&format!("job-{k}")),
        )
        .await
        .expect("submit");
        wait_terminal(&mut client, &id).await;
        ids.push(id);
    }
    let long = submit_json(&mut client, ball_json(1e-6, 50_000_000, 1000), Some("long"))
        .await
        .expect("submit long");
    wait_running(&mut client, &long, 1).await;
    client
        .cancel_job(pb::CancelJobRequest { id: long.clone() })
        .await
        .expect("cancel");
    ids.push(long.clone());
    let newest_first: Vec<String> = ids.iter().rev().cloned().collect();

    // HTTP: pages of 3, following next_page_token to the end.
    let mut seen = Vec::new();
    let mut token = String::new();
    for page in 0.. {
        let (code, body) = server
            .http(
                "GET",
                &format!("/v1/jobs?limit=3&page_token={token}"),
                None,
                None,
            )
            .await;
        assert_eq!(code, 200, "{body}");
        let jobs = body["jobs"].as_array().expect("jobs");
        assert!(jobs.len() <= 3);
        seen.extend(
            jobs.iter()
                .map(|j| j["id"].as_str().expect("id").to_string()),
        );
        match body["next_page_token"].as_str() {
            Some(t) => token = t.to_string(),
            None => {
                assert!(body["next_page_token"].is_null(), "{body}");
                assert_eq!(page, 2, "8 jobs in pages of 3");
                break;
            }
        }
    }
    assert_eq!(seen, newest_first);
    let (_, body) = server
        .http("GET", "/v1/jobs?state=cancelled", None, None)
        .await;
    assert_eq!(body["jobs"], json!([body["jobs"][0].clone()]), "{body}");
    assert_eq!(body["jobs"][0]["id"], long.as_str());
    for (query, field) in [
        ("limit=-1", "limit"),
        ("state=done", "state"),
        ("page_token=xyz", "page_token"),
    ] {
        let (code, body) = server
            .http("GET", &format!("/v1/jobs?{query}"), None, None)
            .await;
        assert_eq!(
            (code, body["error"]["field"].as_str()),
            (400, Some(field)),
            "{query}: {body}"
        );
    }

    // gRPC: the same pages, and the state filter.
    let mut seen = Vec::new();
    let mut token = String::new();
    loop {
        let page = client
            .list_jobs(pb::ListJobsRequest {
                limit: 3,
                page_token: token.clone(),
                state: 0,
            })
            .await
            .expect("ListJobs")
            .into_inner();
        seen.extend(page.jobs.into_iter().map(|j| j.id));
        if page.next_page_token.is_empty() {
            break;
        }
        token = page.next_page_token;
    }
    assert_eq!(seen, newest_first);
    let page = client
        .list_jobs(pb::ListJobsRequest {
            state: pb::JobState::Succeeded as i32,
            ..Default::default()
        })
        .await
        .expect("ListJobs succeeded")
        .into_inner();
    assert_eq!(page.jobs.len(), 7);
    assert!(page.next_page_token.is_empty());

    // `signorini list`.
    let out = Command::new(env!("CARGO_BIN_EXE_signorini"))
        .args(["list", "--limit", "2", "--server", &server.grpc_url])
        .output()
        .expect("signorini list");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).expect("utf-8");
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 2, "{text}");
    assert!(lines[0].starts_with("long\tcancelled\t"), "{text}");
    assert!(
        lines[1].starts_with("job-6\tsucceeded\t100.0%\tball"),
        "{text}"
    );
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("--page-token"),
        "the next page is named"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn purge_removes_a_finished_job_and_its_result_but_not_a_running_one() {
    let dir = tempfile::tempdir().expect("tempdir");
    let token = "t0k";
    let server = TestServer::start(
        &dir.path().join("s.db"),
        &Options {
            token: Some(token.into()),
            ..Options::default()
        },
    );
    let mut client = server.grpc().await;
    let (code, body) = server
        .http(
            "POST",
            "/v1/jobs?id=done",
            Some(&ball_json(1e-3, 50_000, 1)),
            Some(token),
        )
        .await;
    assert_eq!(code, 201, "{body}");
    wait_terminal(&mut client, "done").await;
    let (code, body) = server
        .http(
            "POST",
            "/v1/jobs?id=busy",
            Some(&ball_json(1e-6, 50_000_000, 1000)),
            Some(token),
        )
        .await;
    assert_eq!(code, 201, "{body}");
    wait_running(&mut client, "busy", 1).await;

    let (code, _) = server
        .http("DELETE", "/v1/jobs/done?purge=true", None, None)
        .await;
    assert_eq!(code, 401, "purging needs the token");
    let (code, body) = server
        .http("DELETE", "/v1/jobs/busy?purge=true", None, Some(token))
        .await;
    assert_eq!(
        (code, body["error"]["field"].as_str()),
        (409, Some("id")),
        "{body}"
    );
    let (code, body) = server
        .http("DELETE", "/v1/jobs/done?purge=true", None, Some(token))
        .await;
    assert_eq!((code, body), (200, json!({ "id": "done", "purged": true })));
    for path in ["/v1/jobs/done", "/v1/jobs/done/result"] {
        let (code, body) = server.http("GET", path, None, None).await;
        assert_eq!(
            (code, body["error"]["field"].as_str()),
            (404, Some("id")),
            "{path}"
        );
    }
    // The id is free again, and the new job's result is its own (no row of the old one left).
    let (code, _) = server
        .http(
            "POST",
            "/v1/jobs?id=done",
            Some(&ball_json(1e-3, 10, 1)),
            Some(token),
        )
        .await;
    assert_eq!(code, 201);
    wait_terminal(&mut client, "done").await;
    let (code, body) = server.http("GET", "/v1/jobs/done/result", None, None).await;
    assert_eq!(code, 200);
    assert_eq!(body["steps"]["step"], json!((0..=10).collect::<Vec<u64>>()));

    // gRPC: FAILED_PRECONDITION while running; after the cancel it goes.
    let mut req = tonic::Request::new(pb::DeleteJobRequest { id: "busy".into() });
    req.metadata_mut().insert(
        "authorization",
        format!("Bearer {token}").parse().expect("header"),
    );
    let err = client.delete_job(req).await.expect_err("running");
    assert_eq!(
        (err.code(), field(&err)),
        (Code::FailedPrecondition, Some("id"))
    );
    let mut req = tonic::Request::new(pb::CancelJobRequest { id: "busy".into() });
    req.metadata_mut().insert(
        "authorization",
        format!("Bearer {token}").parse().expect("header"),
    );
    client.cancel_job(req).await.expect("cancel");
    let out = Command::new(env!("CARGO_BIN_EXE_signorini"))
        .args([
            "delete",
            "busy",
            "--server",
            &server.grpc_url,
            "--token",
            token,
        ])
        .output()
        .expect("signorini delete");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let page = client
        .list_jobs(pb::ListJobsRequest::default())
        .await
        .expect("ListJobs")
        .into_inner();
    assert_eq!(
        page.jobs.iter().map(|j| j.id.as_str()).collect::<Vec<_>>(),
        ["done"]
    );
}

/// `--retain-days`: a finished job goes once it has been over for longer (here 2 s, as a
/// fraction of a day), with its result; a running one stays.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn finished_jobs_expire_after_the_retention_and_running_ones_stay() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(
        &dir.path().join("s.db"),
        &Options {
            retain_days: Some(2.0 / 86_400.0),
            ..Options::default()
        },
    );
    let mut client = server.grpc().await;
    let done = submit_json(&mut client, ball_json(1e-3, 100, 1), Some("short-lived"))
        .await
        .expect("submit");
    wait_terminal(&mut client, &done).await;
    let busy = submit_json(&mut client, ball_json(1e-6, 50_000_000, 1000), Some("busy"))
        .await
        .expect("submit");
    wait_running(&mut client, &busy, 1).await;
    let (code, body) = server.http("GET", "/v1/jobs/short-lived", None, None).await;
    assert_eq!(code, 200, "still there right after its end");
    let finished_ms = body["finished_ms"].as_u64().expect("finished_ms");
    let start = std::time::Instant::now();
    // Polls the status: a sweep never purges a result being read (see the next test), so
    // fetching it here would only postpone the expiry.
    loop {
        let (code, _) = server.http("GET", "/v1/jobs/short-lived", None, None).await;
        if code == 404 {
            let (code, _) = server
                .http("GET", "/v1/jobs/short-lived/result", None, None)
                .await;
            assert_eq!(code, 404, "the result goes with the job");
            break;
        }
        assert!(start.elapsed() < common::PATIENCE, "never expired");
        tokio::time::sleep(std::time::Duration::from_millis(200)).await;
    }
    let now_ms = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .expect("clock")
        .as_millis() as u64;
    assert!(now_ms >= finished_ms + 2000, "not before its time");
    let (code, body) = server.http("GET", "/v1/jobs/busy", None, None).await;
    assert_eq!((code, body["state"].as_str()), (200, Some("running")));
}

/// A purge never cuts a result stream: while a client reads a result, `DELETE …?purge=true` and
/// gRPC `DeleteJob` answer 409 / FAILED_PRECONDITION naming the readers, the stream goes on to
/// its last row, and once it is closed the purge goes through.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_result_being_streamed_is_purged_only_after_its_reader_is_done() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("s.db"), &Options::default());
    let mut client = server.grpc().await;
    // About 50 stored chunks: far more than the stream's buffers hold.
    let id = submit_json(&mut client, ball_json(1e-6, 500_000, 1), Some("read"))
        .await
        .expect("submit");
    wait_terminal(&mut client, &id).await;
    let mut stream = common::result_stream(&mut client, &id).await;
    let mut rows = 0;
    let mut count = |msg: pb::ResultChunk| {
        if let Some(pb::result_chunk::Part::Rows(r)) = msg.part {
            rows += r.step.len();
        }
    };
    count(stream.message().await.expect("stream").expect("a header"));

    let (code, body) = server
        .http("DELETE", "/v1/jobs/read?purge=true", None, None)
        .await;
    assert_eq!(
        (code, &body["error"]["field"]),
        (409, &json!("id")),
        "{body}"
    );
    let reason = body["error"]["reason"].as_str().expect("a reason");
    assert!(reason.contains("being read by 1 client"), "{reason}");
    let err = client
        .delete_job(pb::DeleteJobRequest { id: id.clone() })
        .await
        .expect_err("refused while read");
    assert_eq!(err.code(), Code::FailedPrecondition, "{err:?}");

    while let Some(msg) = stream.message().await.expect("the stream, uncut") {
        count(msg);
    }
    assert_eq!(rows, 500_001, "every row");
    drop(stream);
    // The server drops its reader when the stream's producer ends, a moment after the last
    // message.
    let start = std::time::Instant::now();
    loop {
        let (code, body) = server
            .http("DELETE", "/v1/jobs/read?purge=true", None, None)
            .await;
        if code == 200 {
            assert_eq!(body, json!({ "id": "read", "purged": true }));
            break;
        }
        assert_eq!(code, 409, "{body}");
        assert!(start.elapsed() < common::PATIENCE, "never released");
        tokio::time::sleep(std::time::Duration::from_millis(50)).await;
    }
}
