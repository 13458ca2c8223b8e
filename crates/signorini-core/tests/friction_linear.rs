//! Coulomb friction in Moreau–Jean on linear models (issue 11): the chain pressed and dragged
//! against a rough wall (`examples/chain_rough_wall.toml`) closes its energy balance at round-off
//! with `work_friction` in it, for θ ∈ {½, 1}, the variant and every friction solver;
//! `work_friction` ≤ 0 at every step; the block on a slope written as a `linear` model slides by
//! the exact law and matches the `lagrangian` one; μ = 0 is the frictionless model bit for bit;
//! the nonsmooth α-family (ns_hht, ns_generalized_alpha, ns_newmark) closes the chain's balance
//! at round-off with `work_friction` in it; the position-level baselines refuse friction naming
//! `integrator.scheme`; bad friction fields are named; a friction solver that fails stops the
//! run with the step and t.

// Only the core library must stay pure (clippy.toml): a test may read fixtures and print.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use serde_json::{Value, json};
use signorini_core::job::{Job, run};
use signorini_core::observer::Recorder;
use signorini_core::spec::JobSpec;
use std::path::Path;

fn example_json(name: &str) -> Value {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../examples/{name}.toml"));
    let text = std::fs::read_to_string(&path).expect("reading the example");
    let spec: JobSpec = toml::from_str(&text).expect("the example parses");
    serde_json::to_value(spec).expect("as JSON")
}

fn spec(v: &Value) -> JobSpec {
    serde_json::from_value(v.clone()).expect("spec")
}

fn record(v: &Value) -> Recorder {
    let job = Job::from_spec(&spec(v)).unwrap_or_else(|e| panic!("spec refused: {e}"));
    let mut rec = Recorder::default();
    run(&job, 1, &mut rec).unwrap_or_else(|e| panic!("run failed: {e}"));
    rec
}

fn col(rec: &Recorder, name: &str) -> Vec<f64> {
    rec.column(name)
        .unwrap_or_else(|| panic!("no column {name} in {:?}", rec.columns.names()))
}

fn max_abs(x: &[f64]) -> f64 {
    x.iter().fold(0.0f64, |m, a| m.max(a.abs()))
}

/// `work_friction` ≤ 0 at every record up to round-off (1e-12 Σ|pt| max(1, max|ut|): a sticking
/// contact has U_t = 0 only to round-off).
fn assert_dissipative(rec: &Recorder, contacts: usize, what: &str) {
    let pts: Vec<Vec<f64>> = (0..contacts)
        .map(|a| col(rec, &format!("pt_{a}")))
        .collect();
    let vmax = (0..contacts)
        .map(|a| max_abs(&col(rec, &format!("ut_{a}"))))
        .fold(1.0f64, f64::max);
    for (k, w) in col(rec, "work_friction").iter().enumerate() {
        let tol = 1e-12 * vmax * pts.iter().map(|p| p[k].abs()).sum::<f64>();
        assert!(
            *w <= tol,
            "{what}: work_friction {w:e} > {tol:e} at record {k}"
        );
    }
}

/// The chain's run `v` closes its balance: max |balance_residual| ≤ `tolerance` × the largest
/// energy or work, friction dissipating at every record, more than 1 J dissipated, and every
/// mass sliding by the end with P_t = −μ P_n.
fn assert_chain_closes(v: &Value, what: &str, tolerance: f64) {
    let rec = record(v);
    let scale = max_abs(&col(&rec, "energy")).max(max_abs(&col(&rec, "work_ext_total")));
    let residual = max_abs(&col(&rec, "balance_residual"));
    println!("{what}: max |balance_residual| = {residual:e} (scale {scale:.3})");
    assert!(
        residual <= tolerance * scale,
        "{what}: residual {residual:e}"
    );
    assert_dissipative(&rec, 4, what);
    let last = rec.rows.len() - 1;
    let total = col(&rec, "work_friction_total")[last];
    assert!(total < -1.0, "{what}: friction dissipated {total}");
    for a in 0..4 {
        let (p, pt, ut) = (
            col(&rec, &format!("p_{a}"))[last],
            col(&rec, &format!("pt_{a}"))[last],
            col(&rec, &format!("ut_{a}"))[last],
        );
        assert!(ut > 1e-3, "{what}: mass {a} not sliding: U_t = {ut}");
        assert!((pt + 0.3 * p).abs() <= 1e-12 * p, "{what}: {pt} vs −μ {p}");
    }
}

