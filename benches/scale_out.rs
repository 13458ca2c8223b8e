//! Scale-out benchmark (harness = false): throughput of many small jobs through real `signorini
//! serve` processes, on SQLite and on a private PostgreSQL server (tests/common/pg.rs).
//!
//!   cargo bench --bench scale_out      # 500 jobs; SIGNORINI_BENCH_JOBS=N, SIGNORINI_BENCH_STEPS=S
//!
//! Each job is a bouncing ball of S steps (10⁴ by default, every 100th recorded). Configurations:
//! SQLite with 1 replica × 2 workers, PostgreSQL with 1 replica × 2 workers, PostgreSQL with
//! 2 replicas × 1 worker (the jobs all submitted to the first replica). For each: jobs/s from the
//! first submission to the last job's end, the mean busy time of a job (claim to stored end,
//! from its `started_ms`/`finished_ms`), the overhead per job outside runs
//! (workers × elapsed / jobs − busy), with PostgreSQL the median gap between a replica's job
//! end and its next claim (the claim overhead; one worker per replica makes it exact), and the
//! CPU time per job of the machine, split into the servers, this benchmark and the rest (the
//! PostgreSQL server on an otherwise idle machine). The end is awaited with two one-row pages
//! (`state=queued`, `state=running`), so that waiting costs the servers and the store little.

#[path = "../tests/common/mod.rs"]
mod common;

use common::pg::Postgres;
use common::{Options, TestServer, ball_json, submit_json};
use std::path::Path;
use std::time::{Duration, Instant};

