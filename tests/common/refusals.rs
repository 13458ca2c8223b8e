//! One invalid spec sent through the three front ends, and what each says of it: the field
//! paths of an error must be the same whichever way a user submits (`tests/field_paths.rs`,
//! `tests/service_lagrangian.rs`).

use super::{TestServer, submit_json};
use serde_json::Value;
use signorini::proto::v1::simulation_client::SimulationClient;
use std::path::Path;
use tonic::transport::Channel;

/// `spec` with the value at the JSON pointer `pointer` replaced (or a table's key added).
pub fn edit(mut spec: Value, pointer: &str, value: Value) -> Value {
    let (parent, key) = pointer.rsplit_once('/').expect("a JSON pointer");
    match spec.pointer_mut(parent).expect("pointer into the base") {
        Value::Object(table) => {
            table.insert(key.to_string(), value);
        }
        Value::Array(list) => list[key.parse::<usize>().expect("an index")] = value,
        other => panic!("{parent} is {other}"),
    }
    spec
}

/// What the CLI, HTTP and gRPC said of one spec they all refused.
pub struct Refusals {
    /// `signorini run FILE` on the spec written as TOML to `DIR/bad.toml`: exit code, stderr.
    pub cli_code: Option<i32>,
    pub cli_stderr: String,
    /// `POST /v1/jobs` with the spec as JSON: status and body.
    pub http_code: u16,
    pub http_body: Value,
    /// gRPC `SubmitJob` with the spec as JSON: status code, `x-error-field`, message.
    pub grpc_code: tonic::Code,
    pub grpc_field: Option<String>,
    pub grpc_message: String,
}

/// Sends `spec` through the CLI (`signorini run`, files under `dir`), HTTP and gRPC; panics if
/// gRPC accepts it.
pub async fn refusals(
    server: &TestServer,
    client: &mut SimulationClient<Channel>,
    dir: &Path,
    spec: &Value,
) -> Refusals {
    let file = dir.join("bad.toml");
    std::fs::write(&file, toml::to_string(spec).expect("TOML")).expect("writing the spec");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_signorini"))
        .arg("run")
        .arg(&file)
        .arg("--out")
        .arg(dir.join("out"))
        .output()
        .expect("signorini run");
    let text = spec.to_string();
    let (http_code, http_body) = server.http("POST", "/v1/jobs", Some(&text), None).await;
    let err = submit_json(client, text, None)
        .await
        .expect_err("gRPC accepted an invalid spec");
    let grpc_field = err
        .metadata()
        .get("x-error-field")
        .and_then(|v| v.to_str().ok())
        .map(str::to_string);
    Refusals {
        cli_code: out.status.code(),
        cli_stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
        http_code,
        http_body,
        grpc_code: err.code(),
        grpc_field,
        grpc_message: err.message().to_string(),
    }
}
