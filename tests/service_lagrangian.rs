//! `scene = "lagrangian"` through the service: the pendulum example, sent as JSON over HTTP
//! and over gRPC (the JSON spelling of `SubmitJobRequest`; the typed messages have no
//! `lagrangian` scene), runs and returns its result; a bad expression is refused with 400 /
//! INVALID_ARGUMENT naming the field.

mod common;

use common::refusals::{edit, refusals};
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
    let theta = result["steps"]["q_2"].as_array().expect("probe θ");
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

/// A small valid user model (a block on a floor, a joint, a contact) that the bad cases edit.
fn base() -> Value {
    json!({
        "model": {
            "scene": "lagrangian",
            "coordinates": ["x", "y", "phi"],
            "parameters": {"m": 1.0, "w": 0.2, "hgt": 0.4, "g": 9.81, "I": "m*(w^2+hgt^2)/12"},
            "mass": [["m", 0, 0], [0, "m", 0], [0, 0, "I"]],
            "potential": "m*g*y",
            "forces": ["0", "0", "-0.01*phi_dot"],
            "q0": [0.0, 0.2, 0.0],
            "v0": [0.1, 0.0, 1.0],
            "constraints": [{"expr": "x - 0.1*phi"}],
            "contacts": [{"gap": "y - hgt/2*cos(phi) - w/2*sin(phi)", "restitution": 0.5}]
        },
        "integrator": {"scheme": "soi2_generalized_alpha"},
        "time": {"h": 0.001, "t_end": 0.01}
    })
}

/// Every kind of bad user model of the issue (unknown name, sizes, M not symmetric or not
/// positive definite, NaN at q0, a joint violated at q0, friction without a tangent, a parameter
/// cycle, a shadowed name, the wrong scheme) is refused before it runs by the CLI (exit 1, the
/// field on stderr), HTTP (400, `error.field`) and gRPC (INVALID_ARGUMENT, `x-error-field`), with
/// the same field everywhere.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_bad_model_is_refused_naming_its_field_by_cli_http_and_grpc() {
    let cases: Vec<(&str, Value, &str)> = vec![
        (
            "/model/contacts/0/gap",
            json!("y - hgh/2"),
            "model.contacts[0].gap",
        ),
        ("/model/q0", json!([0.0, 0.2]), "model.q0"),
        ("/model/mass/1/0", json!("m"), "model.mass[1][0]"),
        ("/model/mass/2/2", json!("-I"), "model.mass"),
        (
            "/model/potential",
            json!("m*g*log(y - 1)"),
            "model.potential",
        ),
        (
            "/model/constraints/0/expr",
            json!("x - 0.1*phi - 1e-3"),
            "model.constraints[0].expr",
        ),
        (
            "/model/contacts/0/friction",
            json!(0.5),
            "model.contacts[0].friction",
        ),
        ("/model/parameters/phi", json!(1.0), "model.parameters.phi"),
        ("/model/parameters/I", json!("m*ww^2"), "model.parameters.I"),
        (
            "/integrator",
            json!({"scheme": "ns_newmark"}),
            "integrator.scheme",
        ),
    ];
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("store.db"), &Options::default());
    let mut client = server.grpc().await;
    for (pointer, value, field) in cases {
        let spec = edit(base(), pointer, value);
        let said = refusals(&server, &mut client, dir.path(), &spec).await;
        assert_eq!(said.cli_code, Some(1), "{pointer}: {}", said.cli_stderr);
        assert!(
            said.cli_stderr.contains(&format!("{field}:")),
            "{pointer}: CLI says {}",
            said.cli_stderr
        );
        assert_eq!(said.http_code, 400, "{pointer}: {}", said.http_body);
        assert_eq!(
            said.http_body["error"]["field"], field,
            "{pointer}: {}",
            said.http_body
        );
        assert_eq!(said.grpc_code, Code::InvalidArgument, "{pointer}");
        assert_eq!(said.grpc_field.as_deref(), Some(field), "{pointer}");
    }
}

