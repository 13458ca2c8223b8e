//! (1) and (2): a job submitted over gRPC (typed spec) and over HTTP (JSON) streams every step on
//! `signorini/v1/jobs/{id}/energy` to a separate zenoh session, and the streamed values equal the
//! stored result (GetResult / GET …/result) bit for bit.

mod common;

use common::{Options, TestServer, ball_json, ball_typed, collect_until_last, zenoh_barrier};
use signorini::proto::v1 as pb;

const STEPS: u64 = 3000;

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn grpc_job_streams_every_step_over_zenoh_bit_for_bit() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("store.db"), &Options::default());
    let session = server.zenoh_session().await;
    let id = "grpc-stream-1";
    let sub = session
        .declare_subscriber(signorini::stream::energy_key(id))
        .await
        .expect("subscribe");
    zenoh_barrier(&session, id).await;

    let mut client = server.grpc().await;
    let req = pb::SubmitJobRequest {
        spec: Some(pb::submit_job_request::Spec::Typed(ball_typed(
            1e-3, STEPS, 1,
        ))),
        id: Some(id.into()),
    };
    let got = client
        .submit_job(req)
        .await
        .expect("SubmitJob")
        .into_inner()
        .id;
    assert_eq!(got, id);

    let streamed = collect_until_last(&sub).await;
    assert!(streamed.frames > 1, "several frames, several steps each");
    // Decimation 1: every step 0..=STEPS, in order, none missing.
    if streamed.steps != (0..=STEPS).collect::<Vec<_>>() {
        let (_, m) = server.http_raw("GET", "/metrics", None, None).await;
        panic!(
            "missing steps ({} of {}); server: {}",
            streamed.steps.len(),
            STEPS + 1,
            String::from_utf8_lossy(&m)
        );
    }
    assert!(
        streamed.columns.iter().any(|c| c == "energy")
            && streamed.columns.iter().any(|c| c == "balance_residual")
    );

    let result = client
        .get_result(pb::GetResultRequest { id: id.into() })
        .await
        .expect("GetResult")
        .into_inner();
    assert_eq!(result.step, streamed.steps);
    assert_eq!(bits(&result.t), bits(&streamed.t));
    for (c, name) in streamed.columns.iter().enumerate() {
        let series = result
            .series
            .iter()
            .find(|s| &s.column == name)
            .expect("column in result");
        let live: Vec<f64> = streamed.rows.iter().map(|r| r[c]).collect();
        assert_eq!(bits(&series.values), bits(&live), "column {name}");
    }
    let summary: serde_json::Value =
        serde_json::from_str(&result.summary_json).expect("summary json");
    assert_eq!(summary["steps"], STEPS);
    drop(sub);
    session.close().await.expect("close zenoh");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn http_job_streams_every_step_over_zenoh_bit_for_bit() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("store.db"), &Options::default());
    let session = server.zenoh_session().await;
    let id = "http-stream-1";
    let sub = session
        .declare_subscriber(signorini::stream::energy_key(id))
        .await
        .expect("subscribe");
    zenoh_barrier(&session, id).await;

    let (code, body) = server
        .http(
            "POST",
            &format!("/v1/jobs?id={id}"),
            Some(&ball_json(1e-3, STEPS, 1)),
            None,
        )
        .await;
    assert_eq!(code, 201, "{body}");
    assert_eq!(body["id"], id);

    let streamed = collect_until_last(&sub).await;
    assert_eq!(streamed.steps, (0..=STEPS).collect::<Vec<_>>());

    let (code, status) = server
        .http("GET", &format!("/v1/jobs/{id}"), None, None)
        .await;
    assert_eq!(code, 200);
    // The status may lag the last frame by a moment: the result call below waits for nothing,
    // so ask until the job says it succeeded (it is written before its final status goes out).
    assert!(
        status.get("progress").is_some() && status["id"] == id,
        "{status}"
    );
    let mut client = server.grpc().await;
    let fin = common::wait_terminal(&mut client, id).await;
    assert_eq!(fin.state, pb::JobState::Succeeded as i32);

    let (code, result) = server
        .http("GET", &format!("/v1/jobs/{id}/result"), None, None)
        .await;
    assert_eq!(code, 200, "{result}");
    let steps = &result["steps"];
    let step: Vec<u64> = serde_json::from_value(steps["step"].clone()).expect("step column");
    assert_eq!(step, streamed.steps);
    let t: Vec<f64> = serde_json::from_value(steps["t"].clone()).expect("t column");
    assert_eq!(bits(&t), bits(&streamed.t));
    for (c, name) in streamed.columns.iter().enumerate() {
        let stored: Vec<f64> =
            serde_json::from_value(steps[name].clone()).expect("column in result");
        let live: Vec<f64> = streamed.rows.iter().map(|r| r[c]).collect();
        assert_eq!(bits(&stored), bits(&live), "column {name}");
    }
    assert_eq!(result["summary"]["steps"], STEPS);
    assert_eq!(result["columns"][0], "step");

    let (code, body) = server.http_raw("GET", "/metrics", None, None).await;
    let text = String::from_utf8_lossy(&body);
    assert_eq!(code, 200);
    assert!(
        text.contains("signorini_jobs{state=\"succeeded\"} 1")
            && text.contains("signorini_queue_depth"),
        "{text}"
    );
    let (code, caps) = server.http("GET", "/v1/capabilities", None, None).await;
    assert_eq!(code, 200);
    assert!(
        caps["models"]
            .as_array()
            .is_some_and(|m| m.iter().any(|m| m["name"] == "bouncing_ball"))
    );
    let (code, page) = server
        .http_raw("GET", &format!("/jobs/{id}"), None, None)
        .await;
    assert_eq!(code, 200);
    assert!(String::from_utf8_lossy(&page).contains("EventSource"));
    drop(sub);
    session.close().await.expect("close zenoh");
}
