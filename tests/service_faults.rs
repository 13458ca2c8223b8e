//! Faults a long-running service must survive, each against the real
//! `signorini serve` binary: the store's disk full (the job fails with the store's reason,
//! `/healthz` degraded, submissions refused until there is room, nothing stored damaged).

mod common;

use common::pg::Postgres;
use common::{Options, TestServer, ball_json, has_ended, poll_job, submit_json, wait_terminal};
use signorini::proto::v1 as pb;
use signorini::proto::v1::simulation_client::SimulationClient;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

/// A server with `workers` workers and the flags `extra` on a store in a temporary directory
/// (kept while the returned `TempDir` lives: bind it first, so that it goes after the server),
/// and a gRPC client of it.
async fn serve(
    workers: usize,
    extra: &[&str],
) -> (
    tempfile::TempDir,
    TestServer,
    SimulationClient<tonic::transport::Channel>,
) {
    let tmp = tempfile::tempdir().expect("tempdir");
    let opts = Options {
        workers,
        ..Options::default()
    };
    let server = TestServer::start_with(&tmp.path().join("store.db"), &opts, extra);
    let client = server.grpc().await;
    (tmp, server, client)
}

/// A tmpfs mounted by the test, unmounted on drop (also when the test panics).
struct Mount(PathBuf);

impl Mount {
    /// Mounts a tmpfs of `mib` MiB on `dir`: `None` when not root or when mounting fails.
    fn tmpfs(dir: &Path, mib: u64) -> Option<Mount> {
        let ok = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={mib}m"), "tmpfs"])
            .arg(dir)
            .status()
            .is_ok_and(|s| s.success());
        ok.then(|| Mount(dir.to_path_buf()))
    }
}

impl Drop for Mount {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg("-l").arg(&self.0).status();
    }
}

/// How the test makes the store's disk full.
enum Room {
    /// A tmpfs of [`TMPFS_MIB`] with a filler file of [`FILLER_MIB`]; room is made by removing it.
    Tmpfs { _mount: Mount, filler: PathBuf },
    /// SQLite's `max_page_count` (`--store-max-mb`); room is made by purging the failed job.
    PageLimit,
}

const TMPFS_MIB: u64 = 8;
const FILLER_MIB: usize = 5;
const PAGE_LIMIT_MIB: u64 = 3;