/// Issue 30: a spec file goes over HTTP as it is (`content-type: application/toml`; it was
/// "malformed JSON at line 1, column 1"), a bad field in it is named as for JSON, and `t` (and
/// `step`) may be asked for in `?columns=` (it was 400 "no column t" though every cut has it).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn toml_goes_over_http_and_t_is_a_column() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("store.db"), &Options::default());
    let toml_text = toml::to_string(&pendulum_json()).expect("TOML");
    let toml_header = [("content-type", "application/toml")];
    let (code, _, body) = server
        .request("POST", "/v1/jobs", &toml_text, &toml_header)
        .await;
    let body: Value = serde_json::from_slice(&body).expect("JSON answer");
    assert_eq!(code, 201, "{body}");
    let id = body["id"].as_str().expect("id").to_string();
    let mut client = server.grpc().await;
    let s = wait_terminal(&mut client, &id).await;
    assert_eq!(s.state, pb::JobState::Succeeded as i32, "{s:?}");
    let (code, result) = server
        .http(
            "GET",
            &format!("/v1/jobs/{id}/result?columns=t,energy"),
            None,
            None,
        )
        .await;
    assert_eq!(code, 200, "{result}");
    assert_eq!(
        result["columns"],
        json!(["step", "t", "energy"]),
        "{result}"
    );
    let t = result["steps"]["t"].as_array().expect("t");
    assert_eq!(t.len(), 128 / 4 + 1);
    assert_eq!(t[1], json!(4.0 * 0.25 / 128.0));
    let (code, _, csv) = server
        .request(
            "GET",
            &format!("/v1/jobs/{id}/result?format=csv&columns=step,t"),
            "",
            &[],
        )
        .await;
    assert_eq!(code, 200);
    let csv = String::from_utf8(csv).expect("CSV");
    assert_eq!(csv.lines().next(), Some("step,t"), "{csv}");

    let bad = toml_text.replace("q0 = [", "q0 = [true, ");
    assert_ne!(bad, toml_text);
    let (code, _, body) = server.request("POST", "/v1/jobs", &bad, &toml_header).await;
    let body: Value = serde_json::from_slice(&body).expect("JSON answer");
    assert_eq!(code, 400, "{body}");
    assert_eq!(body["error"]["field"], "model.q0[0]", "{body}");
}

