//! The nonsmooth generalized-α scheme for nonlinear systems (`nonlinear::generalized_alpha`) on
//! `lagrangian` models, through the job path: second order on the double pendulum with joints
//! (q, v, λ), an energy error shrinking as h² on a conservative model where Moreau–Jean θ = 1
//! dissipates at order 1, Newton's impact law to round-off and no penetration on the pendulum
//! against a wall, joints held at both levels through the impacts of the slider-crank with
//! clearance, and the spec checks.

// Only the core library must stay pure (clippy.toml): a test may read fixtures and print.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use signorini_core::job::{Job, run};
use signorini_core::observer::Recorder;
use signorini_core::spec::JobSpec;
use std::path::Path;

/// An example with its `[integrator]`, `[time]` and `[output]` replaced.
fn example_with(name: &str, integrator: &str, time: &str, output: &str) -> JobSpec {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../examples/{name}.toml"));
    let text = std::fs::read_to_string(&path).expect("reading the example");
    let mut doc: toml::Table = toml::from_str(&text).expect("the example parses");
    for (key, value) in [
        ("integrator", integrator),
        ("time", time),
        ("output", output),
    ] {
        let table: toml::Table = toml::from_str(value).expect("a table");
        doc.insert(key.into(), toml::Value::Table(table));
    }
    doc.try_into().expect("a job spec")
}

fn record(spec: &JobSpec) -> (Recorder, serde_json::Value) {
    let job = Job::from_spec(spec).unwrap_or_else(|e| panic!("spec refused: {e}"));
    let mut rec = Recorder::default();
    let out = run(&job, 1, &mut rec).unwrap_or_else(|e| panic!("run failed: {e}"));
    (rec, serde_json::Value::Object(out.summary.to_map()))
}

fn col(rec: &Recorder, name: &str) -> Vec<f64> {
    rec.column(name)
        .unwrap_or_else(|| panic!("no column {name} in {:?}", rec.columns.names()))
}

fn last(rec: &Recorder, name: &str) -> f64 {
    *col(rec, name).last().expect("a record")
}

fn num(summary: &serde_json::Value, field: &str) -> f64 {
    summary[field]
        .as_f64()
        .unwrap_or_else(|| panic!("no number {field} in {summary}"))
}

fn sci(x: &[f64]) -> String {
    let parts: Vec<String> = x.iter().map(|v| format!("{v:.3e}")).collect();
    format!("[{}]", parts.join(", "))
}

fn orders(errors: &[f64]) -> Vec<f64> {
    errors.windows(2).map(|w| (w[0] / w[1]).log2()).collect()
}

const NS_ALPHA: &str = "scheme = \"ns_generalized_alpha\"\nrho_inf = 0.9";

