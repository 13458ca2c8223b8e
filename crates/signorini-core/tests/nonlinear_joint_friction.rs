//! Joints and Coulomb friction together under the nonlinear Moreau–Jean time-stepping: the
//! joint rows condensed out of the step's friction problem (`nonlinear::moreau_jean`,
//! `condensed_friction_problem`; `lcp::EqualityElimination`).
//!
//! The reference scene is a pendulum hung from a cart: the cart (mass M, pivot (x_p, y_p)) runs
//! on a frictionless rail y_p = H, the bob (mass m, (x_b, y_b)) hangs on a rod of length L > H
//! and rests on a rough floor y_b ≥ 0 (μ, e = 0), at x_b = x_p + c with c = ±√(L² − H²). Pushed
//! along the rail with speed v₀ > 0, the cart drags (c < 0) or pushes (c > 0) the bob, which
//! slides on the floor: the whole pendulum translates, the rod's angle fixed by the floor.
//! Newton's second law on the cart and on the bob, with the rod's tension T along (−c, H)/L on
//! the bob, gives a constant deceleration and normal force
//!
//! ```text
//! M a = T c/L,   m a = −μN − T c/L,   0 = N − m g + T H/L
//! a = −μ m g / (M + m − μ M H/c),      N = −(M + m) a/μ
//! ```
//!
//! (the rod presses a pushed bob into the floor: N > m g for c > 0). Moreau–Jean with θ = ½
//! integrates a constant acceleration exactly, so its steps are, to round-off,
//! `v_{k+1} = max(v_k + h a, 0)`, `x_{k+1} = x_k + h(v_k + v_{k+1})/2`, with the normal impulse
//! p_n = h N and p_t = −μ h N on every sliding step: the scheme's closed form, which the scene is
//! checked against, written twice: in Cartesian coordinates with two joints (the rail and the
//! rod: the friction problem with equality rows), and in the minimal coordinates (x_p, φ) of
//! the same pendulum on its cart, without joints (the planar friction problem alone).

// Only the core library must stay pure (clippy.toml): a test may read fixtures and print.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use serde_json::json;
use signorini_core::job::{Job, run};
use signorini_core::observer::Recorder;
use signorini_core::spec::JobSpec;
use std::path::Path;

const M_CART: f64 = 2.0;
const M_BOB: f64 = 1.0;
const L: f64 = 1.0;
const H: f64 = 0.6;
const G: f64 = 9.81;
const MU: f64 = 0.3;
const V0: f64 = 1.5;
const STEP: f64 = 1e-3;

fn parameters(c: f64) -> serde_json::Value {
    json!({"M": M_CART, "m": M_BOB, "L": L, "H": H, "g": G, "c": c})
}

fn contact(mu: f64, tangent: &str, gap: &str) -> serde_json::Value {
    let mut contact = json!({"gap": gap, "restitution": 0.0});
    if mu > 0.0 {
        contact["friction"] = json!(mu);
        contact["tangent"] = json!(tangent);
    }
    contact
}

/// The pendulum on its cart in Cartesian coordinates (x_p, y_p, x_b, y_b): the rail and the rod
/// are joints, the floor a rough contact at the bob.
fn jointed(c: f64, mu: f64, t_end: f64) -> serde_json::Value {
    json!({
        "model": {
            "scene": "lagrangian",
            "coordinates": ["xp", "yp", "xb", "yb"],
            "parameters": parameters(c),
            "mass": [["M", 0, 0, 0], [0, "M", 0, 0], [0, 0, "m", 0], [0, 0, 0, "m"]],
            "potential": "M*g*yp + m*g*yb",
            "q0": [0.0, H, c, 0.0],
            "v0": [V0, 0.0, V0, 0.0],
            "constraints": [
                {"expr": "yp - H"},
                {"expr": "((xb - xp)^2 + (yb - yp)^2 - L^2)/2"}
            ],
            "contacts": [contact(mu, "xb", "yb")]
        },
        "integrator": {"scheme": "moreau_jean", "theta": 0.5},
        "time": {"h": STEP, "t_end": t_end},
        "output": {"every": 1, "probes": [0, 2]}
    })
}

