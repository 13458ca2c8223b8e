//! Replicas on one PostgreSQL store (`serve --store postgres://…`), each a real `signorini serve`
//! process with one worker, on a private PostgreSQL server (common::pg): the queue is shared
//! (each job claimed and run exactly once, by either replica), a replica killed with SIGKILL
//! loses its lease and its job completes on the other from its last checkpoint, any replica
//! answers for any job, and frames cross a zenoh router (to a subscriber, and to `WatchJob` and
//! SSE on the replica that does not run the job).

mod common;

use common::pg::Postgres;
use common::{
    Options, PATIENCE, TestServer, ball_json, free_port, has_ended, poll_job, submit_json,
};
use prost::Message;
use signorini::proto::v1 as pb;
use std::path::Path;
use std::time::Duration;

/// Lease of the test replicas (short, so a killed replica's job is claimed again soon).
const LEASE_SECS: &str = "2";

fn replica(url: &str, name: &str, extra: &[&str]) -> TestServer {
    let mut args = vec!["--replica", name, "--lease-secs", LEASE_SECS];
    args.extend_from_slice(extra);
    let opts = Options {
        workers: 1,
        queue_limit: 256,
        ..Options::default()
    };
    TestServer::start_with(Path::new(url), &opts, &args)
}

/// Polls the store until `sql` (one value) gives `want`.
async fn poll_sql(pg: &Postgres, db: &str, sql: &str, want: impl Fn(&str) -> bool) -> String {
    let deadline = tokio::time::Instant::now() + PATIENCE;
    loop {
        let got = pg.psql(db, sql);
        if want(&got) {
            return got;
        }
        assert!(tokio::time::Instant::now() < deadline, "{sql}: still {got}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

/// The `step` column of a job's result, read over HTTP from `server`.
async fn result_steps(server: &TestServer, id: &str) -> Vec<f64> {
    let (status, body) = server
        .http("GET", &format!("/v1/jobs/{id}/result"), None, None)
        .await;
    assert_eq!(status, 200, "{body}");
    body["steps"]["step"]
        .as_array()
        .expect("a step column")
        .iter()
        .map(|v| v.as_f64().expect("a number"))
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_replicas_share_one_queue_and_run_each_job_exactly_once() {
    let pg = Postgres::start();
    let url = pg.create_database("queue");
    let a = replica(&url, "a", &[]);
    let b = replica(&url, "b", &[]);
    let mut to_a = a.grpc().await;
    let mut to_b = b.grpc().await;

    // 40 jobs, all submitted to replica a.
    let ids: Vec<String> = (0..40).map(|k| format!("job-{k:02}")).collect();
    for id in &ids {
        submit_json(&mut to_a, ball_json(1e-4, 20_000, 100), Some(id))
            .await
            .expect("submit");
    }
    // Replica b follows the last job (WatchJob) to its end, whichever replica runs it, and
    // answers for every job.
    let last = common::wait_terminal(&mut to_b, &ids[39]).await;
    assert_eq!(last.state, pb::JobState::Succeeded as i32, "{last:?}");
    for id in &ids {
        let s = poll_job(&mut to_b, id, has_ended).await;
        assert_eq!(s.state, pb::JobState::Succeeded as i32, "{id}: {s:?}");
    }

    // Each job claimed once (attempt 1), finished by the replica that claimed it; both
    // replicas did work.
    let per_owner = pg.psql(
        "queue",
        "SELECT owner, count(*), min(attempt), max(attempt) FROM jobs GROUP BY owner ORDER BY owner",
    );
    let rows: Vec<Vec<&str>> = per_owner.lines().map(|l| l.split('|').collect()).collect();
    assert_eq!(rows.len(), 2, "both replicas ran jobs: {per_owner}");
    assert_eq!((rows[0][0], rows[1][0]), ("a", "b"), "{per_owner}");
    let counts: Vec<u64> = rows
        .iter()
        .map(|r| r[1].parse().expect("a count"))
        .collect();
    assert!(counts.iter().all(|&n| n > 0), "{per_owner}");
    assert_eq!(counts.iter().sum::<u64>(), 40);
    assert!(
        rows.iter().all(|r| r[2] == "1" && r[3] == "1"),
        "a job was claimed twice: {per_owner}"
    );
    // One result per job, and each series whole (0, 100, …, 20000).
    assert_eq!(
        pg.psql("queue", "SELECT count(*), count(DISTINCT id) FROM results"),
        "40|40"
    );
    let ran_on_a = pg.psql(
        "queue",
        "SELECT id FROM jobs WHERE owner = 'a' ORDER BY seq LIMIT 1",
    );
    let steps = result_steps(&b, &ran_on_a).await;
    assert_eq!(
        steps,
        (0..=200).map(|k| f64::from(k * 100)).collect::<Vec<_>>()
    );
    // The series are stored uncompressed (migration 0005: pglz cost CPU, saved little).
    assert_eq!(
        pg.psql(
            "queue",
            "SELECT count(*), count(pg_column_compression(vals)) FROM result_chunks"
        ),
        "40|0"
    );
}

/// Steps a server computed (`signorini_steps_total` of `/metrics`).
async fn steps_total(server: &TestServer) -> u64 {
    let (status, body) = server.http_raw("GET", "/metrics", None, None).await;
    assert_eq!(status, 200);
    String::from_utf8(body)
        .expect("metrics text")
        .lines()
        .find_map(|l| l.strip_prefix("signorini_steps_total "))
        .and_then(|v| v.trim().parse().ok())
        .expect("signorini_steps_total")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_replica_killed_mid_job_loses_its_lease_and_the_other_finishes_the_job() {
    let pg = Postgres::start();
    let url = pg.create_database("failover");
    let mut a = replica(&url, "a", &[]);
    let mut b = replica(&url, "b", &[]);
    let mut to_a = a.grpc().await;

    // A job of several seconds that checkpoints every 2·10⁵ steps, then short ones, all to
    // replica a.
    let long = r#"{"name":"ball","model":{"scene":"bouncing_ball","restitution":0.8},"time":{"h":1e-5,"steps":3000000},"output":{"every":1000,"checkpoint_steps":200000}}"#;
    submit_json(&mut to_a, long.to_string(), Some("long"))
        .await
        .expect("submit long");
    let short: Vec<String> = (0..6).map(|k| format!("short-{k}")).collect();
    for id in &short {
        submit_json(&mut to_a, ball_json(1e-4, 5_000, 50), Some(id))
            .await
            .expect("submit short");
    }
    // After its first checkpoint (progress reaches the store with the heartbeat): kill its
    // replica.
    let owner = poll_sql(
        &pg,
        "failover",
        "SELECT j.owner FROM jobs j JOIN checkpoints c ON c.id = j.id WHERE j.id = 'long' AND j.state = 'running' AND c.step >= 200000",
        |o| !o.is_empty(),
    )
    .await;
    let checkpointed: u64 = pg
        .psql("failover", "SELECT step FROM checkpoints WHERE id = 'long'")
        .parse()
        .expect("a step");
    let survivor = match owner.as_str() {
        "a" => {
            a.kill9();
            b
        }
        "b" => {
            b.kill9();
            a
        }
        other => panic!("unexpected owner {other}"),
    };
    let mut client = survivor.grpc().await;
    // Followed on the survivor from before it claims the job (status read from the store) to
    // its end there.
    let s = common::wait_terminal(&mut client, "long").await;
    assert_eq!(s.state, pb::JobState::Succeeded as i32, "{s:?}");
    for id in &short {
        let s = poll_job(&mut client, id, has_ended).await;
        assert_eq!(s.state, pb::JobState::Succeeded as i32, "{id}: {s:?}");
    }
    let survivor_name = if owner == "a" { "b" } else { "a" };
    // The survivor continued from the checkpoint: it computed the rest of the long job and the
    // short jobs, not the long job's first steps again.
    let computed = steps_total(&survivor).await;
    assert!(
        computed <= 3_000_000 - checkpointed + 6 * 5_000,
        "the survivor computed {computed} steps: it did not resume from step {checkpointed}"
    );
    // Claimed a second time, by the survivor, after the lease ran out; the short jobs once.
    assert_eq!(
        pg.psql(
            "failover",
            "SELECT owner, attempt FROM jobs WHERE id = 'long'"
        ),
        format!("{survivor_name}|2")
    );
    assert_eq!(
        pg.psql(
            "failover",
            "SELECT count(*) FROM jobs WHERE id <> 'long' AND attempt = 1 AND state = 'succeeded'"
        ),
        "6"
    );
    // Nothing lost or duplicated: one result per job, the long job's chunks all of its second
    // run (those stored before the checkpoint handed over to it), its series whole and in
    // order; no checkpoint left.
    assert_eq!(
        pg.psql(
            "failover",
            "SELECT count(*), count(DISTINCT id) FROM results"
        ),
        "7|7"
    );
    assert_eq!(
        pg.psql(
            "failover",
            "SELECT string_agg(DISTINCT attempt::TEXT, ',') FROM result_chunks WHERE id = 'long'"
        ),
        "2"
    );
    assert_eq!(pg.psql("failover", "SELECT count(*) FROM checkpoints"), "0");
    let steps = result_steps(&survivor, "long").await;
    assert_eq!(
        steps,
        (0..=3000).map(|k| f64::from(k * 1000)).collect::<Vec<_>>()
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn frames_of_a_job_on_either_replica_reach_a_subscriber_through_a_router() {
    // A zenoh router on loopback (what zenohd is in a deployment); the replicas and the
    // subscriber connect to it only.
    let router_endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let mut config = zenoh::Config::default();
    for (key, value) in [
        ("mode", "\"router\"".to_string()),
        ("scouting/multicast/enabled", "false".into()),
        ("listen/endpoints", format!("[\"{router_endpoint}\"]")),
    ] {
        config.insert_json5(key, &value).expect("router config");
    }
    let router = zenoh::open(config).await.expect("zenoh router");

    let pg = Postgres::start();
    let url = pg.create_database("frames");
    let a = replica(&url, "a", &["--zenoh-connect", &router_endpoint]);
    let b = replica(&url, "b", &["--zenoh-connect", &router_endpoint]);
    let subscriber = signorini::stream::open_session(&signorini::stream::ZenohOptions {
        listen: Vec::new(),
        connect: vec![router_endpoint.clone()],
        ..Default::default()
    })
    .await
    .expect("subscriber session");
    let energy = subscriber
        .declare_subscriber(signorini::stream::energy_key("watched"))
        .await
        .expect("subscribe energy");
    let status = subscriber
        .declare_subscriber(signorini::stream::status_key("watched"))
        .await
        .expect("subscribe status");
    // Both replicas' status queryables answer through the router: routes are up both ways.
    let deadline = tokio::time::Instant::now() + PATIENCE;
    loop {
        let replies = subscriber
            .get(signorini::stream::status_key("watched"))
            .await
            .expect("zenoh get");
        let mut n = 0;
        while replies.recv_async().await.is_ok() {
            n += 1;
        }
        if n >= 2 {
            break;
        }
        assert!(
            tokio::time::Instant::now() < deadline,
            "replicas not routed"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }

    // Two jobs keep both workers busy; the watched one runs on either replica.
    let mut to_a = a.grpc().await;
    submit_json(&mut to_a, ball_json(1e-5, 1_000_000, 1000), Some("other"))
        .await
        .expect("submit other");
    submit_json(&mut to_a, ball_json(1e-5, 1_000_000, 1000), Some("watched"))
        .await
        .expect("submit watched");
    let frames = common::collect_until_last(&energy).await;
    assert!(frames.frames > 0);
    assert_eq!(frames.steps.last(), Some(&1_000_000));
    // The final status goes out after the result is stored.
    let fin = loop {
        let sample = tokio::time::timeout(PATIENCE, status.recv_async())
            .await
            .expect("no status in time")
            .expect("subscriber closed");
        let s = pb::JobStatus::decode(&*sample.payload().to_bytes()).expect("a JobStatus");
        if has_ended(&s) {
            break s;
        }
    };
    assert_eq!(fin.state, pb::JobState::Succeeded as i32);
    let owner = pg.psql("frames", "SELECT owner FROM jobs WHERE id = 'watched'");
    assert!(owner == "a" || owner == "b", "{owner}");
    let mut to_b = b.grpc().await;
    poll_job(&mut to_b, "other", has_ended).await;

    // WatchJob and the SSE route of the replica that does not run a job stream its frames
    // (from the other replica, through the router), equal to the stored result.
    const STEPS: u64 = 20_000_000;
    submit_json(&mut to_a, ball_json(1e-6, STEPS, 10_000), Some("remote"))
        .await
        .expect("submit remote");
    let owner = poll_sql(
        &pg,
        "frames",
        "SELECT owner FROM jobs WHERE id = 'remote'",
        |o| !o.is_empty(),
    )
    .await;
    let (runner, watcher) = if owner == "a" { (&a, &b) } else { (&b, &a) };
    let sse_addr = watcher.http;
    let sse = tokio::spawn(async move {
        let (mut energy, mut last) = (0, None);
        common::read_sse(sse_addr, "/v1/jobs/remote/events", |e| {
            if e.event == "energy" {
                energy += 1;
            }
            let ended = e.event == "status" && e.data["finished_ms"].as_u64() > Some(0);
            if ended {
                last = Some(e.data["state"].clone());
            }
            !ended
        })
        .await;
        (energy, last)
    });
    // Live, and replayed from the first batch (the stored history, then the live frames).
    let (mut live, mut replayed) = (watcher.grpc().await, watcher.grpc().await);
    let (watched, replayed) = tokio::join!(
        watch_energy(&mut live, None),
        watch_energy(&mut replayed, Some(0))
    );
    assert!(
        !replayed.is_empty(),
        "no frame replayed from the other replica"
    );
    let last = watched
        .last()
        .expect("energy frames from the other replica");
    assert!(last.last, "{last:?}");
    let max_step = watched.iter().flat_map(|f| f.step.iter().copied()).max();
    assert_eq!(max_step, Some(STEPS));
    // Every watched row equals the stored one.
    let stored = runner
        .http("GET", "/v1/jobs/remote/result", None, None)
        .await
        .1;
    let steps = &stored["steps"];
    let row_of = |step: u64| {
        steps["step"]
            .as_array()
            .expect("step column")
            .iter()
            .position(|s| s.as_u64() == Some(step))
            .expect("a stored row")
    };
    for f in &watched {
        for (i, &step) in f.step.iter().enumerate() {
            let row = row_of(step);
            for (c, column) in f.columns.iter().enumerate() {
                assert_eq!(
                    steps[column.as_str()][row].as_f64(),
                    Some(f.values[i * f.columns.len() + c]),
                    "{column} at step {step}"
                );
            }
        }
    }
    let (sse_energy, sse_end) = sse.await.expect("SSE reader");
    assert!(sse_energy > 0, "no energy event over SSE");
    assert_eq!(sse_end, Some(serde_json::Value::from("succeeded")));
    drop((to_a, to_b));
    subscriber.close().await.expect("closing the subscriber");
    drop((a, b));
    router.close().await.expect("closing the router");
}

/// The energy frames `WatchJob` (from batch `from_seq`, if given) streams for job `remote` until
/// its final status, which must be `succeeded`.
async fn watch_energy(
    client: &mut signorini::proto::v1::simulation_client::SimulationClient<
        tonic::transport::Channel,
    >,
    from_seq: Option<u64>,
) -> Vec<pb::StepFrame> {
    let mut frames = client
        .watch_job(pb::WatchJobRequest {
            id: "remote".into(),
            from_seq,
        })
        .await
        .expect("WatchJob")
        .into_inner();
    let (mut energy, mut end) = (Vec::new(), None);
    while let Some(frame) = tokio::time::timeout(PATIENCE, frames.message())
        .await
        .expect("a frame in time")
        .expect("WatchJob stream")
    {
        match frame.frame {
            Some(pb::watch_frame::Frame::Energy(f)) => energy.push(f),
            Some(pb::watch_frame::Frame::Status(s)) if has_ended(&s) => end = Some(s),
            _ => {}
        }
    }
    let end = end.expect("the final status");
    assert_eq!(end.state, pb::JobState::Succeeded as i32, "{end:?}");
    energy
}