/// The double pendulum in Cartesian coordinates with its two length joints, t ∈ [0, 1], h
/// halved from 8e-3 to 1e-3 against h = 1.25e-4: the final q, v and λ converge at order 2, the
/// joints hold at every step (position level to the Newton tolerance, velocity level to
/// round-off), and λ agrees with
/// generalized-α-SOI2's (same sign convention) to 1e-6 relative at h = 1.25e-4.
#[test]
fn double_pendulum_with_joints_is_second_order_in_q_v_and_lambda() {
    let output = "every = 1\nprobes = [0, 1, 2, 3]";
    let final_state = |h: f64| {
        let spec = example_with(
            "double_pendulum_cartesian",
            NS_ALPHA,
            &format!("h = {h}\nt_end = 1.0"),
            output,
        );
        let (rec, summary) = record(&spec);
        assert_eq!(num(&summary, "steps"), (1.0 / h).round());
        // Position: the Newton tolerance 1e-10 (this g is of unit scale); velocity: round-off.
        for (name, tol) in [("position_residual", 1e-10), ("velocity_residual", 1e-13)] {
            let worst = col(&rec, name).iter().fold(0.0f64, |m, x| m.max(x.abs()));
            assert!(worst <= tol, "h = {h}: {name} reaches {worst:e}");
        }
        let q: Vec<f64> = (0..4).map(|j| last(&rec, &format!("q_{j}"))).collect();
        let v: Vec<f64> = (0..4).map(|j| last(&rec, &format!("v_{j}"))).collect();
        let l: Vec<f64> = (0..2).map(|j| last(&rec, &format!("lambda_{j}"))).collect();
        (q, v, l)
    };
    let dist = |a: &[f64], b: &[f64]| {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0f64, f64::max)
    };
    let (q_ref, v_ref, l_ref) = final_state(1.25e-4);
    let hs = [8e-3, 4e-3, 2e-3, 1e-3];
    let (mut eq, mut ev, mut el) = (Vec::new(), Vec::new(), Vec::new());
    for &h in &hs {
        let (q, v, l) = final_state(h);
        eq.push(dist(&q, &q_ref));
        ev.push(dist(&v, &v_ref));
        el.push(dist(&l, &l_ref));
    }
    let (oq, ov, ol) = (orders(&eq), orders(&ev), orders(&el));
    println!("errors q {} orders {oq:.2?}", sci(&eq));
    println!("errors v {} orders {ov:.2?}", sci(&ev));
    println!("errors λ {} orders {ol:.2?}", sci(&el));
    for (what, o) in [("q", &oq), ("v", &ov), ("λ", &ol)] {
        assert!(o.iter().all(|&x| x > 1.8), "{what}: observed orders {o:?}");
    }
    // The same λ as generalized-α-SOI2 (M q̈ = F − g_qᵀλ for both).
    let soi2 = example_with(
        "double_pendulum_cartesian",
        "scheme = \"soi2_generalized_alpha\"\nrho_inf = 0.9\nnewton = \"full\"\nnewton_tolerance = 1e-12",
        "h = 1.25e-4\nt_end = 1.0",
        output,
    );
    let (rec, _) = record(&soi2);
    let l_soi2: Vec<f64> = (0..2).map(|j| last(&rec, &format!("lambda_{j}"))).collect();
    let gap = dist(&l_soi2, &l_ref) / l_ref.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    println!("λ: ns_generalized_alpha {l_ref:?}, soi2 {l_soi2:?}, relative gap {gap:.2e}");
    assert!(gap < 1e-6, "λ differs from SOI2's by {gap:e} relative");
}

