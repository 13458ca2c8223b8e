//! Cross-check of our Moreau–Jean θ-scheme against Siconos, the field's reference code
//! (the whole story is in `docs/siconos.md`).
//!
//! The fixtures in `tests/fixtures/siconos/` were written by `scripts/siconos/reference.py`
//! with Siconos (`python3-siconos` 4.4.0+dfsg-2, Python module version 4.5.0):
//! `<scene>.csv` has one row per step (`step, t, q_j…, v_j…, p_0`, row 0 the initial state) and
//! `<scene>.json` the Signorini job spec of the same run plus how the Siconos model was built.
//! CI has no Siconos; this test needs only the committed files.
//!
//! With `activation = "predicted_gap"` and Siconos' γ (`g(q_k) + γ h U_k ≤ 0`, no test on the
//! sign of U_k) both codes compute the same scheme, (21a)–(21d) of Acary 2016 with one θ for the
//! force average and the position update, so the states agree to round-off at every step:
//! [`TOLERANCE`] is relative to each column's largest magnitude over the run.
//!
//! With our default index set (24) (`g(q_k + h v_k) ≤ 0 and U_k ≤ 0`) the runs agree until the
//! first step where the two rules pick different contacts, and then differ by O(h) — see
//! [`default_index_set_differs_as_documented`] and `docs/siconos.md`.

// Only the core library must stay pure (clippy.toml): a test may read fixtures and print.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use serde_json::Value;
use signorini_core::contact::Activation;
use signorini_core::job::{Job, run};
use signorini_core::observer::Recorder;
use signorini_core::spec::{IntegratorSpec, JobSpec};
use std::path::PathBuf;

/// Largest accepted |ours − Siconos| / max_k |Siconos column|, per column (q_j, v_j, p_0).
const TOLERANCE: f64 = 1e-10;

/// A Siconos reference run: its spec and its rows.
struct Fixture {
    name: &'static str,
    spec: JobSpec,
    columns: Vec<String>,
    rows: Vec<Vec<f64>>,
}

fn fixture_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/siconos")
}

fn load(name: &'static str) -> Fixture {
    let dir = fixture_dir();
    let sidecar: Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join(format!("{name}.json"))).expect("sidecar"),
    )
    .expect("json");
    let spec: JobSpec =
        serde_json::from_value(sidecar["spec"].clone()).expect("the sidecar's spec is a JobSpec");
    let text = std::fs::read_to_string(dir.join(format!("{name}.csv"))).expect("csv");
    let mut lines = text.lines();
    let columns: Vec<String> = lines
        .next()
        .expect("header")
        .split(',')
        .map(str::to_owned)
        .collect();
    let rows: Vec<Vec<f64>> = lines
        .filter(|l| !l.is_empty())
        .map(|l| {
            l.split(',')
                .map(|x| x.parse::<f64>().expect("number"))
                .collect()
        })
        .collect();
    assert!(
        rows.iter().all(|r| r.len() == columns.len()),
        "{name}: ragged csv"
    );
    Fixture {
        name,
        spec,
        columns,
        rows,
    }
}

/// Runs `spec` and returns the recorder.
fn run_spec(spec: &JobSpec) -> Recorder {
    let job = Job::from_spec(spec).expect("valid spec");
    let mut rec = Recorder::default();
    run(&job, 1, &mut rec).expect("run");
    rec
}

/// Per column of the fixture: (name, max |ours − theirs|, that divided by max |theirs|).
fn differences(f: &Fixture, rec: &Recorder) -> Vec<(String, f64, f64)> {
    assert_eq!(
        rec.rows.len(),
        f.rows.len(),
        "{}: number of records",
        f.name
    );
    let mut out = Vec::new();
    for (c, name) in f.columns.iter().enumerate() {
        if name == "step" {
            let ours: Vec<f64> = rec.steps.iter().map(|&s| s as f64).collect();
            assert!(
                ours.iter().zip(&f.rows).all(|(a, r)| *a == r[c]),
                "{}: step numbers",
                f.name
            );
            continue;
        }
        let ours = if name == "t" {
            rec.t.clone()
        } else {
            rec.column(name).expect("column recorded")
        };
        let scale = f
            .rows
            .iter()
            .map(|r| r[c].abs())
            .fold(0.0, f64::max)
            .max(f64::MIN_POSITIVE);
        let abs = ours
            .iter()
            .zip(&f.rows)
            .map(|(a, r)| (a - r[c]).abs())
            .fold(0.0, f64::max);
        out.push((name.clone(), abs, abs / scale));
    }
    out
}

