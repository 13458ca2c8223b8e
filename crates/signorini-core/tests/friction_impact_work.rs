//! `work_friction` at impacts with normal–tangential coupling (issue 26): a double pendulum in
//! its two angles whose lower mass strikes a rough wall (e = ½, μ = 0.3), under the nonlinear
//! Moreau–Jean time-stepping with θ = ½ and h = 1e-3, every step recorded. This is the setting
//! of Kane's double-pendulum paradox: at the first impact the normal impulse drives the lower
//! mass's tangential velocity through the Delassus operator's coupling W_tn, friction takes it
//! back, and the tangential impulse's work on U_{t,k+½} is positive (+4.4 J) although the whole
//! impulse's work is negative. `work_friction` is split as `friction::split_tangential_work`
//! says: ≤ 0 at every step, the reversing steps reporting ½ P_t U_{t,k+1}, and the ledger
//! (ΔE − work_ext − work_contact − work_friction = energy_error) closed at every step.

// Only the core library must stay pure (clippy.toml): a test may print.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use signorini_core::friction::split_tangential_work;
use signorini_core::job::{Job, run};
use signorini_core::observer::Recorder;
use signorini_core::spec::JobSpec;

/// The rough double pendulum: point masses m1 = m2 = 1 on rods L1 = L2 = 1, angles from the
/// downward vertical, released from rest with both rods horizontal to the left; the wall
/// x = 0.5 (gap 0.5 − x2) with restitution ½ and friction μ, tangent the lower mass's height.
fn rough_double_pendulum(mu: f64) -> JobSpec {
    let mut contact =
        serde_json::json!({"gap": "0.5 - L1*sin(p1) - L2*sin(p2)", "restitution": 0.5});
    if mu > 0.0 {
        contact["friction"] = serde_json::json!(mu);
        contact["tangent"] = serde_json::json!("-L1*cos(p1) - L2*cos(p2)");
    }
    serde_json::from_value(serde_json::json!({
        "model": {
            "scene": "lagrangian",
            "coordinates": ["p1", "p2"],
            "parameters": {"m1": 1.0, "m2": 1.0, "L1": 1.0, "L2": 1.0, "g": 9.81},
            "mass": [
                ["(m1 + m2)*L1^2", "m2*L1*L2*cos(p1 - p2)"],
                ["m2*L1*L2*cos(p1 - p2)", "m2*L2^2"]
            ],
            "potential": "-(m1 + m2)*g*L1*cos(p1) - m2*g*L2*cos(p2)",
            "q0": [-std::f64::consts::FRAC_PI_2, -std::f64::consts::FRAC_PI_2],
            "contacts": [contact]
        },
        "integrator": {"scheme": "moreau_jean", "theta": 0.5},
        "time": {"h": 1e-3, "t_end": 1.5},
        "output": {"probes": [0, 1]}
    }))
    .expect("rough double pendulum spec")
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

#[test]
fn friction_never_does_positive_work_at_the_impacts_of_a_rough_double_pendulum() {
    let rec = record(&rough_double_pendulum(0.3));
    let (pt, ut, p) = (col(&rec, "pt_0"), col(&rec, "ut_0"), col(&rec, "p_0"));
    let wf = col(&rec, "work_friction");
    let (energy, work_ext, work_contact, error) = (
        col(&rec, "energy"),
        col(&rec, "work_ext"),
        col(&rec, "work_contact"),
        col(&rec, "energy_error"),
    );
    let scale = energy.iter().fold(1.0f64, |m, e| m.max(e.abs()));
    let (mut reversals, mut moved) = (0, 0.0);
    for k in 1..rec.rows.len() {
        // Round-off of Coulomb's law on U_t,{k+1} (the friction solver's tolerance).
        let tol = 1e-12 * pt[k].abs() * ut[k].abs().max(1.0);
        assert!(wf[k] <= tol, "step {k}: work_friction {:e} > 0", wf[k]);
        // The ledger closes on every step: the split moves work, it does not create any.
        let ledger = (energy[k] - energy[k - 1]) - work_ext[k] - work_contact[k] - wf[k];
        assert!(
            (ledger - error[k]).abs() <= 1e-12 * scale,
            "step {k}: ledger {ledger:e} vs energy_error {:e}",
            error[k]
        );
        // A reversing step (the friction impulse along the start velocity, U_t,k = the last
        // step's ut_0) reports ½ P_t U_t,{k+1}.
        let at_start = pt[k] * ut[k - 1];
        if p[k] > 0.0 && at_start > 0.0 {
            reversals += 1;
            moved += 0.5 * at_start;
            let end = 0.5 * pt[k] * ut[k];
            // ut_0 is T(q_{k+1}) v_{k+1}, the split's U_t,{k+1} the last Newton iterate's.
            assert!(
                (wf[k] - end).abs() <= 1e-8 * pt[k].abs() * ut[k].abs().max(1.0),
                "step {k}: work_friction {:e} vs ½ P_t U_t,k+1 = {end:e}",
                wf[k]
            );
        }
    }
    let worst_error = error.iter().fold(0.0f64, |m, e| m.max(e.abs()));
    let total = *col(&rec, "work_friction_total").last().unwrap();
    println!(
        "{reversals} reversing steps, {moved:.4} J moved to work_contact, Σ work_friction = \
         {total:.4} J, max |energy_error| = {worst_error:e}"
    );
    // Kane's setting is reached: the first impact alone moves more than 4 J.
    assert!(moved > 4.0, "moved {moved}");
    assert!(total < 0.0, "Σ work_friction = {total}");
    // The scheme's energy error of this nonlinear model (O(h²) between impacts) stays small.
    assert!(
        worst_error <= 1e-2 * scale,
        "max |energy_error| {worst_error:e}"
    );
}

#[test]
fn the_rough_double_pendulum_without_friction_is_the_frictionless_model_bit_for_bit() {
    let smooth = record(&rough_double_pendulum(0.0));
    let mut spec = serde_json::to_value(rough_double_pendulum(0.0)).unwrap();
    spec["model"]["contacts"][0]["friction"] = serde_json::json!(0.0);
    spec["model"]["contacts"][0]["tangent"] = serde_json::json!("-L1*cos(p1) - L2*cos(p2)");
    let zero = record(&serde_json::from_value(spec).unwrap());
    assert_eq!(smooth.columns.names(), zero.columns.names());
    assert_eq!(smooth.rows.len(), zero.rows.len());
    for (a, b) in smooth.rows.iter().zip(&zero.rows) {
        let (a, b): (Vec<u64>, Vec<u64>) = (
            a.iter().map(|x| x.to_bits()).collect(),
            b.iter().map(|x| x.to_bits()).collect(),
        );
        assert_eq!(a, b);
    }
}

#[test]
fn a_step_without_reversal_keeps_its_tangential_work() {
    let w = split_tangential_work(-0.3, 0.5, -0.2, -0.4);
    assert_eq!(w.friction.to_bits(), (-0.3f64).to_bits());
    assert_eq!(w.contact, 0.0);
}

#[test]
fn a_reversing_step_reports_the_end_term_and_moves_the_rest_to_the_contact() {
    // Kane's setting: P_t = 4, U_t = 2.2 before and 0 after (sticking): W_t = ½·4·2.2.
    let (pt, before, after) = (4.0, 2.2, 0.0);
    let work = pt * (0.5 * after + 0.5 * before);
    let w = split_tangential_work(work, 0.5, pt * before, pt * after);
    assert_eq!(w.friction, 0.0);
    assert_eq!(w.contact, 4.4);
    // Sliding on after the reversal: the friction part is ½ P_t U_t,{k+1} < 0.
    let w = split_tangential_work(pt * 0.5 * (2.2 - 1.0), 0.5, pt * 2.2, -pt);
    assert_eq!(w.friction, -2.0);
    assert!((w.friction + w.contact - 2.4).abs() <= 1e-15);
}