/// A double pendulum in angles (M(q) with the coupling cos(φ1 − φ2), no joints, no contacts, no
/// applied force), from both rods horizontal, t ∈ [0, 1]: the energy drift |E(1) − E(0)| and
/// Σ_k |energy_error| of this scheme shrink as h², those of Moreau–Jean θ = 1 as h (it
/// dissipates: E(1) < E(0)).
#[test]
fn energy_error_is_second_order_where_moreau_jean_dissipates_at_order_one() {
    let run_with = |integrator: &str, h: f64| {
        let spec: JobSpec = serde_json::from_str(&format!(
            r#"{{"model": {{"scene": "lagrangian", "coordinates": ["p1", "p2"],
                "parameters": {{"m1": 1.0, "m2": 1.0, "L1": 1.0, "L2": 1.0, "g": 9.81}},
                "mass": [["(m1 + m2)*L1^2", "m2*L1*L2*cos(p1 - p2)"],
                         ["m2*L1*L2*cos(p1 - p2)", "m2*L2^2"]],
                "potential": "-(m1 + m2)*g*L1*cos(p1) - m2*g*L2*cos(p2)",
                "q0": [1.5707963267948966, 1.5707963267948966], "v0": [0.0, 0.0]}},
              "integrator": {integrator},
              "time": {{"h": {h}, "t_end": 1.0}}, "output": {{"every": 1}}}}"#
        ))
        .expect("spec");
        let (rec, summary) = record(&spec);
        let e = col(&rec, "energy");
        let sum: f64 = col(&rec, "energy_error").iter().map(|x| x.abs()).sum();
        (e[e.len() - 1] - num(&summary, "energy_initial"), sum)
    };
    let hs = [4e-3, 2e-3, 1e-3, 5e-4];
    for (name, integrator, expected) in [
        (
            "ns_generalized_alpha ρ∞ = 0.9",
            r#"{"scheme": "ns_generalized_alpha", "rho_inf": 0.9}"#,
            2.0,
        ),
        (
            "ns_generalized_alpha ρ∞ = 1",
            r#"{"scheme": "ns_generalized_alpha", "rho_inf": 1.0}"#,
            2.0,
        ),
        (
            "moreau_jean θ = 1",
            r#"{"scheme": "moreau_jean", "theta": 1.0}"#,
            1.0,
        ),
    ] {
        let (drift, sum): (Vec<f64>, Vec<f64>) =
            hs.iter().map(|&h| run_with(integrator, h)).unzip();
        let od = orders(&drift.iter().map(|d| d.abs()).collect::<Vec<_>>());
        let os = orders(&sum);
        println!(
            "{name}: E(1) − E(0) {} orders {od:.2?}; Σ|energy_error| {} orders {os:.2?}",
            sci(&drift),
            sci(&sum)
        );
        for o in od.iter().chain(&os) {
            assert!(
                (o - expected).abs() < 0.25,
                "{name}: observed orders {od:?} (drift), {os:?} (Σ), expected {expected}"
            );
        }
        if expected == 1.0 {
            assert!(drift.iter().all(|&d| d < 0.0), "{name} dissipates");
        }
    }
}

/// The pendulum against a wall (gap L sin θ, e ∈ {0, 0.5, 0.8, 1}), h = 1e-3, 5 s: at every
/// impact the velocity after is −e times the velocity before, to round-off (U⁺ = −e U⁻ with the
/// same Jacobian, the gap's L cos θ, on both sides); the gap is never below −1e-10 (the
/// Newton tolerance on this unit-size gap) at any step; the contact work is never positive.
#[test]
fn pendulum_wall_impacts_follow_newtons_law_to_round_off_without_penetration() {
    for e in [0.0, 0.5, 0.8, 1.0] {
        let mut spec = example_with(
            "pendulum_wall",
            NS_ALPHA,
            "h = 0.001\nt_end = 5.0",
            "every = 1\nprobes = [0]",
        );
        let mut doc = serde_json::to_value(&spec).expect("json");
        doc["model"]["contacts"][0]["restitution"] = e.into();
        spec = serde_json::from_value(doc).expect("spec");
        let (rec, summary) = record(&spec);
        let (v, p, gap, wc) = (
            col(&rec, "v_0"),
            col(&rec, "p_0"),
            col(&rec, "gap_0"),
            col(&rec, "work_contact"),
        );
        let mut impacts = 0;
        let mut worst = 0.0f64;
        for k in 1..v.len() {
            if p[k] > 0.0 && v[k - 1] < 0.0 && (k < 2 || p[k - 1] == 0.0) {
                impacts += 1;
                worst = worst.max((v[k] + e * v[k - 1]).abs() / v[k - 1].abs());
            }
        }
        let min_gap = gap.iter().fold(f64::INFINITY, |m, &x| m.min(x));
        let max_work = wc.iter().fold(f64::NEG_INFINITY, |m, &x| m.max(x));
        println!(
            "e = {e}: {impacts} impacts, max |v⁺ + e v⁻|/|v⁻| = {worst:.1e}, min gap {min_gap:.1e}, max work_contact {max_work:.1e}, E {} → {}",
            num(&summary, "energy_initial"),
            num(&summary, "energy_final")
        );
        assert!(
            impacts >= if e > 0.0 { 3 } else { 1 },
            "e = {e}: {impacts} impacts"
        );
        assert!(
            worst <= 4.0 * f64::EPSILON,
            "e = {e}: Newton's law off by {worst:e}"
        );
        assert!(min_gap >= -1e-10, "e = {e}: penetration {min_gap:e}");
        assert!(num(&summary, "max_penetration") <= 1e-10);
        assert!(max_work <= 1e-15, "e = {e}: contact work {max_work:e} > 0");
    }
}

