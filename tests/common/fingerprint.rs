//! A job's result as values that tell every f64 apart, for bit-for-bit comparisons of runs
//! (resumed, paused, extended) against an uninterrupted one.

use signorini::proto::v1 as pb;
use signorini::proto::v1::simulation_client::SimulationClient;
use tonic::transport::Channel;

/// A result's summary (without the wall time, rate and CPU seconds), times, series (as bits) and figures.
pub type Fingerprint = (String, Vec<u64>, Vec<(String, Vec<u64>)>, Vec<String>);

/// The result as values that tell every f64 apart, without the wall time, rate and CPU seconds and the
/// summary keys in `drop` (e.g. `extends`).
pub fn fingerprint_without(r: &pb::JobResult, drop: &[&str]) -> Fingerprint {
    let mut summary: serde_json::Map<String, serde_json::Value> =
        serde_json::from_str(&r.summary_json).expect("summary");
    for key in ["wall_s", "steps_per_s", "cpu_s"].iter().chain(drop) {
        summary.remove(*key);
    }
    (
        serde_json::to_string(&summary).expect("summary"),
        r.t.iter().map(|x| x.to_bits()).collect(),
        r.series
            .iter()
            .map(|s| {
                (
                    s.column.clone(),
                    s.values.iter().map(|v| v.to_bits()).collect(),
                )
            })
            .collect(),
        r.figures.iter().map(|f| f.svg.clone()).collect(),
    )
}

/// [`fingerprint_without`] dropping no other key.
pub fn fingerprint(r: &pb::JobResult) -> Fingerprint {
    fingerprint_without(r, &[])
}

/// A job's whole result over gRPC `GetResult`.
pub async fn result(client: &mut SimulationClient<Channel>, id: &str) -> pb::JobResult {
    client
        .get_result(pb::GetResultRequest {
            id: id.to_string(),
            ..Default::default()
        })
        .await
        .expect("result")
        .into_inner()
}

/// A result cut to its rows after step `n` (the rows an extension from step `n` records), the
/// summary, tables and figures unchanged.
pub fn rows_after(r: &pb::JobResult, n: u64) -> pb::JobResult {
    let after = r
        .step
        .iter()
        .position(|&k| k > n)
        .expect("rows after the step");
    pb::JobResult {
        step: r.step[after..].to_vec(),
        t: r.t[after..].to_vec(),
        series: r
            .series
            .iter()
            .map(|s| pb::Series {
                column: s.column.clone(),
                values: s.values[after..].to_vec(),
            })
            .collect(),
        ..r.clone()
    }
}