/// The chain of `examples/chain_rough_wall.toml`, every step recorded: the balance residual at
/// round-off (≤ 1e-13 × the largest energy or work) at every step, friction dissipating at every
/// step, the cumulative works consistent with the energy, and the chain sliding by the end
/// (every mass with U_t > 0 and P_t = −μ P_n).
#[test]
fn the_chain_dragged_on_a_rough_wall_closes_its_balance_at_round_off() {
    let base = example_json("chain_rough_wall");
    for (scheme, theta) in [
        ("moreau_jean", 0.5),
        ("moreau_jean", 1.0),
        ("moreau_jean", 0.7),
        ("moreau_jean_variant", 0.5),
    ] {
        for kind in ["auto", "lemke", "pgs"] {
            let mut v = base.clone();
            v["integrator"] = json!({"scheme": scheme, "theta": theta});
            v["contact_solver"] = json!({"kind": kind});
            v["output"]["every"] = json!(1);
            assert_chain_closes(&v, &format!("{scheme} θ = {theta}, {kind}"), 1e-13);
        }
    }
}

/// The same chain under the nonsmooth α-family (Acary 2016 (25) with the tangential impulse in
/// (25b), `integrators::alpha`), every step recorded: the balance residual of Lemma 2 with
/// `work_friction` in it at round-off (≤ 1e-12 × the largest energy or work) at every step,
/// friction dissipating at every step (≤ 0 to round-off), more than 1 J dissipated, and the
/// chain sliding by the end with P_t = −μ P_n on every mass.
#[test]
fn the_chain_dragged_on_a_rough_wall_closes_its_balance_under_the_alpha_family() {
    let base = example_json("chain_rough_wall");
    for integrator in [
        json!({"scheme": "ns_hht", "alpha": 0.1}),
        json!({"scheme": "ns_generalized_alpha", "rho_inf": 0.8}),
        json!({"scheme": "ns_newmark"}),
    ] {
        for kind in ["auto", "lemke"] {
            let mut v = base.clone();
            v["integrator"] = integrator.clone();
            v["contact_solver"] = json!({"kind": kind});
            v["output"]["every"] = json!(1);
            assert_chain_closes(&v, &format!("{integrator}, {kind}"), 1e-12);
        }
    }
}

/// The block on a slope as a `linear` model (dofs x along the slope, y normal to it; gravity
/// as a constant force): sliding follows x = ½ g (sin α − μ cos α) t² to round-off with θ = ½,
/// its trajectory and impulses equal those of the `lagrangian` model of
/// `examples/block_on_slope.toml` to 1e-12, and μ m g cos α × x is dissipated.
#[test]
fn the_linear_block_on_a_slope_matches_the_exact_law_and_the_lagrangian_model() {
    let (m, g, mu) = (2.0f64, 9.81f64, 0.3f64);
    let alpha = 30f64.to_radians();
    let time = json!({"h": 0.001, "t_end": 1.0});
    let linear = json!({
        "model": {
            "scene": "linear",
            "mass": [[m, 0.0], [0.0, m]],
            "force": [m * g * alpha.sin(), -m * g * alpha.cos()],
            "g_matrix": [[0.0, 1.0]],
            "t_matrix": [[1.0, 0.0]],
            "friction": [mu],
            "restitution": [0.0]
        },
        "integrator": {"scheme": "moreau_jean", "theta": 0.5},
        "time": time,
        "output": {"probes": [0, 1]}
    });
    let mut user = example_json("block_on_slope");
    user["time"] = time.clone();
    user["output"] = json!({"probes": [0, 1]});
    let (a, b) = (record(&linear), record(&user));
    let x = col(&a, "q_0");
    let exact = 0.5 * g * (alpha.sin() - mu * alpha.cos());
    for (t, x) in a.t.iter().zip(&x) {
        assert!((x - exact * t * t).abs() <= 1e-12, "t = {t}: x = {x}");
    }
    for name in [
        "q_0",
        "v_0",
        "q_1",
        "p_0",
        "pt_0",
        "ut_0",
        "work_friction_total",
    ] {
        let (x, y) = (col(&a, name), col(&b, name));
        let scale = max_abs(&x).max(1e-300);
        let worst = x
            .iter()
            .zip(&y)
            .map(|(u, v)| (u - v).abs())
            .fold(0.0, f64::max);
        assert!(worst <= 1e-12 * scale, "{name}: {worst:e} of {scale:e}");
    }
    let wf = *col(&a, "work_friction_total").last().unwrap();
    let expected = -mu * m * g * alpha.cos() * x.last().unwrap();
    assert!((wf - expected).abs() <= 1e-12 * expected.abs());
    assert_dissipative(&a, 1, "linear slope");
}

