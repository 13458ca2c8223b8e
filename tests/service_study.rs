//! Studies as service jobs: a `[study]` submitted over HTTP or gRPC becomes a parent job whose
//! runs are child jobs on the pool; the parent's report (summary, `study` table,
//! `work_precision` figure) equals what `signorini run` writes for the same study, errors bit for
//! bit (CPU times differ). Cancelling the parent cancels its children; purging it purges them;
//! a base given as a file name is refused naming `study.base`; on two PostgreSQL replicas the
//! children run on both and the parent completes.

mod common;

use common::pg::Postgres;
use common::{LONG_BALL_STUDY, Options, PATIENCE, TestServer, has_ended, poll_job, submit_json};
use quick_xml::Reader;
use quick_xml::events::Event;
use serde_json::Value;
use signorini::proto::v1 as pb;
use signorini::spec_file::{self, Format};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

/// The DEP bar study of the examples: 3 schemes × 4 (N, h = Δx/c) against the exact solution.
fn dep_bar_study() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/study_dep_bar.toml")
}

/// A study spec file as the JSON spelling the service takes.
fn as_json(path: &Path) -> String {
    let text = std::fs::read_to_string(path).expect("reading the study");
    let spec = spec_file::parse(&text, Format::Toml).expect("a valid study");
    serde_json::to_string(&spec).expect("JSON")
}

/// `signorini run STUDY --out DIR`: (summary.json, study.csv rows as cells).
fn cli_run(study: &Path, out: &Path) -> (Value, Vec<Vec<String>>) {
    let status = Command::new(env!("CARGO_BIN_EXE_signorini"))
        .args(["run", &study.display().to_string(), "--out"])
        .arg(out)
        .arg("-q")
        .status()
        .expect("running signorini");
    assert!(status.success(), "signorini run {}", study.display());
    let summary: Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("summary.json")).expect("summary.json"),
    )
    .expect("summary JSON");
    let csv = std::fs::read_to_string(out.join("study.csv")).expect("study.csv");
    let rows = csv
        .lines()
        .map(|l| {
            // The label is quoted and holds no comma in this study; grid arrays use ';'.
            l.split(',')
                .map(|c| c.trim_matches('"').to_string())
                .collect()
        })
        .collect();
    (summary, rows)
}