/// The same pendulum in the minimal coordinates (x_p, φ), φ the rod's angle from the downward
/// vertical: the bob at (x_p + L sin φ, H − L cos φ), no joint. H is written as L cos φ₀ (equal
/// to 0.6 within 1e-16) so that the bob starts on the floor exactly, gap 0, as in Cartesian
/// coordinates.
fn minimal(c: f64, mu: f64, t_end: f64) -> serde_json::Value {
    let phi0 = (c / L).asin();
    let mut parameters = parameters(c);
    parameters["H"] = json!(L * phi0.cos());
    json!({
        "model": {
            "scene": "lagrangian",
            "coordinates": ["x", "phi"],
            "parameters": parameters,
            "mass": [["M + m", "m*L*cos(phi)"], ["m*L*cos(phi)", "m*L^2"]],
            "potential": "M*g*H + m*g*(H - L*cos(phi))",
            "q0": [0.0, phi0],
            "v0": [V0, 0.0],
            "contacts": [contact(mu, "x + L*sin(phi)", "H - L*cos(phi)")]
        },
        "integrator": {"scheme": "moreau_jean", "theta": 0.5},
        "time": {"h": STEP, "t_end": t_end},
        "output": {"every": 1, "probes": [0, 1]}
    })
}

fn record(doc: serde_json::Value) -> Recorder {
    let spec: JobSpec = serde_json::from_value(doc).expect("a job spec");
    let job = Job::from_spec(&spec).unwrap_or_else(|e| panic!("spec refused: {e}"));
    let mut rec = Recorder::default();
    run(&job, 1, &mut rec).unwrap_or_else(|e| panic!("run failed: {e}"));
    rec
}

fn col(rec: &Recorder, name: &str) -> Vec<f64> {
    rec.column(name)
        .unwrap_or_else(|| panic!("no column {name} in {:?}", rec.columns.names()))
}

/// The scheme's closed form (module documentation): the cart's position and velocity at every
/// step, and the normal force N of the sliding steps.
fn closed_form(c: f64, steps: usize) -> (Vec<f64>, Vec<f64>, f64) {
    let a = -MU * M_BOB * G / (M_CART + M_BOB - MU * M_CART * H / c);
    let normal = -(M_CART + M_BOB) * a / MU;
    let (mut x, mut v) = (vec![0.0], vec![V0]);
    for k in 0..steps {
        let next = (v[k] + STEP * a).max(0.0);
        x.push(x[k] + STEP * (v[k] + next) / 2.0);
        v.push(next);
    }
    (x, v, normal)
}