/// `GET /healthz` until its status is `code`, at most `within`: the last answer.
async fn healthz_until(
    server: &TestServer,
    code: u16,
    within: Duration,
) -> (u16, serde_json::Value) {
    let started = Instant::now();
    loop {
        let answer = server.http("GET", "/healthz", None, None).await;
        if answer.0 == code || started.elapsed() > within {
            return answer;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

/// The disk under a SQLite store fills while a job records: the job fails with the store's
/// reason, `/healthz` answers 503 degraded naming it, HTTP and gRPC submissions are refused
/// (503 / UNAVAILABLE) naming it, the earlier job's result is unchanged; once there is room again
/// the store is healthy within seconds, a new job succeeds, and `PRAGMA integrity_check` finds
/// the database whole. (Before the fix `/healthz` said ok and submissions were accepted.)
#[tokio::test(flavor = "multi_thread")]
async fn a_full_disk_fails_the_job_degrades_the_store_and_refuses_jobs_until_there_is_room() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let dir = tmp.path().join("small");
    std::fs::create_dir(&dir).expect("mkdir");
    let (room, extra) = match Mount::tmpfs(&dir, TMPFS_MIB) {
        Some(mount) => {
            println!(
                "disk full: a tmpfs of {TMPFS_MIB} MiB mounted by the test, {FILLER_MIB} MiB filled"
            );
            let filler = dir.join("filler");
            std::fs::write(&filler, vec![1u8; FILLER_MIB << 20]).expect("writing the filler");
            (
                Room::Tmpfs {
                    _mount: mount,
                    filler,
                },
                Vec::new(),
            )
        }
        None => {
            println!(
                "disk full: mounting a tmpfs failed (not root?): SQLite's max_page_count, --store-max-mb {PAGE_LIMIT_MIB}"
            );
            (
                Room::PageLimit,
                vec!["--store-max-mb".to_string(), PAGE_LIMIT_MIB.to_string()],
            )
        }
    };
    let store = dir.join("store.db");
    let extra: Vec<&str> = extra.iter().map(String::as_str).collect();
    let opts = Options {
        workers: 1,
        ..Options::default()
    };
    let mut server = TestServer::start_with(&store, &opts, &extra);
    let mut client = server.grpc().await;

    // A small job is stored whole.
    let a = submit_json(&mut client, ball_json(1e-3, 300, 1), None)
        .await
        .expect("submitting A");
    let end = wait_terminal(&mut client, &a).await;
    assert_eq!(end.state, pb::JobState::Succeeded as i32, "{end:?}");
    let result_path = format!("/v1/jobs/{a}/result");
    let (code, result_a) = server.http("GET", &result_path, None, None).await;
    assert_eq!(code, 200, "{result_a}");
    assert_eq!(
        result_a["steps"]["step"].as_array().map(Vec::len),
        Some(301)
    );
    let (code, health) = server.http("GET", "/healthz", None, None).await;
    assert_eq!((code, health["status"].as_str()), (200, Some("ok")));

    // A job recording far more than the store has room for (10⁶ rows, tens of MB).
    let b = submit_json(&mut client, ball_json(1e-6, 1_000_000, 1), None)
        .await
        .expect("submitting B");
    let end = wait_terminal(&mut client, &b).await;
    assert_eq!(end.state, pb::JobState::Failed as i32, "{end:?}");
    let error = end.error.expect("B's error");
    assert_eq!(error.field, "store", "{error:?}");
    assert!(error.reason.contains("full"), "{error:?}");

    // The store is degraded, with its reason, and stays so while there is no room.
    let (code, health) = healthz_until(&server, 503, Duration::from_secs(5)).await;
    assert_eq!(code, 503, "{health}");
    assert_eq!(health["status"], "degraded", "{health}");
    let reason = health["reason"].as_str().expect("a reason").to_string();
    assert!(reason.contains("full"), "{reason}");
    tokio::time::sleep(Duration::from_millis(1500)).await;
    let (code, health) = server.http("GET", "/healthz", None, None).await;
    assert_eq!(code, 503, "a probe found room that is not there: {health}");

    // Submissions are refused, naming the store's reason, over both protocols.
    let (code, refused) = server
        .http("POST", "/v1/jobs", Some(&ball_json(1e-3, 100, 1)), None)
        .await;
    assert_eq!(code, 503, "{refused}");
    assert_eq!(refused["error"]["field"], "store", "{refused}");
    let why = refused["error"]["reason"].as_str().unwrap_or_default();
    assert!(why.contains("full"), "{refused}");
    let status = submit_json(&mut client, ball_json(1e-3, 100, 1), None)
        .await
        .expect_err("a submission to a full store");
    assert_eq!(status.code(), tonic::Code::Unavailable, "{status:?}");
    assert!(status.message().contains("full"), "{status:?}");

    // What was stored before is untouched.
    let (code, again) = server.http("GET", &result_path, None, None).await;
    assert_eq!((code, &again), (200, &result_a));

    // Room again: the store is healthy within seconds and takes a job to its end.
    match &room {
        Room::Tmpfs { filler, .. } => std::fs::remove_file(filler).expect("removing the filler"),
        Room::PageLimit => {
            let (code, body) = server
                .http("DELETE", &format!("/v1/jobs/{b}?purge=true"), None, None)
                .await;
            assert_eq!(code, 200, "purging B: {body}");
        }
    }
    let (code, health) = healthz_until(&server, 200, Duration::from_secs(10)).await;
    assert_eq!(
        (code, health["status"].as_str()),
        (200, Some("ok")),
        "{health}"
    );
    let c = submit_json(&mut client, ball_json(1e-3, 200, 1), None)
        .await
        .expect("submitting C once there is room");
    let end = wait_terminal(&mut client, &c).await;
    assert_eq!(end.state, pb::JobState::Succeeded as i32, "{end:?}");
    let (code, again) = server.http("GET", &result_path, None, None).await;
    assert_eq!((code, &again), (200, &result_a));

    // Stopped cleanly, the database is whole.
    let stopped = server.terminate(Duration::from_secs(20));
    assert!(stopped.is_some_and(|(s, _)| s.success()), "{stopped:?}");
    let conn = rusqlite::Connection::open(&store).expect("opening the store");
    let check: String = conn
        .query_row("PRAGMA integrity_check", [], |r| r.get(0))
        .expect("integrity_check");
    assert_eq!(check, "ok");
    drop(conn);
    drop(room);
}

/// A `lagrangian` model of `n` coordinates with an identity mass matrix written out in full
/// (n rows of n numbers: 18 MB for n = 3000), a spring on each coordinate, one contact.
fn identity_mass_model(n: usize) -> String {
    let mut s = String::with_capacity(3 * n * n + 64 * n);
    s.push_str(r#"{"model":{"scene":"lagrangian","coordinates":["#);
    for i in 0..n {
        if i > 0 {
            s.push(',');
        }
        s.push_str(&format!("\"x{i}\""));
    }
    s.push_str(r#"],"mass":["#);
    for i in 0..n {
        s.push_str(if i > 0 { ",[" } else { "[" });
        for j in 0..n {
            if j > 0 {
                s.push(',');
            }
            s.push(if i == j { '1' } else { '0' });
        }
        s.push(']');
    }
    s.push_str(r#"],"potential":"0.5*("#);
    for i in 0..n {
        if i > 0 {
            s.push('+');
        }
        s.push_str(&format!("x{i}^2"));
    }
    s.push_str(r#")","q0":["#);
    s.push_str(&vec!["0.5"; n].join(","));
    s.push_str(
        r#"],"contacts":[{"gap":"x0 + 1","restitution":0.5}]},"integrator":{"scheme":"moreau_jean"},"time":{"h":0.01,"steps":10}}"#,
    );
    s
}

/// A JSON spec's model outline, read as the server reads it before building the spec: its
/// scene and its coordinates, every other value skipped.
#[derive(serde::Deserialize)]
struct Outline {
    model: ModelOutline,
}

#[derive(serde::Deserialize)]
struct ModelOutline {
    scene: String,
    coordinates: Vec<serde::de::IgnoredAny>,
}

/// Issue 31's request that took a server down: a `lagrangian` model of 3 000 coordinates with
/// an identity mass matrix (an 18 MB body). With the default limits it is refused by the memory
/// estimate naming `max_memory_mb`, from the spec's outline before the spec is built, with less
/// than 2 s of the server's CPU (before, the request held for more than 60 s and grew the server
/// to 11 GB), and `/healthz` answers while it is being handled.
#[tokio::test(flavor = "multi_thread")]
async fn a_model_too_large_is_refused_by_its_memory_estimate_with_under_two_seconds_of_cpu() {
    let (_tmp, server, _) = serve(2, &[]).await;
    let body = identity_mass_model(3000);
    assert!(body.len() > 16 << 20, "{} bytes", body.len());
    // What this machine takes now, under its present load, for the two parts of the work: the
    // same body refused for its query (`id` twice) once the server has read all of it (the
    // upload), and the same outline read here, by the same code as the server's (its parse).
    let started = Instant::now();
    let (code, refused) = server
        .http("POST", "/v1/jobs?id=a&id=b", Some(&body), None)
        .await;
    let upload = started.elapsed();
    assert_eq!(code, 400, "{refused}");
    let started = Instant::now();
    let outline: Outline = serde_json::from_str(&body).expect("the outline");
    let parse = started.elapsed();
    assert_eq!(
        (
            outline.model.scene.as_str(),
            outline.model.coordinates.len()
        ),
        ("lagrangian", 3000)
    );
    let cpu_before = cpu_seconds(server.pid());
    let started = Instant::now();
    let (submit, health) =
        tokio::join!(server.http("POST", "/v1/jobs", Some(&body), None), async {
            tokio::time::sleep(Duration::from_millis(300)).await;
            let asked = Instant::now();
            let answer = server.http("GET", "/healthz", None, None).await;
            (answer, asked.elapsed())
        });
    let took = started.elapsed();
    let cpu = cpu_seconds(server.pid()) - cpu_before;
    println!("the 3 000-coordinate model: answered after {took:?}, {cpu:.2} s of the server's CPU");
    let (code, refused) = submit;
    assert_eq!(code, 400, "{refused}");
    assert_eq!(refused["error"]["field"], "model.coordinates", "{refused}");
    let reason = refused["error"]["reason"].as_str().unwrap_or_default();
    assert!(reason.contains("max_memory_mb"), "{reason}");
    // The server's own work stays under 2 s of CPU (a debug build), which the machine's load
    // does not stretch; the answer comes within the upload and three times the outline's parse
    // timed here just before (the load stretches those as much), far below the minute it took
    // before.
    assert!(cpu < 2.0, "the server spent {cpu:.2} s of CPU on it");
    let bound = upload + parse * 3 + Duration::from_secs(1);
    println!("the upload alone: {upload:?}, the outline's parse: {parse:?}");
    assert!(
        took < bound,
        "answered after {took:?}, over {bound:?} (upload {upload:?}, parse {parse:?})"
    );
    let ((code, body), health_took) = health;
    assert_eq!((code, body["status"].as_str()), (200, Some("ok")));
    assert!(health_took < Duration::from_millis(500), "{health_took:?}");
}

/// A model within the memory limit whose compilation takes longer than `max_compile_seconds`
/// is refused naming that limit soon after it (the compilation runs on a thread of its own, the
/// server answers `/healthz` meanwhile); and SIGTERM during such a compilation stops the server
/// within seconds (before, it ignored SIGTERM for more than 15 s).
#[tokio::test(flavor = "multi_thread")]
async fn a_long_compilation_is_refused_at_its_limit_and_sigterm_stops_the_server_mid_compile() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let limits = ["--max-memory-mb", "8192", "--max-compile-seconds", "1"];
    let server = TestServer::start_with(&tmp.path().join("a.db"), &Options::default(), &limits);
    let body = slow_compile_model();
    // The same request refused before its compilation starts (a `check.min_order` outside a
    // study is the first thing the compilation's thread refuses): what uploading, parsing and
    // checking this body take on this machine now.
    let early = body.replacen(r#""time":"#, r#""check":{"min_order":1},"time":"#, 1);
    let started = Instant::now();
    let (code, refused) = server.http("POST", "/v1/jobs", Some(&early), None).await;
    let baseline = started.elapsed();
    assert_eq!(code, 400, "{refused}");
    assert_eq!(refused["error"]["field"], "check.min_order", "{refused}");
    let started = Instant::now();
    let (submit, health) =
        tokio::join!(server.http("POST", "/v1/jobs", Some(&body), None), async {
            tokio::time::sleep(Duration::from_millis(700)).await;
            let asked = Instant::now();
            let answer = server.http("GET", "/healthz", None, None).await;
            (answer, asked.elapsed())
        });
    let took = started.elapsed();
    let (code, refused) = submit;
    assert_eq!(code, 400, "{refused}");
    let reason = refused["error"]["reason"].as_str().unwrap_or_default();
    assert!(reason.contains("max_compile_seconds"), "{reason}");
    // Refused within its 1 s limit of the compilation's start, which comes after the work the
    // early refusal measured (3 to 6 s of a debug build on the loaded test machine; twice that
    // allowed for the load's swings between two requests). The whole compilation takes about
    // 6 s of CPU on top of that work ([`slow_compile_model`]).
    let bound = baseline * 2 + Duration::from_secs(3);
    println!("refused after {took:?}; before its compilation, after {baseline:?}");
    assert!(
        took < bound,
        "answered after {took:?}, over {bound:?} (refused before compiling after {baseline:?})"
    );
    let ((code, _), health_took) = health;
    assert_eq!(code, 200);
    assert!(health_took < Duration::from_millis(500), "{health_took:?}");
    drop(server);

    // SIGTERM while a compilation runs (no compile limit to end it first).
    let limits = ["--max-memory-mb", "8192"];
    let mut server = TestServer::start_with(&tmp.path().join("b.db"), &Options::default(), &limits);
    let http = server.http;
    let submit = tokio::spawn(async move {
        let client: hyper_util::client::legacy::Client<
            _,
            http_body_util::Full<hyper::body::Bytes>,
        > = hyper_util::client::legacy::Client::builder(hyper_util::rt::TokioExecutor::new())
            .build_http();
        let req = hyper::Request::post(format!("http://{http}/v1/jobs"))
            .header("content-type", "application/json")
            .body(http_body_util::Full::new(hyper::body::Bytes::from(body)))
            .expect("request");
        client.request(req).await.map(|r| r.status().as_u16())
    });
    tokio::time::sleep(Duration::from_millis(3500)).await;
    assert!(
        !submit.is_finished(),
        "the compilation ended before SIGTERM"
    );
    let stopped = tokio::task::spawn_blocking(move || server.terminate(Duration::from_secs(20)))
        .await
        .expect("terminate");
    let (status, took) = stopped.expect("the server did not stop within 20 s of SIGTERM");
    assert!(status.success(), "{status:?}");
    assert!(
        took < Duration::from_secs(3),
        "stopped {took:?} after SIGTERM"
    );
    let answer = submit.await.expect("submission task");
    assert!(
        matches!(answer, Err(_) | Ok(503)),
        "the submission cut by the shutdown: {answer:?}"
    );
}

/// A model within the memory limit whose compilation outlasts a 1 s limit on this machine
/// kind: the identity-mass model of [`COMPILE_N`] coordinates with Π_{i<K} cos(x_i) added to
/// its potential, K = [`COMPILE_PRODUCT`]. Since compiling is linear in the nonzeros (issue 27)
/// a large sparse model no longer takes long; this product's ∂F/∂q is a dense K×K block whose
/// every entry is a product of K − 1 factors, K³ of work (K = 400: 4.5 s of CPU and 1.3 GB
/// here; 450 for margin on a faster machine).
fn slow_compile_model() -> String {
    let product: Vec<String> = (0..COMPILE_PRODUCT).map(|i| format!("cos(x{i})")).collect();
    identity_mass_model(COMPILE_N).replacen(
        r#""potential":"0.5*("#,
        &format!(r#""potential":"{} + 0.5*("#, product.join("*")),
        1,
    )
}

/// Coordinates of [`slow_compile_model`].
const COMPILE_N: usize = 1200;

/// Factors of [`slow_compile_model`]'s product.
const COMPILE_PRODUCT: usize = 450;

/// A client that reads the first message of `StreamResult` and goes away: the server stops
/// reading the store for it and lets go of the result (a purge, refused while a stream is open,
/// succeeds within seconds: no reader leaks), and it serves the same stream whole to the next
/// client and runs the next job.
#[tokio::test(flavor = "multi_thread")]
async fn a_client_gone_mid_stream_result_leaks_nothing() {
    let (_tmp, server, mut client) = serve(2, &[]).await;
    // 300 000 rows: a few stored chunks, many messages.
    let id = submit_json(&mut client, ball_json(1e-5, 300_000, 1), None)
        .await
        .expect("submit");
    let end = wait_terminal(&mut client, &id).await;
    assert_eq!(end.state, pb::JobState::Succeeded as i32, "{end:?}");

    for _ in 0..5 {
        let mut other = server.grpc().await;
        let mut stream = common::result_stream(&mut other, &id).await;
        let first = stream
            .message()
            .await
            .expect("a message")
            .expect("the header");
        assert!(matches!(
            first.part,
            Some(pb::result_chunk::Part::Header(_))
        ));
        drop(stream);
        drop(other);
    }

    // A whole stream for the next client.
    let mut stream = common::result_stream(&mut client, &id).await;
    let mut rows = 0;
    while let Some(msg) = stream.message().await.expect("stream") {
        if let Some(pb::result_chunk::Part::Rows(r)) = msg.part {
            rows += r.step.len();
        }
    }
    assert_eq!(rows, 300_001);

    // No reader left behind: the purge goes through.
    let started = Instant::now();
    let purge = format!("/v1/jobs/{id}?purge=true");
    let (code, body) = loop {
        let answer = server.http("DELETE", &purge, None, None).await;
        if answer.0 != 409 || started.elapsed() > Duration::from_secs(10) {
            break answer;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    };
    assert_eq!(code, 200, "{body}");
    let next = submit_json(&mut client, ball_json(1e-3, 100, 1), None)
        .await
        .expect("submit");
    let end = wait_terminal(&mut client, &next).await;
    assert_eq!(end.state, pb::JobState::Succeeded as i32, "{end:?}");
}

/// CPU seconds (user + system) process `pid` has used.
fn cpu_seconds(pid: u32) -> f64 {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).expect("/proc stat");
    // The fields after the command's closing parenthesis: utime and stime are the 12th and
    // 13th, in clock ticks (100 per second on Linux).
    let after = stat.rsplit_once(')').map_or("", |(_, rest)| rest);
    let fields: Vec<&str> = after.split_whitespace().collect();
    let ticks = |k: usize| {
        fields
            .get(k)
            .and_then(|v| v.parse::<f64>().ok())
            .unwrap_or(0.0)
    };
    (ticks(11) + ticks(12)) / 100.0
}

/// Resident memory of process `pid`, bytes.
fn rss(pid: u32) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).expect("/proc status");
    let kib: u64 = status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.split_whitespace().next())
        .and_then(|v| v.parse().ok())
        .expect("VmRSS");
    kib << 10
}

/// A subscriber that never reads: an SSE client of a job's events that sends its request and
/// then reads nothing (its socket's buffers fill). The job runs to its end at its pace, a watcher
/// that reads gets every status to the final one, the server answers meanwhile, and its memory
/// does not grow with what the silent client is not reading.
#[tokio::test(flavor = "multi_thread")]
async fn a_subscriber_that_never_reads_holds_up_nothing() {
    use std::io::Write;
    let (_tmp, server, mut client) = serve(2, &[]).await;
    let id = submit_json(&mut client, ball_json(1e-6, 2_000_000, 1), None)
        .await
        .expect("submit");
    // Silent clients of the job's events (a few, to fill more than one socket).
    let silent: Vec<std::net::TcpStream> = (0..4)
        .map(|_| {
            let mut s = std::net::TcpStream::connect(server.http).expect("connect");
            write!(
                s,
                "GET /v1/jobs/{id}/events HTTP/1.1\r\nHost: x\r\nAccept: text/event-stream\r\n\r\n"
            )
            .expect("request");
            s
        })
        .collect();
    tokio::time::sleep(Duration::from_millis(500)).await;
    let before = rss(server.pid());
    let end = wait_terminal(&mut client, &id).await;
    assert_eq!(end.state, pb::JobState::Succeeded as i32, "{end:?}");
    let (code, _) = server.http("GET", "/healthz", None, None).await;
    assert_eq!(code, 200);
    let grown = rss(server.pid()).saturating_sub(before);
    assert!(grown < 64 << 20, "the server grew by {} MiB", grown >> 20);
    // The silent clients are still connected, and nothing waits for them.
    let next = submit_json(&mut client, ball_json(1e-3, 100, 1), None)
        .await
        .expect("submit");
    let end = wait_terminal(&mut client, &next).await;
    assert_eq!(end.state, pb::JobState::Succeeded as i32, "{end:?}");
    drop(silent);
}

/// The disk under a PostgreSQL store fills: the store's database lives in a tablespace on a
/// tmpfs of 32 MiB (mounted by the test; root is needed, as for the PostgreSQL tests), partly
/// filled. A job recording more than the room left fails with PostgreSQL's reason (SQLSTATE
/// 53100, "No space left on device"), `/healthz` is degraded naming it, submissions are refused
/// (503), the earlier result is unchanged; with room again the store is healthy and takes a job.
#[tokio::test(flavor = "multi_thread")]
async fn a_full_disk_under_postgresql_fails_the_job_and_refuses_jobs_until_there_is_room() {
    let pg = common::pg::Postgres::start();
    let tmp = tempfile::tempdir().expect("tempdir");
    let dir = tmp.path().join("small");
    std::fs::create_dir(&dir).expect("mkdir");
    let _mount = Mount::tmpfs(&dir, 32)
        .expect("mounting a tmpfs for the tablespace (this test needs root, as PostgreSQL's do)");
    println!("disk full: a PostgreSQL tablespace on a tmpfs of 32 MiB mounted by the test");
    let space = dir.join("tablespace");
    std::fs::create_dir(&space).expect("mkdir");
    let _ = Command::new("chown")
        .args(["postgres:postgres"])
        .arg(&space)
        .status();
    pg.psql(
        "postgres",
        &format!("CREATE TABLESPACE small LOCATION '{}'", space.display()),
    );
    pg.psql("postgres", "CREATE DATABASE faults TABLESPACE small");
    let filler = dir.join("filler");
    std::fs::write(&filler, vec![1u8; 12 << 20]).expect("writing the filler");
    let opts = Options {
        workers: 1,
        ..Options::default()
    };
    let url = pg.url("faults");
    let server = TestServer::start_with(Path::new(&url), &opts, &["--replica", "r1"]);
    let mut client = server.grpc().await;

    let a = submit_json(&mut client, ball_json(1e-3, 300, 1), None)
        .await
        .expect("submitting A");
    let end = wait_terminal(&mut client, &a).await;
    assert_eq!(end.state, pb::JobState::Succeeded as i32, "{end:?}");
    let result_path = format!("/v1/jobs/{a}/result");
    let (code, result_a) = server.http("GET", &result_path, None, None).await;
    assert_eq!(code, 200, "{result_a}");

    let b = submit_json(&mut client, ball_json(1e-6, 1_000_000, 1), None)
        .await
        .expect("submitting B");
    let end = wait_terminal(&mut client, &b).await;
    assert_eq!(end.state, pb::JobState::Failed as i32, "{end:?}");
    let error = end.error.expect("B's error");
    assert_eq!(error.field, "store", "{error:?}");
    assert!(error.reason.contains("53100"), "{error:?}");

    let (code, health) = healthz_until(&server, 503, Duration::from_secs(5)).await;
    assert_eq!(code, 503, "{health}");
    assert_eq!(health["status"], "degraded", "{health}");
    assert!(
        health["reason"]
            .as_str()
            .unwrap_or_default()
            .contains("53100"),
        "{health}"
    );
    let (code, refused) = server
        .http("POST", "/v1/jobs", Some(&ball_json(1e-3, 100, 1)), None)
        .await;
    assert_eq!(code, 503, "{refused}");
    assert_eq!(refused["error"]["field"], "store", "{refused}");
    let (code, again) = server.http("GET", &result_path, None, None).await;
    assert_eq!((code, &again), (200, &result_a));

    std::fs::remove_file(&filler).expect("removing the filler");
    let (code, health) = healthz_until(&server, 200, Duration::from_secs(10)).await;
    assert_eq!(
        (code, health["status"].as_str()),
        (200, Some("ok")),
        "{health}"
    );
    let c = submit_json(&mut client, ball_json(1e-3, 200, 1), None)
        .await
        .expect("submitting C once there is room");
    let end = wait_terminal(&mut client, &c).await;
    assert_eq!(end.state, pb::JobState::Succeeded as i32, "{end:?}");
    let (code, again) = server.http("GET", &result_path, None, None).await;
    assert_eq!((code, &again), (200, &result_a));
    drop(server);
    // The database goes before the tablespace's file system is unmounted.
    pg.psql("postgres", "DROP DATABASE faults WITH (FORCE)");
    pg.psql("postgres", "DROP TABLESPACE small");
}

/// A job that runs longer than the server's `max_wall_seconds` ends `failed` naming the limit
/// (field `time`), with what it recorded kept as a partial result; the next job runs.
#[tokio::test(flavor = "multi_thread")]
async fn a_job_past_the_wall_time_limit_fails_naming_it() {
    let (_tmp, server, mut client) =
        serve(1, &["--max-steps", "1000000000", "--max-wall-seconds", "1"]).await;
    // 5·10⁸ steps: minutes of work.
    let id = submit_json(&mut client, ball_json(1e-6, 500_000_000, 100_000), None)
        .await
        .expect("submit");
    let started = Instant::now();
    let end = wait_terminal(&mut client, &id).await;
    let took = started.elapsed();
    assert_eq!(end.state, pb::JobState::Failed as i32, "{end:?}");
    let error = end.error.expect("an error");
    assert_eq!(error.field, "time", "{error:?}");
    assert!(error.reason.contains("max_wall_seconds"), "{error:?}");
    assert!(took < Duration::from_secs(20), "ended after {took:?}");
    let (code, result) = server
        .http("GET", &format!("/v1/jobs/{id}/result"), None, None)
        .await;
    assert_eq!(code, 200, "{result}");
    assert!(
        !result["steps"]["step"]
            .as_array()
            .expect("steps")
            .is_empty(),
        "{result}"
    );
    let next = submit_json(&mut client, ball_json(1e-3, 100, 1), None)
        .await
        .expect("submit");
    let end = wait_terminal(&mut client, &next).await;
    assert_eq!(end.state, pb::JobState::Succeeded as i32, "{end:?}");
}

/// Names the endpoint the router process of [`zenoh_router_process`] listens on.
const ROUTER_ENV: &str = "SIGNORINI_TEST_ZENOH_ROUTER";

/// Not a test of its own: the body of the zenoh router *process* that
/// `a_zenoh_router_killed_and_restarted_while_a_client_watches_leaves_no_gap` starts (this test
/// binary run again on this one function, with the endpoint in [`ROUTER_ENV`]), so that the
/// router can be killed with SIGKILL like a real `zenohd`. It runs until it is killed.
#[tokio::test(flavor = "multi_thread")]
#[ignore = "the router process of the router test, started by it"]
async fn zenoh_router_process() {
    let endpoint = std::env::var(ROUTER_ENV).expect("started by the router test, which sets it");
    let mut config = zenoh::Config::default();
    for (key, value) in [
        ("mode", "\"router\"".to_string()),
        ("scouting/multicast/enabled", "false".into()),
        ("listen/endpoints", format!("[\"{endpoint}\"]")),
    ] {
        config.insert_json5(key, &value).expect("router config");
    }
    let _router = zenoh::open(config).await.expect("zenoh router");
    println!("zenoh router listening on {endpoint}");
    loop {
        tokio::time::sleep(Duration::from_secs(3600)).await;
    }
}

/// Starts the router process on `endpoint` and waits until it listens.
fn router_process(endpoint: &str) -> common::ChildGuard {
    let mut child = common::ChildGuard(
        Command::new(std::env::current_exe().expect("the test binary"))
            .args([
                "zenoh_router_process",
                "--exact",
                "--ignored",
                "--nocapture",
            ])
            .env(ROUTER_ENV, endpoint)
            .stdout(std::process::Stdio::piped())
            .spawn()
            .expect("starting the router process"),
    );
    let lines = common::stdout_lines(&mut child.0);
    loop {
        match lines.recv_timeout(common::PATIENCE) {
            Ok(Some(line)) if line.starts_with("zenoh router listening") => break,
            Ok(Some(_)) => {}
            other => panic!("the router process did not start: {other:?}"),
        }
    }
    std::thread::spawn(move || while let Ok(Some(_)) = lines.recv() {});
    child
}

/// `signorini watch --json` follows a job through a zenoh router (the watcher a zenoh client
/// of the router only, as in deploy/zenoh/viewer.json5; the server a peer connected to it).
/// The router is killed with SIGKILL while the job runs and started again on the same endpoint
/// seconds later: the watcher's stream resumes live (a frame past the restart arrives while the
/// job still runs), and its output holds every energy frame from the first it saw to the job's
/// last, each once and in `seq` order, whose rows are the stored result's, bit for bit: the
/// frames put while the router was down come from the server's history. (Before `watch` asked
/// the history, the frames put during the outage were simply missing from its output.)
#[tokio::test(flavor = "multi_thread")]
async fn a_zenoh_router_killed_and_restarted_while_a_client_watches_leaves_no_gap() {
    let router_endpoint = format!("tcp/127.0.0.1:{}", common::free_port());
    let mut router = router_process(&router_endpoint);
    let (tmp, server, mut client) = serve(1, &["--zenoh-connect", &router_endpoint]).await;
    let viewer = tmp.path().join("viewer.json5");
    std::fs::write(
        &viewer,
        r#"{ mode: "client", scouting: { multicast: { enabled: false } } }"#,
    )
    .expect("viewer config");
    // 2·10⁷ steps recorded every 1000th: about 30 s (6·10⁵ steps/s measured).
    const STEPS: u64 = 20_000_000;
    let id = submit_json(&mut client, ball_json(1e-6, STEPS, 1000), Some("through"))
        .await
        .expect("submit");
    common::wait_running(&mut client, &id, 1).await;
    let mut watcher = common::ChildGuard(
        Command::new(env!("CARGO_BIN_EXE_signorini"))
            .args(["watch", &id, "--json", "--zenoh-connect", &router_endpoint])
            .arg("--zenoh-config")
            .arg(&viewer)
            .args(["--server", &server.grpc_url])
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .expect("signorini watch"),
    );
    let lines = common::stdout_lines(&mut watcher.0);
    let mut out: Vec<serde_json::Value> = Vec::new();
    let next_line = |out: &mut Vec<serde_json::Value>| -> Option<serde_json::Value> {
        let line = lines
            .recv_timeout(common::PATIENCE)
            .expect("a line of watch in time")?;
        let v: serde_json::Value = serde_json::from_str(&line).expect("a JSON line");
        out.push(v.clone());
        Some(v)
    };
    let energy_step = |v: &serde_json::Value| {
        (v["kind"] == "energy")
            .then(|| v["step"].as_array()?.last()?.as_u64())
            .flatten()
    };
    // A few live frames, then the router goes.
    let mut frames = 0;
    while frames < 5 {
        let v = next_line(&mut out).expect("watch ended early");
        frames += usize::from(energy_step(&v).is_some());
    }
    let get = |c: &mut SimulationClient<tonic::transport::Channel>| {
        let mut c = c.clone();
        let id = id.clone();
        async move {
            c.get_job(pb::GetJobRequest { id })
                .await
                .expect("GetJob")
                .into_inner()
        }
    };
    router.0.kill().expect("SIGKILL to the router");
    router.0.wait().expect("the router's end");
    let at_kill = get(&mut client).await.progress.map_or(0, |p| p.step);
    tokio::time::sleep(Duration::from_secs(3)).await;
    let at_restart = get(&mut client).await;
    let done = at_restart.progress.as_ref().map_or(0, |p| p.step);
    assert!(
        at_restart.state == pb::JobState::Running as i32 && done > at_kill,
        "the job must run on while the router is down: {at_kill} then {at_restart:?}"
    );
    let _router = router_process(&router_endpoint);
    // Live again: a frame past the restart while the job still runs.
    loop {
        let v = next_line(&mut out).expect("watch ended before the stream resumed");
        if energy_step(&v).is_some_and(|s| s > done) {
            let now = get(&mut client).await;
            assert_eq!(
                now.state,
                pb::JobState::Running as i32,
                "the stream resumed only after the job's end: {now:?}"
            );
            break;
        }
    }
    while next_line(&mut out).is_some() {}
    let status = watcher.0.wait().expect("watch's end");
    assert!(status.success(), "watch: {status}");

    // Every energy frame from the first seen to the last, once, in order, as stored.
    let energy: Vec<&serde_json::Value> = out.iter().filter(|v| v["kind"] == "energy").collect();
    let seqs: Vec<u64> = energy
        .iter()
        .map(|v| v["seq"].as_u64().expect("seq"))
        .collect();
    let first = seqs[0];
    assert_eq!(
        seqs,
        (first..first + seqs.len() as u64).collect::<Vec<_>>(),
        "energy frames missing or repeated"
    );
    assert_eq!(
        energy.last().map(|v| &v["last"]),
        Some(&serde_json::Value::Bool(true))
    );
    let (code, stored) = server
        .http("GET", &format!("/v1/jobs/{id}/result"), None, None)
        .await;
    assert_eq!(code, 200, "{stored}");
    let stored_steps = stored["steps"]["step"].as_array().expect("steps");
    let first_step = energy[0]["step"][0].as_u64().expect("a step");
    let mut row = stored_steps
        .iter()
        .position(|s| s.as_u64() == Some(first_step))
        .expect("the first watched step is stored");
    for f in &energy {
        let columns = f["columns"].as_array().expect("columns");
        for (step, values) in f["step"]
            .as_array()
            .expect("steps")
            .iter()
            .zip(f["rows"].as_array().expect("rows"))
        {
            assert_eq!(step, &stored_steps[row], "row {row}");
            for (c, v) in columns.iter().zip(values.as_array().expect("a row")) {
                let column = c.as_str().expect("a column name");
                assert_eq!(v, &stored["steps"][column][row], "{column} at row {row}");
            }
            row += 1;
        }
    }
    assert_eq!(
        row,
        stored_steps.len(),
        "the watched rows end where the result does"
    );
    assert_eq!(stored_steps.last().and_then(|s| s.as_u64()), Some(STEPS));
}

/// PostgreSQL killed with SIGKILL (the postmaster and all its processes: a crash) while two
/// replicas run four jobs that store their series as they go, and started again on the same
/// port [`PG_DOWN`] later (crash recovery from its write-ahead log). The replicas reconnect;
/// every job ends `succeeded` on its first claim (none lost, none run twice: `attempt` is 1,
/// the lease of 30 s outlives the outage); each stored series is whole (one row per step, no
/// chunk missing or twice) and the four results, of one spec, are equal; a job submitted after
/// the restart runs; `/healthz` is ok.
#[tokio::test(flavor = "multi_thread")]
async fn postgresql_killed_and_restarted_mid_run_loses_no_job_and_runs_none_twice() {
    let pg = Postgres::start();
    let url = pg.create_database("crash");
    // The test server runs with synchronous_commit off (fast, and harmless for the other
    // tests), which PostgreSQL documents may lose the last commits in a crash: a chunk the store
    // was told was committed went missing that way in this test. A deployment keeps the
    // default (on), as this database does.
    pg.psql(
        "postgres",
        "ALTER DATABASE crash SET synchronous_commit = on",
    );
    let opts = Options {
        workers: 2,
        ..Options::default()
    };
    let replica = |name: &str| {
        TestServer::start_with(
            Path::new(&url),
            &opts,
            &["--replica", name, "--lease-secs", "30"],
        )
    };
    let (a, b) = (replica("a"), replica("b"));
    let mut to_a = a.grpc().await;
    let mut to_b = b.grpc().await;
    let ids: Vec<String> = (0..4).map(|k| format!("crash-{k}")).collect();
    for id in &ids {
        submit_json(&mut to_a, ball_json(1e-5, PG_STEPS, 1), Some(id))
            .await
            .expect("submit");
    }
    // All four running, each with a stored chunk of its series.
    let deadline = Instant::now() + common::PATIENCE;
    while pg.psql(
        "crash",
        "SELECT (SELECT count(*) FROM jobs WHERE state = 'running') || ',' || (SELECT count(DISTINCT id) FROM result_chunks)",
    ) != "4,4"
    {
        assert!(Instant::now() < deadline, "the jobs did not all start");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    pg.kill9();
    let killed = Instant::now();
    tokio::time::sleep(PG_DOWN).await;
    pg.restart();
    println!(
        "PostgreSQL killed (SIGKILL) and started again {:?} later",
        killed.elapsed()
    );

    for id in &ids {
        let end = poll_job(&mut to_b, id, has_ended).await;
        assert_eq!(end.state, pb::JobState::Succeeded as i32, "{id}: {end:?}");
    }
    assert_eq!(
        pg.psql(
            "crash",
            "SELECT string_agg(attempt::text, ',' ORDER BY id) FROM jobs"
        ),
        "1,1,1,1",
        "a job was claimed twice"
    );
    let whole = format!("{}|{}|{PG_STEPS}", PG_STEPS + 1, PG_STEPS + 1);
    for row in pg
        .psql(
            "crash",
            "SELECT id, sum(rows), max(first_row + rows), max(step_last), count(*) = count(DISTINCT chunk) FROM result_chunks GROUP BY id ORDER BY id",
        )
        .lines()
    {
        let (id, rest) = row.split_once('|').expect("a row");
        assert_eq!(rest, format!("{whole}|t"), "{id}'s series");
    }
    let first = steps_every_997(&a, &ids[0]).await;
    // Steps 0, 997, …, 599 197, and the last one.
    let steps = first["step"].as_array().expect("steps");
    assert_eq!(steps.len(), PG_STEPS as usize / 997 + 2);
    assert_eq!(steps.last().and_then(|s| s.as_u64()), Some(PG_STEPS));
    for id in &ids[1..] {
        assert!(
            steps_every_997(&b, id).await == first,
            "{id}'s result differs"
        );
    }
    let after = submit_json(&mut to_b, ball_json(1e-3, 200, 1), None)
        .await
        .expect("a submission after the restart");
    let end = wait_terminal(&mut to_b, &after).await;
    assert_eq!(end.state, pb::JobState::Succeeded as i32, "{end:?}");
    for server in [&a, &b] {
        let (code, health) = server.http("GET", "/healthz", None, None).await;
        assert_eq!((code, health["status"].as_str()), (200, Some("ok")));
    }
}

/// Every 997th row of job `id`'s result, over HTTP.
async fn steps_every_997(server: &TestServer, id: &str) -> serde_json::Value {
    let path = format!("/v1/jobs/{id}/result?every=997");
    let (code, body) = server.http("GET", &path, None, None).await;
    assert_eq!(code, 200, "{body}");
    body["steps"].clone()
}

/// Memory watched while a job runs: on a server whose `max_memory_mb` is 1, a string of
/// 90 000 nodes passes the checks before the run (only a `lagrangian` model is estimated from
/// its sizes) but its run holds more than 1 MiB from its first steps (each of its state vectors
/// is 0.7 MB): it ends `failed` naming the limit and the field `model`, with the amount it held,
/// while a bouncing ball, which holds a few kilobytes, succeeds on the same server. (Before,
/// memory was only estimated before a run: the string succeeded.)
#[tokio::test(flavor = "multi_thread")]
async fn a_run_holding_more_memory_than_the_limit_fails_naming_it() {
    let (_tmp, _server, mut client) = serve(1, &["--max-memory-mb", "1"]).await;
    let string = r#"{"name":"long string","model":{"scene":"string","nodes":90000,"length":1.0,"tension":100.0,"linear_density":0.01,"pluck":{"position":0.3,"amplitude":0.002}},"integrator":{"scheme":"moreau_jean","theta":0.5},"time":{"h":2e-5,"steps":20},"output":{"every":10}}"#;
    let id = submit_json(&mut client, string.to_string(), None)
        .await
        .expect("submit");
    let end = wait_terminal(&mut client, &id).await;
    assert_eq!(end.state, pb::JobState::Failed as i32, "{end:?}");
    let error = end.error.expect("an error");
    assert_eq!(error.field, "model", "{error:?}");
    assert!(error.reason.contains("max_memory_mb"), "{error:?}");
    assert!(error.reason.contains("limit of 1 MiB"), "{error:?}");
    let ball = submit_json(&mut client, ball_json(1e-3, 1000, 1), None)
        .await
        .expect("submit");
    let end = wait_terminal(&mut client, &ball).await;
    assert_eq!(end.state, pb::JobState::Succeeded as i32, "{end:?}");
}

/// Steps of each job of the PostgreSQL crash test (every one recorded: a chunk of the series
/// stored about every 10⁴ steps).
const PG_STEPS: u64 = 600_000;

/// How long PostgreSQL stays down in the crash test.
const PG_DOWN: Duration = Duration::from_secs(3);

/// A zenoh subscriber that never reads (a session of this test whose subscriber's queue fills:
/// zenoh then stops reading its link, and the server's frames to it block until zenoh drops the
/// link, 5 s) and a gRPC `WatchJob` client that never reads (its HTTP/2 window fills), both on a
/// job of 2·10⁶ steps recorded every 10th: the job succeeds, `signorini watch --json` (another
/// process, a peer of the server) still shows every energy frame from the first it saw to the
/// last, once and in order, with the stored rows (what the blocked publisher dropped comes from
/// the history), the server's memory grows by less than 64 MiB, and the next job runs.
#[tokio::test(flavor = "multi_thread")]
async fn a_zenoh_and_a_grpc_watcher_that_never_read_hold_up_nothing() {
    let (_tmp, server, mut client) = serve(1, &[]).await;
    const STEPS: u64 = 2_000_000;
    let id = submit_json(&mut client, ball_json(1e-6, STEPS, 10), Some("silent"))
        .await
        .expect("submit");
    let silent = server.zenoh_session().await;
    let _never_read = silent
        .declare_subscriber(format!("signorini/v1/jobs/{id}/*"))
        .await
        .expect("subscribe");
    common::zenoh_barrier(&silent, &id).await;
    let mut other = server.grpc().await;
    let _never_read_either = other
        .watch_job(pb::WatchJobRequest {
            id: id.clone(),
            from_seq: Some(0),
        })
        .await
        .expect("WatchJob")
        .into_inner();
    let before = rss(server.pid());
    let watch = Command::new(env!("CARGO_BIN_EXE_signorini"))
        .args(["watch", &id, "--json", "--zenoh-connect", &server.zenoh])
        .args(["--server", &server.grpc_url])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("signorini watch");
    let out = tokio::task::spawn_blocking(move || watch.wait_with_output())
        .await
        .expect("watch's thread")
        .expect("watch's output");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let end = wait_terminal(&mut client, &id).await;
    assert_eq!(end.state, pb::JobState::Succeeded as i32, "{end:?}");
    let grown = rss(server.pid()).saturating_sub(before);
    assert!(grown < 64 << 20, "the server grew by {} MiB", grown >> 20);

    let text = String::from_utf8(out.stdout).expect("UTF-8");
    let energy: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).expect("a JSON line"))
        .filter(|v| v["kind"] == "energy")
        .collect();
    let seqs: Vec<u64> = energy
        .iter()
        .map(|v| v["seq"].as_u64().expect("seq"))
        .collect();
    let first = *seqs.first().expect("energy frames");
    assert!(
        seqs.iter().copied().eq(first..first + seqs.len() as u64),
        "energy frames missing or repeated"
    );
    assert_eq!(
        energy.last().map(|v| &v["last"]),
        Some(&serde_json::Value::Bool(true)),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rows: usize = energy
        .iter()
        .map(|v| v["step"].as_array().map_or(0, Vec::len))
        .sum();
    let first_step = energy[0]["step"][0].as_u64().expect("a step");
    assert_eq!(
        rows as u64,
        (STEPS - first_step) / 10 + 1,
        "rows from step {first_step}"
    );
    let (_, metrics) = server.http_raw("GET", "/metrics", None, None).await;
    let dropped = String::from_utf8_lossy(&metrics)
        .lines()
        .find(|l| l.starts_with("signorini_frames_dropped_total"))
        .map(str::to_string);
    println!(
        "silent subscribers: {dropped:?}, the server grew by {} KiB",
        grown >> 10
    );
    let next = submit_json(&mut client, ball_json(1e-3, 100, 1), None)
        .await
        .expect("submit");
    let end = wait_terminal(&mut client, &next).await;
    assert_eq!(end.state, pb::JobState::Succeeded as i32, "{end:?}");
    let _ = silent.close().await;
}