/// Polls HTTP `GET /v1/jobs/{id}` until the job has ended; the progress seen on the way.
async fn http_wait(server: &TestServer, id: &str) -> (Value, Vec<(u64, u64)>) {
    let mut seen = Vec::new();
    let fut = async {
        loop {
            let (code, status) = server
                .http("GET", &format!("/v1/jobs/{id}"), None, None)
                .await;
            assert_eq!(code, 200, "{status}");
            let p = (
                status["progress"]["step"].as_u64().unwrap_or(0),
                status["progress"]["total"].as_u64().unwrap_or(0),
            );
            if seen.last() != Some(&p) {
                seen.push(p);
            }
            if ["succeeded", "failed", "cancelled"]
                .contains(&status["state"].as_str().unwrap_or(""))
            {
                return status;
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    };
    let status = tokio::time::timeout(PATIENCE, fut)
        .await
        .expect("the study did not end in time");
    (status, seen)
}

/// The service's summary and `study` table agree with the CLI's summary.json and study.csv:
/// the same runs and errors bit for bit, the same observed orders.
fn assert_same_report(summary: &Value, table: &Value, cli: &(Value, Vec<Vec<String>>)) {
    let (cli_summary, cli_rows) = cli;
    for key in [
        "kind",
        "name",
        "scene",
        "reference",
        "error",
        "runs",
        "schemes",
        "axes",
    ] {
        assert_eq!(summary[key], cli_summary[key], "summary.{key}");
    }
    let orders = summary["orders"].as_array().expect("orders");
    let cli_orders = cli_summary["orders"].as_array().expect("CLI orders");
    assert_eq!(orders.len(), 3, "{summary}");
    assert_eq!(orders.len(), cli_orders.len());
    for (o, c) in orders.iter().zip(cli_orders) {
        assert_eq!(o["scheme"], c["scheme"]);
        assert_eq!(o["points"], 4);
        let (a, b) = (o["order"].as_f64().unwrap(), c["order"].as_f64().unwrap());
        assert!(
            (a - b).abs() <= 1e-12 * b.abs(),
            "{}: {a} vs {b}",
            o["scheme"]
        );
    }
    // The orders of docs/study.md: first order for WFEM, about 0.7 for the two time-stepping
    // schemes (the largest error over both contact phases).
    let order = |i: usize| orders[i]["order"].as_f64().unwrap();
    assert!((order(0) - 0.707).abs() < 0.01, "moreau_jean {}", order(0));
    assert!(
        (order(1) - 0.689).abs() < 0.01,
        "ns_generalized_alpha {}",
        order(1)
    );
    assert!((order(2) - 1.0).abs() < 0.01, "wfem {}", order(2));

    assert_eq!(table["name"], "study");
    let columns: Vec<&str> = table["columns"]
        .as_array()
        .expect("columns")
        .iter()
        .map(|c| c.as_str().unwrap())
        .collect();
    assert_eq!(
        columns,
        [
            "run",
            "scheme",
            "model.elements",
            "time.h",
            "h",
            "steps",
            "cpu_s",
            "error",
            "max_balance_residual",
            "max_energy_error"
        ]
    );
    let rows = table["rows"].as_array().expect("rows");
    assert_eq!(rows.len(), 12);
    assert_eq!(cli_rows.len(), 13, "header + 12 runs");
    let col = |name: &str| columns.iter().position(|c| *c == name).unwrap();
    // study.csv's header splits an axis of several paths at its comma while the rows keep its
    // value in one cell: its last six columns are found from the end.
    let last = [
        "h",
        "steps",
        "cpu_s",
        "error",
        "max_balance_residual",
        "max_energy_error",
    ];
    let cli_col = |name: &str| {
        let from_end = last.len() - last.iter().position(|c| *c == name).unwrap();
        move |row: &Vec<String>| row[row.len() - from_end].clone()
    };
    for (i, row) in rows.iter().enumerate() {
        let cli_row = &cli_rows[i + 1];
        let error = row[col("error")].as_f64().expect("an error");
        let cli_error: f64 = cli_col("error")(cli_row).parse().expect("CLI error");
        assert_eq!(error.to_bits(), cli_error.to_bits(), "run {i}: error");
        let h = row[col("h")].as_f64().unwrap();
        assert_eq!(
            h.to_bits(),
            cli_col("h")(cli_row).parse::<f64>().unwrap().to_bits()
        );
        assert_eq!(
            row[col("steps")].as_f64().unwrap(),
            cli_col("steps")(cli_row).parse::<f64>().unwrap()
        );
        assert!(
            row[col("cpu_s")].as_f64().unwrap() > 0.0,
            "run {i}: CPU seconds"
        );
        let scheme = row[col("scheme")].as_f64().unwrap() as usize;
        assert_eq!(
            summary["schemes"][scheme].as_str(),
            Some(cli_row[1].as_str())
        );
    }
}

/// The work–precision SVG is well-formed XML whose text names the reference.
fn assert_svg_names_the_reference(svg: &str, reference: &str) {
    let mut reader = Reader::from_str(svg);
    let mut text = String::new();
    let mut elements = 0;
    loop {
        match reader.read_event().expect("well-formed SVG") {
            Event::Start(_) | Event::Empty(_) => elements += 1,
            Event::Text(t) => text.push_str(&t.decode().expect("UTF-8 text")),
            Event::Eof => break,
            _ => {}
        }
    }
    assert!(elements > 10, "an SVG with a chart");
    assert!(
        text.contains(reference),
        "the title names {reference}: {text}"
    );
}

#[tokio::test(flavor = "multi_thread")]
async fn a_dep_bar_study_over_http_and_grpc_reports_what_the_cli_does() {
    let dir = tempfile::tempdir().unwrap();
    let cli = cli_run(&dep_bar_study(), &dir.path().join("cli"));
    let server = TestServer::start(&dir.path().join("store.db"), &Options::default());
    let spec = as_json(&dep_bar_study());

    // HTTP.
    let (code, body) = server.http("POST", "/v1/jobs", Some(&spec), None).await;
    assert_eq!(code, 201, "{body}");
    let id = body["id"].as_str().expect("an id").to_string();
    let (status, seen) = http_wait(&server, &id).await;
    assert_eq!(status["state"], "succeeded", "{status}");
    assert_eq!(status["progress"]["step"], 12);
    assert_eq!(status["progress"]["total"], 12);
    assert!(
        seen.windows(2).all(|w| w[0].0 <= w[1].0) && seen.iter().all(|p| p.1 == 12),
        "the parent's progress counts finished children: {seen:?}"
    );
    let (code, children) = server
        .http("GET", &format!("/v1/jobs/{id}/children"), None, None)
        .await;
    assert_eq!(code, 200, "{children}");
    let children = children["jobs"].as_array().expect("jobs").clone();
    assert_eq!(children.len(), 12, "one child per run, no reference run");
    for child in &children {
        assert_eq!(child["state"], "succeeded", "{child}");
        let cid = child["id"].as_str().unwrap();
        assert_ne!(cid, id);
        let (code, r) = server
            .http(
                "GET",
                &format!("/v1/jobs/{cid}/result?columns=gap_0&every=100"),
                None,
                None,
            )
            .await;
        assert_eq!(code, 200, "{r}");
        assert!(
            r["summary"]["cpu_s"].as_f64().unwrap() > 0.0,
            "{}",
            r["summary"]
        );
    }
    let (code, result) = server
        .http("GET", &format!("/v1/jobs/{id}/result"), None, None)
        .await;
    assert_eq!(code, 200, "{result}");
    assert_same_report(&result["summary"], &result["tables"][0], &cli);
    assert_eq!(result["figures"], serde_json::json!(["work_precision"]));
    let (code, ctype, svg) = server
        .http_get_typed(&format!("/v1/jobs/{id}/figures/work_precision.svg"))
        .await;
    assert_eq!(code, 200);
    assert_eq!(ctype, "image/svg+xml");
    let svg = String::from_utf8(svg).expect("UTF-8 SVG");
    assert_svg_names_the_reference(&svg, "exact (dep_bar, by characteristics)");

    // gRPC.
    let mut client = server.grpc().await;
    let gid = submit_json(&mut client, spec.clone(), Some("dep-bar-study"))
        .await
        .expect("SubmitJob");
    assert_eq!(gid, "dep-bar-study");
    let status = poll_job(&mut client, &gid, has_ended).await;
    assert_eq!(status.state, pb::JobState::Succeeded as i32, "{status:?}");
    let listed = client
        .list_children(pb::ListChildrenRequest { id: gid.clone() })
        .await
        .expect("ListChildren")
        .into_inner();
    assert_eq!(listed.jobs.len(), 12);
    assert!(
        listed
            .jobs
            .iter()
            .all(|j| j.state == pb::JobState::Succeeded as i32)
    );
    let result = client
        .get_result(pb::GetResultRequest {
            id: gid.clone(),
            ..Default::default()
        })
        .await
        .expect("GetResult")
        .into_inner();
    let summary: Value = serde_json::from_str(&result.summary_json).expect("summary JSON");
    let table = &result.tables[0];
    let table = serde_json::json!({
        "name": table.name,
        "columns": table.columns,
        "rows": table.rows.iter().map(|r| r.values.clone()).collect::<Vec<_>>(),
    });
    assert_same_report(&summary, &table, &cli);
    assert_eq!(result.figures.len(), 1);
    assert_svg_names_the_reference(
        &result.figures[0].svg,
        "exact (dep_bar, by characteristics)",
    );
    // A plain job has no children; an unknown one is not found.
    let none = client
        .list_children(pb::ListChildrenRequest {
            id: listed.jobs[0].id.clone(),
        })
        .await
        .expect("ListChildren of a child")
        .into_inner();
    assert!(none.jobs.is_empty());
    let err = client
        .list_children(pb::ListChildrenRequest { id: "nope".into() })
        .await
        .expect_err("unknown id");
    assert_eq!(err.code(), tonic::Code::NotFound);
}

/// `GET /v1/jobs/{id}/children`.
async fn children_of(server: &TestServer, id: &str) -> Vec<Value> {
    let (code, c) = server
        .http("GET", &format!("/v1/jobs/{id}/children"), None, None)
        .await;
    assert_eq!(code, 200, "{c}");
    c["jobs"].as_array().expect("jobs").clone()
}

/// A study of long ball runs (one worker): cancelling the parent cancels the running child and
/// the queued ones; purging the parent purges its children.
#[tokio::test(flavor = "multi_thread")]
async fn cancelling_a_study_cancels_its_children_and_purging_it_purges_them() {
    let dir = tempfile::tempdir().unwrap();
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
    let id = body["id"].as_str().unwrap().to_string();
    // Wait until the first child runs.
    let deadline = tokio::time::Instant::now() + PATIENCE;
    loop {
        let c = children_of(&server, &id).await;
        assert_eq!(c.len(), 4);
        if c[0]["state"] == "running" && c[0]["progress"]["step"].as_u64().unwrap_or(0) > 0 {
            assert!(c[1..].iter().all(|j| j["state"] == "queued"), "{c:?}");
            break;
        }
        assert!(tokio::time::Instant::now() < deadline, "no child started");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let (code, parent) = server
        .http("GET", &format!("/v1/jobs/{id}"), None, None)
        .await;
    assert_eq!(code, 200);
    assert_eq!(parent["state"], "running", "{parent}");
    // A parent still running cannot be purged.
    let (code, body) = server
        .http("DELETE", &format!("/v1/jobs/{id}?purge=true"), None, None)
        .await;
    assert_eq!(code, 409, "{body}");
    let (code, parent) = server
        .http("DELETE", &format!("/v1/jobs/{id}"), None, None)
        .await;
    assert_eq!(code, 200, "{parent}");
    assert_eq!(parent["state"], "cancelled", "{parent}");
    let deadline = tokio::time::Instant::now() + PATIENCE;
    let ended = loop {
        let c = children_of(&server, &id).await;
        if c.iter()
            .all(|j| j["state"] != "queued" && j["state"] != "running")
        {
            break c;
        }
        assert!(
            tokio::time::Instant::now() < deadline,
            "children still live: {c:?}"
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    };
    assert!(ended.iter().all(|j| j["state"] == "cancelled"), "{ended:?}");
    let (_, parent) = server
        .http("GET", &format!("/v1/jobs/{id}"), None, None)
        .await;
    assert_eq!(
        parent["state"], "cancelled",
        "the parent stays cancelled: {parent}"
    );
    // Purging the parent purges its children.
    let (code, body) = server
        .http("DELETE", &format!("/v1/jobs/{id}?purge=true"), None, None)
        .await;
    assert_eq!(code, 200, "{body}");
    for j in ended.iter().chain([&parent]) {
        let jid = j["id"].as_str().unwrap();
        let (code, _) = server
            .http("GET", &format!("/v1/jobs/{jid}"), None, None)
            .await;
        assert_eq!(code, 404, "{jid} purged");
    }
}

/// A base given as a file name is refused (the server does not read the client's files), over
/// HTTP (400) and gRPC (INVALID_ARGUMENT), naming `study.base`; nothing is queued.
#[tokio::test(flavor = "multi_thread")]
async fn a_study_whose_base_is_a_file_is_refused_naming_study_base() {
    let dir = tempfile::tempdir().unwrap();
    let server = TestServer::start(&dir.path().join("store.db"), &Options::default());
    let spec = r#"{"study": {"base": "dep_bar.toml", "reference": "exact",
        "schemes": [{"scheme": "moreau_jean"}], "grid": {"time.h": [1e-3, 5e-4]}}}"#;
    let (code, body) = server.http("POST", "/v1/jobs", Some(spec), None).await;
    assert_eq!(code, 400, "{body}");
    assert_eq!(body["error"]["field"], "study.base", "{body}");
    let reason = body["error"]["reason"].as_str().unwrap();
    assert!(
        reason.contains("inline") && reason.contains("dep_bar.toml"),
        "{reason}"
    );
    let mut client = server.grpc().await;
    let err = submit_json(&mut client, spec.to_string(), None)
        .await
        .expect_err("a file base");
    assert_eq!(err.code(), tonic::Code::InvalidArgument);
    assert!(
        err.message().starts_with("study.base: "),
        "{}",
        err.message()
    );
    // A bad run names the study's field: a grid value the model refuses.
    let bad = r#"{"study": {"reference": "exact",
        "base": {"model": {"scene": "bouncing_ball"}, "time": {"h": 1e-3, "t_end": 1.0}},
        "schemes": [{"scheme": "moreau_jean"}], "grid": {"time.h": [1e-3, -1.0]}}}"#;
    let (code, body) = server.http("POST", "/v1/jobs", Some(bad), None).await;
    assert_eq!(code, 400, "{body}");
    let field = body["error"]["field"].as_str().unwrap();
    assert!(field.starts_with("study.schemes[0] at time.h=-1"), "{body}");
    // More runs than the server's queue holds (64 in the tests): refused naming `study`.
    let hs: Vec<String> = (1..=65)
        .map(|k| format!("{:?}", 1e-3 / f64::from(k)))
        .collect();
    let big = format!(
        r#"{{"study": {{"reference": "exact",
        "base": {{"model": {{"scene": "bouncing_ball"}}, "time": {{"h": 1e-3, "t_end": 0.1}}}},
        "schemes": [{{"scheme": "moreau_jean"}}], "grid": {{"time.h": [{}]}}}}}}"#,
        hs.join(", ")
    );
    let (code, body) = server.http("POST", "/v1/jobs", Some(&big), None).await;
    assert_eq!(code, 400, "{body}");
    assert_eq!(body["error"]["field"], "study", "{body}");
    assert!(
        body["error"]["reason"]
            .as_str()
            .unwrap()
            .contains("65 runs"),
        "{body}"
    );
    let (code, list) = server.http("GET", "/v1/jobs", None, None).await;
    assert_eq!(code, 200);
    assert_eq!(list["jobs"], serde_json::json!([]), "nothing queued");
}

