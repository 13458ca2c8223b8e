//! (1) and (2): a job submitted over gRPC (typed spec) and over HTTP (JSON) streams every step on
//! `signorini/v1/jobs/{id}/energy` to a separate zenoh session, and the streamed values equal the
//! stored result (GetResult / GET …/result) bit for bit. A modal analysis's stored figures (gRPC
//! GetResult, HTTP `…/figures/{name}`, `signorini result --out`) equal the files `signorini run`
//! writes for the same spec, byte for byte.

mod common;

use common::{
    Options, TestServer, ball_json, ball_typed, collect_until_last, submit_json, wait_terminal,
    zenoh_barrier,
};
use signorini::proto::v1 as pb;
use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

const STEPS: u64 = 3000;

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn grpc_job_streams_every_step_over_zenoh_bit_for_bit() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("store.db"), &Options::default());
    let session = server.zenoh_session().await;
    let id = "grpc-stream-1";
    let sub = session
        .declare_subscriber(signorini::stream::energy_key(id))
        .await
        .expect("subscribe");
    zenoh_barrier(&session, id).await;

    let mut client = server.grpc().await;
    let req = pb::SubmitJobRequest {
        spec: Some(pb::submit_job_request::Spec::Typed(ball_typed(
            1e-3, STEPS, 1,
        ))),
        id: Some(id.into()),
    };
    let got = client
        .submit_job(req)
        .await
        .expect("SubmitJob")
        .into_inner()
        .id;
    assert_eq!(got, id);

    let streamed = collect_until_last(&sub).await;
    assert!(streamed.frames > 1, "several frames, several steps each");
    // Decimation 1: every step 0..=STEPS, in order, none missing.
    if streamed.steps != (0..=STEPS).collect::<Vec<_>>() {
        let (_, m) = server.http_raw("GET", "/metrics", None, None).await;
        panic!(
            "missing steps ({} of {}); server: {}",
            streamed.steps.len(),
            STEPS + 1,
            String::from_utf8_lossy(&m)
        );
    }
    assert!(
        streamed.columns.iter().any(|c| c == "energy")
            && streamed.columns.iter().any(|c| c == "balance_residual")
    );

    let result = client
        .get_result(pb::GetResultRequest {
            id: id.into(),
            ..Default::default()
        })
        .await
        .expect("GetResult")
        .into_inner();
    assert_eq!(result.step, streamed.steps);
    assert_eq!(bits(&result.t), bits(&streamed.t));
    for (c, name) in streamed.columns.iter().enumerate() {
        let series = result
            .series
            .iter()
            .find(|s| &s.column == name)
            .expect("column in result");
        let live: Vec<f64> = streamed.rows.iter().map(|r| r[c]).collect();
        assert_eq!(bits(&series.values), bits(&live), "column {name}");
    }
    let summary: serde_json::Value =
        serde_json::from_str(&result.summary_json).expect("summary json");
    assert_eq!(summary["steps"], STEPS);
    drop(sub);
    session.close().await.expect("close zenoh");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn http_job_streams_every_step_over_zenoh_bit_for_bit() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("store.db"), &Options::default());
    let session = server.zenoh_session().await;
    let id = "http-stream-1";
    let sub = session
        .declare_subscriber(signorini::stream::energy_key(id))
        .await
        .expect("subscribe");
    zenoh_barrier(&session, id).await;

    let (code, body) = server
        .http(
            "POST",
            &format!("/v1/jobs?id={id}"),
            Some(&ball_json(1e-3, STEPS, 1)),
            None,
        )
        .await;
    assert_eq!(code, 201, "{body}");
    assert_eq!(body["id"], id);

    let streamed = collect_until_last(&sub).await;
    assert_eq!(streamed.steps, (0..=STEPS).collect::<Vec<_>>());

    let (code, status) = server
        .http("GET", &format!("/v1/jobs/{id}"), None, None)
        .await;
    assert_eq!(code, 200);
    // The status may lag the last frame by a moment: the result call below waits for nothing,
    // so ask until the job says it succeeded (it is written before its final status goes out).
    assert!(
        status.get("progress").is_some() && status["id"] == id,
        "{status}"
    );
    let mut client = server.grpc().await;
    let fin = common::wait_terminal(&mut client, id).await;
    assert_eq!(fin.state, pb::JobState::Succeeded as i32);

    let (code, result) = server
        .http("GET", &format!("/v1/jobs/{id}/result"), None, None)
        .await;
    assert_eq!(code, 200, "{result}");
    let steps = &result["steps"];
    let step: Vec<u64> = serde_json::from_value(steps["step"].clone()).expect("step column");
    assert_eq!(step, streamed.steps);
    let t: Vec<f64> = serde_json::from_value(steps["t"].clone()).expect("t column");
    assert_eq!(bits(&t), bits(&streamed.t));
    for (c, name) in streamed.columns.iter().enumerate() {
        let stored: Vec<f64> =
            serde_json::from_value(steps[name].clone()).expect("column in result");
        let live: Vec<f64> = streamed.rows.iter().map(|r| r[c]).collect();
        assert_eq!(bits(&stored), bits(&live), "column {name}");
    }
    assert_eq!(result["summary"]["steps"], STEPS);
    assert_eq!(result["columns"][0], "step");

    // A cut of the result: two columns, every 7th row and the last, the same bits.
    let (code, cut) = server
        .http(
            "GET",
            &format!("/v1/jobs/{id}/result?columns=energy,kinetic&every=7"),
            None,
            None,
        )
        .await;
    assert_eq!(code, 200, "{cut}");
    assert_eq!(
        cut["columns"],
        serde_json::json!(["step", "t", "energy", "kinetic"])
    );
    let rows: Vec<usize> = (0..=STEPS as usize)
        .filter(|i| i % 7 == 0 || *i == STEPS as usize)
        .collect();
    let cut_steps: Vec<u64> = serde_json::from_value(cut["steps"]["step"].clone()).expect("step");
    assert_eq!(cut_steps, rows.iter().map(|&i| step[i]).collect::<Vec<_>>());
    for name in ["energy", "kinetic"] {
        let full: Vec<f64> = serde_json::from_value(steps[name].clone()).expect("full");
        let part: Vec<f64> = serde_json::from_value(cut["steps"][name].clone()).expect("cut");
        let want: Vec<f64> = rows.iter().map(|&i| full[i]).collect();
        assert_eq!(bits(&part), bits(&want), "cut column {name}");
    }
    assert!(cut["steps"].get("strain").is_none());
    let (code, body) = server
        .http(
            "GET",
            &format!("/v1/jobs/{id}/result?columns=energy,nope"),
            None,
            None,
        )
        .await;
    assert_eq!(
        (code, body["error"]["field"].as_str()),
        (400, Some("columns")),
        "{body}"
    );
    let grpc_cut = client
        .get_result(pb::GetResultRequest {
            id: id.into(),
            columns: vec!["energy".into()],
            every: 1000,
            ..Default::default()
        })
        .await
        .expect("GetResult with a cut")
        .into_inner();
    assert_eq!(grpc_cut.step, [0, 1000, 2000, 3000]);
    assert_eq!(grpc_cut.columns, ["energy"]);

    let (code, body) = server.http_raw("GET", "/metrics", None, None).await;
    let text = String::from_utf8_lossy(&body);
    assert_eq!(code, 200);
    assert!(
        text.contains("signorini_jobs{state=\"succeeded\"} 1")
            && text.contains("signorini_queue_depth"),
        "{text}"
    );
    let (code, caps) = server.http("GET", "/v1/capabilities", None, None).await;
    assert_eq!(code, 200);
    assert!(
        caps["models"]
            .as_array()
            .is_some_and(|m| m.iter().any(|m| m["name"] == "bouncing_ball"))
    );
    let (code, page) = server
        .http_raw("GET", &format!("/jobs/{id}"), None, None)
        .await;
    assert_eq!(code, 200);
    assert!(String::from_utf8_lossy(&page).contains("EventSource"));
    // An unknown job's page is a 404 (it answered 200 and spun forever); `/` lists the jobs.
    let (code, body) = server.http("GET", "/jobs/no-such-job", None, None).await;
    assert_eq!((code, body["error"]["field"].as_str()), (404, Some("id")));
    let (code, ctype, index) = server.http_get_typed("/").await;
    assert_eq!((code, ctype.as_str()), (200, "text/html; charset=utf-8"));
    assert!(String::from_utf8_lossy(&index).contains("/v1/jobs?limit=50"));
    drop(sub);
    session.close().await.expect("close zenoh");
}

