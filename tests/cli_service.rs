//! The client commands as a user runs them against a real server (issue 13, part 5): `watch`
//! with its stdout on a pipe prints line-wise progress and the final status; `watch --json`
//! whose reader goes away (`| head -1`) ends quietly with status 0; `submit --wait` prints the id,
//! then the final status, and fails for a job that does not succeed; `pause`, `resume`, `extend`
//! and `children` reach the lifecycle routes.

mod common;

use common::{ChildGuard, Options, PATIENCE, TestServer, ball_json, submit_json, wait_running};
use std::io::{BufRead, BufReader, Read};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn signorini() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_signorini"));
    c.env_remove("SIGNORINI_ZENOH_CONNECT")
        .env_remove("SIGNORINI_SERVER")
        .env_remove("SIGNORINI_TOKEN");
    c
}

/// Waits for a child with a deadline; its exit status.
fn wait(child: &mut std::process::Child) -> std::process::ExitStatus {
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait().expect("try_wait") {
            return status;
        }
        assert!(
            start.elapsed() < PATIENCE,
            "the command did not end in time"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn watch_on_a_pipe_prints_lines_and_ends_quietly_when_the_reader_goes() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("s.db"), &Options::default());
    let mut client = server.grpc().await;
    let id = submit_json(&mut client, ball_json(1e-5, 400_000, 1), Some("lines"))
        .await
        .expect("submit");
    wait_running(&mut client, &id, 1).await;

    // Not a terminal: plain lines, then the final status as JSON, exit 0.
    let out = signorini()
        .args(["watch", &id, "--zenoh", &server.zenoh])
        .output()
        .expect("signorini watch");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).expect("utf-8");
    let progress: Vec<&str> = text
        .lines()
        .filter(|l| l.starts_with("lines running step "))
        .collect();
    assert!(!progress.is_empty(), "no progress line in {text}");
    assert!(!text.contains('\u{1b}'), "no terminal escapes on a pipe");
    let json_start = text.find("{\n").expect("the final status");
    let last: serde_json::Value = serde_json::from_str(&text[json_start..]).expect("JSON status");
    assert_eq!(last["state"], "succeeded");

    // `watch --json | head -1`: the reader closes the pipe after one line.
    let id = submit_json(&mut client, ball_json(1e-5, 400_000, 1), Some("piped"))
        .await
        .expect("submit");
    wait_running(&mut client, &id, 1).await;
    let mut child = ChildGuard(
        signorini()
            .args(["watch", &id, "--json", "--zenoh", &server.zenoh])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("signorini watch --json"),
    );
    let stdout = child.0.stdout.take().expect("stdout");
    let mut first = String::new();
    BufReader::new(stdout)
        .read_line(&mut first)
        .expect("a first line");
    assert!(first.contains("\"kind\":\"status\""), "{first}");
    // The reader is gone (dropped above): the next write fails with EPIPE.
    let status = wait(&mut child.0);
    let mut stderr = String::new();
    child
        .0
        .stderr
        .take()
        .expect("stderr")
        .read_to_string(&mut stderr)
        .expect("stderr");
    assert!(status.success(), "{status}: {stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(stderr.is_empty(), "quiet: {stderr}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn submit_wait_prints_the_final_status_and_fails_unless_it_succeeded() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("s.db"), &Options::default());
    let spec = dir.path().join("ball.json");
    std::fs::write(&spec, ball_json(1e-3, 2000, 10)).expect("spec");
    let out = signorini()
        .args([
            "submit",
            "--wait",
            "--id",
            "waited",
            "--server",
            &server.grpc_url,
        ])
        .arg(&spec)
        .output()
        .expect("signorini submit --wait");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).expect("utf-8");
    let (id, status) = text.split_once('\n').expect("the id, then the status");
    assert_eq!(id, "waited");
    let status: serde_json::Value = serde_json::from_str(status).expect("JSON status");
    assert_eq!(
        (
            status["state"].as_str(),
            status["progress"]["step"].as_u64()
        ),
        (Some("succeeded"), Some(2000))
    );

    // A job cancelled while --wait waits: exit status 1, the state named.
    std::fs::write(&spec, ball_json(1e-6, 50_000_000, 1000)).expect("spec");
    let mut child = ChildGuard(
        signorini()
            .args([
                "submit",
                "--wait",
                "--id",
                "stopped",
                "--server",
                &server.grpc_url,
            ])
            .arg(&spec)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("signorini submit --wait"),
    );
    let mut client = server.grpc().await;
    let start = Instant::now();
    while server.http("GET", "/v1/jobs/stopped", None, None).await.0 != 200 {
        assert!(
            start.elapsed() < PATIENCE,
            "the job was not submitted in time"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    wait_running(&mut client, "stopped", 1).await;
    let (code, _) = server.http("DELETE", "/v1/jobs/stopped", None, None).await;
    assert_eq!(code, 200);
    let status = wait(&mut child.0);
    let mut stderr = String::new();
    child
        .0
        .stderr
        .take()
        .expect("stderr")
        .read_to_string(&mut stderr)
        .expect("stderr");
    assert_eq!(status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("job stopped cancelled"), "{stderr}");
}

/// The issue's attack: a stranger on zenoh publishes `JobStatus{SUCCEEDED}` on a running job's
/// status key. `watch` used to print it and exit 0; now the final status is checked with the
/// server's gRPC API and the mismatch is an error. The stranger here is the peer `watch`
/// connects to (it answers the status query and publishes the fake end); the job is real and
/// runs on.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn watch_reports_a_spoofed_final_status_as_an_error() {
    use prost::Message;
    use signorini::proto::v1 as pb;
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("s.db"), &Options::default());
    let mut client = server.grpc().await;
    let id = submit_json(
        &mut client,
        ball_json(1e-6, 50_000_000, 1000),
        Some("target"),
    )
    .await
    .expect("submit");
    wait_running(&mut client, &id, 1).await;

    let endpoint = format!("tcp/127.0.0.1:{}", common::free_port());
    let stranger = signorini::stream::open_session(&signorini::stream::ZenohOptions {
        listen: vec![endpoint.clone()],
        ..Default::default()
    })
    .await
    .expect("the stranger's zenoh peer");
    let status = |state: pb::JobState| {
        pb::JobStatus {
            id: id.clone(),
            state: state as i32,
            ..Default::default()
        }
        .encode_to_vec()
    };
    let queryable = stranger
        .declare_queryable(signorini::stream::status_key(&id))
        .await
        .expect("queryable");
    let running = status(pb::JobState::Running);
    let answering = tokio::spawn(async move {
        while let Ok(q) = queryable.recv_async().await {
            let key = q.key_expr().clone();
            let _ = q.reply(key, running.clone()).await;
        }
    });
    let mut child = ChildGuard(
        signorini()
            .args(["watch", &id, "--json", "--zenoh", &endpoint])
            .args(["--server", &server.grpc_url])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("signorini watch"),
    );
    let mut lines = BufReader::new(child.0.stdout.take().expect("stdout"));
    let mut first = String::new();
    lines.read_line(&mut first).expect("a first line");
    assert!(first.contains("\"running\""), "{first}");
    std::thread::spawn(move || std::io::copy(&mut lines, &mut std::io::sink()));
    let exit = {
        let start = Instant::now();
        loop {
            stranger
                .put(
                    signorini::stream::status_key(&id),
                    status(pb::JobState::Succeeded),
                )
                .await
                .expect("put");
            if let Some(s) = child.0.try_wait().expect("try_wait") {
                break s;
            }
            assert!(
                start.elapsed() < PATIENCE,
                "watch never saw the spoofed status"
            );
            tokio::time::sleep(Duration::from_millis(200)).await;
        }
    };
    let mut stderr = String::new();
    child
        .0
        .stderr
        .take()
        .expect("stderr")
        .read_to_string(&mut stderr)
        .expect("stderr");
    assert_eq!(exit.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("that status was not the server's"),
        "{stderr}"
    );
    let s = client
        .get_job(pb::GetJobRequest { id: id.clone() })
        .await
        .expect("GetJob")
        .into_inner();
    assert_eq!(s.state, pb::JobState::Running as i32, "the job runs on");
    answering.abort();
    let _ = stranger.close().await;
}

