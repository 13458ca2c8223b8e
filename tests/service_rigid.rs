//! A `rigid_bodies` job through the service, as every other model (issue 29, items 4
//! and 6):
//!
//! - submitted over HTTP and over gRPC (JSON spec), its result equals `signorini run`'s
//!   `steps.csv` and `contacts.csv` bit for bit;
//! - paused mid-run and resumed, it equals an uninterrupted run bit for bit;
//! - a study over `time.h` and `model.contact.friction` runs it as child jobs against a fine run;
//! - its live page shows the bodies in 3D (WebGL) in a real headless Chromium, running and
//!   finished, at poses equal to the stored ones of the step it shows.

mod common;

use common::browser::Browser;
use common::fingerprint::{fingerprint, result};
use common::{Options, PATIENCE, TestServer, submit_json, wait_running, wait_terminal};
use serde_json::{Value, json};
use signorini::proto::v1 as pb;
use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

/// A box thrown spinning onto a floor next to a ball: impacts, sliding, rolling, four-corner
/// contacts; `steps` steps of 1 ms recorded every `every`-th.
fn box_and_ball(steps: u64, every: u64, contacts: bool) -> Value {
    json!({
        "name": "box and ball",
        "model": {
            "scene": "rigid_bodies",
            "contact": { "friction": 0.4, "restitution": 0.3, "margin": 1e-6 },
            "bodies": [
                { "name": "cube", "shape": { "kind": "box", "half_extents": [0.1, 0.1, 0.1] },
                  "density": 500.0, "position": [0.0, 0.0, 0.3],
                  "velocity": [1.0, 0.2, 0.0], "angular_velocity": [0.5, 1.0, 3.0] },
                { "name": "ball", "shape": { "kind": "sphere", "radius": 0.1 }, "density": 800.0,
                  "position": [0.5, 0.0, 0.1], "velocity": [-1.0, 0.0, 0.0] },
                { "name": "floor", "shape": { "kind": "half_space", "normal": [0.0, 0.0, 1.0] } }
            ]
        },
        "integrator": { "scheme": "moreau_jean" },
        "time": { "h": 1e-3, "steps": steps },
        "output": { "every": every, "contacts": contacts }
    })
}

/// A CSV file of numbers as columns of bits.
fn csv_bits(path: &Path) -> BTreeMap<String, Vec<u64>> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .expect("a header")
        .split(',')
        .map(str::to_string)
        .collect();
    let mut cols: Vec<Vec<u64>> = vec![Vec::new(); header.len()];
    for line in lines {
        for (i, v) in line.split(',').enumerate() {
            cols[i].push(v.parse::<f64>().expect("a number").to_bits());
        }
    }
    header.into_iter().zip(cols).collect()
}

/// A gRPC result's series (with `step` and `t`) as columns of bits.
fn result_bits(r: &pb::JobResult) -> BTreeMap<String, Vec<u64>> {
    let mut cols: BTreeMap<String, Vec<u64>> = r
        .series
        .iter()
        .map(|s| {
            (
                s.column.clone(),
                s.values.iter().map(|v| v.to_bits()).collect(),
            )
        })
        .collect();
    cols.insert(
        "step".into(),
        r.step.iter().map(|&k| (k as f64).to_bits()).collect(),
    );
    cols.insert("t".into(), r.t.iter().map(|x| x.to_bits()).collect());
    cols
}

/// A result table as columns of bits.
fn table_bits(t: &pb::Table) -> BTreeMap<String, Vec<u64>> {
    t.columns
        .iter()
        .enumerate()
        .map(|(i, c)| {
            (
                c.clone(),
                t.rows.iter().map(|r| r.values[i].to_bits()).collect(),
            )
        })
        .collect()
}

