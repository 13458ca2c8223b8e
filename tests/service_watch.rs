//! The streams users watch, end to end against the real binary: gRPC `WatchJob`, the CLI's
//! `signorini watch ID --json` (zenoh), and the live page's server-sent events
//! (`/v1/jobs/{id}/events`). Each test keeps the only worker busy with a long job, so the watched
//! job waits in the queue while the watcher subscribes (no step can run before the watcher is
//! known); cancelling the long job lets it run. Every value streamed must equal `GetResult`.

mod common;

use common::{
    ChildGuard, Options, PATIENCE, SseEvent, TestServer, ball_json, occupy_the_worker, read_sse,
    stdout_lines, submit_json,
};
use serde_json::Value;
use signorini::proto::v1 as pb;
use std::collections::BTreeMap;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const STEPS: u64 = 3000;

fn one_worker() -> Options {
    Options {
        workers: 1,
        max_steps: Some(1_000_000_000),
        ..Options::default()
    }
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// Steps, times and columns gathered from step frames of one kind.
#[derive(Default)]
struct Series {
    columns: Vec<String>,
    step: Vec<u64>,
    t: Vec<f64>,
    values: BTreeMap<String, Vec<f64>>,
}

impl Series {
    fn push(&mut self, columns: &[String], step: &[u64], t: &[f64], rows: &[Vec<f64>]) {
        assert_eq!(step.len(), rows.len(), "one row per step");
        assert_eq!(t.len(), rows.len(), "one time per step");
        if self.columns.is_empty() {
            self.columns = columns.to_vec();
        }
        assert_eq!(self.columns, columns, "columns stay the same");
        self.step.extend(step);
        self.t.extend(t);
        for (c, name) in columns.iter().enumerate() {
            let col = self.values.entry(name.clone()).or_default();
            col.extend(rows.iter().map(|r| r[c]));
        }
    }

    /// Every step 0..=STEPS in order, and each value bit-equal to the stored result.
    fn assert_equals_result(&self, what: &str, result: &pb::JobResult) {
        assert_eq!(
            self.step,
            (0..=STEPS).collect::<Vec<_>>(),
            "{what}: every step once, in order"
        );
        assert_eq!(result.step, self.step, "{what}: steps of GetResult");
        assert_eq!(bits(&result.t), bits(&self.t), "{what}: t");
        assert!(!self.columns.is_empty(), "{what}: some columns");
        for name in &self.columns {
            let stored = result
                .series
                .iter()
                .find(|s| &s.column == name)
                .unwrap_or_else(|| panic!("{what}: column {name} not in the result"));
            assert_eq!(
                bits(&stored.values),
                bits(&self.values[name]),
                "{what}: column {name}"
            );
        }
    }
}

fn rows_of(values: &[f64], columns: usize) -> Vec<Vec<f64>> {
    values.chunks(columns.max(1)).map(<[f64]>::to_vec).collect()
}

async fn get_result(server: &TestServer, id: &str) -> pb::JobResult {
    server
        .grpc()
        .await
        .get_result(pb::GetResultRequest {
            id: id.into(),
            ..Default::default()
        })
        .await
        .expect("GetResult")
        .into_inner()
}

async fn cancel(server: &TestServer, id: &str) {
    let s = server
        .grpc()
        .await
        .cancel_job(pb::CancelJobRequest { id: id.into() })
        .await
        .expect("CancelJob")
        .into_inner();
    assert_eq!(s.state, pb::JobState::Cancelled as i32, "{s:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn grpc_watch_job_frames_equal_get_result_and_end_with_the_final_state() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("store.db"), &one_worker());
    let mut client = server.grpc().await;
    occupy_the_worker(&mut client, "blocker").await;
    let id = submit_json(&mut client, ball_json(1e-3, STEPS, 1), Some("watched"))
        .await
        .expect("submit");
    let mut stream = client
        .watch_job(pb::WatchJobRequest {
            id: id.clone(),
            ..Default::default()
        })
        .await
        .expect("WatchJob")
        .into_inner();
    let first = tokio::time::timeout(PATIENCE, stream.message())
        .await
        .expect("first frame in time")
        .expect("stream")
        .expect("a first frame");
    match first.frame {
        Some(pb::watch_frame::Frame::Status(s)) => {
            assert_eq!(s.state, pb::JobState::Queued as i32, "{s:?}")
        }
        other => panic!("the first frame is the current status, got {other:?}"),
    }
    cancel(&server, "blocker").await;

    let mut frames = Vec::new();
    let collect = async {
        while let Some(f) = stream.message().await.expect("WatchJob stream") {
            frames.push(f);
        }
    };
    tokio::time::timeout(PATIENCE, collect)
        .await
        .expect("WatchJob ended in time");

    let (mut energy, mut state) = (Series::default(), Series::default());
    let (mut energy_seq, mut state_seq) = (0, 0);
    let mut last_progress = 0;
    for (i, f) in frames.iter().enumerate() {
        match f.frame.as_ref().expect("a frame") {
            pb::watch_frame::Frame::Status(s) => {
                assert_eq!(s.id, id);
                let step = s.progress.expect("progress").step;
                assert!(step >= last_progress, "progress goes forward");
                last_progress = step;
                let terminal = common::has_ended(s);
                assert_eq!(
                    terminal,
                    i + 1 == frames.len(),
                    "only the last frame is final"
                );
            }
            pb::watch_frame::Frame::Energy(sf) | pb::watch_frame::Frame::State(sf) => {
                let is_energy = matches!(f.frame, Some(pb::watch_frame::Frame::Energy(_)));
                let (series, seq) = if is_energy {
                    (&mut energy, &mut energy_seq)
                } else {
                    (&mut state, &mut state_seq)
                };
                assert_eq!(sf.id, id);
                assert_eq!(sf.seq, *seq, "no frame dropped");
                *seq += 1;
                series.push(
                    &sf.columns,
                    &sf.step,
                    &sf.t,
                    &rows_of(&sf.values, sf.columns.len()),
                );
            }
        }
    }
    let Some(pb::watch_frame::Frame::Status(fin)) = frames.last().and_then(|f| f.frame.clone())
    else {
        panic!("the stream ends with a status");
    };
    assert_eq!(fin.state, pb::JobState::Succeeded as i32, "{fin:?}");
    let p = fin.progress.expect("progress");
    assert_eq!((p.step, p.total, p.fraction), (STEPS, STEPS, 1.0));

    let result = get_result(&server, &id).await;
    assert_eq!(result.status.as_ref().expect("status").state, fin.state);
    energy.assert_equals_result("energy frames", &result);
    state.assert_equals_result("state frames", &result);
    assert!(energy.columns.iter().any(|c| c == "energy"));
    // Energy and state frames together carry every column of steps.csv.
    let mut all: Vec<&String> = energy.columns.iter().chain(&state.columns).collect();
    all.sort();
    let mut stored: Vec<&String> = result.series.iter().map(|s| &s.column).collect();
    stored.sort();
    assert_eq!(all, stored, "the frames carry every stored column");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cli_watch_json_prints_status_and_energy_lines_and_exits_when_the_job_ends() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("store.db"), &one_worker());
    let mut client = server.grpc().await;
    occupy_the_worker(&mut client, "blocker").await;
    let id = submit_json(&mut client, ball_json(1e-3, STEPS, 1), Some("cli-watched"))
        .await
        .expect("submit");
    let mut child = ChildGuard(
        Command::new(env!("CARGO_BIN_EXE_signorini"))
            .args(["watch", &id, "--json", "--zenoh", &server.zenoh])
            .env_remove("SIGNORINI_ZENOH_CONNECT")
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("starting signorini watch"),
    );
    let lines = stdout_lines(&mut child.0);
    let next = || {
        lines
            .recv_timeout(PATIENCE)
            .expect("signorini watch printed nothing in time")
    };
    // Its first line is the job's current status, answered by the server's queryable: from then
    // on the watcher's subscription is known to the server.
    let first: Value = serde_json::from_str(&next().expect("a first line")).expect("JSON line");
    assert_eq!(first["kind"], "status", "{first}");
    assert_eq!(first["status"]["state"], "queued", "{first}");
    assert_eq!(first["status"]["id"], id.as_str());
    cancel(&server, "blocker").await;

    let mut printed = Vec::new();
    while let Some(line) = next() {
        printed.push(serde_json::from_str::<Value>(&line).unwrap_or_else(|e| {
            panic!("not a JSON line ({e}): {line}");
        }));
    }
    // stdout closed: the process must be exiting on its own, successfully.
    let deadline = Instant::now() + PATIENCE;
    let status = loop {
        if let Some(s) = child.0.try_wait().expect("try_wait") {
            break s;
        }
        assert!(Instant::now() < deadline, "signorini watch did not exit");
        std::thread::sleep(Duration::from_millis(20));
    };
    assert!(status.success(), "signorini watch exited with {status}");

    let last = printed.last().expect("lines after the first");
    assert_eq!(
        last["kind"], "status",
        "the last line is the final status: {last}"
    );
    assert_eq!(last["status"]["state"], "succeeded", "{last}");
    assert_eq!(last["status"]["progress"]["step"], STEPS);
    assert_eq!(last["status"]["progress"]["fraction"], 1.0);

    let (mut energy, mut state) = (Series::default(), Series::default());
    for line in &printed {
        let kind = line["kind"].as_str().expect("every line has a kind");
        let series = match kind {
            "status" => continue,
            "energy" => &mut energy,
            "state" => &mut state,
            other => panic!("unknown kind {other}"),
        };
        assert_eq!(line["id"], id.as_str());
        let columns: Vec<String> =
            serde_json::from_value(line["columns"].clone()).expect("columns");
        let step: Vec<u64> = serde_json::from_value(line["step"].clone()).expect("step");
        let t: Vec<f64> = serde_json::from_value(line["t"].clone()).expect("t");
        let rows: Vec<Vec<f64>> = serde_json::from_value(line["rows"].clone()).expect("rows");
        series.push(&columns, &step, &t, &rows);
    }
    assert!(
        energy.columns.iter().any(|c| c == "kinetic")
            && energy.columns.iter().any(|c| c == "energy")
    );
    // The lines are JSON numbers printed and parsed with serde_json's float_roundtrip: exact.
    let result = get_result(&server, &id).await;
    energy.assert_equals_result("energy lines", &result);
    state.assert_equals_result("state lines", &result);
}

async fn recv(rx: &mut tokio::sync::mpsc::UnboundedReceiver<SseEvent>) -> Option<SseEvent> {
    tokio::time::timeout(PATIENCE, rx.recv())
        .await
        .expect("an event in time")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn live_page_events_carry_energy_while_the_job_runs() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("store.db"), &one_worker());
    let mut client = server.grpc().await;
    occupy_the_worker(&mut client, "blocker").await;
    let id = submit_json(&mut client, ball_json(1e-3, STEPS, 1), Some("sse-watched"))
        .await
        .expect("submit");

    let (tx, mut rx) = tokio::sync::mpsc::unbounded_channel::<SseEvent>();
    let addr = server.http;
    let path = format!("/v1/jobs/{id}/events");
    let reader = tokio::spawn(async move {
        read_sse(addr, &path, |e| {
            let terminal = e.event == "status"
                && matches!(
                    e.data["state"].as_str(),
                    Some("succeeded" | "failed" | "cancelled")
                );
            tx.send(e).is_ok() && !terminal
        })
        .await;
    });
    let first = recv(&mut rx).await.expect("a first event");
    assert_eq!(first.event, "status");
    assert_eq!(first.data["state"], "queued", "{:?}", first.data);
    cancel(&server, "blocker").await;

    let mut events = Vec::new();
    while let Some(e) = recv(&mut rx).await {
        events.push(e);
    }
    tokio::time::timeout(PATIENCE, reader)
        .await
        .expect("reader stopped")
        .expect("reader task");

    let last = events.last().expect("events after the first");
    assert_eq!(
        (last.event.as_str(), &last.data["state"]),
        ("status", &Value::from("succeeded"))
    );
    // Every status event has the shape of `GET /v1/jobs/{id}` (error, name and timestamps
    // included), and the final one says what GET says once the job is over.
    for e in events
        .iter()
        .chain([&first])
        .filter(|e| e.event == "status")
    {
        for key in [
            "id",
            "name",
            "state",
            "progress",
            "error",
            "created_ms",
            "started_ms",
            "finished_ms",
        ] {
            assert!(
                e.data.get(key).is_some(),
                "status event lacks {key}: {:?}",
                e.data
            );
        }
    }
    assert!(
        last.data["finished_ms"].as_u64().is_some_and(|ms| ms > 0),
        "{:?}",
        last.data
    );
    let (code, got) = server
        .http("GET", &format!("/v1/jobs/{id}"), None, None)
        .await;
    assert_eq!(code, 200);
    assert_eq!(last.data, got);
    let energy_events: Vec<&SseEvent> = events.iter().filter(|e| e.event == "energy").collect();
    assert!(
        !energy_events.is_empty(),
        "energy events before the final status: {events:?}"
    );
    assert!(
        events
            .iter()
            .all(|e| e.event == "status" || e.event == "energy")
    );
    // The job was running when its energy was streamed: a `running` status precedes the first
    // energy event, and the final status comes after the last one.
    let first_energy = events
        .iter()
        .position(|e| e.event == "energy")
        .expect("energy");
    assert!(
        events[..first_energy]
            .iter()
            .any(|e| e.event == "status" && e.data["state"] == "running"),
        "no running status before the energy events: {:?}",
        &events[..first_energy]
    );
    let mut energy = Series::default();
    for e in energy_events {
        let columns: Vec<String> =
            serde_json::from_value(e.data["columns"].clone()).expect("columns");
        let step: Vec<u64> = serde_json::from_value(e.data["step"].clone()).expect("step");
        let t: Vec<f64> = serde_json::from_value(e.data["t"].clone()).expect("t");
        let rows: Vec<Vec<f64>> = serde_json::from_value(e.data["rows"].clone()).expect("rows");
        energy.push(&columns, &step, &t, &rows);
    }
    assert!(energy.columns.iter().any(|c| c == "energy"));
    let result = get_result(&server, &id).await;
    energy.assert_equals_result("energy events", &result);
}
