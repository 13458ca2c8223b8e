//! Results of any size, in bounded memory (issue 13, part 1), against the real server:
//!
//! - a result spanning many stored chunks comes out of `GET …/result` as CSV (the bytes of
//!   `signorini run`'s `steps.csv`), gzip-compressed CSV, NPZ (parsed here: zip central
//!   directory, `.npy` headers) and JSON, and out of gRPC `StreamResult` in messages under 4 MiB,
//!   every value bit for bit the one `run` wrote; the cuts `columns`, `every`, `from`, `to` keep
//!   exactly the rows a filter over `steps.csv` keeps;
//! - fetching a result several times larger than the bound leaves the server's peak resident
//!   memory (VmHWM) within the bound: nothing holds the whole result;
//! - a cancelled job's recorded rows are served, marked partial; unary `GetResult` still refuses
//!   them.

mod common;

use common::{Options, PATIENCE, TestServer, ball_json, submit_json, wait_running, wait_terminal};
use prost::Message;
use signorini::proto::v1 as pb;
use std::io::Read;
use std::process::Command;

/// `steps.csv` as rows of exact values: (header, rows of (step, [t, values…] as f64 bits)).
fn parse_csv(text: &str) -> (Vec<String>, Vec<(u64, Vec<u64>)>) {
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .expect("a header")
        .split(',')
        .map(str::to_string)
        .collect();
    let rows = lines
        .map(|l| {
            let mut cells = l.split(',');
            let step = cells.next().expect("step").parse().expect("a step number");
            let vals = cells
                .map(|c| c.parse::<f64>().expect("a number").to_bits())
                .collect();
            (step, vals)
        })
        .collect();
    (header, rows)
}

/// The `.npy` arrays of an `.npz`, by name (without `.npy`): (descr, shape, raw data), read
/// through the zip's central directory as numpy does.
fn parse_npz(zip: &[u8]) -> Vec<(String, String, u64, Vec<u8>)> {
    let u16_at = |i: usize| u16::from_le_bytes([zip[i], zip[i + 1]]) as usize;
    let u32_at = |i: usize| u32::from_le_bytes(zip[i..i + 4].try_into().expect("4 bytes")) as u64;
    let eocd = zip.len() - 22;
    assert_eq!(u32_at(eocd), 0x0605_4b50, "end of central directory");
    let entries = u16_at(eocd + 10);
    let mut at = u32_at(eocd + 16) as usize;
    let mut out = Vec::new();
    for _ in 0..entries {
        assert_eq!(u32_at(at), 0x0201_4b50, "central directory entry");
        let crc = u32_at(at + 16) as u32;
        let size = u32_at(at + 24) as usize;
        let name_len = u16_at(at + 28);
        let extra_len = u16_at(at + 30);
        let comment_len = u16_at(at + 32);
        let local = u32_at(at + 42) as usize;
        let name = String::from_utf8(zip[at + 46..at + 46 + name_len].to_vec()).expect("name");
        at += 46 + name_len + extra_len + comment_len;
        assert_eq!(u32_at(local), 0x0403_4b50, "local header of {name}");
        assert_eq!(u16_at(local + 8), 0, "{name} is stored");
        let data_at = local + 30 + u16_at(local + 26) + u16_at(local + 28);
        let data = &zip[data_at..data_at + size];
        let mut c = flate2::Crc::new();
        c.update(data);
        assert_eq!(c.sum(), crc, "crc of {name}");
        assert_eq!(&data[..8], b"\x93NUMPY\x01\x00", "{name}");
        let hlen = u16::from_le_bytes([data[8], data[9]]) as usize;
        let dict = std::str::from_utf8(&data[10..10 + hlen]).expect("npy header");
        let descr = dict
            .split("'descr': '")
            .nth(1)
            .and_then(|r| r.split('\'').next())
            .expect("descr")
            .to_string();
        let shape: u64 = dict
            .split("'shape': (")
            .nth(1)
            .and_then(|r| r.split(',').next())
            .expect("shape")
            .parse()
            .expect("shape number");
        assert_eq!((10 + hlen) % 64, 0, "{name}: aligned data");
        let stem = name.strip_suffix(".npy").expect(".npy").to_string();
        out.push((stem, descr, shape, data[10 + hlen..].to_vec()));
    }
    out
}

