//! Pause, resume and extend in the service (`POST /v1/jobs/{id}/pause`, `…/resume`, `…/extend`,
//! gRPC `PauseJob`, `ResumeJob`, `ExtendJob`):
//!
//! * for every scheme family (Moreau–Jean, the α-family, position contact, nonlinear Moreau–Jean
//!   and the nonsmooth generalized-α of user models, SOI2, WFEM), a job paused mid-run and
//!   resumed gives an uninterrupted run's result bit for bit: every column (the energy ledger
//!   included), the summary (but for the wall time) and the figures; also over gRPC;
//! * extend(t₁ → t₂) gives the rows after t₁ of one run to t₂ and its summary bit for bit;
//! * calls in the wrong state answer 409 naming the state, an unknown id 404, a job that writes
//!   no checkpoints is refused with the reason; a paused job survives a restart, can be
//!   cancelled, and is not purged; a study's parent is refused, its children are paused.

mod common;

use common::fingerprint::{fingerprint, fingerprint_without, result, rows_after};
use common::{
    LONG_BALL_STUDY, Options, PATIENCE, TestServer, occupy_the_worker, submit_json, wait_terminal,
};
use serde_json::Value;
use signorini::proto::v1 as pb;
use signorini::spec_file::{Format, parse};
use std::time::{Duration, Instant};