struct Figures {
    label: &'static str,
    jobs_per_s: f64,
    submit_per_s: f64,
    busy_ms: f64,
    overhead_ms: f64,
    claim_gap_ms: Option<f64>,
    /// CPU ms per job: the machine, the servers, the benchmark, the rest (PostgreSQL).
    cpu_ms: [f64; 4],
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Submits `jobs` jobs to `servers[0]`, waits for all to succeed (listing from the last server),
/// and measures.
async fn measure(
    label: &'static str,
    servers: &[TestServer],
    workers: usize,
    jobs: usize,
    steps: u64,
) -> Figures {
    let mut client = servers[0].grpc().await;
    let spec = ball_json(1e-4, steps, 100);
    let cpu = CpuTicks::now(servers);
    let started = Instant::now();
    for k in 0..jobs {
        submit_json(&mut client, spec.clone(), Some(&format!("b{k:05}")))
            .await
            .expect("submit");
    }
    let submitted = started.elapsed();
    let reader = servers.last().expect("a server");
    // Until no job is queued or running (two one-row pages), then the whole list once: the
    // wait itself costs the servers and the store little.
    loop {
        let mut pending = false;
        for state in ["queued", "running"] {
            let (status, body) = reader
                .http(
                    "GET",
                    &format!("/v1/jobs?state={state}&limit=1"),
                    None,
                    None,
                )
                .await;
            assert_eq!(status, 200, "{body}");
            pending |= body["jobs"].as_array().is_some_and(|j| !j.is_empty());
        }
        if !pending {
            break;
        }
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    let elapsed = started.elapsed().as_secs_f64();
    let cpu = cpu.since(servers);
    let listed = loop {
        let mut done = Vec::new();
        let mut token = String::new();
        loop {
            let (status, body) = reader
                .http(
                    "GET",
                    &format!("/v1/jobs?state=succeeded&limit=1000&page_token={token}"),
                    None,
                    None,
                )
                .await;
            assert_eq!(status, 200, "{body}");
            done.extend(body["jobs"].as_array().cloned().unwrap_or_default());
            match body["next_page_token"].as_str() {
                Some(t) => token = t.to_string(),
                None => break,
            }
        }
        if done.len() >= jobs {
            break done;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    };
    let ms = |j: &serde_json::Value, k: &str| j[k].as_f64().expect("a time");
    let busy: Vec<f64> = listed
        .iter()
        .map(|j| ms(j, "finished_ms") - ms(j, "started_ms"))
        .collect();
    let mean_busy = busy.iter().sum::<f64>() / busy.len() as f64;
    Figures {
        label,
        jobs_per_s: jobs as f64 / elapsed,
        submit_per_s: jobs as f64 / submitted.as_secs_f64(),
        busy_ms: mean_busy,
        overhead_ms: workers as f64 * elapsed * 1e3 / jobs as f64 - mean_busy,
        claim_gap_ms: None,
        cpu_ms: cpu.map(|t| t / jobs as f64 * 1e3 / TICKS_PER_S),
    }
}

/// Clock ticks per second of `/proc` CPU times (USER_HZ, 100 on Linux).
const TICKS_PER_S: f64 = 100.0;

/// CPU time so far, in clock ticks: the whole machine's busy time (`/proc/stat`), the servers'
/// processes and this benchmark's own (`/proc/PID/stat`, user + system).
#[derive(Clone, Copy)]
struct CpuTicks {
    machine: f64,
    servers: f64,
    bench: f64,
}

impl CpuTicks {
    fn now(servers: &[TestServer]) -> CpuTicks {
        let stat = std::fs::read_to_string("/proc/stat").expect("/proc/stat");
        let ticks: Vec<f64> = stat
            .lines()
            .next()
            .expect("the cpu line")
            .split_whitespace()
            .skip(1)
            .map(|x| x.parse().expect("a tick count"))
            .collect();
        // user nice system idle iowait irq softirq steal …: busy is all but idle and iowait.
        let machine = ticks.iter().take(8).sum::<f64>() - ticks[3] - ticks[4];
        CpuTicks {
            machine,
            servers: servers
                .iter()
                .map(|s| process_ticks(&s.pid().to_string()))
                .sum(),
            bench: process_ticks("self"),
        }
    }

    /// The CPU used since `self`, split as [machine, servers, bench, the rest] (the rest is the
    /// PostgreSQL server's processes on an otherwise idle machine).
    fn since(self, servers: &[TestServer]) -> [f64; 4] {
        let now = CpuTicks::now(servers);
        let (machine, servers, bench) = (
            now.machine - self.machine,
            now.servers - self.servers,
            now.bench - self.bench,
        );
        [machine, servers, bench, machine - servers - bench]
    }
}

/// User + system clock ticks of process `pid` (`self` for this one).
fn process_ticks(pid: &str) -> f64 {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).expect("/proc/PID/stat");
    let fields: Vec<&str> = stat
        .rsplit_once(')')
        .expect("comm")
        .1
        .split_whitespace()
        .collect();
    // After the command: state (field 3) … utime (14) and stime (15).
    fields[11].parse::<f64>().expect("utime") + fields[12].parse::<f64>().expect("stime")
}

/// Median gap between one replica's job end and its next claim (PostgreSQL, one worker per
/// replica).
fn claim_gap(pg: &Postgres, db: &str) -> f64 {
    let rows = pg.psql(
        db,
        "SELECT started_ms - lag(finished_ms) OVER (PARTITION BY owner ORDER BY started_ms) FROM jobs",
    );
    median(rows.lines().filter_map(|l| l.parse::<f64>().ok()).collect())
}

/// The queue's own cost in one PostgreSQL: a job queued, claimed (the service's claim statement)
/// and ended, three autocommit statements per transaction, by 4 clients for 5 s (pgbench):
/// transactions (jobs) per second.
fn queue_ops_per_s(pg: &Postgres, db: &str) -> f64 {
    let script = pg.dir().join("claim.sql");
    std::fs::write(
        &script,
        "\\set n random(1, 1000000000)
INSERT INTO jobs (id, spec_json, state, created_ms) VALUES ('p' || :n || '-' || :client_id, '{}', 'queued', 0) ON CONFLICT DO NOTHING;
WITH next AS (SELECT id FROM jobs WHERE state = 'queued' OR (state = 'running' AND lease_until < now()) ORDER BY seq LIMIT 1 FOR UPDATE SKIP LOCKED) UPDATE jobs j SET state = 'running', owner = 'bench-' || :client_id, attempt = j.attempt + 1, lease_until = now() + make_interval(secs => 10) FROM next WHERE j.id = next.id;
UPDATE jobs SET state = 'succeeded', lease_until = NULL WHERE owner = 'bench-' || :client_id AND state = 'running';
",
    )
    .expect("writing the pgbench script");
    let script = script.display().to_string();
    let out = pg.pgbench(db, &["-n", "-c", "4", "-j", "2", "-T", "5", "-f", &script]);
    out.lines()
        .find_map(|l| {
            l.strip_prefix("tps = ")
                .and_then(|r| r.split_whitespace().next())
                .and_then(|x| x.parse().ok())
        })
        .unwrap_or(f64::NAN)
}

fn main() {
    let jobs: usize = std::env::var("SIGNORINI_BENCH_JOBS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(500);
    let steps: u64 = std::env::var("SIGNORINI_BENCH_STEPS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(10_000);
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("tokio");
    let opts = |workers| Options {
        workers,
        queue_limit: jobs + 1,
        ..Options::default()
    };
    let figures = runtime.block_on(async {
        let mut out = Vec::new();
        let dir = tempfile::tempdir().expect("tempdir");
        {
            let server = TestServer::start(&dir.path().join("bench.db"), &opts(2));
            out.push(measure("SQLite, 1 replica × 2 workers", &[server], 2, jobs, steps).await);
        }
        let pg = Postgres::start();
        {
            let url = pg.create_database("one");
            let server = TestServer::start_with(Path::new(&url), &opts(2), &["--replica", "a"]);
            out.push(
                measure(
                    "PostgreSQL, 1 replica × 2 workers",
                    &[server],
                    2,
                    jobs,
                    steps,
                )
                .await,
            );
        }
        {
            let url = pg.create_database("two");
            let a = TestServer::start_with(Path::new(&url), &opts(1), &["--replica", "a"]);
            let b = TestServer::start_with(Path::new(&url), &opts(1), &["--replica", "b"]);
            let mut f = measure("PostgreSQL, 2 replicas × 1 worker", &[a, b], 2, jobs, steps).await;
            f.claim_gap_ms = Some(claim_gap(&pg, "two"));
            out.push(f);
        }
        (out, queue_ops_per_s(&pg, "two"))
    });
    let (figures, queue_ops) = figures;
    println!("{jobs} jobs: bouncing_ball, h = 1e-4, {steps} steps, every 100th recorded");
    println!(
        "{:<36} {:>9} {:>11} {:>10} {:>13} {:>14}",
        "configuration", "jobs/s", "submits/s", "busy ms", "overhead ms", "claim gap ms"
    );
    for f in &figures {
        println!(
            "{:<36} {:>9.1} {:>11.1} {:>10.2} {:>13.2} {:>14}",
            f.label,
            f.jobs_per_s,
            f.submit_per_s,
            f.busy_ms,
            f.overhead_ms,
            f.claim_gap_ms
                .map_or_else(|| "-".to_string(), |g| format!("{g:.1}"))
        );
    }
    let sqlite = figures[0].jobs_per_s;
    for f in &figures[1..] {
        println!(
            "{}: {:+.1} % throughput against SQLite",
            f.label,
            100.0 * (f.jobs_per_s / sqlite - 1.0)
        );
    }
    println!("CPU ms per job: machine = servers + bench client + the rest (PostgreSQL)");
    for f in &figures {
        let [machine, servers, bench, rest] = f.cpu_ms;
        println!(
            "{:<36} {machine:>6.2} = {servers:.2} + {bench:.2} + {rest:.2}",
            f.label
        );
    }
    println!(
        "one PostgreSQL alone (pgbench, 4 clients): {queue_ops:.0} jobs/s queued + claimed + ended"
    );
}