/// One study on two PostgreSQL replicas with one worker each: its children run on both, and the
/// parent completes with the CLI's report.
#[tokio::test(flavor = "multi_thread")]
async fn a_study_on_two_postgres_replicas_runs_its_children_on_both() {
    let dir = tempfile::tempdir().unwrap();
    let cli = cli_run(&dep_bar_study(), &dir.path().join("cli"));
    let pg = Postgres::start();
    let url = pg.create_database("studies");
    let opts = Options {
        workers: 1,
        queue_limit: 256,
        ..Options::default()
    };
    let a = TestServer::start_with(
        Path::new(&url),
        &opts,
        &["--replica", "a", "--lease-secs", "2"],
    );
    let b = TestServer::start_with(
        Path::new(&url),
        &opts,
        &["--replica", "b", "--lease-secs", "2"],
    );
    let spec = as_json(&dep_bar_study());
    let (code, body) = a.http("POST", "/v1/jobs", Some(&spec), None).await;
    assert_eq!(code, 201, "{body}");
    let id = body["id"].as_str().unwrap().to_string();
    // Either replica answers for the parent.
    let (status, _) = http_wait(&b, &id).await;
    assert_eq!(status["state"], "succeeded", "{status}");
    let owners = pg.psql(
        "studies",
        &format!(
            "SELECT owner || '=' || COUNT(*) FROM jobs WHERE parent = '{id}' GROUP BY owner ORDER BY owner"
        ),
    );
    let counts: Vec<(&str, u64)> = owners
        .lines()
        .map(|l| {
            let (o, n) = l.split_once('=').expect("owner=count");
            (o, n.parse().expect("a count"))
        })
        .collect();
    assert_eq!(
        counts.iter().map(|c| c.0).collect::<Vec<_>>(),
        ["a", "b"],
        "children on both replicas: {owners}"
    );
    assert_eq!(counts.iter().map(|c| c.1).sum::<u64>(), 12);
    // Each run names its study on either replica (the PostgreSQL `parent` column).
    for child in children_of(&b, &id).await {
        let child = child["id"].as_str().expect("id");
        let (code, body) = a
            .http("GET", &format!("/v1/jobs/{child}"), None, None)
            .await;
        assert_eq!(
            (code, &body["parent"]),
            (200, &Value::from(id.as_str())),
            "{body}"
        );
    }
    let (code, result) = a
        .http("GET", &format!("/v1/jobs/{id}/result"), None, None)
        .await;
    assert_eq!(code, 200, "{result}");
    assert_same_report(&result["summary"], &result["tables"][0], &cli);
    let (code, result_b) = b
        .http("GET", &format!("/v1/jobs/{id}/result"), None, None)
        .await;
    assert_eq!(code, 200);
    assert_eq!(result_b["summary"], result["summary"]);
}