/// Runs the CLI with `args` against `server`; its stdout, after asserting it succeeded.
fn run_ok(server: &TestServer, args: &[&str]) -> String {
    let out = signorini()
        .args(args)
        .args(["--server", &server.grpc_url])
        .output()
        .expect("signorini");
    assert!(
        out.status.success(),
        "signorini {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("utf-8")
}

/// The JSON a command printed.
fn json_of(text: &str) -> serde_json::Value {
    serde_json::from_str(text).unwrap_or_else(|e| panic!("{e}: {text}"))
}

/// `pause`, `resume`, `extend` and `children` as a user types them: a running job parks and is
/// queued again; a succeeded job is extended to a later time (`status` names the job it
/// extends); a study's runs are listed and each names its study.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn pause_resume_extend_and_children_from_the_command_line() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("s.db"), &Options::default());

    let long = dir.path().join("long.json");
    std::fs::write(&long, ball_json(1e-6, 50_000_000, 1000)).expect("spec");
    let long = long.to_str().expect("path");
    assert_eq!(run_ok(&server, &["submit", "--id", "long", long]), "long\n");
    let mut client = server.grpc().await;
    wait_running(&mut client, "long", 1).await;
    let paused = json_of(&run_ok(&server, &["pause", "long"]));
    assert_eq!(paused["state"], "paused", "{paused}");
    let step = paused["progress"]["step"].as_u64().expect("step");
    assert!(step > 0, "{paused}");
    let resumed = json_of(&run_ok(&server, &["resume", "long"]));
    assert!(
        ["queued", "running"].contains(&resumed["state"].as_str().expect("state")),
        "{resumed}"
    );
    // Paused again only once it runs from its checkpoint, past the step it parked at.
    wait_running(&mut client, "long", step + 1).await;
    let cancelled = json_of(&run_ok(&server, &["cancel", "long"]));
    assert_eq!(cancelled["state"], "cancelled", "{cancelled}");
    // A job that is not paused cannot be resumed: the state is named.
    let out = signorini()
        .args(["resume", "long", "--server", &server.grpc_url])
        .output()
        .expect("signorini resume");
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("FailedPrecondition") && stderr.contains("cancelled"),
        "{stderr}"
    );

    let first = dir.path().join("first.json");
    std::fs::write(
        &first,
        r#"{"model":{"scene":"bouncing_ball","restitution":0.8},"time":{"h":1e-3,"t_end":1.0},"output":{"every":10}}"#,
    )
    .expect("spec");
    run_ok(
        &server,
        &[
            "submit",
            "--wait",
            "--id",
            "first",
            first.to_str().expect("path"),
        ],
    );
    let text = run_ok(
        &server,
        &[
            "extend", "first", "--t-end", "2.0", "--new-id", "second", "--wait",
        ],
    );
    let (id, end) = text.split_once('\n').expect("the id, then the status");
    assert_eq!(id, "second");
    let end = json_of(end);
    assert_eq!(
        (end["state"].as_str(), end["progress"]["step"].as_u64()),
        (Some("succeeded"), Some(2000)),
        "{end}"
    );
    let second = json_of(&run_ok(&server, &["status", "second"]));
    assert_eq!(second["extends"], "first", "{second}");
    assert!(second.get("parent").is_none(), "{second}");

    let study = dir.path().join("study.json");
    std::fs::write(
        &study,
        r#"{"study": {"reference": "exact",
            "base": {"model": {"scene": "bouncing_ball"}, "time": {"h": 1e-3, "t_end": 0.5}},
            "schemes": [{"scheme": "moreau_jean", "theta": 0.5}],
            "grid": {"time.h": [1e-3, 5e-4]}}}"#,
    )
    .expect("spec");
    run_ok(
        &server,
        &[
            "submit",
            "--wait",
            "--id",
            "study",
            study.to_str().expect("path"),
        ],
    );
    let kids = json_of(&run_ok(&server, &["children", "study", "--json"]));
    let kids = kids["jobs"].as_array().expect("jobs");
    assert_eq!(kids.len(), 2, "{kids:?}");
    for kid in kids {
        assert_eq!(kid["state"], "succeeded", "{kid}");
        let id = kid["id"].as_str().expect("id");
        let status = json_of(&run_ok(&server, &["status", id]));
        assert_eq!(status["parent"], "study", "{status}");
    }
    let lines = run_ok(&server, &["children", "study"]);
    assert_eq!(lines.lines().count(), 2, "{lines}");
    assert!(
        lines.lines().all(|l| l.contains("\tsucceeded\t100.0%")),
        "{lines}"
    );
}