/// μ = 0 everywhere (with tangent rows given) is the frictionless model: same columns, same
/// values bit for bit.
#[test]
fn zero_friction_is_the_frictionless_linear_model_bit_for_bit() {
    let mut frictionless = example_json("chain_rough_wall");
    let obj = frictionless["model"].as_object_mut().expect("model");
    obj.remove("friction");
    obj.remove("t_matrix");
    let mut zero = example_json("chain_rough_wall");
    zero["model"]["friction"] = json!([0.0, 0.0, 0.0, 0.0]);
    let (a, b) = (record(&frictionless), record(&zero));
    assert_eq!(a.columns.names(), b.columns.names());
    assert!(a.columns.index("work_friction").is_none());
    assert_eq!(a.rows, b.rows);
}

/// Refusals, each naming its field: the position-level baselines refuse friction
/// (`integrator.scheme`), μ > 0 needs `t_matrix`, μ must be ≥ 0 and finite, the sizes must
/// match.
#[test]
fn friction_specs_are_checked_naming_the_field() {
    let base = example_json("chain_rough_wall");
    type Edit = fn(&mut Value);
    let cases: Vec<(Edit, &str, &str)> = vec![
        (
            |v| v["integrator"] = json!({"scheme": "newmark_position_contact"}),
            "integrator.scheme",
            "does not take Coulomb friction",
        ),
        (
            |v| {
                v["model"]
                    .as_object_mut()
                    .expect("model")
                    .remove("t_matrix");
            },
            "model.t_matrix",
            "required when friction > 0",
        ),
        (
            |v| v["model"]["friction"][1] = json!(-0.1),
            "model.friction[1]",
            "outside [0, ∞)",
        ),
        (
            |v| v["model"]["friction"] = json!([0.3, 0.3]),
            "model.friction",
            "expected 4 entries, got 2",
        ),
        (
            |v| v["model"]["t_matrix"][2] = json!([1.0, 0.0]),
            "model.t_matrix[2]",
            "expected 8 entries, got 2",
        ),
        (
            |v| v["model"]["t_matrix"][0] = json!(vec![0.0; 8]),
            "model.t_matrix[0]",
            "non-zero tangent rows where friction > 0",
        ),
    ];
    for (edit, field, reason) in cases {
        let mut v = base.clone();
        edit(&mut v);
        let e = Job::from_spec(&spec(&v)).expect_err("must be refused");
        assert_eq!(e.field, field, "{e}");
        assert!(e.reason.contains(reason), "{field}: {e}");
    }
}

/// A friction solver that does not reach its tolerance fails the run with the step and t:
/// one NSGS sweep on the coupled chain.
#[test]
fn a_failing_friction_solve_names_the_step_and_t() {
    let mut v = example_json("chain_rough_wall");
    v["contact_solver"] = json!({"kind": "pgs", "max_iterations": 1});
    let job = Job::from_spec(&spec(&v)).expect("valid");
    let e = run(&job, 1, &mut Recorder::default()).expect_err("must fail");
    let text = e.to_string();
    assert!(
        text.starts_with("step 1 (t = 0.001): contact friction problem failed: nsgs did not reach"),
        "{text}"
    );
}
