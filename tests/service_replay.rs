//! History and replay (issue 13, part 3), against the real server: gRPC `WatchJob` with
//! `from_seq` sends the job's stored frames, then the live ones, with no gap and no duplicate at
//! the seam, whether the job is over or half-way; SSE energy events carry `id:` = seq and a
//! reconnecting client's `Last-Event-ID` resumes right after it.

mod common;

use common::{
    Options, PATIENCE, TestServer, ball_json, read_sse, submit_json, wait_running, wait_terminal,
};
use signorini::proto::v1 as pb;
use std::collections::BTreeMap;

/// The frames of a `WatchJob` call until its final status: (energy frames, final state).
async fn watch_from(
    client: &mut signorini::proto::v1::simulation_client::SimulationClient<
        tonic::transport::Channel,
    >,
    id: &str,
    from_seq: u64,
) -> (Vec<pb::StepFrame>, Vec<pb::StepFrame>, i32) {
    let fut = async {
        let mut stream = client
            .watch_job(pb::WatchJobRequest {
                id: id.into(),
                from_seq: Some(from_seq),
            })
            .await
            .expect("WatchJob")
            .into_inner();
        let (mut energy, mut state) = (Vec::new(), Vec::new());
        while let Some(f) = stream.message().await.expect("WatchJob stream") {
            match f.frame.expect("a frame") {
                pb::watch_frame::Frame::Energy(e) => energy.push(e),
                pb::watch_frame::Frame::State(s) => state.push(s),
                pb::watch_frame::Frame::Status(s) => {
                    if common::has_ended(&s) {
                        assert!(
                            stream.message().await.expect("end").is_none(),
                            "ends after the final status"
                        );
                        return (energy, state, s.state);
                    }
                }
            }
        }
        panic!("WatchJob ended without a final status");
    };
    tokio::time::timeout(PATIENCE, fut).await.expect("in time")
}

/// Steps and values (bits) per column of a run's frames, checked consecutive in `seq` and `step`.
fn rows_of(frames: &[pb::StepFrame], first_seq: u64) -> BTreeMap<String, Vec<u64>> {
    let mut cols: BTreeMap<String, Vec<u64>> = BTreeMap::new();
    let mut steps = Vec::new();
    for (k, f) in frames.iter().enumerate() {
        assert_eq!(
            f.seq,
            first_seq + k as u64,
            "seq numbers without gap or repeat"
        );
        let n = f.columns.len();
        for (i, &step) in f.step.iter().enumerate() {
            steps.push(step);
            for (c, name) in f.columns.iter().enumerate() {
                cols.entry(name.clone())
                    .or_default()
                    .push(f.values[i * n + c].to_bits());
            }
        }
    }
    assert!(
        steps.windows(2).all(|w| w[1] == w[0] + 1),
        "steps without gap or repeat"
    );
    cols.insert("step".into(), steps);
    cols
}

