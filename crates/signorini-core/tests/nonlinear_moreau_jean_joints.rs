//! Joints and contacts together under the nonlinear Moreau–Jean time-stepping (the mixed LCP of
//! `nonlinear::moreau_jean`), through the job path on `examples/double_pendulum_wall.toml`: a
//! double pendulum in Cartesian coordinates (two rod joints) whose lower mass hits a wall; and an
//! elastic bar clamped by a joint (x₀ = 0) as a long user model, on the band LU.

// Only the core library must stay pure (clippy.toml): a test may read fixtures and print.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use signorini_core::job::{Job, run};
use signorini_core::observer::Recorder;
use signorini_core::spec::JobSpec;
use std::path::Path;

fn example() -> serde_json::Value {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/double_pendulum_wall.toml");
    let text = std::fs::read_to_string(&path).expect("reading the example");
    let spec: JobSpec = toml::from_str(&text).expect("the example parses");
    serde_json::to_value(&spec).expect("json")
}

fn record(doc: serde_json::Value) -> (Recorder, serde_json::Value) {
    let spec: JobSpec = serde_json::from_value(doc).expect("a job spec");
    let job = Job::from_spec(&spec).unwrap_or_else(|e| panic!("spec refused: {e}"));
    let mut rec = Recorder::default();
    let out = run(&job, 1, &mut rec).unwrap_or_else(|e| panic!("run failed: {e}"));
    (rec, serde_json::Value::Object(out.summary.to_map()))
}

fn col(rec: &Recorder, name: &str) -> Vec<f64> {
    rec.column(name)
        .unwrap_or_else(|| panic!("no column {name} in {:?}", rec.columns.names()))
}

fn num(summary: &serde_json::Value, field: &str) -> f64 {
    summary[field]
        .as_f64()
        .unwrap_or_else(|| panic!("no number {field} in {summary}"))
}

/// The example for e ∈ {0, 0.5, 1}, h = 1e-3, 3 s, every step recorded. The wall's gap is
/// affine (0.5 − x2), so u_0 = −ẋ2 is the local velocity the LCP sees on both sides of a step.
/// - At each impact (p_0 > 0 after a step without) u⁺ = −e u⁻ to round-off: Newton's impact
///   law, as `ns_generalized_alpha` enforces it;
/// - the rods hold to Newton's tolerance at every step, impacts included: position_residual
///   ≤ 1e-9 (tolerance 1e-10 relative to the joints' scale, about 2 here);
/// - the ledger closes: |energy_error| ≤ 1e-8 J at every step (ideal joints do no work: their
///   impulse acts along the rods at the step's midpoint), and the energy lost is the contact
///   work, E_end − E_0 = Σ work_contact to 1e-6 J; work_contact ≤ 0 at every step (≤ 1e-12),
///   zero for e = 1 up to the same level;
/// - the mass never goes through the wall by more than 1e-9.
#[test]
fn double_pendulum_against_a_wall_follows_newtons_law_with_its_joints_held() {
    for e in [0.0, 0.5, 1.0] {
        let mut doc = example();
        doc["model"]["contacts"][0]["restitution"] = e.into();
        let (rec, summary) = record(doc);
        let (u, p, gap) = (col(&rec, "u_0"), col(&rec, "p_0"), col(&rec, "gap_0"));
        let (err, wc, res) = (
            col(&rec, "energy_error"),
            col(&rec, "work_contact"),
            col(&rec, "position_residual"),
        );
        let mut impacts = 0;
        let mut worst_law = 0.0f64;
        for k in 1..u.len() {
            if p[k] > 0.0 && p[k - 1] == 0.0 && u[k - 1] < 0.0 {
                impacts += 1;
                worst_law = worst_law.max((u[k] + e * u[k - 1]).abs() / u[k - 1].abs());
            }
        }
        let amax = |x: &[f64]| x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let max_work = wc.iter().fold(f64::NEG_INFINITY, |m, &x| m.max(x));
        let min_gap = gap.iter().fold(f64::INFINITY, |m, &x| m.min(x));
        let lost = num(&summary, "energy_final") - num(&summary, "energy_initial");
        let contact = num(&summary, "work_contact_total");
        println!(
            "e = {e}: {impacts} impacts, law {worst_law:.1e}, position residual {:.1e}, |energy_error| {:.1e}, ΔE {lost:.6} vs work_contact {contact:.6}, max work {max_work:.1e}, min gap {min_gap:.1e}",
            amax(&res),
            amax(&err)
        );
        assert!(impacts >= 1, "e = {e}: no impact");
        assert!(
            worst_law <= 1e-12,
            "e = {e}: Newton's law off by {worst_law:e}"
        );
        assert!(
            amax(&res) <= 1e-9,
            "e = {e}: joints violated by {:e}",
            amax(&res)
        );
        assert!(num(&summary, "max_position_residual") <= 1e-9);
        assert!(amax(&err) <= 1e-8, "e = {e}: energy error {:e}", amax(&err));
        assert!(
            (lost - contact).abs() <= 1e-6,
            "e = {e}: ΔE {lost} vs {contact}"
        );
        assert!(max_work <= 1e-12, "e = {e}: contact work {max_work:e} > 0");
        if e < 1.0 {
            assert!(
                contact < -1e-3,
                "e = {e}: no energy lost at the wall ({contact})"
            );
        } else {
            assert!(contact.abs() <= 1e-6, "e = 1: energy lost {contact}");
        }
        assert!(min_gap >= -1e-9, "e = {e}: penetration {min_gap:e}");
    }
}

