//! Per-client tokens with scopes (`serve --tokens FILE`): with tokens configured
//! every call but `/healthz` needs one, over HTTP and gRPC: a read without a token is refused
//! (401 / UNAUTHENTICATED), a write with a read token is refused (403 / PERMISSION_DENIED), a
//! write token reads and writes; the file holds SHA-256 digests, never the tokens.

mod common;

use common::{Options, TestServer, ball_json};
use signorini::proto::v1 as pb;
use signorini::server::auth::sha256_hex;
use tonic::Request;

fn with_token<T>(msg: T, token: &str) -> Request<T> {
    let mut req = Request::new(msg);
    req.metadata_mut().insert(
        "authorization",
        format!("Bearer {token}").parse().expect("metadata"),
    );
    req
}

#[tokio::test(flavor = "multi_thread")]
async fn reads_need_a_token_and_writes_a_write_token_over_http_and_grpc() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let tokens = tmp.path().join("tokens.toml");
    std::fs::write(
        &tokens,
        format!(
            "[[token]]\nname = \"dashboard\"\nscope = \"read\"\nsha256 = \"{}\"\n\n[[token]]\nname = \"ci\"\nscope = \"write\"\nsha256 = \"{}\"\n",
            sha256_hex("read-token-1"),
            sha256_hex("write-token-2")
        ),
    )
    .expect("tokens file");
    let tokens = tokens.display().to_string();
    let server = TestServer::start_with(
        &tmp.path().join("store.db"),
        &Options::default(),
        &["--tokens", &tokens],
    );
    let (read, write) = (Some("read-token-1"), Some("write-token-2"));
    let spec = ball_json(1e-3, 100, 1);

    // HTTP.
    let (code, _) = server.http("GET", "/healthz", None, None).await;
    assert_eq!(code, 200, "/healthz stays open");
    for path in ["/v1/jobs", "/v1/capabilities", "/metrics"] {
        let (code, body) = server.http("GET", path, None, None).await;
        assert_eq!(code, 401, "GET {path} without a token: {body}");
        let (code, body) = server.http("GET", path, None, Some("wrong")).await;
        assert_eq!(code, 401, "GET {path} with an unknown token: {body}");
        let (code, _) = server.http_raw("GET", path, None, read).await;
        assert_eq!(code, 200, "GET {path} with a read token");
    }
    let (code, body) = server.http("POST", "/v1/jobs", Some(&spec), None).await;
    assert_eq!(code, 401, "{body}");
    let (code, body) = server.http("POST", "/v1/jobs", Some(&spec), read).await;
    assert_eq!(code, 403, "{body}");
    assert_eq!(body["error"]["field"], "authorization", "{body}");
    assert!(
        body["error"]["reason"]
            .as_str()
            .unwrap_or_default()
            .contains("dashboard"),
        "{body}"
    );
    let (code, body) = server.http("POST", "/v1/jobs", Some(&spec), write).await;
    assert_eq!(code, 201, "{body}");
    let id = body["id"].as_str().expect("an id").to_string();
    let (code, body) = server
        .http("GET", &format!("/v1/jobs/{id}"), None, write)
        .await;
    assert_eq!(code, 200, "a write token reads too: {body}");
    let (code, _) = server
        .http("DELETE", &format!("/v1/jobs/{id}"), None, read)
        .await;
    assert_eq!(code, 403, "cancel with a read token");

    // gRPC.
    let mut client = server.grpc().await;
    let get = || pb::GetJobRequest { id: id.clone() };
    let status = client
        .get_job(get())
        .await
        .expect_err("GetJob without a token");
    assert_eq!(status.code(), tonic::Code::Unauthenticated, "{status:?}");
    let status = client
        .capabilities(pb::CapabilitiesRequest {})
        .await
        .expect_err("Capabilities without a token");
    assert_eq!(status.code(), tonic::Code::Unauthenticated, "{status:?}");
    let job = client
        .get_job(with_token(get(), "read-token-1"))
        .await
        .expect("GetJob with a read token")
        .into_inner();
    assert_eq!(job.id, id);
    let submit = |token: &str| {
        with_token(
            pb::SubmitJobRequest {
                spec: Some(pb::submit_job_request::Spec::Json(spec.clone())),
                id: None,
            },
            token,
        )
    };
    let status = client
        .submit_job(submit("read-token-1"))
        .await
        .expect_err("SubmitJob with a read token");
    assert_eq!(status.code(), tonic::Code::PermissionDenied, "{status:?}");
    let next = client
        .submit_job(submit("write-token-2"))
        .await
        .expect("SubmitJob with a write token")
        .into_inner()
        .id;
    // WatchJob is a read: with the read token it follows the job to its end.
    let mut watch = client
        .watch_job(with_token(
            pb::WatchJobRequest {
                id: next.clone(),
                ..Default::default()
            },
            "read-token-1",
        ))
        .await
        .expect("WatchJob with a read token")
        .into_inner();
    let mut ended = false;
    while let Some(frame) = watch.message().await.expect("watch") {
        if let Some(pb::watch_frame::Frame::Status(s)) = frame.frame
            && common::has_ended(&s)
        {
            assert_eq!(s.state, pb::JobState::Succeeded as i32, "{s:?}");
            ended = true;
            break;
        }
    }
    assert!(ended, "the watch ended without a final status");
}