/// A SQLite server killed (SIGKILL) mid-study: after the restart the parent is still `running`
/// (not re-queued as a job), its unfinished children run again, and the parent completes with
/// every run in its report.
#[tokio::test(flavor = "multi_thread")]
async fn a_study_interrupted_by_kill9_completes_after_the_restart() {
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("store.db");
    let opts = Options {
        workers: 1,
        max_steps: Some(1_000_000_000),
        ..Options::default()
    };
    let mut first = TestServer::start(&store, &opts);
    let spec = r#"{"study": {
        "reference": "exact",
        "base": {"model": {"scene": "bouncing_ball"}, "time": {"h": 1e-5, "t_end": 1.7},
                 "output": {"every": 1}},
        "schemes": [{"scheme": "moreau_jean", "theta": 0.5}],
        "grid": {"time.h": [8e-6, 4e-6, 2e-6]}}}"#;
    let (code, body) = first.http("POST", "/v1/jobs", Some(spec), None).await;
    assert_eq!(code, 201, "{body}");
    let id = body["id"].as_str().unwrap().to_string();
    // Killed once the second run has started (the first has ended).
    let deadline = tokio::time::Instant::now() + PATIENCE;
    loop {
        let c = children_of(&first, &id).await;
        if c[1]["state"] == "running" {
            assert_eq!(c[0]["state"], "succeeded", "{c:?}");
            break;
        }
        assert!(
            tokio::time::Instant::now() < deadline,
            "the second run never started"
        );
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    first.kill9();
    let second = TestServer::start(&store, &opts);
    let (status, _) = http_wait(&second, &id).await;
    assert_eq!(status["state"], "succeeded", "{status}");
    assert_eq!(status["progress"]["step"], 3);
    let c = children_of(&second, &id).await;
    assert!(c.iter().all(|j| j["state"] == "succeeded"), "{c:?}");
    let (code, result) = second
        .http("GET", &format!("/v1/jobs/{id}/result"), None, None)
        .await;
    assert_eq!(code, 200, "{result}");
    assert_eq!(result["summary"]["runs"], 3);
    let rows = result["tables"][0]["rows"].as_array().unwrap();
    assert!(
        rows.iter().all(|r| r[6].as_f64().is_some_and(|e| e > 0.0)),
        "every run has its error: {rows:?}"
    );
    assert_eq!(result["summary"]["orders"].as_array().unwrap().len(), 1);
}

