//! (5) kill -9 the server in the middle of a job and restart it on the same store: the earlier
//! result is intact (bit for bit) and the interrupted job runs again to completion.

mod common;

use common::{Options, TestServer, ball_json, submit_json, wait_running, wait_terminal};
use signorini::proto::v1 as pb;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn kill9_mid_job_then_restart_keeps_results_and_reruns_the_job() {
    let dir = tempfile::tempdir().expect("tempdir");
    let store = dir.path().join("store.db");
    let opts = Options {
        workers: 1,
        ..Options::default()
    };
    let mut first = TestServer::start(&store, &opts);
    let mut client = first.grpc().await;
    let done = submit_json(&mut client, ball_json(1e-3, 2000, 1), Some("before-crash"))
        .await
        .expect("submit");
    assert_eq!(
        wait_terminal(&mut client, &done).await.state,
        pb::JobState::Succeeded as i32
    );
    let before = client
        .get_result(pb::GetResultRequest {
            id: done.clone(),
            ..Default::default()
        })
        .await
        .expect("result")
        .into_inner();

    // A job of several seconds (recording every 1000th step); kill while it runs, and one queued.
    let long = ball_json(1e-5, 4_000_000, 1000);
    let running = submit_json(&mut client, long.clone(), Some("interrupted"))
        .await
        .expect("submit long");
    let queued = submit_json(&mut client, ball_json(1e-3, 500, 1), Some("queued"))
        .await
        .expect("submit queued");
    wait_running(&mut client, &running, 10_000).await;
    drop(client);
    first.kill9();

    let second = TestServer::start(&store, &opts);
    let mut client = second.grpc().await;
    let after = client
        .get_result(pb::GetResultRequest {
            id: done.clone(),
            ..Default::default()
        })
        .await
        .expect("result after")
        .into_inner();
    assert_eq!(after.step, before.step);
    assert_eq!(after.summary_json, before.summary_json);
    for (a, b) in after.series.iter().zip(&before.series) {
        assert_eq!(a.column, b.column);
        assert_eq!(
            a.values.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            b.values.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        );
    }
    for id in [&running, &queued] {
        let s = wait_terminal(&mut client, id).await;
        assert_eq!(s.state, pb::JobState::Succeeded as i32, "{s:?}");
    }
    let r = client
        .get_result(pb::GetResultRequest {
            id: running.clone(),
            ..Default::default()
        })
        .await
        .expect("rerun result")
        .into_inner();
    assert_eq!(r.step.last().copied(), Some(4_000_000));
}
