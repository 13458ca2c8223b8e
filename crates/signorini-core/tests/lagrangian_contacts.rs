//! `lagrangian` models with contacts through the whole job path (`Job::from_spec`, `job::run`)
//! under the nonlinear Moreau–Jean time-stepping: the bouncing ball written as a user model
//! equals the built-in scene to round-off, the pendulum against a wall loses e² of its energy at
//! each impact, Newton's cradle hands the velocity down the row as the linear chain scene does,
//! and the contact work is never positive on a fixed obstacle.

// Only the core library must stay pure (clippy.toml): a test may read fixtures and print.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use signorini_core::job::{Job, run};
use signorini_core::observer::Recorder;
use signorini_core::spec::JobSpec;
use std::path::Path;

fn example(name: &str) -> JobSpec {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../examples/{name}.toml"));
    let text = std::fs::read_to_string(&path).expect("reading the example");
    toml::from_str(&text).expect("the example parses")
}

fn record(spec: &JobSpec) -> Recorder {
    let job = Job::from_spec(spec).unwrap_or_else(|e| panic!("spec refused: {e}"));
    let mut rec = Recorder::default();
    run(&job, 1, &mut rec).unwrap_or_else(|e| panic!("run failed: {e}"));
    rec
}

fn col(rec: &Recorder, name: &str) -> Vec<f64> {
    rec.column(name)
        .unwrap_or_else(|| panic!("no column {name} in {:?}", rec.columns.names()))
}

/// The ball of `scene = "bouncing_ball"` and the same ball written as a `lagrangian` model
/// (M = m, V = m g q, gap q) give the same trajectory and impulses to round-off, for both
/// index-set rules, θ ∈ {½, 1} and several restitutions.
#[test]
fn the_ball_as_a_user_model_equals_the_built_in_scene() {
    for theta in [0.5, 1.0] {
        for e in [0.0, 0.5, 0.9] {
            for activation in ["gap_and_velocity", "predicted_gap"] {
                let integrator = format!(
                    r#""integrator": {{"scheme": "moreau_jean", "theta": {theta}, "activation": "{activation}"}},
                       "time": {{"h": 0.001, "t_end": 3.0}}, "output": {{"probes": [0]}}"#
                );
                let builtin: JobSpec = serde_json::from_str(&format!(
                    r#"{{"model": {{"scene": "bouncing_ball", "mass": 2.0, "gravity": 9.81,
                        "q0": 1.0, "v0": 0.5, "restitution": {e}}}, {integrator}}}"#
                ))
                .expect("built-in spec");
                let user: JobSpec = serde_json::from_str(&format!(
                    r#"{{"model": {{"scene": "lagrangian", "coordinates": ["q"],
                        "parameters": {{"m": 2.0, "g": 9.81}}, "mass": [["m"]],
                        "potential": "m*g*q", "q0": [1.0], "v0": [0.5],
                        "contacts": [{{"gap": "q", "restitution": {e}}}]}}, {integrator}}}"#
                ))
                .expect("user spec");
                let (a, b) = (record(&builtin), record(&user));
                assert_eq!(a.steps, b.steps);
                for name in [
                    "q_0",
                    "v_0",
                    "gap_0",
                    "u_0",
                    "p_0",
                    "kinetic",
                    "work_contact",
                ] {
                    let (x, y) = (col(&a, name), col(&b, name));
                    let scale = x.iter().fold(1e-300_f64, |m, v| m.max(v.abs()));
                    let worst = x
                        .iter()
                        .zip(&y)
                        .map(|(u, v)| (u - v).abs() / scale)
                        .fold(0.0, f64::max);
                    assert!(
                        worst <= 1e-12,
                        "θ = {theta}, e = {e}, {activation}: column {name} differs by {worst:.2e} of its scale"
                    );
                }
                assert!(col(&a, "p_0").iter().any(|&p| p > 0.0), "the ball bounced");
            }
        }
    }
}

/// examples/pendulum_wall.toml: at each impact the energy is multiplied by e² (the bob hits
/// the wall with all its energy kinetic and leaves with e times its speed), to the scheme's
/// accuracy; between impacts the energy error of θ = ½ stays far below the loss.
#[test]
fn the_pendulum_against_a_wall_loses_e_squared_of_its_energy_per_impact() {
    let spec = example("pendulum_wall");
    let e = match &spec.model {
        Some(signorini_core::spec::ModelSpec::Lagrangian(l)) => l.contacts[0].restitution,
        other => panic!("a lagrangian example, got {other:?}"),
    };
    let mut fine = spec.clone();
    fine.output.every = 1;
    let rec = record(&fine);
    let (energy, p) = (col(&rec, "energy"), col(&rec, "p_0"));
    let impacts: Vec<usize> = (1..p.len())
        .filter(|&k| p[k] > 0.0 && p[k - 1] == 0.0)
        .collect();
    assert!(impacts.len() >= 3, "impacts at records {impacts:?}");
    for &k in &impacts {
        let ratio = energy[k] / energy[k - 1];
        assert!(
            (ratio - e * e).abs() <= 1e-3,
            "impact at record {k}: E after / E before = {ratio}, e² = {}",
            e * e
        );
    }
    let work_contact = col(&rec, "work_contact");
    assert!(work_contact.iter().all(|&w| w <= 1e-12), "contact work ≤ 0");
}

