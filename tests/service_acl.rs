//! zenoh access control (issue 13, part 4), against the real server: its embedded zenoh session
//! is the router of the deployment (the shape of deploy/zenoh/router.json5: user/password
//! authentication, access control denying by default), a watcher and a stranger connect as
//! read-only users, and the stranger's `JobStatus{SUCCEEDED}` on a running job's status key is
//! dropped by the router: the watcher follows the job to its real end and `watch` exits 0 (its
//! final status confirmed by the server; a spoofed one would have made it exit 1).

mod common;

use common::{ChildGuard, Options, PATIENCE, TestServer, ball_json, submit_json, wait_running};
use prost::Message;
use signorini::proto::v1 as pb;
use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The router's access control of deploy/zenoh/router.json5, users from `credentials`.
fn router_config(credentials: &std::path::Path) -> String {
    format!(
        r#"{{
  mode: "router",
  scouting: {{ multicast: {{ enabled: false }} }},
  transport: {{ auth: {{ usrpwd: {{ dictionary_file: "{}" }} }} }},
  access_control: {{
    enabled: true,
    default_permission: "deny",
    rules: [
      {{ id: "read", permission: "allow", flows: ["ingress"], messages: ["declare_subscriber", "query"], key_exprs: ["signorini/v1/**"] }},
      {{ id: "deliver", permission: "allow", flows: ["egress"], messages: ["put", "delete", "reply", "declare_subscriber", "query", "declare_queryable"], key_exprs: ["signorini/v1/**"] }},
    ],
    subjects: [ {{ id: "watchers", usernames: ["viewer", "stranger"] }} ],
    policies: [ {{ rules: ["read", "deliver"], subjects: ["watchers"] }} ],
  }},
}}"#,
        credentials.display()
    )
}

fn client_config(user: &str, password: &str) -> String {
    format!(
        r#"{{ mode: "client", scouting: {{ multicast: {{ enabled: false }} }}, transport: {{ auth: {{ usrpwd: {{ user: "{user}", password: "{password}" }} }} }} }}"#
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_router_drops_a_strangers_status_and_watch_follows_the_real_job() {
    let dir = tempfile::tempdir().expect("tempdir");
    let credentials = dir.path().join("credentials.txt");
    std::fs::write(&credentials, "viewer:v1ewer\nstranger:str4nger\n").expect("credentials");
    let router = dir.path().join("router.json5");
    std::fs::write(&router, router_config(&credentials)).expect("router config");
    let viewer = dir.path().join("viewer.json5");
    std::fs::write(&viewer, client_config("viewer", "v1ewer")).expect("viewer config");
    let stranger_cfg = dir.path().join("stranger.json5");
    std::fs::write(&stranger_cfg, client_config("stranger", "str4nger")).expect("config");
    let server = TestServer::start(
        &dir.path().join("s.db"),
        &Options {
            zenoh_config: Some(router.clone()),
            ..Options::default()
        },
    );
    let mut client = server.grpc().await;
    let id = submit_json(&mut client, ball_json(1e-5, 600_000, 1), Some("guarded"))
        .await
        .expect("submit");
    wait_running(&mut client, &id, 1).await;

    let mut child = ChildGuard(
        Command::new(env!("CARGO_BIN_EXE_signorini"))
            .args(["watch", &id, "--json", "--zenoh", &server.zenoh])
            .arg("--zenoh-config")
            .arg(&viewer)
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
    let printed =
        std::thread::spawn(move || lines.lines().map_while(Result::ok).collect::<Vec<String>>());

    let stranger = signorini::stream::open_session(&signorini::stream::ZenohOptions {
        connect: vec![server.zenoh.clone()],
        config: Some(stranger_cfg),
        ..Default::default()
    })
    .await
    .expect("the stranger connects (a valid read-only user)");
    let fake = pb::JobStatus {
        id: id.clone(),
        state: pb::JobState::Succeeded as i32,
        ..Default::default()
    };
    for _ in 0..10 {
        // `put` succeeds locally; the router drops it.
        let _ = stranger
            .put(signorini::stream::status_key(&id), fake.encode_to_vec())
            .await;
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let running = client
        .get_job(pb::GetJobRequest { id: id.clone() })
        .await
        .expect("GetJob")
        .into_inner();
    assert_eq!(
        running.state,
        pb::JobState::Running as i32,
        "the job outlives the fake end"
    );
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.0.try_wait().expect("try_wait") {
            break s;
        }
        assert!(start.elapsed() < PATIENCE, "watch did not end");
        tokio::time::sleep(Duration::from_millis(100)).await;
    };
    let mut stderr = String::new();
    std::io::Read::read_to_string(&mut child.0.stderr.take().expect("stderr"), &mut stderr)
        .expect("stderr");
    assert!(status.success(), "{stderr}");
    let printed = printed.join().expect("reader");
    let ends: Vec<&String> = printed
        .iter()
        .filter(|l| l.contains("\"succeeded\""))
        .collect();
    assert_eq!(ends.len(), 1, "only the real end: {ends:?}");
    assert!(
        printed.iter().any(|l| l.contains("\"kind\":\"energy\"")),
        "the real frames reached the watcher through the router"
    );
    let _ = stranger.close().await;
}