/// The slider-crank with clearance with the slider pinned to the rod by two joints (a mixed LCP
/// at each impact), 0.02 s at h = 1e-5: the pin holds at position and velocity level to
/// round-off at velocity level and to the Newton tolerance at position level at every step,
/// impacts included; no corner penetrates the guide beyond the Newton
/// tolerance; the contact work is never positive; the slider does hit the guide.
#[test]
fn joints_and_contacts_hold_together_on_the_slider_crank_with_clearance() {
    let spec = example_with(
        "slider_crank_clearance_joints",
        "scheme = \"ns_generalized_alpha\"\nrho_inf = 0.8",
        "h = 0.00001\nt_end = 0.02",
        "every = 1\nprobes = [0, 1, 4]",
    );
    let (rec, summary) = record(&spec);
    println!("{summary:#}");
    for (name, tol) in [("position_residual", 1e-10), ("velocity_residual", 1e-13)] {
        let worst = col(&rec, name).iter().fold(0.0f64, |m, x| m.max(x.abs()));
        println!("{name}: max {worst:.2e}");
        assert!(worst <= tol, "{name} reaches {worst:e}");
    }
    assert!(num(&summary, "impacts") >= 2.0, "the slider hits the guide");
    assert!(num(&summary, "max_penetration") <= 1e-12);
    let max_work = col(&rec, "work_contact")
        .iter()
        .fold(f64::NEG_INFINITY, |m, &x| m.max(x));
    assert!(max_work <= 1e-15, "contact work {max_work:e} > 0");
}

/// The rocking block and the slider-crank with clearance (minimal coordinates) run with this
/// scheme as their `*_ns_generalized_alpha` examples say, without penetration and with contact
/// work ≤ 0, and the block loses energy at its impacts as under Moreau–Jean.
#[test]
fn the_contact_examples_run_without_penetration() {
    for (name, time) in [
        (
            "rocking_block_ns_generalized_alpha",
            "h = 0.0005\nt_end = 2.0",
        ),
        (
            "slider_crank_clearance_ns_generalized_alpha",
            "h = 0.00001\nt_end = 0.02",
        ),
    ] {
        let path =
            Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../examples/{name}.toml"));
        let text = std::fs::read_to_string(&path).expect("reading the example");
        let mut spec: JobSpec = toml::from_str(&text).expect("the example parses");
        let t: toml::Table = toml::from_str(time).expect("time");
        spec.time = Some(toml::Value::Table(t).try_into().expect("time section"));
        let (rec, summary) = record(&spec);
        println!("{name}: {summary}");
        assert!(num(&summary, "impacts") >= 1.0, "{name}: no impact");
        assert!(
            num(&summary, "max_penetration") <= 1e-10,
            "{name}: penetration {}",
            num(&summary, "max_penetration")
        );
        let max_work = col(&rec, "work_contact")
            .iter()
            .fold(f64::NEG_INFINITY, |m, &x| m.max(x));
        assert!(max_work <= 1e-15, "{name}: contact work {max_work:e} > 0");
    }
}