/// The stored result's columns as bits (`step` as is).
async fn stored(
    client: &mut signorini::proto::v1::simulation_client::SimulationClient<
        tonic::transport::Channel,
    >,
    id: &str,
) -> BTreeMap<String, Vec<u64>> {
    let r = client
        .get_result(pb::GetResultRequest {
            id: id.into(),
            ..Default::default()
        })
        .await
        .expect("GetResult")
        .into_inner();
    let mut cols: BTreeMap<String, Vec<u64>> = r
        .series
        .into_iter()
        .map(|s| (s.column, s.values.iter().map(|v| v.to_bits()).collect()))
        .collect();
    cols.insert("step".into(), r.step);
    cols
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn watch_replays_a_finished_job_from_any_seq() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("s.db"), &Options::default());
    let mut client = server.grpc().await;
    let id = submit_json(&mut client, ball_json(1e-3, 30_000, 1), Some("done"))
        .await
        .expect("submit");
    wait_terminal(&mut client, &id).await;
    let want = stored(&mut client, &id).await;

    let (energy, state, end) = watch_from(&mut client, &id, 0).await;
    assert_eq!(end, pb::JobState::Succeeded as i32);
    assert!(energy.len() > 100, "{} frames", energy.len());
    assert!(
        energy.last().is_some_and(|f| f.last),
        "the last frame is marked"
    );
    let mut got = rows_of(&energy, 0);
    let state_rows = rows_of(&state, 0);
    assert_eq!(got["step"], state_rows["step"]);
    got.extend(state_rows);
    assert_eq!(got, want, "the replay is the stored result, bit for bit");

    // From anywhere, in any of the stored chunks (30 001 rows are three of them), up to past
    // the last frame: the same frames from that seq on.
    let n = energy.len();
    for from in [40, n / 3, n / 2, 2 * n / 3, n - 1, n, n + 5] {
        let (later, _, end) = watch_from(&mut client, &id, from as u64).await;
        assert_eq!(end, pb::JobState::Succeeded as i32);
        assert_eq!(later, energy[from.min(n)..], "from seq {from}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn watch_from_the_start_of_a_running_job_has_no_gap_or_duplicate_at_the_seam() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("s.db"), &Options::default());
    let mut client = server.grpc().await;
    let id = submit_json(&mut client, ball_json(1e-5, 300_000, 1), Some("half"))
        .await
        .expect("submit");
    // Half-way: chunks in the store, rows in the buffer, batches still to come.
    wait_running(&mut client, &id, 60_000).await;
    let (energy, state, end) = watch_from(&mut client, &id, 0).await;
    assert_eq!(end, pb::JobState::Succeeded as i32);
    let mut got = rows_of(&energy, 0);
    got.extend(rows_of(&state, 0));
    assert_eq!(got["step"].len(), 300_001);
    assert_eq!(got, stored(&mut client, &id).await);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sse_events_carry_their_seq_and_resume_after_the_last_event_id() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("s.db"), &Options::default());
    let mut client = server.grpc().await;
    let id = submit_json(&mut client, ball_json(1e-3, 20_000, 1), Some("sse"))
        .await
        .expect("submit");
    wait_terminal(&mut client, &id).await;
    // The whole history, ids 0, 1, 2, …, then the final status.
    let mut ids = Vec::new();
    let mut last_status = None;
    read_sse(
        server.http,
        &format!("/v1/jobs/{id}/events?from_seq=0"),
        |e| {
            if e.event == "energy" {
                ids.push(
                    e.id.clone()
                        .expect("an id")
                        .parse::<u64>()
                        .expect("a number"),
                );
                return true;
            }
            last_status = Some(e.data.clone());
            e.data["state"] != "succeeded"
        },
    )
    .await;
    assert!(ids.len() > 50);
    assert_eq!(ids, (0..ids.len() as u64).collect::<Vec<_>>());
    assert_eq!(last_status.expect("a status")["state"], "succeeded");
    // A reconnect with Last-Event-ID: 41 starts at 42.
    let mut resumed = Vec::new();
    common::read_sse_with(
        server.http,
        &format!("/v1/jobs/{id}/events"),
        &[("last-event-id", "41")],
        |e| {
            if e.event == "energy" {
                resumed.push(
                    e.id.clone()
                        .expect("an id")
                        .parse::<u64>()
                        .expect("a number"),
                );
                return true;
            }
            e.data["state"] != "succeeded"
        },
    )
    .await;
    assert_eq!(resumed, (42..ids.len() as u64).collect::<Vec<_>>());
}

/// The frames a zenoh `get` on `key` answers (the server's history queryable), in `seq` order
/// (zenoh's default consolidation delivers distinct keys in no set order).
async fn zenoh_history(session: &zenoh::Session, key: &str) -> Vec<pb::StepFrame> {
    use prost::Message;
    let replies = session.get(key).await.expect("zenoh get");
    let mut frames = Vec::new();
    while let Ok(reply) = replies.recv_async().await {
        let sample = reply.result().expect("a frame, not an error");
        frames.push(pb::StepFrame::decode(&*sample.payload().to_bytes()).expect("a StepFrame"));
    }
    frames.sort_by_key(|f| f.seq);
    frames
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_zenoh_late_joiner_gets_the_recorded_frames_from_the_store() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("s.db"), &Options::default());
    let mut client = server.grpc().await;
    let id = submit_json(&mut client, ball_json(1e-3, 30_000, 1), Some("late"))
        .await
        .expect("submit");
    wait_terminal(&mut client, &id).await;
    let session = server.zenoh_session().await;
    common::zenoh_barrier(&session, &id).await;
    let all = |key: String| format!("{key}/*");
    let energy = zenoh_history(&session, &all(signorini::stream::energy_key(&id))).await;
    let state = zenoh_history(&session, &all(signorini::stream::state_key(&id))).await;
    assert!(energy.len() > 100 && energy.len() < signorini::stream::HISTORY_FRAMES);
    let mut got = rows_of(&energy, 0);
    got.extend(rows_of(&state, 0));
    assert_eq!(
        got,
        stored(&mut client, &id).await,
        "the stored frames, bit for bit"
    );
    let later = zenoh_history(
        &session,
        &format!("{}/*?from_seq=100", signorini::stream::energy_key(&id)),
    )
    .await;
    assert_eq!(later.len(), energy.len() - 100);
    assert_eq!(later[0], energy[100]);
    let one = zenoh_history(
        &session,
        &format!("{}/7", signorini::stream::energy_key(&id)),
    )
    .await;
    assert_eq!(one, [energy[7].clone()]);
    // An unknown job: an error reply, not silence.
    let replies = session
        .get(format!(
            "{}/*",
            signorini::stream::energy_key("no-such-job")
        ))
        .await
        .expect("zenoh get");
    let reply = replies.recv_async().await.expect("a reply");
    assert!(reply.result().is_err());
    let _ = session.close().await;
}