/// Cartesian with joints and minimal without: both equal the closed form to 1e-10 (positions
/// and velocities), through the sliding phase, the stop and the rest after it, for a dragged
/// (c < 0) and a pushed (c > 0) bob; on each sliding step p_n = h N and p_t = −μ h N (1e-9
/// relative: Newton stops at a residual of 1e-10 relative to the size of its terms, and the
/// joint impulses of a step that needed an iterate on the rod's curvature carry that error);
/// friction never does positive work, its work while sliding is −μ N × distance (1e-9) and in
/// all −½(M + m)v₀² (1e-10), the whole energy lost (the rod and the rail are ideal joints; the
/// energy error stays at Newton's tolerance); the joints hold to 1e-10. Seen: deviation from the
/// closed form 2.1e-12 (dragged, N = 8.53 < m g: the rod lifts the bob) and 1.4e-12 (pushed,
/// N = 11.54 > m g: the rod presses it down).
#[test]
fn a_pendulum_whose_bob_slides_on_a_rough_floor_follows_the_closed_form() {
    for c in [-(L * L - H * H).sqrt(), (L * L - H * H).sqrt()] {
        let t_end = 2.5;
        let steps = (t_end / STEP).round() as usize;
        let (x, v, normal) = closed_form(c, steps);
        let stop = v
            .iter()
            .position(|&s| s == 0.0)
            .expect("stops within t_end");
        assert!(stop + 100 < steps, "rest is recorded after the stop");
        let cart = record(jointed(c, MU, t_end));
        let reduced = record(minimal(c, MU, t_end));
        assert_eq!(cart.rows.len(), steps + 1);
        assert_eq!(reduced.rows.len(), steps + 1);
        let mut worst = 0.0f64;
        for (rec, xq, vq) in [(&cart, "q_0", "v_0"), (&reduced, "q_0", "v_0")] {
            let (xs, vs) = (col(rec, xq), col(rec, vq));
            for k in 0..=steps {
                worst = worst.max((xs[k] - x[k]).abs()).max((vs[k] - v[k]).abs());
            }
            let (pn, pt) = (col(rec, "p_0"), col(rec, "pt_0"));
            for k in 1..stop {
                assert!(
                    (pn[k] - STEP * normal).abs() <= 1e-9 * STEP * normal,
                    "c = {c}, step {k}: p_n {} vs h N {}",
                    pn[k],
                    STEP * normal
                );
                assert!(
                    (pt[k] + MU * STEP * normal).abs() <= 1e-9 * STEP * normal,
                    "c = {c}, step {k}: p_t {}",
                    pt[k]
                );
            }
            let wf = col(rec, "work_friction");
            let (k_max, w_max) =
                wf.iter()
                    .enumerate()
                    .fold(
                        (0, f64::NEG_INFINITY),
                        |m, (k, &w)| if w > m.1 { (k, w) } else { m },
                    );
            // At rest after the stop, P_t and U_t are round-off: so is their product.
            assert!(
                w_max <= 1e-15 * MU * STEP * normal * V0,
                "c = {c}: work_friction {w_max:e} > 0 at step {k_max} (p_t {}, u_t {})",
                pt[k_max],
                col(rec, "ut_0")[k_max]
            );
            // While it slides, friction's work is −μ N times the distance; the step that stops
            // it takes what kinetic energy is left, with |p_t| < μ p_n: in all, ½(M + m)v₀².
            let sliding = wf[1..stop].iter().sum::<f64>();
            let expected = -MU * normal * (x[stop - 1] - x[0]);
            assert!(
                (sliding - expected).abs() <= 1e-9 * expected.abs(),
                "c = {c}: Σ work_friction while sliding {sliding} vs −μ N Δx {expected}"
            );
            let total = wf.iter().sum::<f64>();
            let kinetic = -0.5 * (M_CART + M_BOB) * V0 * V0;
            assert!(
                (total - kinetic).abs() <= 1e-10 * kinetic.abs(),
                "c = {c}: Σ work_friction {total} vs −½(M + m)v₀² {kinetic}"
            );
            let err = col(rec, "energy_error");
            let e = col(rec, "energy");
            let lost = e[steps] - e[0];
            assert!(
                (lost - total).abs() <= 1e-9 * lost.abs(),
                "c = {c}: ΔE {lost} vs Σ work_friction {total}"
            );
            assert!(err.iter().all(|x| x.abs() <= 1e-9), "c = {c}: energy_error");
        }
        let res = col(&cart, "position_residual");
        assert!(res.iter().all(|&r| r <= 1e-10), "c = {c}: joints drift");
        println!(
            "c = {c:+}: N = {normal:.6} (m g = {:.6}), stops at step {stop}, x_end = {:.9}, worst deviation {worst:.1e}",
            M_BOB * G,
            x[steps]
        );
        assert!(worst <= 1e-10, "c = {c}: deviation {worst:e}");
    }
}

fn example(name: &str) -> serde_json::Value {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples")
        .join(format!("{name}.toml"));
    let text = std::fs::read_to_string(&path).expect("reading the example");
    let spec: JobSpec = toml::from_str(&text).expect("the example parses");
    serde_json::to_value(&spec).expect("json")
}