/// Issue 30: `capabilities --local` answers offline, the same as a server of this version
/// over gRPC and over HTTP (issue 26: one shape of the scheme × feature table);
/// `watch` takes the zenoh endpoint as `--zenoh-connect`, the name `serve` uses (`--zenoh`
/// stays as a hidden alias).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn capabilities_offline_and_one_flag_name_for_zenoh_endpoints() {
    let offline = signorini()
        .args(["capabilities", "--local", "--server", "http://127.0.0.1:9"])
        .output()
        .expect("signorini capabilities --local");
    assert!(
        offline.status.success(),
        "{}",
        String::from_utf8_lossy(&offline.stderr)
    );
    let caps: serde_json::Value = serde_json::from_slice(&offline.stdout).expect("JSON");
    let schemes: Vec<&str> = caps["integrators"]
        .as_array()
        .expect("integrators")
        .iter()
        .filter_map(|c| c["name"].as_str())
        .collect();
    assert!(schemes.contains(&"moreau_jean"), "{schemes:?}");
    assert!(schemes.contains(&"ns_generalized_alpha"), "{schemes:?}");

    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("s.db"), &Options::default());
    let online = signorini()
        .args(["capabilities", "--server", &server.grpc_url])
        .output()
        .expect("signorini capabilities");
    assert!(online.status.success());
    assert_eq!(
        String::from_utf8_lossy(&online.stdout),
        String::from_utf8_lossy(&offline.stdout)
    );
    // HTTP answers the same document, the scheme × feature table in the same shape (it was
    // `family` and `[feature, {support}]` pairs over HTTP, `model` and objects over gRPC).
    let (code, over_http) = server.http("GET", "/v1/capabilities", None, None).await;
    assert_eq!(code, 200);
    assert_eq!(over_http, caps);
    assert_eq!(
        caps["support"][0]["features"][0]
            .as_object()
            .map(|cell| cell.keys().cloned().collect::<Vec<_>>()),
        Some(vec![
            "feature".into(),
            "support".into(),
            "field".into(),
            "reason".into()
        ])
    );

    let mut client = server.grpc().await;
    let id = submit_json(&mut client, ball_json(1e-3, 200, 1), Some("flag"))
        .await
        .expect("submit");
    let out = signorini()
        .args(["watch", &id, "--json", "--zenoh-connect", &server.zenoh])
        .args(["--server", &server.grpc_url])
        .output()
        .expect("signorini watch --zenoh-connect");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).expect("utf-8");
    assert!(text.contains("\"succeeded\""), "{text}");
}