/// An example spec run `factor` times longer (its `steps` or `t_end` scaled), recording every
/// `every`-th step.
fn longer(name: &str, factor: f64, every: u64) -> String {
    let path = format!("{}/examples/{name}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).expect("example");
    let mut spec = parse(&text, Format::Toml).expect("example spec");
    let time = spec.time.as_mut().expect("a time integration");
    match (time.steps, time.t_end) {
        (Some(n), _) => time.steps = Some((n as f64 * factor) as u64),
        (None, Some(t)) => time.t_end = Some(t * factor),
        (None, None) => panic!("{name}: no end"),
    }
    spec.output.every = every;
    serde_json::to_string(&spec).expect("JSON")
}

/// A job's status over HTTP.
async fn status(server: &TestServer, id: &str) -> Value {
    let (code, body) = server
        .http("GET", &format!("/v1/jobs/{id}"), None, None)
        .await;
    assert_eq!(code, 200, "{body}");
    body
}

/// Polls a job's status until `done(status)` holds.
async fn poll_until(server: &TestServer, id: &str, done: impl Fn(&Value) -> bool) -> Value {
    let started = Instant::now();
    loop {
        let s = status(server, id).await;
        if done(&s) {
            return s;
        }
        assert!(started.elapsed() < PATIENCE, "waiting for {id}: {s}");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

/// Submits `spec` over HTTP as job `id`.
async fn submit(server: &TestServer, spec: &str, id: &str) {
    let (code, body) = server
        .http("POST", &format!("/v1/jobs?id={id}"), Some(spec), None)
        .await;
    assert_eq!(code, 201, "{body}");
}

/// Pauses job `id` once it has done a tenth of its steps; returns the paused status.
async fn pause_mid_run(server: &TestServer, id: &str) -> Value {
    poll_until(server, id, |s| {
        s["state"] == "running"
            && s["progress"]["step"].as_u64().unwrap_or(0) * 10
                >= s["progress"]["total"].as_u64().unwrap_or(u64::MAX)
    })
    .await;
    let (code, body) = server
        .http("POST", &format!("/v1/jobs/{id}/pause"), None, None)
        .await;
    assert_eq!(code, 200, "{body}");
    let paused = poll_until(server, id, |s| s["state"] != "running").await;
    assert_eq!(paused["state"], "paused", "{paused}");
    paused
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn pause_then_resume_equals_an_uninterrupted_run_for_every_scheme_family() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("store.db"), &Options::default());
    let mut client = server.grpc().await;
    // (example, factor, every): each runs for a few seconds.
    let families = [
        ("bar.toml", 300.0, 1000),                              // Moreau–Jean
        ("bar_ns_generalized_alpha.toml", 100.0, 500),          // α-family
        ("chain_ns_hht.toml", 100.0, 500),                      // α-family (HHT)
        ("bar_newmark_position_contact.toml", 50.0, 500),       // position contact
        ("rocking_block.toml", 100.0, 500),                     // nonlinear Moreau–Jean
        ("rocking_block_ns_generalized_alpha.toml", 80.0, 500), // user-model generalized-α
        ("pendulum_soi2.toml", 100.0, 500),                     // SOI2
        ("wfem_dep_bar.toml", 300.0, 1000),                     // WFEM
        ("string_bridge.toml", 30.0, 50), // banded contact path, contact region
    ];
    for (k, (name, factor, every)) in families.into_iter().enumerate() {
        let spec = longer(name, factor, every);
        let (paused_id, whole_id) = (format!("paused-{k}"), format!("whole-{k}"));
        submit(&server, &spec, &paused_id).await;
        submit(&server, &spec, &whole_id).await;
        let paused = pause_mid_run(&server, &paused_id).await;
        let step = paused["progress"]["step"].as_u64().expect("step");
        let total = paused["progress"]["total"].as_u64().expect("total");
        assert!(step > 0 && step < total, "{name}: {paused}");
        // Paused, not finished: no result; pausing again is refused naming the state.
        let (code, body) = server
            .http("POST", &format!("/v1/jobs/{paused_id}/pause"), None, None)
            .await;
        assert_eq!(code, 409, "{body}");
        assert!(
            body["error"]["reason"]
                .as_str()
                .is_some_and(|r| r.contains("is paused")),
            "{body}"
        );
        let (code, _) = server
            .http("GET", &format!("/v1/jobs/{paused_id}/result"), None, None)
            .await;
        assert_eq!(code, 409);
        // The progress stays where the checkpoint was written.
        tokio::time::sleep(Duration::from_millis(100)).await;
        assert_eq!(status(&server, &paused_id).await["progress"]["step"], step);

        let (code, body) = server
            .http("POST", &format!("/v1/jobs/{paused_id}/resume"), None, None)
            .await;
        assert_eq!(code, 200, "{body}");
        assert_eq!(body["state"], "queued", "{body}");
        let s = wait_terminal(&mut client, &paused_id).await;
        assert_eq!(s.state, pb::JobState::Succeeded as i32, "{name}: {s:?}");
        let s = wait_terminal(&mut client, &whole_id).await;
        assert_eq!(s.state, pb::JobState::Succeeded as i32, "{name}: {s:?}");
        let (resumed, whole) = (
            result(&mut client, &paused_id).await,
            result(&mut client, &whole_id).await,
        );
        assert!(resumed.step.len() > 2, "{name}");
        assert_eq!(resumed.step, whole.step, "{name}");
        assert_eq!(fingerprint(&resumed), fingerprint(&whole), "{name}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn pause_and_resume_over_grpc() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("store.db"), &Options::default());
    let mut client = server.grpc().await;
    let spec = longer("bar_ns_generalized_alpha.toml", 100.0, 500);
    let id = submit_json(&mut client, spec.clone(), Some("grpc-paused"))
        .await
        .expect("submit");
    let whole = submit_json(&mut client, spec, Some("grpc-whole"))
        .await
        .expect("submit");
    poll_until(&server, &id, |s| {
        s["state"] == "running" && s["progress"]["step"].as_u64().unwrap_or(0) > 10_000
    })
    .await;
    let s = client
        .pause_job(pb::PauseJobRequest { id: id.clone() })
        .await
        .expect("PauseJob")
        .into_inner();
    assert_eq!(s.state, pb::JobState::Paused as i32, "{s:?}");
    let e = client
        .pause_job(pb::PauseJobRequest { id: id.clone() })
        .await
        .expect_err("paused already");
    assert_eq!(e.code(), tonic::Code::FailedPrecondition);
    assert!(e.message().contains("is paused"), "{}", e.message());
    let e = client
        .resume_job(pb::ResumeJobRequest {
            id: "nobody".into(),
        })
        .await
        .expect_err("unknown id");
    assert_eq!(e.code(), tonic::Code::NotFound);
    let s = client
        .resume_job(pb::ResumeJobRequest { id: id.clone() })
        .await
        .expect("ResumeJob")
        .into_inner();
    assert_eq!(s.state, pb::JobState::Queued as i32, "{s:?}");
    wait_terminal(&mut client, &id).await;
    wait_terminal(&mut client, &whole).await;
    assert_eq!(
        fingerprint(&result(&mut client, &id).await),
        fingerprint(&result(&mut client, &whole).await)
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn wrong_states_unknown_ids_queued_pauses_cancel_and_restart() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("store.db");
    let opts = Options {
        workers: 1,
        max_steps: Some(1_000_000_000),
        ..Options::default()
    };
    let server = TestServer::start(&store, &opts);
    let mut client = server.grpc().await;
    for route in ["pause", "resume", "extend"] {
        let (code, body) = server
            .http(
                "POST",
                &format!("/v1/jobs/nobody/{route}"),
                Some(r#"{"t_end":1.0}"#),
                None,
            )
            .await;
        assert_eq!(code, 404, "{route}: {body}");
    }
    // A queued job is parked at once; resuming a running job is refused naming its state.
    occupy_the_worker(&mut client, "blocker").await;
    let (code, body) = server
        .http("POST", "/v1/jobs/blocker/resume", None, None)
        .await;
    assert_eq!(code, 409, "{body}");
    assert_eq!(body["error"]["field"], "id");
    assert!(
        body["error"]["reason"]
            .as_str()
            .is_some_and(|r| r.contains("is running") && r.contains("paused")),
        "{body}"
    );
    let spec = longer("bar.toml", 1.0, 100);
    submit(&server, &spec, "waiting").await;
    let (code, body) = server
        .http("POST", "/v1/jobs/waiting/pause", None, None)
        .await;
    assert_eq!(code, 200, "{body}");
    assert_eq!(body["state"], "paused");
    assert_eq!(body["progress"]["step"], 0);
    // A paused job is listed as such and is not purged.
    let (_, list) = server
        .http("GET", "/v1/jobs?state=paused", None, None)
        .await;
    assert_eq!(list["jobs"][0]["id"], "waiting", "{list}");
    let (code, body) = server
        .http("DELETE", "/v1/jobs/waiting?purge=true", None, None)
        .await;
    assert_eq!(code, 409, "{body}");
    // An analysis writes no checkpoints: it cannot be paused.
    let analysis = r#"{"analysis":{"kind":"forced_response","excitation":"force","cells":10}}"#;
    submit(&server, analysis, "analysis").await;
    let (code, body) = server
        .http("POST", "/v1/jobs/analysis/pause", None, None)
        .await;
    assert_eq!(code, 409, "{body}");
    assert!(
        body["error"]["reason"]
            .as_str()
            .is_some_and(|r| r.contains("writes no checkpoints")),
        "{body}"
    );
    // A paused job stays paused across a restart (SIGTERM), and runs when resumed.
    drop(client);
    let mut server = server;
    server.terminate(Duration::from_secs(60)).expect("exits");
    let server = TestServer::start(&store, &opts);
    let mut client = server.grpc().await;
    assert_eq!(status(&server, "waiting").await["state"], "paused");
    let (code, body) = server.http("DELETE", "/v1/jobs/blocker", None, None).await;
    assert_eq!(code, 200, "{body}");
    let (code, body) = server
        .http("POST", "/v1/jobs/waiting/resume", None, None)
        .await;
    assert_eq!(code, 200, "{body}");
    let s = wait_terminal(&mut client, "waiting").await;
    assert_eq!(s.state, pb::JobState::Succeeded as i32, "{s:?}");
    // Pausing a finished job is refused naming its state.
    let (code, body) = server
        .http("POST", "/v1/jobs/waiting/pause", None, None)
        .await;
    assert_eq!(code, 409, "{body}");
    assert!(
        body["error"]["reason"]
            .as_str()
            .is_some_and(|r| r.contains("is succeeded")),
        "{body}"
    );
    // A paused job can be cancelled (it keeps no checkpoint), then purged.
    submit(&server, &longer("bar.toml", 300.0, 1000), "to-cancel").await;
    pause_mid_run(&server, "to-cancel").await;
    let (code, body) = server
        .http("DELETE", "/v1/jobs/to-cancel", None, None)
        .await;
    assert_eq!(code, 200, "{body}");
    assert_eq!(body["state"], "cancelled", "{body}");
    let (code, body) = server
        .http("POST", "/v1/jobs/to-cancel/resume", None, None)
        .await;
    assert_eq!(code, 409, "{body}");
    let (code, body) = server
        .http("DELETE", "/v1/jobs/to-cancel?purge=true", None, None)
        .await;
    assert_eq!(code, 200, "{body}");
}

/// Extends `first` (a succeeded run to t₁) to `t2` and compares with one run to `t2`: the
/// extension's rows are the long run's after t₁, its summary (but for `extends`) and figures
/// the long run's.
async fn extends_bit_for_bit(server: &TestServer, name: &str, every: u64, t2: f64) {
    let mut client = server.grpc().await;
    let short = longer(name, 1.0, every);
    let stem = name.trim_end_matches(".toml");
    let first = format!("first-{stem}");
    submit(server, &short, &first).await;
    let s = wait_terminal(&mut client, &first).await;
    assert_eq!(s.state, pb::JobState::Succeeded as i32, "{s:?}");
    let t1 = s.progress.as_ref().expect("progress").t;
    let n1 = s.progress.as_ref().expect("progress").step;

    let mut long: Value = serde_json::from_str(&short).expect("spec");
    long["time"]["t_end"] = t2.into();
    let whole = format!("whole-{stem}");
    submit(server, &long.to_string(), &whole).await;

    // Not after t₁: 400 naming t_end.
    for t in [t1, 0.5 * t1] {
        let (code, body) = server
            .http(
                "POST",
                &format!("/v1/jobs/{first}/extend"),
                Some(&format!(r#"{{"t_end":{t}}}"#)),
                None,
            )
            .await;
        assert_eq!(code, 400, "{body}");
        assert_eq!(body["error"]["field"], "t_end", "{body}");
    }
    let (code, body) = server
        .http(
            "POST",
            &format!("/v1/jobs/{first}/extend"),
            Some(&format!(r#"{{"t_end":{t2}}}"#)),
            None,
        )
        .await;
    assert_eq!(code, 201, "{body}");
    assert_eq!(body["extends"], first.as_str());
    let ext = body["id"].as_str().expect("id").to_string();
    let s = wait_terminal(&mut client, &ext).await;
    assert_eq!(s.state, pb::JobState::Succeeded as i32, "{s:?}");
    wait_terminal(&mut client, &whole).await;
    assert_eq!(status(server, &ext).await["extends"], first.as_str());

    let (ext_r, whole_r) = (
        result(&mut client, &ext).await,
        result(&mut client, &whole).await,
    );
    let summary: Value = serde_json::from_str(&ext_r.summary_json).expect("summary");
    assert_eq!(summary["extends"], first.as_str());
    // The extension holds the rows after t₁: the long run's from the first step after n₁.
    let tail = rows_after(&whole_r, n1);
    assert_eq!(ext_r.step, tail.step);
    // Every column (the energy ledger included), the summary and the figures.
    assert_eq!(
        fingerprint_without(&ext_r, &["extends"]),
        fingerprint(&tail),
        "{name}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn extend_equals_one_longer_run() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("store.db"), &Options::default());
    // Moreau–Jean (t₁ = 5) and the generalized-α (t₁ = 5), both to t₂ = 8.
    extends_bit_for_bit(&server, "bar.toml", 10, 8.0).await;
    extends_bit_for_bit(&server, "bar_ns_generalized_alpha.toml", 10, 8.0).await;
    // Over gRPC; a job that has not succeeded cannot be extended.
    let mut client = server.grpc().await;
    let e = client
        .extend_job(pb::ExtendJobRequest {
            id: "nobody".into(),
            t_end: 9.0,
            new_id: None,
        })
        .await
        .expect_err("unknown id");
    assert_eq!(e.code(), tonic::Code::NotFound);
    let r = client
        .extend_job(pb::ExtendJobRequest {
            id: "first-bar".into(),
            t_end: 6.0,
            new_id: Some("bar-to-6".into()),
        })
        .await
        .expect("ExtendJob")
        .into_inner();
    assert_eq!(
        (r.id.as_str(), r.extends.as_str()),
        ("bar-to-6", "first-bar")
    );
    let s = wait_terminal(&mut client, "bar-to-6").await;
    assert_eq!(s.state, pb::JobState::Succeeded as i32, "{s:?}");
    assert_eq!(s.progress.expect("progress").step, 6000);
    // GetJob names the job an extension continues.
    let s = client
        .get_job(pb::GetJobRequest {
            id: "bar-to-6".into(),
        })
        .await
        .expect("GetJob")
        .into_inner();
    assert_eq!(
        (s.extends.as_deref(), s.parent.as_deref()),
        (Some("first-bar"), None)
    );
    // A run drawing a contact region sizes the chart's time buckets by its length: refused.
    submit(&server, &longer("string_bridge.toml", 0.05, 5), "bridge").await;
    let s = wait_terminal(&mut client, "bridge").await;
    assert_eq!(s.state, pb::JobState::Succeeded as i32, "{s:?}");
    let e = client
        .extend_job(pb::ExtendJobRequest {
            id: "bridge".into(),
            t_end: 0.06,
            new_id: None,
        })
        .await
        .expect_err("a contact region");
    assert_eq!(e.code(), tonic::Code::FailedPrecondition);
    assert!(e.message().contains("contact region"), "{}", e.message());
    submit(&server, &longer("bar.toml", 300.0, 1000), "running").await;
    poll_until(&server, "running", |s| s["state"] == "running").await;
    let e = client
        .extend_job(pb::ExtendJobRequest {
            id: "running".into(),
            t_end: 1e6,
            new_id: None,
        })
        .await
        .expect_err("running");
    assert_eq!(e.code(), tonic::Code::FailedPrecondition);
    assert!(e.message().contains("is running"), "{}", e.message());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_study_parent_is_not_paused_its_children_are() {
    let dir = tempfile::tempdir().expect("tempdir");
    let opts = Options {
        workers: 1,
        max_steps: Some(1_000_000_000),
        ..Options::default()
    };
    let server = TestServer::start(&dir.path().join("store.db"), &opts);
    let (code, body) = server
        .http("POST", "/v1/jobs", Some(LONG_BALL_STUDY), None)
        .await;
    assert_eq!(code, 201, "{body}");
    let parent = body["id"].as_str().expect("id").to_string();
    let (code, body) = server
        .http("GET", &format!("/v1/jobs/{parent}/children"), None, None)
        .await;
    assert_eq!(code, 200, "{body}");
    let kids = body["jobs"].as_array().expect("children").clone();
    assert_eq!(kids.len(), 4);
    for route in ["pause", "extend"] {
        let (code, body) = server
            .http(
                "POST",
                &format!("/v1/jobs/{parent}/{route}"),
                Some(r#"{"t_end":200.0}"#),
                None,
            )
            .await;
        assert_eq!(code, 409, "{route}: {body}");
        assert!(
            body["error"]["reason"]
                .as_str()
                .is_some_and(|r| r.contains("no run of its own")),
            "{body}"
        );
    }
    // The last child waits in the queue: parked at once; cancelled, it counts as ended.
    let last = kids[3]["id"].as_str().expect("id").to_string();
    // A run names its study, over HTTP and gRPC; the study names none.
    assert_eq!(status(&server, &last).await["parent"], parent.as_str());
    assert!(status(&server, &parent).await.get("parent").is_none());
    let s = server
        .grpc()
        .await
        .get_job(pb::GetJobRequest { id: last.clone() })
        .await
        .expect("GetJob")
        .into_inner();
    assert_eq!(
        (s.parent.as_deref(), s.extends.as_deref()),
        (Some(parent.as_str()), None)
    );
    let (code, body) = server
        .http("POST", &format!("/v1/jobs/{last}/pause"), None, None)
        .await;
    assert_eq!(code, 200, "{body}");
    assert_eq!(body["state"], "paused");
    assert_eq!(status(&server, &parent).await["progress"]["step"], 0);
    let (code, body) = server
        .http("DELETE", &format!("/v1/jobs/{last}"), None, None)
        .await;
    assert_eq!(code, 200, "{body}");
    assert_eq!(body["state"], "cancelled");
    assert_eq!(status(&server, &parent).await["progress"]["step"], 1);
    let (code, body) = server
        .http("DELETE", &format!("/v1/jobs/{parent}"), None, None)
        .await;
    assert_eq!(code, 200, "{body}");
}