/// examples/newtons_cradle.toml: three equal balls, e = 1, impacts one after the other. As in
/// the linear chain scene, each impact hands the whole velocity to the next ball: after the
/// first sweep the third ball moves with the first ball's speed and the others are (nearly) at
/// rest — the residue is the gravity impulse over the few steps between the two impacts.
#[test]
fn newtons_cradle_hands_the_velocity_down_the_row() {
    let mut spec = example("newtons_cradle");
    spec.output.every = 1;
    spec.time.as_mut().expect("a time section").t_end = Some(0.5);
    let rec = record(&spec);
    let (p0, p1) = (col(&rec, "p_0"), col(&rec, "p_1"));
    let v: Vec<Vec<f64>> = (0..3).map(|j| col(&rec, &format!("v_{j}"))).collect();
    let first = p0
        .iter()
        .position(|&p| p > 0.0)
        .expect("ball 1 hits ball 2");
    let second = p1
        .iter()
        .position(|&p| p > 0.0)
        .expect("ball 2 hits ball 3");
    assert!(second > first, "the impacts come one after the other");
    let speed = v[0][first - 1];
    assert!(
        speed > 1.0,
        "ball 1 arrives with its swing speed, got {speed}"
    );
    // Right after the first impact ball 2 has ball 1's speed.
    assert!(
        (v[1][first] - speed).abs() <= 1e-4 * speed,
        "{} vs {speed}",
        v[1][first]
    );
    assert!(
        v[0][first].abs() <= 1e-4 * speed,
        "ball 1 stops: {}",
        v[0][first]
    );
    // Right after the second, ball 3 has it and the first two are at rest.
    assert!(
        (v[2][second] - speed).abs() <= 1e-4 * speed,
        "{} vs {speed}",
        v[2][second]
    );
    for (j, vj) in v.iter().take(2).enumerate() {
        assert!(
            vj[second].abs() <= 1e-4 * speed,
            "ball {j} at rest: {}",
            vj[second]
        );
    }
    // e = 1: the cradle keeps its energy up to the scheme's error.
    let energy = col(&rec, "energy");
    let drift = energy
        .iter()
        .map(|x| (x - energy[0]).abs())
        .fold(0.0, f64::max);
    assert!(drift <= 1e-8 * energy[0], "energy drift {drift:e}");
}

/// examples/rocking_block.toml: plastic impacts on a fixed floor never do positive work, and
/// the energy never rises above its start.
#[test]
fn the_rocking_block_never_gains_energy_from_its_contacts() {
    let mut spec = example("rocking_block");
    spec.output.every = 1;
    let rec = record(&spec);
    let work_contact = col(&rec, "work_contact");
    assert!(work_contact.iter().all(|&w| w <= 1e-12));
    assert!(
        work_contact.iter().any(|&w| w < -1e-9),
        "the corners do hit"
    );
    let energy = col(&rec, "energy");
    assert!(energy.iter().all(|&x| x <= energy[0] * (1.0 + 1e-9)));
}

/// A joint whose Jacobian is undefined at q0 (√u at u = 0: g_q holds an infinity) is refused naming
/// `model.constraints` and the entry; it panicked inside nalgebra's SVD, which sorts its
/// singular values (found by the `spec_json` fuzz target, fuzz/corpus/spec_json/crash-2731…).
#[test]
fn a_joint_undefined_at_q0_is_refused_naming_it() {
    let spec: JobSpec = serde_json::from_str(
        r#"{"name": "undefined joint", "model": {"scene": "lagrangian",
            "coordinates": ["x1", "y1", "x2", "y2"],
            "mass": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]],
            "potential": "9.81*(y1 + y2)", "q0": [-1.0, 0.0, -2.0, 0.0], "v0": [0, 0, 0, 0],
            "constraints": [{"expr": "(x1^2 + y1^2 - 1)/2"}, {"expr": "sqrt(x2 - x1 + 1)"}],
            "contacts": [{"gap": "0.5 - x2", "restitution": 0.5}]},
          "integrator": {"scheme": "moreau_jean"}, "time": {"h": 0.001, "t_end": 0.01}}"#,
    )
    .expect("the spec parses");
    let e = Job::from_spec(&spec).expect_err("g_q is not finite at q0");
    assert_eq!(e.field, "model.constraints", "{e}");
    assert!(e.to_string().contains("not finite: entry (1, "), "{e}");
}