fn words(data: &[u8]) -> Vec<u64> {
    data.chunks_exact(8)
        .map(|c| u64::from_le_bytes(c.try_into().expect("8 bytes")))
        .collect()
}

/// The server's peak resident memory so far (kB), from /proc.
fn vm_hwm_kb(pid: u32) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).expect("/proc status");
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .expect("VmHWM")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_result_of_many_chunks_streams_bit_for_bit_in_every_format() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("s.db"), &Options::default());
    let mut client = server.grpc().await;
    // 200 000 recorded rows of 10+ columns: about 20 stored chunks of 1 MiB.
    let spec = ball_json(1e-5, 200_000, 1);
    let id = submit_json(&mut client, spec.clone(), Some("big"))
        .await
        .expect("submit");
    let st = wait_terminal(&mut client, &id).await;
    assert_eq!(st.state, pb::JobState::Succeeded as i32, "{st:?}");

    // The reference: `signorini run` of the same spec.
    let spec_path = dir.path().join("ball.json");
    std::fs::write(&spec_path, &spec).expect("spec file");
    let out = Command::new(env!("CARGO_BIN_EXE_signorini"))
        .arg("run")
        .arg(&spec_path)
        .arg("--out")
        .arg(dir.path().join("run"))
        .output()
        .expect("signorini run");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let reference = std::fs::read(dir.path().join("run/steps.csv")).expect("steps.csv");
    let (header, rows) = parse_csv(std::str::from_utf8(&reference).expect("utf-8"));
    assert_eq!(rows.len(), 200_001);
    let columns = &header[2..];

    // CSV: the very bytes of steps.csv, in a streamed body.
    let (code, head, csv) = server
        .http_get_with(&format!("/v1/jobs/{id}/result?format=csv"), &[])
        .await;
    assert_eq!(code, 200);
    assert_eq!(head["content-type"], "text/csv; charset=utf-8");
    assert_eq!(head["x-signorini-partial"], "false");
    assert_eq!(head["x-signorini-rows"], "200001");
    assert!(
        head.get("content-length").is_none(),
        "streamed, not built: {head:?}"
    );
    assert!(csv == reference, "CSV differs from steps.csv");

    // gzip when asked: the same bytes once inflated.
    let (code, head, gz) = server
        .http_get_with(
            &format!("/v1/jobs/{id}/result?format=csv"),
            &[("accept-encoding", "br;q=1.0, gzip;q=0.8")],
        )
        .await;
    assert_eq!(code, 200);
    assert_eq!(head["content-encoding"], "gzip");
    assert!(gz.len() * 2 < csv.len(), "{} of {}", gz.len(), csv.len());
    let mut inflated = Vec::new();
    flate2::read::GzDecoder::new(&gz[..])
        .read_to_end(&mut inflated)
        .expect("gunzip");
    assert!(inflated == reference, "gzip CSV differs from steps.csv");
    let (_, head, _) = server
        .http_get_with(
            &format!("/v1/jobs/{id}/result?format=csv&columns=energy&every=100000"),
            &[("accept-encoding", "gzip;q=0")],
        )
        .await;
    assert!(
        head.get("content-encoding").is_none(),
        "gzip;q=0 refuses gzip"
    );

    // NPZ: one array per column, bit for bit.
    let (code, head, npz) = server
        .http_get_with(&format!("/v1/jobs/{id}/result?format=npz"), &[])
        .await;
    assert_eq!(code, 200);
    assert_eq!(
        head["content-disposition"],
        format!("attachment; filename=\"{id}.npz\"")
    );
    let arrays = parse_npz(&npz);
    assert_eq!(
        arrays.iter().map(|a| a.0.as_str()).collect::<Vec<_>>(),
        header.iter().map(String::as_str).collect::<Vec<_>>()
    );
    for (k, (name, descr, shape, data)) in arrays.iter().enumerate() {
        assert_eq!(*shape, 200_001, "{name}");
        let got = words(data);
        let want: Vec<u64> = if k == 0 {
            assert_eq!(descr, "<u8");
            rows.iter().map(|r| r.0).collect()
        } else {
            assert_eq!(descr, "<f8");
            rows.iter().map(|r| r.1[k - 1]).collect()
        };
        assert!(got == want, "npz column {name} differs");
    }

    // JSON: the pinned shape, values exact (serde_json reads floats exactly here).
    let (code, json) = server
        .http("GET", &format!("/v1/jobs/{id}/result"), None, None)
        .await;
    assert_eq!(code, 200);
    assert_eq!(json["partial"], false);
    assert_eq!(json["columns"], serde_json::json!(header));
    assert!(json["summary"]["steps"].is_number(), "{}", json["summary"]);
    for (k, name) in header.iter().enumerate().skip(1) {
        let got: Vec<u64> = json["steps"][name]
            .as_array()
            .expect("a column")
            .iter()
            .map(|v| v.as_f64().expect("a number").to_bits())
            .collect();
        let want: Vec<u64> = rows.iter().map(|r| r.1[k - 1]).collect();
        assert!(got == want, "JSON column {name} differs");
    }

    // Cuts while streaming: columns, a step range, every N-th row of it and its last.
    let (code, _, cut) = server
        .http_get_with(
            &format!(
                "/v1/jobs/{id}/result?format=csv&columns=energy&every=7000&from=12345&to=150000"
            ),
            &[],
        )
        .await;
    assert_eq!(code, 200);
    let (cut_header, cut_rows) = parse_csv(std::str::from_utf8(&cut).expect("utf-8"));
    assert_eq!(cut_header, ["step", "t", "energy"]);
    let energy = header.iter().position(|c| c == "energy").expect("energy") - 1;
    let in_range: Vec<&(u64, Vec<u64>)> = rows
        .iter()
        .filter(|r| (12_345..=150_000).contains(&r.0))
        .collect();
    let want: Vec<(u64, Vec<u64>)> = in_range
        .iter()
        .enumerate()
        .filter(|(i, _)| i % 7000 == 0 || i + 1 == in_range.len())
        .map(|(_, r)| (r.0, vec![r.1[0], r.1[energy]]))
        .collect();
    assert_eq!(cut_rows, want);

    // gRPC StreamResult: every message under the default 4 MiB, rows in order, exact.
    let mut stream = common::result_stream(&mut client, &id).await;
    let mut messages = 0;
    let mut got_header = None;
    let mut next_row = 0u64;
    while let Some(msg) = stream.message().await.expect("StreamResult stream") {
        assert!(
            msg.encoded_len() < 4 << 20,
            "a message of {} bytes",
            msg.encoded_len()
        );
        messages += 1;
        match msg.part.expect("a part") {
            pb::result_chunk::Part::Header(h) => {
                assert_eq!(h.rows, 200_001);
                assert!(!h.partial);
                assert_eq!(h.columns, columns);
                got_header = Some(h);
            }
            pb::result_chunk::Part::Figure(_) => {}
            pb::result_chunk::Part::Rows(r) => {
                assert_eq!(r.first_row, next_row);
                let n = columns.len();
                for (i, (&step, &t)) in r.step.iter().zip(&r.t).enumerate() {
                    let want = &rows[(next_row as usize) + i];
                    assert_eq!(step, want.0);
                    assert_eq!(t.to_bits(), want.1[0]);
                    let vals: Vec<u64> = r.values[i * n..(i + 1) * n]
                        .iter()
                        .map(|v| v.to_bits())
                        .collect();
                    assert_eq!(vals, want.1[1..], "row {}", next_row as usize + i);
                }
                next_row += r.step.len() as u64;
            }
        }
    }
    assert!(got_header.is_some());
    assert_eq!(next_row, 200_001);
    assert!(
        messages > 10,
        "{messages} messages: the series comes in chunks"
    );

    // `signorini result ID --out DIR` (through StreamResult) writes steps.csv as `run` did, and
    // `--column/--every` without --out prints the cut as CSV.
    let out_dir = dir.path().join("fetched");
    let out = Command::new(env!("CARGO_BIN_EXE_signorini"))
        .args(["result", &id, "--server", &server.grpc_url, "--out"])
        .arg(&out_dir)
        .output()
        .expect("signorini result");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(std::fs::read(out_dir.join("steps.csv")).expect("steps.csv") == reference);
    let out = Command::new(env!("CARGO_BIN_EXE_signorini"))
        .args(["result", &id, "--server", &server.grpc_url])
        .args(["--column", "energy", "--every", "50000"])
        .output()
        .expect("signorini result --column");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let (h, printed) = parse_csv(std::str::from_utf8(&out.stdout).expect("utf-8"));
    assert_eq!(h, ["step", "t", "energy"]);
    assert_eq!(
        printed.iter().map(|r| r.0).collect::<Vec<_>>(),
        [0, 50_000, 100_000, 150_000, 200_000]
    );
    assert_eq!(printed[1].1[1], rows[50_000].1[energy]);
}