/// `signorini run SPEC --out DIR` of a JSON spec.
fn cli_run(spec: &Value, dir: &Path) {
    let file = dir.join("spec.json");
    std::fs::write(&file, spec.to_string()).expect("writing the spec");
    let out = Command::new(env!("CARGO_BIN_EXE_signorini"))
        .args(["run", &file.display().to_string(), "--quiet", "--out"])
        .arg(dir.join("out"))
        .output()
        .expect("signorini run");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Polls a job's HTTP status until `done` holds.
async fn poll_until(server: &TestServer, id: &str, done: impl Fn(&Value) -> bool) -> Value {
    let started = Instant::now();
    loop {
        let (code, s) = server
            .http("GET", &format!("/v1/jobs/{id}"), None, None)
            .await;
        assert_eq!(code, 200, "{s}");
        if done(&s) {
            return s;
        }
        assert!(started.elapsed() < PATIENCE, "waiting for {id}: {s}");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_rigid_job_over_http_and_grpc_equals_the_cli_and_pauses_bit_for_bit() {
    let dir = tempfile::tempdir().expect("tempdir");
    let spec = box_and_ball(600, 7, true);
    cli_run(&spec, dir.path());
    let steps = csv_bits(&dir.path().join("out/steps.csv"));
    let contacts = csv_bits(&dir.path().join("out/contacts.csv"));
    assert!(contacts["p_n"].len() > 100, "contacts.csv has few rows");

    let server = TestServer::start(&dir.path().join("s.db"), &Options::default());
    let mut client = server.grpc().await;
    let (code, body) = server
        .http(
            "POST",
            "/v1/jobs?id=rigid-http",
            Some(&spec.to_string()),
            None,
        )
        .await;
    assert_eq!(code, 201, "{body}");
    let grpc = submit_json(&mut client, spec.to_string(), Some("rigid-grpc"))
        .await
        .expect("gRPC submit");
    for id in ["rigid-http", grpc.as_str()] {
        let s = wait_terminal(&mut client, id).await;
        assert_eq!(s.state, pb::JobState::Succeeded as i32, "{s:?}");
        let r = result(&mut client, id).await;
        assert_eq!(result_bits(&r), steps, "{id}: steps ≠ the CLI's steps.csv");
        let table = r
            .tables
            .iter()
            .find(|t| t.name == "contacts")
            .expect("a contacts table");
        assert_eq!(
            table_bits(table),
            contacts,
            "{id}: ≠ the CLI's contacts.csv"
        );
    }
    // The HTTP result has the same columns (and the table, by name).
    let (code, body) = server
        .http(
            "GET",
            "/v1/jobs/rigid-http/result?columns=cube_z",
            None,
            None,
        )
        .await;
    assert_eq!(code, 200, "{body}");
    let z: Vec<u64> = body["steps"]["cube_z"]
        .as_array()
        .expect("cube_z")
        .iter()
        .map(|v| v.as_f64().expect("a number").to_bits())
        .collect();
    assert_eq!(z, steps["cube_z"]);

    // Paused at a tenth and resumed: the same result as an uninterrupted run, bit for bit.
    let long = box_and_ball(20_000, 50, false).to_string();
    for id in ["rigid-paused", "rigid-whole"] {
        let (code, body) = server
            .http("POST", &format!("/v1/jobs?id={id}"), Some(&long), None)
            .await;
        assert_eq!(code, 201, "{body}");
    }
    poll_until(&server, "rigid-paused", |s| {
        s["state"] == "running" && s["progress"]["step"].as_u64().unwrap_or(0) >= 2_000
    })
    .await;
    let (code, body) = server
        .http("POST", "/v1/jobs/rigid-paused/pause", None, None)
        .await;
    assert_eq!(code, 200, "{body}");
    let paused = poll_until(&server, "rigid-paused", |s| s["state"] != "running").await;
    assert_eq!(paused["state"], "paused", "{paused}");
    let at = paused["progress"]["step"].as_u64().expect("step");
    assert!(at > 0 && at < 20_000, "{paused}");
    let (code, body) = server
        .http("POST", "/v1/jobs/rigid-paused/resume", None, None)
        .await;
    assert_eq!(code, 200, "{body}");
    for id in ["rigid-paused", "rigid-whole"] {
        let s = wait_terminal(&mut client, id).await;
        assert_eq!(s.state, pb::JobState::Succeeded as i32, "{id}: {s:?}");
    }
    let (a, b) = (
        result(&mut client, "rigid-paused").await,
        result(&mut client, "rigid-whole").await,
    );
    assert_eq!(a.step.len(), 20_000 / 50 + 1);
    assert_eq!(fingerprint(&a), fingerprint(&b), "paused at step {at}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_study_over_h_and_friction_runs_rigid_jobs_against_a_fine_run() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("s.db"), &Options::default());
    // A ball thrown sliding on a rough floor (no impact): it slides with deceleration μ g, then
    // rolls from t* = 2 v₀ / (7 μ g) on (0.29 s for μ = 0.2, 0.10 s for μ = 0.6).
    let base = json!({
        "model": {
            "scene": "rigid_bodies",
            "contact": { "friction": 0.2, "restitution": 0.0, "margin": 1e-6 },
            "bodies": [
                { "name": "ball", "shape": { "kind": "sphere", "radius": 0.1 }, "density": 1000.0,
                  "position": [0.0, 0.0, 0.1], "velocity": [2.0, 0.0, 0.0] },
                { "name": "floor", "shape": { "kind": "half_space", "normal": [0.0, 0.0, 1.0] } }
            ]
        },
        "integrator": { "scheme": "moreau_jean" },
        "time": { "h": 2e-3, "t_end": 0.5 },
        "output": { "every": 10 }
    });
    let study = json!({
        "name": "rigid study",
        "study": {
            "base": base,
            "reference": { "scheme": "moreau_jean", "h": 2.5e-4 },
            "error": "max_abs",
            "schemes": [{ "scheme": "moreau_jean", "theta": 0.5 }],
            "grid": { "time.h": [2e-3, 1e-3], "model.contact.friction": [0.2, 0.6] }
        }
    });
    let (code, body) = server
        .http(
            "POST",
            "/v1/jobs?id=rigid-study",
            Some(&study.to_string()),
            None,
        )
        .await;
    assert_eq!(code, 201, "{body}");
    let mut client = server.grpc().await;
    let s = wait_terminal(&mut client, "rigid-study").await;
    assert_eq!(s.state, pb::JobState::Succeeded as i32, "{s:?}");
    let r = result(&mut client, "rigid-study").await;
    let table = r
        .tables
        .iter()
        .find(|t| t.name == "study")
        .expect("the study table");
    assert_eq!(
        table.rows.len(),
        4,
        "2 step sizes × 2 friction coefficients"
    );
    let error = table
        .columns
        .iter()
        .position(|c| c == "error")
        .expect("an error column");
    let h = table
        .columns
        .iter()
        .position(|c| c == "time.h")
        .expect("a time.h column");
    let mu = table
        .columns
        .iter()
        .position(|c| c == "model.contact.friction")
        .expect("a model.contact.friction column");
    let row = |hv: f64, m: f64| {
        table
            .rows
            .iter()
            .find(|r| r.values[h] == hv && r.values[mu] == m)
            .unwrap_or_else(|| panic!("no run h = {hv}, μ = {m}"))
            .values[error]
    };
    // The ball's position is compared with the fine run, one run of the base (μ = 0.2). Both
    // phases have constant acceleration, which θ = ½ integrates exactly; only the step of the
    // switch to rolling is off, by at most one step: a velocity error ≤ μ g h (the jump of the
    // acceleration), hence a position error ≤ μ g (h + h_ref) t_end. With μ = 0.6 the error is
    // the distance between the two balls: x(t) = (5/7) v₀ t + (1/7) v₀ t* once rolling, so
    // (1/7) v₀ (t*(0.2) − t*(0.6)) after both roll.
    let (g, v0, t_end, h_ref) = (9.81, 2.0, 0.5, 2.5e-4);
    let bound = |m: f64, hv: f64| m * g * (hv + h_ref) * t_end;
    let t_star = |m: f64| 2.0 * v0 / (7.0 * m * g);
    let apart = v0 / 7.0 * (t_star(0.2) - t_star(0.6));
    for hv in [2e-3, 1e-3] {
        let e = row(hv, 0.2);
        assert!(
            e > 0.0 && e <= bound(0.2, hv),
            "μ = 0.2, h = {hv}: error {e}"
        );
        let e = row(hv, 0.6);
        assert!(
            (e - apart).abs() <= bound(0.2, hv) + bound(0.6, hv),
            "μ = 0.6, h = {hv}: error {e}, the balls are {apart} apart"
        );
    }
}

/// What the live page's 3D view shows: (bodies, step, poses, drawn pixels).
fn view(b: &mut Browser) -> (u64, u64, Vec<Vec<f64>>, u64) {
    let d = b.eval(
        "(() => { const d = document.getElementById('scene3d').dataset; \
           return [d.bodies, d.step, d.poses, d.drawn]; })()",
    );
    let num = |v: &Value| {
        v.as_str()
            .and_then(|s| s.parse::<u64>().ok())
            .unwrap_or_else(|| panic!("{d}"))
    };
    let poses: Vec<Vec<f64>> = serde_json::from_str(d[2].as_str().expect("poses")).expect("JSON");
    (num(&d[0]), num(&d[1]), poses, num(&d[3]))
}

/// The stored poses of every body at `step` ([x, y, z, qw, qx, qy, qz] each).
async fn stored_poses(server: &TestServer, id: &str, step: u64) -> Vec<Vec<f64>> {
    let names = ["cube", "ball", "floor"];
    let cols: Vec<String> = names
        .iter()
        .flat_map(|n| ["x", "y", "z", "qw", "qx", "qy", "qz"].map(|c| format!("{n}_{c}")))
        .collect();
    let (code, body) = server
        .http(
            "GET",
            &format!(
                "/v1/jobs/{id}/result?columns={}&from={step}&to={step}",
                cols.join(",")
            ),
            None,
            None,
        )
        .await;
    assert_eq!(code, 200, "{body}");
    names
        .iter()
        .enumerate()
        .map(|(b, _)| {
            (0..7)
                .map(|k| {
                    body["steps"][&cols[7 * b + k]][0]
                        .as_f64()
                        .expect("a value")
                })
                .collect()
        })
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_rigid_jobs_page_draws_the_bodies_in_3d_at_the_streamed_poses() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("s.db"), &Options::default());
    let mut client = server.grpc().await;
    let done = submit_json(
        &mut client,
        box_and_ball(300, 10, false).to_string(),
        Some("rigid-done"),
    )
    .await
    .expect("submit");
    let st = wait_terminal(&mut client, &done).await;
    assert_eq!(st.state, pb::JobState::Succeeded as i32, "{st:?}");
    // Long enough to stay running while the page watches; cancelled, it keeps its rows.
    let running = submit_json(
        &mut client,
        box_and_ball(5_000_000, 100, false).to_string(),
        Some("rigid-running"),
    )
    .await
    .expect("submit");
    wait_running(&mut client, &running, 100).await;

    // The scene: three bodies with their surfaces; another job has none.
    let (code, scene) = server
        .http("GET", "/v1/jobs/rigid-done/scene", None, None)
        .await;
    assert_eq!(code, 200, "{scene}");
    let points: Vec<usize> = scene["bodies"]
        .as_array()
        .expect("bodies")
        .iter()
        .map(|b| b["points"].as_array().expect("points").len())
        .collect();
    assert_eq!(points, [8, 2 + 11 * 24, 4]);
    let half_spaces: Vec<&Value> = scene["bodies"]
        .as_array()
        .expect("bodies")
        .iter()
        .map(|b| &b["half_space"])
        .collect();
    assert_eq!(half_spaces, [false, false, true]);

    let mut b = Browser::launch();
    let base = format!("http://{}", server.http);
    b.open(&format!("{base}/jobs/{running}"));
    b.wait_for(
        "a 3D view drawn from the stream",
        "+document.getElementById('scene3d').dataset.drawn > 2000 \
         && +document.getElementById('scene3d').dataset.step > 0",
    );
    let (bodies, step, poses, drawn) = view(&mut b);
    assert_eq!(bodies, 3);
    assert!(drawn > 2000 && drawn < 640 * 400, "{drawn} pixels");
    // The view follows the stream.
    b.wait_for(
        "a later step",
        &format!("+document.getElementById('scene3d').dataset.step > {step}"),
    );
    client
        .cancel_job(pb::CancelJobRequest {
            id: running.clone(),
        })
        .await
        .expect("cancel");
    wait_terminal(&mut client, &running).await;
    // The streamed poses were the stored ones of that step, bit for bit.
    assert_eq!(poses, stored_poses(&server, &running, step).await);

    b.open(&format!("{base}/jobs/{done}"));
    b.wait_for(
        "the finished job's last step",
        "+document.getElementById('scene3d').dataset.step === 300",
    );
    let (bodies, step, poses, drawn) = view(&mut b);
    assert_eq!((bodies, step), (3, 300));
    assert!(drawn > 2000, "{drawn} pixels");
    assert_eq!(poses, stored_poses(&server, &done, 300).await);
    // The energy plot is still there, beside the 3D view.
    b.wait_for(
        "the energy plot",
        "+document.getElementById('energy').dataset.points > 10",
    );
    // A ball in a box of five half-spaces: the camera, outside the box, sees the ball through
    // the walls between them, which are drawn only from inside.
    let mut boxed = box_and_ball(10, 10, false);
    let walls = [
        ("xm", [1.0, 0.0, 0.0]),
        ("xp", [-1.0, 0.0, 0.0]),
        ("ym", [0.0, 1.0, 0.0]),
        ("yp", [0.0, -1.0, 0.0]),
    ];
    let bodies = boxed["model"]["bodies"].as_array_mut().expect("bodies");
    for (name, normal) in walls {
        bodies.push(json!({
            "name": format!("wall_{name}"),
            "shape": { "kind": "half_space", "normal": normal },
            "position": normal.map(|x| -0.8 * x)
        }));
    }
    let (code, body) = server
        .http("POST", "/v1/jobs?id=boxed", Some(&boxed.to_string()), None)
        .await;
    assert_eq!(code, 201, "{body}");
    wait_terminal(&mut client, "boxed").await;
    b.open(&format!("{base}/jobs/boxed"));
    b.wait_for(
        "the boxed job's last step",
        "+document.getElementById('scene3d').dataset.step === 10",
    );
    let coloured = b.eval("+document.getElementById('scene3d').dataset.coloured");
    assert!(
        coloured.as_u64().is_some_and(|n| n > 2000),
        "{coloured} pixels of the free bodies in the box"
    );
    // A job of another model has no 3D view.
    let (code, body) = server
        .http(
            "POST",
            "/v1/jobs?id=ball",
            Some(&common::ball_json(1e-3, 100, 1)),
            None,
        )
        .await;
    assert_eq!(code, 201, "{body}");
    let (code, body) = server.http("GET", "/v1/jobs/ball/scene", None, None).await;
    assert_eq!(code, 400, "{body}");
    assert_eq!(body["error"]["field"], "model.scene");
    b.open(&format!("{base}/jobs/ball"));
    b.wait_for(
        "the ball's energy plot",
        "+document.getElementById('energy').dataset.points > 10",
    );
    assert_eq!(
        b.eval("document.getElementById('scene3d-panel').hidden"),
        Value::Bool(true)
    );
}