fn same_bits(a: &Recorder, b: &Recorder) {
    assert_eq!(a.columns.names(), b.columns.names());
    assert_eq!(a.rows.len(), b.rows.len());
    for (k, (x, y)) in a.rows.iter().zip(&b.rows).enumerate() {
        let bits = |r: &[f64]| r.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(x), bits(y), "row {k}");
    }
}

/// μ = 0 is the frictionless path bit for bit: the jointed double pendulum against a wall
/// (examples/double_pendulum_wall.toml, its mixed LCP) with `friction = 0` and a tangent gives
/// the same steps as without them, and so does the pendulum on its cart.
#[test]
fn joints_with_zero_friction_are_the_frictionless_path_bit_for_bit() {
    let mut smooth = example("double_pendulum_wall");
    smooth["time"]["t_end"] = json!(1.5);
    let mut zero = smooth.clone();
    zero["model"]["contacts"][0]["friction"] = json!(0.0);
    zero["model"]["contacts"][0]["tangent"] = json!("y2");
    same_bits(&record(smooth), &record(zero));
    let c = -(L * L - H * H).sqrt();
    let mut zero = jointed(c, 0.0, 0.3);
    zero["model"]["contacts"][0]["friction"] = json!(0.0);
    zero["model"]["contacts"][0]["tangent"] = json!("xb");
    same_bits(&record(jointed(c, 0.0, 0.3)), &record(zero));
}

/// The Cartesian double pendulum of examples/double_pendulum_wall.toml against a rough wall
/// (μ = 0.3, tangent the lower mass's height y2), h = 1e-3, 1.5 s: a friction problem with two
/// equality rows at every impact and lasting contact. At every step work_friction ≤ 0 (to the
/// solver's round-off), the rods hold to 1e-9, and the ledger closes:
/// ΔE − work_ext − work_contact − work_friction = energy_error to 1e-12 of the energy scale,
/// with |energy_error| ≤ 1e-6 J (θ = ½, ideal joints); friction acts (Σ work_friction < 0),
/// and the friction problem was solved to its tolerance.
#[test]
fn a_jointed_double_pendulum_on_a_rough_wall_closes_its_ledger() {
    let mut doc = example("double_pendulum_wall");
    doc["time"]["t_end"] = json!(1.5);
    doc["model"]["contacts"][0]["friction"] = json!(0.3);
    doc["model"]["contacts"][0]["tangent"] = json!("y2");
    let rec = record(doc);
    let (energy, work_ext, work_contact, wf, err) = (
        col(&rec, "energy"),
        col(&rec, "work_ext"),
        col(&rec, "work_contact"),
        col(&rec, "work_friction"),
        col(&rec, "energy_error"),
    );
    let (pt, ut, res) = (
        col(&rec, "pt_0"),
        col(&rec, "ut_0"),
        col(&rec, "position_residual"),
    );
    let scale = energy.iter().fold(1.0f64, |m, e| m.max(e.abs()));
    let (mut worst_ledger, mut worst_error) = (0.0f64, 0.0f64);
    for k in 1..rec.rows.len() {
        let tol = 1e-12 * pt[k].abs() * ut[k].abs().max(1.0);
        assert!(wf[k] <= tol, "step {k}: work_friction {:e} > 0", wf[k]);
        let ledger = (energy[k] - energy[k - 1]) - work_ext[k] - work_contact[k] - wf[k];
        worst_ledger = worst_ledger.max((ledger - err[k]).abs());
        worst_error = worst_error.max(err[k].abs());
        assert!(res[k] <= 1e-9, "step {k}: position residual {:e}", res[k]);
    }
    let total: f64 = wf.iter().sum();
    println!(
        "Σ work_friction {total:.6} J, Σ work_contact {:.6} J, max |energy_error| {worst_error:.1e} J, ledger {worst_ledger:.1e}",
        work_contact.iter().sum::<f64>()
    );
    assert!(worst_ledger <= 1e-12 * scale, "ledger {worst_ledger:e}");
    assert!(worst_error <= 1e-6, "max |energy_error| {worst_error:e}");
    assert!(total < -1e-3, "friction acts: Σ work_friction {total}");
}
