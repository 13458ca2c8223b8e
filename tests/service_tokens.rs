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
