//! Pause, resume and extend on a PostgreSQL store shared by two replicas (each a real
//! `signorini serve` with one worker, on a private PostgreSQL server, common::pg): a job running
//! on one replica is paused through the other (the `pause_requested` flag, read at the running
//! replica's heartbeat), parked with its checkpoint, resumed through either, claimed by any
//! replica, and finishes equal to an uninterrupted run bit for bit; a queued job is parked at
//! once; a succeeded job is extended from its final state.

mod common;

use common::fingerprint::{fingerprint, fingerprint_without, result, rows_after};
use common::pg::Postgres;
use common::{Options, TestServer, has_ended, poll_job, submit_json};
use signorini::proto::v1 as pb;
use signorini::spec_file::{Format, parse};
use std::path::Path;

fn replica(url: &str, name: &str) -> TestServer {
    let opts = Options {
        workers: 1,
        ..Options::default()
    };
    TestServer::start_with(
        Path::new(url),
        &opts,
        &["--replica", name, "--lease-secs", "2"],
    )
}

/// `examples/bar.toml` (Moreau–Jean) to t = 6000 (6·10⁶ steps, seconds even on a quiet machine,
/// so a pause sent through the other replica reaches it at a heartbeat well before its end),
/// recording every 1000th step.
fn long_bar() -> String {
    let path = format!("{}/examples/bar.toml", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(path).expect("example");
    let mut spec = parse(&text, Format::Toml).expect("example spec");
    let time = spec.time.as_mut().expect("time");
    (time.t_end, time.steps) = (Some(6000.0), None);
    spec.output.every = 1000;
    serde_json::to_string(&spec).expect("JSON")
}

fn step(s: &pb::JobStatus) -> u64 {
    s.progress.as_ref().map_or(0, |p| p.step)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_job_paused_through_another_replica_resumes_anywhere_bit_for_bit() {
    let pg = Postgres::start();
    let url = pg.create_database("pause");
    let a = replica(&url, "a");
    let b = replica(&url, "b");
    let (mut to_a, mut to_b) = (a.grpc().await, b.grpc().await);

    submit_json(&mut to_a, long_bar(), Some("paused"))
        .await
        .expect("submit");
    let s = poll_job(&mut to_a, "paused", |s| {
        s.state == pb::JobState::Running as i32 && step(s) >= 50_000
    })
    .await;
    assert!(step(&s) < s.progress.as_ref().expect("progress").total);
    // Through the replica that does not run it.
    let owner = pg.psql("pause", "SELECT owner FROM jobs WHERE id = 'paused'");
    let other = if owner == "a" { &mut to_b } else { &mut to_a };
    other
        .pause_job(pb::PauseJobRequest {
            id: "paused".into(),
        })
        .await
        .expect("PauseJob");
    let s = poll_job(other, "paused", |s| s.state != pb::JobState::Running as i32).await;
    assert_eq!(s.state, pb::JobState::Paused as i32, "{s:?}");
    let at = pg.psql("pause", "SELECT step FROM checkpoints WHERE id = 'paused'");
    assert_eq!(at, step(&s).to_string(), "the checkpoint of the pause");
    assert_eq!(
        pg.psql(
            "pause",
            "SELECT coalesce(owner, '-') FROM jobs WHERE id = 'paused'"
        ),
        "-"
    );
    // A queued job is parked at once (both workers busy: the whole run, and a blocker).
    submit_json(&mut to_b, long_bar(), Some("whole"))
        .await
        .expect("submit");
    submit_json(&mut to_b, long_bar(), Some("blocker"))
        .await
        .expect("submit");
    submit_json(&mut to_b, long_bar(), Some("waiting"))
        .await
        .expect("submit");
    let s = to_a
        .pause_job(pb::PauseJobRequest {
            id: "waiting".into(),
        })
        .await
        .expect("PauseJob")
        .into_inner();
    assert_eq!(s.state, pb::JobState::Paused as i32, "{s:?}");
    to_a.cancel_job(pb::CancelJobRequest {
        id: "blocker".into(),
    })
    .await
    .expect("cancel");
    let s = to_b
        .cancel_job(pb::CancelJobRequest {
            id: "waiting".into(),
        })
        .await
        .expect("cancel a paused job")
        .into_inner();
    assert_eq!(s.state, pb::JobState::Cancelled as i32, "{s:?}");

    let s = to_b
        .resume_job(pb::ResumeJobRequest {
            id: "paused".into(),
        })
        .await
        .expect("ResumeJob")
        .into_inner();
    assert_eq!(s.state, pb::JobState::Queued as i32, "{s:?}");
    for id in ["paused", "whole"] {
        let s = poll_job(&mut to_a, id, has_ended).await;
        assert_eq!(s.state, pb::JobState::Succeeded as i32, "{id}: {s:?}");
    }
    // Claimed twice (before and after the pause), continued from the checkpoint.
    assert_eq!(
        pg.psql("pause", "SELECT attempt FROM jobs WHERE id = 'paused'"),
        "2"
    );
    let (paused, whole) = (
        result(&mut to_a, "paused").await,
        result(&mut to_b, "whole").await,
    );
    assert_eq!(paused.step, whole.step);
    assert_eq!(fingerprint(&paused), fingerprint(&whole));

    // Extend the whole run from its final state (t = 6000) to 6100, on either replica.
    let r = to_b
        .extend_job(pb::ExtendJobRequest {
            id: "whole".into(),
            t_end: 6100.0,
            new_id: Some("longer".into()),
        })
        .await
        .expect("ExtendJob")
        .into_inner();
    assert_eq!(r.extends, "whole");
    let mut spec: serde_json::Value = serde_json::from_str(&long_bar()).expect("spec");
    spec["time"]["t_end"] = 6100.0.into();
    submit_json(&mut to_a, spec.to_string(), Some("to-6100"))
        .await
        .expect("submit");
    for id in ["longer", "to-6100"] {
        let s = poll_job(&mut to_a, id, has_ended).await;
        assert_eq!(s.state, pb::JobState::Succeeded as i32, "{id}: {s:?}");
    }
    let (ext, full) = (
        result(&mut to_a, "longer").await,
        result(&mut to_b, "to-6100").await,
    );
    let tail = rows_after(&full, 6_000_000);
    assert_eq!(ext.step, tail.step);
    assert_eq!(fingerprint_without(&ext, &["extends"]), fingerprint(&tail));
}