/// Issue 30, item 3, over the CLI and HTTP. A start written as expressions of the parameters,
/// off the joint x − 0.1φ = 0, with `project_onto_joints`: the CLI prints a note with the values
/// the run starts from and both put them in the summary (`start_projection`, the projection onto
/// the joint in the M norm: q0 − M⁻¹a (a·q0)/(a M⁻¹ aᵀ), a = (1, 0, −0.1),
/// M = diag(m, m, I), I = m (w² + hgt²)/12). A block sliding on a floor
/// whose friction takes `tangent_velocity = "x_dot"` stops where Coulomb's law says,
/// v0²/(2μg), having dissipated all its kinetic energy as friction work. Bad start expressions
/// and a non-linear tangential velocity are refused naming their fields.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn start_expressions_projection_and_tangent_velocity_over_cli_and_http() {
    let mut projected = base();
    projected["model"]["contacts"] = json!([]);
    projected["model"]["q0"] = json!(["hgt/8", "hgt/2", 0]);
    projected["model"]["v0"] = json!(["w/2", 0, "1"]);
    projected["model"]["project_onto_joints"] = json!(true);
    let inertia = 1.0 * (0.2_f64.powi(2) + 0.4_f64.powi(2)) / 12.0;
    let minv_a = [1.0, 0.0, -0.1 / inertia];
    let a_minv_a = 1.0 + 0.01 / inertia;
    let (ga, va) = (0.05 / a_minv_a, (0.1 - 0.1) / a_minv_a);
    let q0: Vec<f64> = [0.05, 0.2, 0.0]
        .iter()
        .zip(minv_a)
        .map(|(q, a)| q - a * ga)
        .collect();
    let v0: Vec<f64> = [0.1, 0.0, 1.0]
        .iter()
        .zip(minv_a)
        .map(|(v, a)| v - a * va)
        .collect();
    let close = |got: &Value, want: &[f64]| {
        let got: Vec<f64> = serde_json::from_value(got.clone()).expect("numbers");
        got.len() == want.len() && got.iter().zip(want).all(|(g, w)| (g - w).abs() < 1e-15)
    };

    let sliding = json!({
        "model": {
            "scene": "lagrangian",
            "coordinates": ["x", "y"],
            "parameters": {"m": 1.0, "g": 9.81, "mu": 0.5},
            "mass": {"diagonal": ["m", "m"]},
            "potential": "m*g*y",
            "q0": [0, 0],
            "v0": ["sqrt(2*g*mu*0.1)", 0],
            "contacts": [{"gap": "y", "friction": 0.5, "tangent_velocity": "x_dot"}]
        },
        "integrator": {"scheme": "moreau_jean", "theta": 0.5},
        "time": {"h": 0.0005, "t_end": 0.3},
        "output": {"every": 10, "probes": [0]}
    });

    let dir = tempfile::tempdir().expect("tempdir");
    for (name, spec) in [("projected", &projected), ("sliding", &sliding)] {
        let file = dir.path().join(format!("{name}.toml"));
        std::fs::write(&file, toml::to_string(spec).expect("TOML")).expect("writing the spec");
        let out_dir = dir.path().join(name);
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_signorini"))
            .args(["run", "--quiet"])
            .arg(&file)
            .arg("--out")
            .arg(&out_dir)
            .output()
            .expect("signorini run");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(0), "{name}: {stderr}");
        let summary: Value = serde_json::from_str(
            &std::fs::read_to_string(out_dir.join("summary.json")).expect("summary.json"),
        )
        .expect("JSON");
        if name == "projected" {
            assert!(
                stderr.contains("note: q0 and v0 were projected onto the joints"),
                "{stderr}"
            );
            assert!(close(&summary["start_projection"]["q0"], &q0), "{summary}");
            assert!(close(&summary["start_projection"]["v0"], &v0), "{summary}");
            assert_eq!(
                summary["start_projection"]["q0_given"],
                json!([0.05, 0.2, 0.0])
            );
        } else {
            assert!(!stderr.contains("projected"), "{stderr}");
            assert!(summary.get("start_projection").is_none(), "{summary}");
            let csv = std::fs::read_to_string(out_dir.join("steps.csv")).expect("steps.csv");
            let header: Vec<&str> = csv.lines().next().expect("header").split(',').collect();
            let last: Vec<f64> = csv
                .lines()
                .last()
                .expect("rows")
                .split(',')
                .map(|x| x.parse().expect("a number"))
                .collect();
            let col = |c: &str| last[header.iter().position(|h| *h == c).expect(c)];
            // Stops at v0²/(2μg) = 0.1 m (to the first order of the step); with θ = ½ the
            // friction work of a step, P_t (U_t,k + U_t,k+1)/2, is the kinetic energy it takes.
            assert!((col("q_0") - 0.1).abs() < 2e-3, "x = {}", col("q_0"));
            assert!(col("v_0").abs() < 1e-12, "v = {}", col("v_0"));
            let friction = summary["work_friction_total"].as_f64().expect("work");
            assert!(
                (friction + 0.5 * 2.0 * 9.81 * 0.5 * 0.1).abs() < 1e-9,
                "{summary}"
            );
        }
    }

    let server = TestServer::start(&dir.path().join("store.db"), &Options::default());
    let mut client = server.grpc().await;
    for spec in [&projected, &sliding] {
        let (code, body) = server
            .http("POST", "/v1/jobs", Some(&spec.to_string()), None)
            .await;
        assert_eq!(code, 201, "{body}");
        let id = body["id"].as_str().expect("id").to_string();
        let s = wait_terminal(&mut client, &id).await;
        assert_eq!(s.state, pb::JobState::Succeeded as i32, "{s:?}");
        let (code, result) = server
            .http("GET", &format!("/v1/jobs/{id}/result"), None, None)
            .await;
        assert_eq!(code, 200, "{result}");
        if spec == &projected {
            let report = &result["summary"]["start_projection"];
            assert!(close(&report["q0"], &q0), "{result}");
            assert!(close(&report["v0"], &v0), "{result}");
        } else {
            assert!(
                result["summary"]["work_friction_total"]
                    .as_f64()
                    .expect("work")
                    < -0.49
            );
        }
    }
    for (spec, pointer, value, field) in [
        (&projected, "/model/q0/1", json!("hgh/2"), "model.q0[1]"),
        (
            &sliding,
            "/model/contacts/0/tangent_velocity",
            json!("x_dot^2"),
            "model.contacts[0].tangent_velocity",
        ),
    ] {
        let mut bad = spec.clone();
        *bad.pointer_mut(pointer).expect("pointer") = value;
        let (code, body) = server
            .http("POST", "/v1/jobs", Some(&bad.to_string()), None)
            .await;
        assert_eq!(code, 400, "{body}");
        assert_eq!(body["error"]["field"], field, "{body}");
    }
}
