//! `scene = "lagrangian"` through the service: the pendulum example, sent as JSON over HTTP
//! and over gRPC (the JSON spelling of `SubmitJobRequest`; the typed messages have no
//! `lagrangian` scene), runs and returns its result; a bad expression is refused with 400 /
//! INVALID_ARGUMENT naming the field.

mod common;

use common::{Options, TestServer, submit_json, wait_terminal};
use serde_json::{Value, json};
use signorini::proto::v1 as pb;
use std::path::Path;
use tonic::Code;

/// examples/pendulum_lagrangian.toml as JSON, over a shorter time (0.25 s).
fn pendulum_json() -> Value {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/pendulum_lagrangian.toml");
    let text = std::fs::read_to_string(path).expect("example");
    let mut spec: Value = toml::from_str(&text).expect("TOML");
    spec["time"]["t_end"] = json!(0.25);
    spec
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_lagrangian_model_runs_over_http_and_grpc_json() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("store.db"), &Options::default());
    let spec = pendulum_json().to_string();
    let (code, body) = server.http("POST", "/v1/jobs", Some(&spec), None).await;
    assert_eq!(code, 201, "{body}");
    let id = body["id"].as_str().expect("id").to_string();
    let mut client = server.grpc().await;
    let s = wait_terminal(&mut client, &id).await;
    assert_eq!(s.state, pb::JobState::Succeeded as i32, "{s:?}");
    let (code, result) = server
        .http("GET", &format!("/v1/jobs/{id}/result"), None, None)
        .await;
    assert_eq!(code, 200, "{result}");
    assert_eq!(result["summary"]["scene"], "lagrangian");
    assert_eq!(result["summary"]["steps"], 128);
    assert!(
        result["summary"]["max_position_residual"]
            .as_f64()
            .expect("residual")
            < 1e-12
    );
    let theta = result["steps"]["y_2"].as_array().expect("probe θ");
    assert_eq!(theta.len(), 128 / 4 + 1);

    let grpc_id = submit_json(&mut client, spec, None)
        .await
        .expect("SubmitJob JSON");
    let s = wait_terminal(&mut client, &grpc_id).await;
    assert_eq!(s.state, pb::JobState::Succeeded as i32, "{s:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_bad_expression_is_refused_naming_its_field() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("store.db"), &Options::default());
    let mut spec = pendulum_json();
    spec["model"]["constraints"][1]["expr"] = json!("y - LL*sin(theta)");
    let spec = spec.to_string();
    let (code, body) = server.http("POST", "/v1/jobs", Some(&spec), None).await;
    assert_eq!(code, 400, "{body}");
    assert_eq!(
        body["error"]["field"], "model.constraints[1].expr",
        "{body}"
    );
    assert!(
        body["error"]["reason"]
            .as_str()
            .is_some_and(|r| r.contains("unknown name 'LL'") && r.contains("did you mean 'L'?")),
        "{body}"
    );
    let mut client = server.grpc().await;
    let err = submit_json(&mut client, spec, None)
        .await
        .expect_err("invalid");
    assert_eq!(err.code(), Code::InvalidArgument);
    assert_eq!(
        err.metadata()
            .get("x-error-field")
            .and_then(|v| v.to_str().ok()),
        Some("model.constraints[1].expr")
    );
}