/// The tokens file of these tests: a read token for "dashboard", a write token for "ci".
fn tokens_server(dir: &std::path::Path) -> TestServer {
    let tokens = dir.join("tokens.toml");
    std::fs::write(
        &tokens,
        format!(
            "[[token]]\nname = \"dashboard\"\nscope = \"read\"\nsha256 = \"{}\"\n\n[[token]]\nname = \"ci\"\nscope = \"write\"\nsha256 = \"{}\"\n",
            sha256_hex("read-token-1"),
            sha256_hex("write-token-2")
        ),
    )
    .expect("tokens file");
    let tokens = tokens.display().to_string();
    TestServer::start_with(
        &dir.join("store.db"),
        &Options::default(),
        &["--tokens", &tokens],
    )
}

/// The CLI with `args` (and `SIGNORINI_TOKEN` when `env_token` is given): exit status, stdout,
/// stderr.
fn cli(args: &[&str], env_token: Option<&str>) -> (bool, String, String) {
    let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_signorini"));
    cmd.args(args)
        .env_remove("SIGNORINI_SERVER")
        .env_remove("SIGNORINI_TOKEN")
        .env_remove("SIGNORINI_CA");
    if let Some(t) = env_token {
        cmd.env("SIGNORINI_TOKEN", t);
    }
    let out = cmd.output().expect("running signorini");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The CLI's client commands send `--token` (or `SIGNORINI_TOKEN`) with every call: with a read
/// token `status`, `list` and `result` work and `submit` is refused (PermissionDenied); without
/// one even `status` is refused (Unauthenticated); a write token submits. (Before, the CLI sent
/// its token with the mutating calls only, so no read worked against a server with `--tokens`.)
#[tokio::test(flavor = "multi_thread")]
async fn the_cli_sends_its_token_with_reads_and_writes() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let server = tokens_server(tmp.path());
    let spec = tmp.path().join("ball.json");
    std::fs::write(&spec, ball_json(1e-3, 100, 1)).expect("spec");
    let spec = spec.display().to_string();
    let url = server.grpc_url.as_str();

    let (ok, out, err) = cli(
        &[
            "submit",
            &spec,
            "--wait",
            "--server",
            url,
            "--token",
            "write-token-2",
        ],
        None,
    );
    assert!(ok, "submit with a write token: {err}");
    let id = out.lines().next().expect("the job id").trim().to_string();

    let (ok, _, err) = cli(&["status", &id, "--server", url], None);
    assert!(!ok, "status without a token");
    assert!(err.contains("Unauthenticated"), "{err}");
    let (ok, out, err) = cli(
        &["status", &id, "--server", url, "--token", "read-token-1"],
        None,
    );
    assert!(ok, "status with a read token: {err}");
    let status: serde_json::Value = serde_json::from_str(&out).expect("status JSON");
    assert_eq!(status["state"], "succeeded", "{out}");
    let (ok, out, err) = cli(&["list", "--json", "--server", url], Some("read-token-1"));
    assert!(ok, "list with SIGNORINI_TOKEN: {err}");
    assert!(out.contains(&id), "{out}");
    let (ok, out, err) = cli(&["result", &id, "--server", url], Some("read-token-1"));
    assert!(ok, "result with SIGNORINI_TOKEN: {err}");
    assert!(out.contains("balance_residual"), "{out}");
    let (ok, _, err) = cli(
        &["submit", &spec, "--server", url, "--token", "read-token-1"],
        None,
    );
    assert!(!ok, "submit with a read token");
    assert!(err.contains("PermissionDenied"), "{err}");
}