/// What the scheme cannot take with joints is refused naming the field: θ = 0
/// (`integrator.theta`: q_{k+1} would not depend on v_{k+1}). Coulomb friction on a contact,
/// refused here before the joint rows could be condensed out of the friction problem, is
/// accepted (tests/nonlinear_joint_friction.rs runs it).
#[test]
fn joints_refuse_theta_zero_naming_the_field_and_take_friction() {
    let refused = |doc: serde_json::Value| {
        let spec: JobSpec = serde_json::from_value(doc).expect("a job spec");
        Job::from_spec(&spec).expect_err("must be refused")
    };
    let mut doc = example();
    doc["integrator"]["theta"] = 0.0.into();
    let e = refused(doc);
    assert_eq!(e.field, "integrator.theta", "{e}");
    assert!(e.reason.contains("joints"), "{e}");
    let mut doc = example();
    doc["model"]["contacts"][0]["friction"] = 0.3.into();
    doc["model"]["contacts"][0]["tangent"] = "y2".into();
    let spec: JobSpec = serde_json::from_value(doc).expect("a job spec");
    Job::from_spec(&spec).expect("joints and friction under moreau_jean");
}

/// An elastic bar of `n` nodes as a `lagrangian` model: its consistent mass as the entries of
/// a tridiagonal M (node mass m), springs k between neighbours, gravity along the bar; clamped
/// by the joint x₀ = 0 and falling towards a stop at x_{n−1} = −`stop`; θ = ½, h = 10⁻⁴.
fn clamped_bar(n: usize, stop: f64, steps: u64, probes: &[usize]) -> serde_json::Value {
    let mut mass = Vec::new();
    for i in 0..n {
        let ends = if i == 0 || i + 1 == n { 1 } else { 2 };
        mass.push(serde_json::json!([i, i, format!("{ends}*m/3")]));
        if i + 1 < n {
            mass.push(serde_json::json!([i, i + 1, "m/6"]));
        }
    }
    let springs: Vec<String> = (0..n - 1)
        .map(|i| format!("k/2*(x{} - x{i})^2", i + 1))
        .chain((0..n).map(|i| format!("m*g*x{i}")))
        .collect();
    serde_json::json!({
        "name": "clamped bar",
        "model": {
            "scene": "lagrangian",
            "coordinates": (0..n).map(|i| format!("x{i}")).collect::<Vec<_>>(),
            "parameters": { "m": 0.01, "k": 1.0e4, "g": 9.81 },
            "mass": { "entries": mass },
            "potential": springs.join(" + "),
            "q0": vec![0.0; n],
            "constraints": [{ "expr": "x0" }],
            "contacts": [{ "gap": format!("x{} + {stop:?}", n - 1) }],
        },
        "integrator": { "scheme": "moreau_jean", "theta": 0.5 },
        "time": { "h": 1e-4, "steps": steps },
        "output": { "probes": probes },
    })
}

/// A joint whose coordinates stay at zero:/// A joint whose coordinates stay at zero: an elastic bar of 10 nodes clamped by the joint
/// x₀ = 0 (tridiagonal mass, springs between neighbours, gravity along the bar) falls onto a
/// stop. Newton used to fail at step 4 ("relative residual 5e-1"): the joint's violation,
/// 10⁻²⁰ of round-off from the solve, was measured against its own coordinate's size and
/// motion, 10⁻²⁰ too. Now the 2 000 steps run, the clamp holds to round-off and the ledger
/// closes at every step.
#[test]
fn a_joint_at_rest_at_zero_holds_a_falling_bar() {
    let doc = clamped_bar(10, 1e-4, 2000, &[]);
    let (rec, summary) = record(doc);
    let amax = |x: &[f64]| x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let (res, err) = (col(&rec, "position_residual"), col(&rec, "energy_error"));
    let p = col(&rec, "p_0");
    println!(
        "position residual {:.1e}, |energy_error| {:.1e}, {} steps in contact",
        amax(&res),
        amax(&err),
        p.iter().filter(|&&x| x > 0.0).count()
    );
    assert_eq!(num(&summary, "steps"), 2000.0);
    assert!(p.iter().any(|&x| x > 0.0), "the bar never reached its stop");
    assert!(amax(&res) <= 1e-15, "clamp violated by {:e}", amax(&res));
    assert!(amax(&err) <= 1e-12, "energy error {:e}", amax(&err));
}