fn print_table(name: &str, diffs: &[(String, f64, f64)]) {
    let worst = diffs
        .iter()
        .fold((0.0f64, 0.0f64), |(a, r), d| (a.max(d.1), r.max(d.2)));
    println!(
        "{name}: max abs diff {:.3e}, max rel diff {:.3e}",
        worst.0, worst.1
    );
    for (c, a, r) in diffs {
        println!("  {c:>5}: abs {a:.3e} rel {r:.3e}");
    }
}

fn check_agreement(name: &'static str) {
    let f = load(name);
    match &f.spec.integrator {
        IntegratorSpec::MoreauJean(p) => {
            assert_eq!(p.index_set.activation, Some(Activation::PredictedGap))
        }
        other => panic!("{name}: unexpected scheme {}", other.scheme()),
    }
    let rec = run_spec(&f.spec);
    let diffs = differences(&f, &rec);
    print_table(name, &diffs);
    for (c, abs, rel) in &diffs {
        assert!(
            *rel <= TOLERANCE,
            "{name}: column {c} differs from Siconos by {abs:e} (relative {rel:e})"
        );
    }
    // The impulse must be switched on at exactly the same steps.
    let p = f.columns.iter().position(|c| c == "p_0").expect("p_0");
    let ours = rec.column("p_0").expect("p_0");
    for (k, (a, r)) in ours.iter().zip(&f.rows).enumerate() {
        assert_eq!(
            *a > 0.0,
            r[p] > 0.0,
            "{name}: step {k}: contact active here and not there"
        );
    }
}

#[test]
fn ball_e09_theta05_matches_siconos() {
    check_agreement("ball_e09_theta05");
}

#[test]
fn ball_e05_theta1_matches_siconos() {
    check_agreement("ball_e05_theta1");
}

#[test]
fn bar_e0_theta05_matches_siconos() {
    check_agreement("bar_e0_theta05");
}

/// Siconos was built without γ here (`MoreauJeanOSI(1.0)`): its default γ is ½, recorded in the
/// sidecar and passed to us explicitly (our own default γ is 1).
#[test]
fn bar_e05_theta1_force_matches_siconos_default_gamma() {
    check_agreement("bar_e05_theta1_force");
}

/// How the default index set (24) parts from Siconos' rule in a scene.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Parting {
    /// Same contacts at every step: γ = 1 and U_k ≤ 0 whenever the predicted gap is ≤ 0. For
    /// `bar_e0_theta05` this pins the round-off-aware sign test of (24)
    /// (`IndexSetRule::is_active_within`): in its lasting contact U_14 = +5.55e-17 is zero up
    /// to the LCP's round-off and must not release the contact.
    Never,
    /// γ = ½ in Siconos: (24), which is the predicted-gap rule with γ = 1 for a constant G and a
    /// fixed obstacle, activates the contact one step earlier, on the step reaching this row.
    EarlierActivation(usize),
}