/// A run of 5·10⁶ steps (714 287 recorded rows: every 7th and the last, about 80 MB of values) is fetched whole as CSV,
/// NPZ and through gRPC `StreamResult` while the server's peak resident memory grows by less than
/// 30 MB: the bodies are made from one stored chunk at a time.
#[cfg(target_os = "linux")]
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn fetching_a_large_result_leaves_the_servers_peak_memory_bounded() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("s.db"), &Options::default());
    let mut client = server.grpc().await;
    let id = submit_json(&mut client, ball_json(1e-6, 5_000_000, 7), Some("large"))
        .await
        .expect("submit");
    let st = wait_terminal(&mut client, &id).await;
    assert_eq!(st.state, pb::JobState::Succeeded as i32, "{st:?}");
    let before = vm_hwm_kb(server.pid());
    let (code, head, npz) = server
        .http_get_with(&format!("/v1/jobs/{id}/result?format=npz"), &[])
        .await;
    assert_eq!(code, 200);
    assert_eq!(head["x-signorini-rows"], "714287");
    let arrays = parse_npz(&npz);
    let bytes: usize = arrays.iter().map(|a| a.3.len()).sum();
    assert!(bytes > 60 << 20, "a result of {} MiB", bytes >> 20);
    drop(npz);
    let (code, _, csv) = server
        .http_get_with(&format!("/v1/jobs/{id}/result?format=csv"), &[])
        .await;
    assert_eq!(code, 200);
    let (_, csv_rows) = parse_csv(std::str::from_utf8(&csv).expect("utf-8"));
    assert_eq!(csv_rows.len(), 714_287);
    assert_eq!(csv_rows.last().map(|r| r.0), Some(5_000_000));
    drop((csv, csv_rows));
    let mut stream = common::result_stream(&mut client, &id).await;
    let mut rows = 0;
    while let Some(msg) = stream.message().await.expect("stream") {
        if let Some(pb::result_chunk::Part::Rows(r)) = msg.part {
            rows += r.step.len();
        }
    }
    assert_eq!(rows, 714_287);
    let after = vm_hwm_kb(server.pid());
    assert!(
        after.saturating_sub(before) < 30 << 10,
        "peak RSS grew from {before} kB to {after} kB while serving {} MiB",
        bytes >> 20
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_cancelled_jobs_recorded_rows_are_served_marked_partial() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("s.db"), &Options::default());
    let mut client = server.grpc().await;
    let id = submit_json(&mut client, ball_json(1e-6, 5_000_000, 1), Some("stopped"))
        .await
        .expect("submit");
    // Past the first stored chunks.
    wait_running(&mut client, &id, 50_000).await;
    client
        .cancel_job(pb::CancelJobRequest { id: id.clone() })
        .await
        .expect("cancel");
    let st = wait_terminal(&mut client, &id).await;
    assert_eq!(st.state, pb::JobState::Cancelled as i32);
    let (code, head, csv) = tokio::time::timeout(
        PATIENCE,
        server.http_get_with(&format!("/v1/jobs/{id}/result?format=csv"), &[]),
    )
    .await
    .expect("in time");
    assert_eq!(code, 200);
    assert_eq!(head["x-signorini-partial"], "true");
    let (_, rows) = parse_csv(std::str::from_utf8(&csv).expect("utf-8"));
    assert!(rows.len() >= 50_000, "{} rows", rows.len());
    assert!(
        rows.iter().enumerate().all(|(i, r)| r.0 == i as u64),
        "consecutive steps from 0"
    );
    let (code, json) = server
        .http(
            "GET",
            &format!("/v1/jobs/{id}/result?columns=energy&every=10000"),
            None,
            None,
        )
        .await;
    assert_eq!(code, 200);
    assert_eq!(
        (json["partial"].as_bool(), json["state"].as_str()),
        (Some(true), Some("cancelled"))
    );
    // The one-message call keeps refusing anything but a succeeded job's result.
    let err = client
        .get_result(pb::GetResultRequest {
            id: id.clone(),
            ..Default::default()
        })
        .await
        .expect_err("no unary result");
    assert_eq!(err.code(), tonic::Code::FailedPrecondition);
}