/// A nonsmooth modal analysis small enough for a debug build (≈ 20 ms): a backbone figure and one
/// orbit figure per gap.
const MODES_JSON: &str = r#"{"name":"modes","analysis":{"kind":"nonsmooth_modes","cells":10,"gaps":[1e-3,0.0,-1e-3],"max_period_steps":40,"phases":1,"stability_periods":10}}"#;

/// Every file of `dir` but `summary.json` (whose `wall_s` differs run to run), by name.
fn files_but_summary(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut files = BTreeMap::new();
    for e in std::fs::read_dir(dir).expect("reading an output dir") {
        let path = e.expect("dir entry").path();
        let name = path
            .file_name()
            .and_then(|n| n.to_str())
            .expect("UTF-8 file name")
            .to_string();
        if name != "summary.json" {
            files.insert(name, std::fs::read(&path).expect("reading an output file"));
        }
    }
    assert!(dir.join("summary.json").is_file(), "{}", dir.display());
    files
}

fn svgs(files: &BTreeMap<String, Vec<u8>>) -> BTreeMap<String, Vec<u8>> {
    files
        .iter()
        .filter_map(|(n, b)| Some((n.strip_suffix(".svg")?.to_string(), b.clone())))
        .collect()
}

fn signorini(args: &[&str]) {
    let out = Command::new(env!("CARGO_BIN_EXE_signorini"))
        .args(args)
        .env_remove("SIGNORINI_SERVER")
        .env_remove("SIGNORINI_TOKEN")
        .env_remove("SIGNORINI_CONFIG")
        .output()
        .expect("running signorini");
    assert!(
        out.status.success(),
        "signorini {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn modal_figures_over_grpc_http_and_result_out_equal_what_run_writes() {
    let dir = tempfile::tempdir().expect("tempdir");
    let spec = dir.path().join("modes.json");
    std::fs::write(&spec, MODES_JSON).expect("writing the spec");
    let run_dir = dir.path().join("run");
    let spec_arg = spec.display().to_string();
    let run_arg = run_dir.display().to_string();
    signorini(&["run", &spec_arg, "--out", &run_arg, "--quiet"]);
    let ran = files_but_summary(&run_dir);
    let ran_svgs = svgs(&ran);
    assert!(
        ran_svgs.contains_key("backbone") && ran_svgs.len() >= 2,
        "run wrote {:?}",
        ran.keys()
    );

    let server = TestServer::start(&dir.path().join("store.db"), &Options::default());
    let mut client = server.grpc().await;
    let id = "modes-1";
    submit_json(&mut client, MODES_JSON.to_string(), Some(id))
        .await
        .expect("SubmitJob");
    let fin = wait_terminal(&mut client, id).await;
    assert_eq!(fin.state, pb::JobState::Succeeded as i32, "{fin:?}");

    // (a) gRPC GetResult: the same figures, the same text.
    let result = client
        .get_result(pb::GetResultRequest {
            id: id.into(),
            ..Default::default()
        })
        .await
        .expect("GetResult")
        .into_inner();
    let grpc_svgs: BTreeMap<String, Vec<u8>> = result
        .figures
        .iter()
        .map(|f| (f.name.clone(), f.svg.clone().into_bytes()))
        .collect();
    assert_eq!(grpc_svgs.len(), result.figures.len(), "figure names repeat");
    assert_eq!(
        grpc_svgs.keys().collect::<Vec<_>>(),
        ran_svgs.keys().collect::<Vec<_>>()
    );
    assert!(
        grpc_svgs == ran_svgs,
        "gRPC SVG text differs from run's files"
    );

    // (b) HTTP: names in the result JSON, each SVG under …/figures/{name}, with or without .svg.
    let (code, body) = server
        .http("GET", &format!("/v1/jobs/{id}/result"), None, None)
        .await;
    assert_eq!(code, 200, "{body}");
    let mut names: Vec<String> =
        serde_json::from_value(body["figures"].clone()).expect("figures: a list of names");
    names.sort();
    assert_eq!(names, ran_svgs.keys().cloned().collect::<Vec<_>>());
    let (code, listed) = server
        .http("GET", &format!("/v1/jobs/{id}/figures"), None, None)
        .await;
    assert_eq!(code, 200, "{listed}");
    assert_eq!(
        listed["figures"], body["figures"],
        "…/figures lists the result's figures"
    );
    for (name, svg) in &ran_svgs {
        for path in [
            format!("/v1/jobs/{id}/figures/{name}"),
            format!("/v1/jobs/{id}/figures/{name}.svg"),
        ] {
            let (code, ctype, bytes) = server.http_get_typed(&path).await;
            assert_eq!(code, 200, "{path}: {}", String::from_utf8_lossy(&bytes));
            assert_eq!(ctype, "image/svg+xml", "{path}");
            assert!(&bytes == svg, "{path}: SVG differs from run's file");
        }
    }
    for (path, want, field) in [
        (
            format!("/v1/jobs/{id}/figures/no_such_figure"),
            404,
            "figure",
        ),
        (
            format!("/v1/jobs/{id}/figures/..%2Fsummary.json"),
            404,
            "figure",
        ),
        (format!("/v1/jobs/{id}/figures/backbone.csv"), 404, "figure"),
        (
            "/v1/jobs/no-such-job/figures/backbone".to_string(),
            404,
            "id",
        ),
    ] {
        let (code, body) = server.http("GET", &path, None, None).await;
        assert_eq!(code, want, "{path}: {body}");
        assert_eq!(body["error"]["field"], field, "{path}: {body}");
        assert!(body["error"]["reason"].is_string(), "{path}: {body}");
    }
    // A job without a result yet: the same 409 as …/result.
    let long = submit_json(
        &mut client,
        ball_json(1e-5, 4_000_000, 1000),
        Some("long-1"),
    )
    .await
    .expect("submitting a long job");
    let (code, body) = server
        .http(
            "GET",
            &format!("/v1/jobs/{long}/figures/backbone"),
            None,
            None,
        )
        .await;
    assert_eq!(code, 409, "{body}");
    assert_eq!(body["error"]["field"], "id", "{body}");
    client
        .cancel_job(pb::CancelJobRequest { id: long })
        .await
        .expect("CancelJob");

    // (c) `signorini result ID --out DIR2` writes the files `run` wrote.
    let fetched_dir = dir.path().join("fetched");
    let fetched_arg = fetched_dir.display().to_string();
    signorini(&[
        "result",
        id,
        "--out",
        &fetched_arg,
        "--server",
        &server.grpc_url,
    ]);
    let fetched = files_but_summary(&fetched_dir);
    assert_eq!(
        fetched.keys().collect::<Vec<_>>(),
        ran.keys().collect::<Vec<_>>()
    );
    for (name, bytes) in &ran {
        assert!(&fetched[name] == bytes, "{name} differs from run's");
    }
}