/// Spec checks: `activation` is refused (the scheme has its own index set), a start that
/// violates the joints at velocity level is refused naming `model.v0`, and dependent joints
/// naming `model.constraints`.
#[test]
fn bad_specs_name_their_field() {
    let refused = |spec: &JobSpec| match Job::from_spec(spec) {
        Ok(_) => panic!("accepted"),
        Err(e) => e.to_string(),
    };
    let spec = example_with(
        "pendulum_wall",
        "scheme = \"ns_generalized_alpha\"\nactivation = \"predicted_gap\"",
        "h = 0.001\nt_end = 1.0",
        "every = 1",
    );
    let e = refused(&spec);
    assert!(e.starts_with("integrator.activation"), "{e}");

    let base = example_with(
        "double_pendulum_cartesian",
        NS_ALPHA,
        "h = 0.001\nt_end = 1.0",
        "every = 1",
    );
    let mut doc = serde_json::to_value(&base).expect("json");
    doc["model"]["v0"] = serde_json::json!([1.0, 0.0, 0.0, 0.0]);
    let e = refused(&serde_json::from_value(doc).expect("spec"));
    assert!(e.starts_with("model.v0"), "{e}");

    let mut doc = serde_json::to_value(&base).expect("json");
    doc["model"]["constraints"][1]["expr"] = "(x1^2 + y1^2 - L1^2)".into();
    let e = refused(&serde_json::from_value(doc).expect("spec"));
    assert!(e.starts_with("model.constraints"), "{e}");
}

/// The joints' curvature term κ = d/dt(G v + g_t) at q̈ = 0 (one dual-number evaluation of the
/// symbolic G v + g_t) against central differences of G v + g_t along (t, q, v) → (1, v, 0),
/// and G against central differences of g, on the two joint examples at random points.
#[test]
fn joint_curvature_matches_central_differences() {
    use signorini_core::lagrangian::UserModel;
    use signorini_core::nonlinear::generalized_alpha::JointedSystem;
    use signorini_core::spec::ModelSpec;
    let mut seed = 0x2545_f491_4f6c_dd1d_u64;
    let mut random = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    for name in ["double_pendulum_cartesian", "slider_crank_clearance_joints"] {
        let spec = example_with(name, NS_ALPHA, "h = 0.001\nt_end = 1.0", "every = 1");
        let Some(ModelSpec::Lagrangian(l)) = spec.model else {
            panic!("a lagrangian example")
        };
        let params = l.validate().expect("valid");
        let q0 = params.q0.clone();
        let model = UserModel::new(params);
        let (n, nb) = (l.coordinates.len(), model.joints());
        for _ in 0..20 {
            let q: Vec<f64> = q0.iter().map(|x| x + 0.3 * random()).collect();
            let v: Vec<f64> = (0..n).map(|_| 2.0 * random()).collect();
            let t = random().abs();
            let mut kappa = vec![0.0; nb];
            model.joint_curvature(t, &q, &v, &mut kappa);
            let eps = 1e-6;
            let rate = |s: f64| {
                let qs: Vec<f64> = q.iter().zip(&v).map(|(x, w)| x + s * w).collect();
                let mut r = vec![0.0; nb];
                model.joint_rates(t + s, &qs, &v, &mut r);
                r
            };
            let (plus, minus) = (rate(eps), rate(-eps));
            let mut g = vec![0.0; nb * n];
            model.joint_jacobian(t, &q, &mut g);
            for j in 0..nb {
                let fd = (plus[j] - minus[j]) / (2.0 * eps);
                assert!(
                    (kappa[j] - fd).abs() <= 1e-7 * (1.0 + fd.abs()),
                    "{name}: κ_{j} = {} against {fd}",
                    kappa[j]
                );
                for i in 0..n {
                    let mut qp = q.clone();
                    let mut qm = q.clone();
                    qp[i] += eps;
                    qm[i] -= eps;
                    let (mut gp, mut gm) = (vec![0.0; nb], vec![0.0; nb]);
                    model.joint_values(t, &qp, &mut gp);
                    model.joint_values(t, &qm, &mut gm);
                    let fd = (gp[j] - gm[j]) / (2.0 * eps);
                    assert!((g[j * n + i] - fd).abs() <= 1e-7 * (1.0 + fd.abs()));
                }
            }
        }
    }
}