/// The same specs with our default index set (24): identical to Siconos, to round-off, up to the
/// first step where the two rules pick different contacts, and that step is explained by
/// [`Parting`]. The drift afterwards is reported in `docs/siconos.md`.
#[test]
fn default_index_set_differs_as_documented() {
    for (name, expected) in [
        ("ball_e09_theta05", Parting::Never),
        ("ball_e05_theta1", Parting::EarlierActivation(90)),
        ("bar_e0_theta05", Parting::Never),
        ("bar_e05_theta1_force", Parting::EarlierActivation(10)),
    ] {
        let f = load(name);
        let mut spec = f.spec.clone();
        let (h, gamma) = match &mut spec.integrator {
            IntegratorSpec::MoreauJean(p) => {
                let gamma = p
                    .index_set
                    .activation_gamma
                    .expect("the sidecar records Siconos' γ");
                p.index_set.activation = Some(Activation::GapAndVelocity);
                p.index_set.activation_gamma = None;
                (spec.time.as_ref().expect("time").h, gamma)
            }
            other => panic!("{name}: unexpected scheme {}", other.scheme()),
        };
        let rec = run_spec(&spec);
        let p = f.columns.iter().position(|c| c == "p_0").expect("p_0");
        let ours = rec.column("p_0").expect("p_0");
        let first = ours
            .iter()
            .zip(&f.rows)
            .position(|(a, r)| (*a > 0.0) != (r[p] > 0.0));
        println!("{name} with (24): first step with a different index set: {first:?}");
        print_table(name, &differences(&f, &rec));

        // Identical up to the first step where the rules disagree …
        let until = first.unwrap_or(f.rows.len());
        let head = Recorder {
            columns: rec.columns.clone(),
            steps: rec.steps[..until].to_vec(),
            t: rec.t[..until].to_vec(),
            rows: rec.rows[..until].to_vec(),
        };
        let siconos_head = Fixture {
            name: f.name,
            spec: f.spec.clone(),
            columns: f.columns.clone(),
            rows: f.rows[..until].to_vec(),
        };
        for (c, abs, rel) in differences(&siconos_head, &head) {
            assert!(
                rel <= TOLERANCE,
                "{name}: (24) differs from Siconos before the index sets part: {c} {abs:e}"
            );
        }

        // … and that step is the documented one, decided by the state of the row before it.
        let (gap, u) = (
            rec.column("gap_0").expect("gap_0"),
            rec.column("u_0").expect("u_0"),
        );
        match (expected, first) {
            (Parting::Never, None) => {}
            (Parting::EarlierActivation(k), Some(j)) if j == k => {
                let (g, u) = (gap[k - 1], u[k - 1]);
                assert!(
                    g + gamma * h * u > 0.0 && g + h * u <= 0.0 && u <= 0.0,
                    "{name}: step {k}: g {g:e}, U {u:e}"
                );
                assert!(
                    ours[k] > 0.0 && f.rows[k][p] == 0.0,
                    "{name}: step {k}: (24) should activate first"
                );
            }
            (e, j) => panic!("{name}: expected {e:?}, the rules parted at {j:?}"),
        }
    }
}

/// The speed-comparison scene of `scripts/siconos/bench.py` (docs/siconos.md §5): our run must
/// end in the state Siconos printed (`q_tip_final`, `v_tip_final`, `q_0_final`), so both sides
/// time the same computation. N = 100: 20 000 steps, 10 081 of them with an impulse.
#[test]
fn bench_scene_ends_where_siconos_ends() {
    for (elements, steps, q_tip, v_tip, q_0, with_impulse) in [
        (
            100usize,
            20_000u64,
            -0.9734956847766547,
            -0.3179620398761584,
            -0.005692193378369261,
            10_081usize,
        ),
        (
            1000,
            200,
            0.0010500000000000002,
            0.0,
            0.0009993172323745877,
            190,
        ),
    ] {
        let spec: JobSpec = serde_json::from_value(serde_json::json!({
            "model": {"scene": "bar", "elements": elements, "length": 1.0, "young": 1.0, "density": 1.0,
                      "area": 1.0, "mass_matrix": "lumped", "left": "fixed", "gap": 1e-3 + 3.7e-6,
                      "restitution": 0.0, "initial_velocity": 1.0},
            "integrator": {"scheme": "moreau_jean", "theta": 0.5, "activation": "predicted_gap",
                           "activation_gamma": 0.5},
            "time": {"h": 1e-4, "steps": steps},
            "contact_solver": {"kind": "lemke"},
            "output": {"every": 1, "probes": [0, elements - 1]},
        }))
        .expect("spec");
        let rec = run_spec(&spec);
        let last = |c: &str| *rec.column(c).expect("column").last().expect("rows");
        let ours = [
            last(&format!("q_{}", elements - 1)),
            last(&format!("v_{}", elements - 1)),
            last("q_0"),
        ];
        let impulses = rec
            .column("p_0")
            .expect("p_0")
            .iter()
            .filter(|&&p| p > 0.0)
            .count();
        println!(
            "bench N = {elements}: ours {ours:?}, Siconos {:?}, impulses {impulses}",
            [q_tip, v_tip, q_0]
        );
        assert_eq!(
            impulses, with_impulse,
            "N = {elements}: steps with an impulse"
        );
        for (a, b) in ours.iter().zip([q_tip, v_tip, q_0]) {
            assert!(
                (a - b).abs() <= 1e-9 * (1.0 + b.abs()),
                "N = {elements}: {a:e} vs Siconos {b:e}"
            );
        }
    }
}