/// The pages (`/`, `/jobs/{id}`, `/auth.js`) are open, static and tell nothing of a job; the
/// data they fetch is read with the read token kept in the cookie `signorini_read` (a browser's
/// fetch and EventSource cannot set a header), percent-encoded as the page writes it; a wrong
/// token in it is refused, and no write takes it (a write token in the cookie is not a write).
#[tokio::test(flavor = "multi_thread")]
async fn the_pages_read_with_the_token_of_their_cookie_and_no_write_takes_it() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let server = tokens_server(tmp.path());
    let spec = ball_json(1e-3, 100, 1);
    let (code, body) = server
        .http("POST", "/v1/jobs", Some(&spec), Some("write-token-2"))
        .await;
    assert_eq!(code, 201, "{body}");
    let id = body["id"].as_str().expect("an id").to_string();

    for page in [
        format!("/jobs/{id}"),
        "/jobs/no-such-job".into(),
        "/".into(),
    ] {
        let (code, _, html) = server.request("GET", &page, "", &[]).await;
        assert_eq!(code, 200, "GET {page} without a token");
        let html = String::from_utf8_lossy(&html);
        assert!(
            html.contains(r#"<script src="/auth.js"></script>"#),
            "{html}"
        );
    }
    let (code, _, script) = server.request("GET", "/auth.js", "", &[]).await;
    assert_eq!(code, 200);
    assert!(String::from_utf8_lossy(&script).contains("signorini_read="));

    let job = format!("/v1/jobs/{id}");
    for cookie in [
        "signorini_read=read-token-1",
        "theme=dark; signorini_read=read%2Dtoken%2D1",
    ] {
        let (code, _, body) = server.request("GET", &job, "", &[("cookie", cookie)]).await;
        assert_eq!(code, 200, "{cookie}: {}", String::from_utf8_lossy(&body));
    }
    let events = format!("/v1/jobs/{id}/events?from_seq=0");
    let (code, _, _) = server
        .request(
            "GET",
            &events,
            "",
            &[("cookie", "signorini_read=read-token-1")],
        )
        .await;
    assert_eq!(code, 200, "the live page's event stream with the cookie");
    for cookie in [
        "signorini_read=nope",
        "signorini_read=read%2",
        "other=read-token-1",
    ] {
        let (code, _, _) = server.request("GET", &job, "", &[("cookie", cookie)]).await;
        assert_eq!(code, 401, "{cookie}");
    }
    let (code, _, _) = server
        .request(
            "POST",
            "/v1/jobs",
            &spec,
            &[
                ("cookie", "signorini_read=write-token-2"),
                ("content-type", "application/json"),
            ],
        )
        .await;
    assert_eq!(code, 401, "a write with the token in the cookie only");
}