/// A bar of 200 nodes: its iteration matrix W = M + h²θ²K is tridiagonal, so the scheme
/// factorises it by band LU from its entries (no 200×200 array). Without contact the clamped
/// bar is linear and Moreau–Jean with θ = ½ is the trapezoidal rule on the 199 free nodes:
/// (M + h²K/4) Δv = −h (K (x_k + h v_k/2) − f), computed here densely with nalgebra. The tip's
/// position and velocity agree with it at every step to 10⁻¹² relative, and energy is kept to
/// round-off.
#[test]
fn a_long_bar_on_the_band_lu_is_the_trapezoidal_rule() {
    use nalgebra::{DMatrix, DVector};
    let (n, steps, h) = (200, 300, 1e-4);
    let (m, k, g) = (0.01, 1.0e4, 9.81);
    let (rec, summary) = record(clamped_bar(n, 10.0, steps, &[n - 1]));
    // The free nodes 1..n: M and K of the bar with node 0 removed.
    let r = n - 1;
    let mut mm = DMatrix::<f64>::zeros(r, r);
    let mut kk = DMatrix::<f64>::zeros(r, r);
    for i in 0..r {
        let node = i + 1;
        mm[(i, i)] = if node + 1 == n {
            m / 3.0
        } else {
            2.0 * m / 3.0
        };
        kk[(i, i)] = if node + 1 == n { k } else { 2.0 * k };
        if i + 1 < r {
            mm[(i, i + 1)] = m / 6.0;
            mm[(i + 1, i)] = m / 6.0;
            kk[(i, i + 1)] = -k;
            kk[(i + 1, i)] = -k;
        }
    }
    let f = DVector::<f64>::from_element(r, -m * g);
    let w = (&mm + &kk * (h * h / 4.0)).lu();
    let (mut x, mut v) = (DVector::<f64>::zeros(r), DVector::<f64>::zeros(r));
    let (tip_q, tip_v) = (
        col(&rec, &format!("q_{}", n - 1)),
        col(&rec, &format!("v_{}", n - 1)),
    );
    let mut worst = 0.0f64;
    for step in 1..=steps as usize {
        let rhs = -(&kk * (&x + &v * (h / 2.0)) - &f) * h;
        let dv = w.solve(&rhs).expect("W is regular");
        x += (&v + &dv * 0.5) * h;
        v += dv;
        let scale_q = x.amax().max(1e-300);
        let scale_v = v.amax().max(1e-300);
        worst = worst
            .max((tip_q[step] - x[r - 1]).abs() / scale_q)
            .max((tip_v[step] - v[r - 1]).abs() / scale_v);
    }
    let err = col(&rec, "energy_error");
    let amax = |x: &[f64]| x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    println!(
        "tip against the trapezoidal rule: {worst:.1e} relative; |energy_error| {:.1e}",
        amax(&err)
    );
    assert_eq!(num(&summary, "steps"), steps as f64);
    assert!(
        worst <= 1e-12,
        "the tip is {worst:e} off the trapezoidal rule"
    );
    assert!(amax(&err) <= 1e-12, "energy error {:e}", amax(&err));
}

/// The same 200-node bar under `ns_generalized_alpha`, whose position and velocity stages now
/// factorise the tridiagonal M by band LU (`MassFactor` in `nonlinear::generalized_alpha`):
/// it runs, holds the clamp to round-off, and its tip follows Moreau–Jean's (both second order
/// at h = 10⁻⁴) to 10⁻⁵ of the tip's travel (6·10⁻⁹ m of 4.6·10⁻³ measured).
#[test]
fn a_long_bar_runs_under_the_nonsmooth_generalized_alpha_on_the_band_lu() {
    let n = 200;
    let (mj, _) = record(clamped_bar(n, 10.0, 300, &[n - 1]));
    let mut doc = clamped_bar(n, 10.0, 300, &[n - 1]);
    doc["integrator"] = serde_json::json!({ "scheme": "ns_generalized_alpha" });
    let (ns, summary) = record(doc);
    let tip = format!("q_{}", n - 1);
    let (a, b) = (col(&mj, &tip), col(&ns, &tip));
    let travel = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let gap = a
        .iter()
        .zip(&b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
    let residual = col(&ns, "position_residual")
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()));
    println!("tip travel {travel:.3e} m, schemes apart by {gap:.1e} m, clamp {residual:.1e}");
    assert_eq!(num(&summary, "steps"), 300.0);
    assert!(travel > 1e-5, "the tip did not move ({travel:e})");
    assert!(gap <= 1e-5 * travel, "the schemes differ by {gap:e}");
    assert!(residual <= 1e-15, "clamp violated by {residual:e}");
}
