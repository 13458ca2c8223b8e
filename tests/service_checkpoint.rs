//! Checkpoints in the service: kill -9 the server while a job runs and restart it on the same
//! store; the job continues from its last stored checkpoint (not from step 0) and its final
//! result equals an uninterrupted run's bit for bit (every column of the series, the summary
//! without its wall time, the figures). A damaged checkpoint row is dropped and the job reruns
//! from step 0, to the same result. A graceful shutdown (SIGTERM) writes a last checkpoint after
//! the step it interrupts: the restart computes only the steps after it. A succeeded job keeps
//! its final state (the checkpoint after its last step), the running checkpoint goes.

mod common;

use common::fingerprint::{fingerprint, result};
use common::{Options, TestServer, submit_json, wait_running, wait_terminal};
use signorini::proto::v1 as pb;
use signorini::store::Store;

/// A bouncing ball of a few seconds, recording every 1000th step, checkpointing every 200 000.
fn long_ball() -> String {
    r#"{"name":"ball","model":{"scene":"bouncing_ball","restitution":0.8},"time":{"h":1e-5,"steps":4000000},"output":{"every":1000,"checkpoint_steps":200000}}"#.to_string()
}

/// What [`kill_restart`] saw.
struct Seen {
    /// The interrupted job's result, after the restart.
    resumed: pb::JobResult,
    /// The same spec run whole.
    whole: pb::JobResult,
    /// The step of the checkpoint the kill left.
    checkpoint_step: u64,
    /// Steps the restarted server computed (both jobs).
    steps_after_restart: u64,
}

/// Steps a server computed (`signorini_steps_total` of `/metrics`).
async fn steps_total(server: &TestServer) -> u64 {
    let (status, body) = server.http_raw("GET", "/metrics", None, None).await;
    assert_eq!(status, 200);
    let text = String::from_utf8(body).expect("metrics text");
    text.lines()
        .find_map(|l| l.strip_prefix("signorini_steps_total "))
        .and_then(|v| v.trim().parse().ok())
        .expect("signorini_steps_total")
}

/// Runs the long job on a server, kills it -9 once a checkpoint is stored, then (after
/// `tamper` on the store) restarts, lets it finish and runs the same spec whole.
async fn kill_restart(tamper: impl FnOnce(&Store, &str)) -> Seen {
    interrupt_restart(&long_ball(), TestServer::kill9, tamper).await
}

/// Runs `spec` on a server, stops it with `stop` after 10⁶ steps, then (after `tamper` on the
/// store) restarts, lets the job finish and runs the same spec whole.
async fn interrupt_restart(
    spec: &str,
    stop: impl FnOnce(&mut TestServer),
    tamper: impl FnOnce(&Store, &str),
) -> Seen {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("store.db");
    let opts = Options {
        workers: 1,
        ..Options::default()
    };
    let mut first = TestServer::start(&store, &opts);
    let mut client = first.grpc().await;
    let id = submit_json(&mut client, spec.to_string(), Some("interrupted"))
        .await
        .expect("submit");
    wait_running(&mut client, &id, 1_000_000).await;
    drop(client);
    stop(&mut first);

    let checkpoint_step = {
        let s = Store::open(&store).expect("store");
        let (attempt, step, _) = s
            .load_checkpoint(&id)
            .expect("load")
            .expect("a checkpoint after 10⁶ steps");
        assert_eq!(attempt, 0);
        assert!(step >= 200_000, "{step}");
        tamper(&s, &id);
        step
    };

    let second = TestServer::start(&store, &opts);
    let mut client = second.grpc().await;
    let s = wait_terminal(&mut client, &id).await;
    assert_eq!(s.state, pb::JobState::Succeeded as i32, "{s:?}");
    let resumed = result(&mut client, &id).await;
    let whole_id = submit_json(&mut client, spec.to_string(), Some("whole"))
        .await
        .expect("submit whole");
    let s = wait_terminal(&mut client, &whole_id).await;
    assert_eq!(s.state, pb::JobState::Succeeded as i32, "{s:?}");
    let whole = result(&mut client, &whole_id).await;
    let steps_after_restart = steps_total(&second).await;
    // Ended jobs keep no checkpoint.
    drop(client);
    drop(second);
    let s = Store::open(&store).expect("store");
    assert!(s.load_checkpoint(&id).expect("load").is_none());
    assert!(s.load_checkpoint(&whole_id).expect("load").is_none());
    // A succeeded job keeps the checkpoint after its last step as its final state (for extend).
    for job in [&id, &whole_id] {
        let (step, _) = s.final_state(job).expect("load").expect("a final state");
        assert_eq!(step, 4_000_000);
    }
    Seen {
        resumed,
        whole,
        checkpoint_step,
        steps_after_restart,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn kill9_then_restart_resumes_from_the_checkpoint_bit_for_bit() {
    let Seen {
        resumed,
        whole,
        checkpoint_step,
        steps_after_restart,
    } = kill_restart(|_, _| {}).await;
    assert!(checkpoint_step.is_multiple_of(200_000), "{checkpoint_step}");
    // The restarted server computed the steps after the checkpoint, and the whole run.
    assert_eq!(
        steps_after_restart,
        (4_000_000 - checkpoint_step) + 4_000_000
    );
    assert_eq!(resumed.step, whole.step);
    assert_eq!(resumed.step.last().copied(), Some(4_000_000));
    assert_eq!(resumed.step.len(), 4001);
    assert_eq!(fingerprint(&resumed), fingerprint(&whole));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_damaged_checkpoint_reruns_the_job_from_step_zero() {
    let seen = kill_restart(|store, id| {
        let (attempt, step, mut bytes) = store.load_checkpoint(id).expect("load").expect("row");
        let mid = bytes.len() / 2;
        bytes[mid] ^= 0x55;
        store
            .save_checkpoint(id, attempt, step, &bytes)
            .expect("save");
    })
    .await;
    // Both runs went from step 0.
    assert_eq!(seen.steps_after_restart, 8_000_000);
    assert_eq!(seen.resumed.step, seen.whole.step);
    assert_eq!(fingerprint(&seen.resumed), fingerprint(&seen.whole));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigterm_writes_a_last_checkpoint_and_the_restart_loses_nothing() {
    // No checkpoint period of steps: the default 30 s, so the checkpoint the restart continues
    // from is the one the graceful shutdown wrote after the step it was at.
    let spec = long_ball().replace(r#","checkpoint_steps":200000"#, "");
    assert!(!spec.contains("checkpoint_steps"));
    let Seen {
        resumed,
        whole,
        checkpoint_step,
        steps_after_restart,
    } = interrupt_restart(
        &spec,
        |server| {
            let (status, _) = server
                .terminate(std::time::Duration::from_secs(60))
                .expect("the server exits after SIGTERM");
            assert!(status.success(), "{status:?}");
        },
        |_, _| {},
    )
    .await;
    // Written after the step the run was at when SIGTERM came (at least 10⁶): the restarted
    // server computed only the steps after it, and the whole run.
    assert!(checkpoint_step >= 1_000_000, "{checkpoint_step}");
    assert_eq!(
        steps_after_restart,
        (4_000_000 - checkpoint_step) + 4_000_000
    );
    assert_eq!(resumed.step, whole.step);
    assert_eq!(fingerprint(&resumed), fingerprint(&whole));
}