/// Issue 30: `?format=csv` of a study job is its `study` table (it returned only `step,t`), and
/// its work–precision figure labels each point with its h and each curve with its observed
/// order.
#[tokio::test(flavor = "multi_thread")]
async fn a_studys_csv_is_its_table_and_its_figure_labels_h_and_orders() {
    let dir = tempfile::tempdir().unwrap();
    let server = TestServer::start(&dir.path().join("store.db"), &Options::default());
    let spec = r#"{"study": {"base": {"model": {"scene": "bouncing_ball", "restitution": 0.8},
        "time": {"h": 1e-3, "t_end": 0.5}}, "reference": "exact", "error": "max_abs",
        "schemes": [{"scheme": "moreau_jean", "theta": 0.5}],
        "grid": {"time.h": [1e-3, 5e-4, 2.5e-4]}}}"#;
    let (code, body) = server.http("POST", "/v1/jobs", Some(spec), None).await;
    assert_eq!(code, 201, "{body}");
    let id = body["id"].as_str().expect("an id").to_string();
    let (status, _) = http_wait(&server, &id).await;
    assert_eq!(status["state"], "succeeded", "{status}");
    let (code, result) = server
        .http("GET", &format!("/v1/jobs/{id}/result"), None, None)
        .await;
    assert_eq!(code, 200, "{result}");
    let table = &result["tables"][0];
    assert_eq!(table["name"], "study");
    let (code, _, csv) = server
        .request("GET", &format!("/v1/jobs/{id}/result?format=csv"), "", &[])
        .await;
    assert_eq!(code, 200);
    let csv = String::from_utf8(csv).expect("CSV");
    let lines: Vec<&str> = csv.lines().collect();
    let columns: Vec<String> = serde_json::from_value(table["columns"].clone()).expect("columns");
    assert_eq!(lines[0], columns.join(","), "{csv}");
    assert_eq!(lines.len(), 1 + 3, "{csv}");
    let h_at = columns.iter().position(|c| c == "h").expect("an h column");
    let hs: Vec<f64> = lines[1..]
        .iter()
        .map(|l| l.split(',').nth(h_at).unwrap().parse().unwrap())
        .collect();
    assert_eq!(hs, [1e-3, 5e-4, 2.5e-4]);

    let order = result["summary"]["orders"][0]["order"]
        .as_f64()
        .expect("an observed order");
    let (code, _, svg) = server
        .request(
            "GET",
            &format!("/v1/jobs/{id}/figures/work_precision.svg"),
            "",
            &[],
        )
        .await;
    assert_eq!(code, 200);
    let svg = String::from_utf8(svg).expect("SVG");
    for h in ["h=1e-3", "h=5e-4", "h=2.5e-4"] {
        assert!(svg.contains(&format!(">{h}</text>")), "{h}");
    }
    assert!(
        svg.contains(&format!("observed order {order:.2}</text>")),
        "order {order:.2}"
    );
}