/// `newton = "simplified"` (the smooth stage's matrix kept across iterates and steps, the start
/// extrapolated) on the double pendulum with joints (h = 1e-3) and on the slider-crank with
/// clearance and joints at its example's h = 1e-5: the same motion as full Newton to 1e-7, the
/// joints held as tightly, fewer matrices formed than iterates (full Newton forms one per
/// iterate), and at most 3 iterates a step on average. (At h = 1e-3 the slider-crank turns
/// 0.15 rad a step and simplified Newton forms a matrix at every step: 3.15 iterates and 1.0
/// matrices a step against full Newton's 2.14 and 2.14.)
#[test]
fn simplified_newton_keeps_the_motion_of_full_newton_with_fewer_matrices() {
    for (example, h, t_end) in [
        ("double_pendulum_cartesian", "1e-3", "1.0"),
        ("slider_crank_clearance_joints", "1e-5", "0.02"),
    ] {
        let run_with = |newton: &str| {
            let spec = example_with(
                example,
                &format!("{NS_ALPHA}\nnewton = \"{newton}\""),
                &format!("h = {h}\nt_end = {t_end}"),
                "every = 1\nprobes = [0, 1]",
            );
            record(&spec)
        };
        let (full, full_summary) = run_with("full");
        let (simplified, summary) = run_with("simplified");
        let steps = num(&summary, "steps");
        let (iterations, matrices) = (
            num(&summary, "newton_iterations_mean"),
            num(&summary, "newton_jacobians_total"),
        );
        println!(
            "{example}: full {:.3} iterates and {} matrices a step; simplified {iterations:.3} and {:.3}",
            num(&full_summary, "newton_iterations_mean"),
            num(&full_summary, "newton_jacobians_total") / steps,
            matrices / steps
        );
        let full_iterates = num(&full_summary, "newton_iterations_mean") * steps;
        assert!(
            (num(&full_summary, "newton_jacobians_total") - full_iterates).abs() < 0.5,
            "full Newton forms a matrix per iterate"
        );
        assert!(matrices < 0.8 * iterations * steps, "{matrices} matrices");
        assert!(iterations <= 3.0, "{iterations} iterates a step");
        for name in ["q_0", "q_1", "v_0", "v_1"] {
            let gap = col(&full, name)
                .iter()
                .zip(col(&simplified, name))
                .map(|(a, b)| (a - b).abs())
                .fold(0.0f64, f64::max);
            assert!(gap < 1e-7, "{example}: {name} differs by {gap:e}");
        }
        for (name, tol) in [
            ("max_position_residual", 1e-9),
            ("max_velocity_residual", 1e-12),
        ] {
            assert!(
                num(&summary, name) <= tol,
                "{example}: {name} {}",
                num(&summary, name)
            );
        }
    }
}

/// `newton` is the smooth stage's: refused, naming `integrator.newton`, on a model whose step
/// has no Newton iteration (a linear chain under `ns_generalized_alpha` or `ns_kh_alpha`).
#[test]
fn the_newton_strategy_is_refused_where_no_step_solves_a_nonlinear_system() {
    for scheme in ["ns_generalized_alpha", "ns_kh_alpha"] {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/chain.toml");
        let text = std::fs::read_to_string(&path).expect("reading the example");
        let mut doc: toml::Table = toml::from_str(&text).expect("the example parses");
        let integrator: toml::Table =
            toml::from_str(&format!("scheme = \"{scheme}\"\nnewton = \"simplified\""))
                .expect("a table");
        doc.insert("integrator".into(), toml::Value::Table(integrator));
        let spec: JobSpec = doc.try_into().expect("a job spec");
        match Job::from_spec(&spec) {
            Ok(_) => panic!("{scheme}: newton accepted on a linear model"),
            Err(e) => {
                let e = e.to_string();
                assert!(e.starts_with("integrator.newton"), "{e}");
                assert!(e.contains("no nonlinear system"), "{e}");
            }
        }
    }
}
