//! Joints between rigid bodies (issue 29, `[[model.joints]]`) through the job API: a
//! rigid spherical pendulum against the compound pendulum's period and its energy, and a
//! revolute trapdoor falling under gravity onto a stop.

use serde_json::{Value, json};
use signorini_collision::ParryDetectors;
use signorini_core::job::{self, Job};
use signorini_core::observer::Recorder;
use signorini_core::spec::JobSpec;
use std::f64::consts::PI;

const G: f64 = 9.81;

fn record(spec: Value) -> Recorder {
    let spec: JobSpec = serde_json::from_value(spec).expect("a spec serde accepts");
    let job = Job::from_spec(&spec).unwrap_or_else(|e| panic!("refused: {e}"));
    let mut rec = Recorder::default();
    job::run_with_detectors(&job, 1, &mut rec, None, &ParryDetectors)
        .unwrap_or_else(|e| panic!("run failed: {e}"));
    rec
}

fn col(rec: &Recorder, name: &str) -> Vec<f64> {
    rec.column(name)
        .unwrap_or_else(|| panic!("no column {name} in {:?}", rec.columns.names()))
}

/// A ball of radius r = 0.05 m and mass m = 1 kg whose centre hangs L = 1 m below a spherical
/// joint to the world, released at angle φ₀ with a sideways speed (a conical-ish 3D motion when
/// `side` ≠ 0).
fn pendulum(phi0: f64, side: f64, h: f64, t_end: f64) -> Value {
    let l = 1.0;
    json!({
        "model": {
            "scene": "rigid_bodies",
            "bodies": [{
                "name": "bob", "shape": { "kind": "sphere", "radius": 0.05 },
                "mass": 1.0, "inertia": [0.001, 0.001, 0.001],
                "position": [l * phi0.sin(), 0.0, 2.0 - l * phi0.cos()],
                "velocity": [0.0, side, 0.0]
            }],
            "joints": [{ "kind": "spherical", "bodies": ["world", "bob"], "anchor": [0.0, 0.0, 2.0] }]
        },
        "integrator": { "scheme": "moreau_jean" },
        "time": { "h": h, "t_end": t_end }
    })
}

/// Small amplitude (φ₀ = 0.05): the period is that of the compound pendulum,
/// T = 2π √(I_O / (m g L)) (1 + φ₀²/16) with I_O = I + m L² about the joint, measured from the
/// upward zero crossings of x over four periods: within 1e-5 of it (measured 2e-7; the θ = ½
/// scheme's phase error is O(h²)). The joint holds to 1e-12 m in every step (the projection's
/// tolerance).
#[test]
fn a_rigid_spherical_pendulum_swings_with_the_compound_pendulum_period() {
    let phi0: f64 = 0.05;
    let (m, l, i) = (1.0, 1.0, 0.001);
    let exact = 2.0 * PI * ((i + m * l * l) / (m * G * l)).sqrt() * (1.0 + phi0 * phi0 / 16.0);
    let h = 1e-3;
    let rec = record(pendulum(phi0, 0.0, h, 4.5 * exact));
    let x = col(&rec, "bob_x");
    let crossings: Vec<f64> = (1..x.len())
        .filter(|&k| x[k - 1] < 0.0 && x[k] >= 0.0)
        .map(|k| rec.t[k - 1] + h * x[k - 1] / (x[k - 1] - x[k]))
        .collect();
    assert!(crossings.len() >= 4, "{crossings:?}");
    let period = (crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as f64;
    let error = (period - exact).abs() / exact;
    assert!(error <= 1e-5, "period {period}, exact {exact}: {error:e}");
    let residual = col(&rec, "position_residual");
    assert!(residual.iter().all(|r| *r <= 1e-12), "{residual:?}");
    assert!(col(&rec, "contacts").iter().all(|c| *c == 0.0));
}

/// Large 3D motion (φ₀ = ½ rad, thrown sideways at 1 m/s), θ = ½: the energy ledger. The joint
/// impulses do no work on an exact trajectory; in the scheme the joint's velocity rows are taken
/// at the poses of t_k, so (v, Ω)_{k+1} is tangent to the old configuration and loses O(h²)
/// of kinetic energy per step to the next step's joint impulse: the energy drift is first order
/// in h (measured 1.98e-2 and 9.7e-3 of the largest kinetic energy over 2 s at h = 2 ms and
/// 1 ms). Asserted: the drift halves with h (ratio in [1.8, 2.2]) and is ≤ 1e-2 at 1 ms; the
/// joint stays at ≤ 1e-12 m and the bob at L from the anchor; and `energy_error` (ΔE − work_ext −
/// work_contact − work_friction) is exactly the scheme's error: its sum is the drift.
#[test]
fn a_spherical_pendulum_loses_energy_at_first_order_in_h_and_keeps_its_joint_to_round_off() {
    let mut drifts = Vec::new();
    for h in [2e-3, 1e-3] {
        let rec = record(pendulum(0.5, 1.0, h, 2.0));
        let energy = col(&rec, "energy");
        let e0 = energy[0];
        let scale = col(&rec, "kinetic").iter().fold(0.0_f64, |a, b| a.max(*b));
        let drift = energy
            .iter()
            .map(|e| (e - e0).abs())
            .fold(0.0_f64, f64::max)
            / scale;
        drifts.push(drift);
        let errors: f64 = col(&rec, "energy_error").iter().sum();
        assert!(
            (errors - (energy.last().unwrap() - e0)).abs() <= 1e-12 * scale,
            "Σ energy_error {errors:e}"
        );
        let residual = col(&rec, "position_residual");
        assert!(residual.iter().all(|r| *r <= 1e-12));
        // The bob stays at L from the anchor (the spherical joint is at its centre's distance).
        for k in 0..rec.rows.len() {
            let (x, y, z) = (
                col(&rec, "bob_x")[k],
                col(&rec, "bob_y")[k],
                col(&rec, "bob_z")[k] - 2.0,
            );
            let r = (x * x + y * y + z * z).sqrt();
            assert!((r - 1.0).abs() <= 1e-12, "record {k}: |r| = {r}");
        }
    }
    let ratio = drifts[0] / drifts[1];
    assert!((1.8..2.2).contains(&ratio), "{drifts:?}");
    assert!(drifts[1] <= 1e-2, "{drifts:?}");
}

/// A trapdoor: a plate (half extents 0.5 × 0.3 × 0.02 m, 1 kg) hinged to the world along its
/// edge x = 0 (axis y, at height 1 m), released horizontal, swings down under gravity and lands
/// on a stop, the floor at z = 0.5 m (e = 0, μ = 0.3). Before the landing it turns about the
/// hinge only (ω along y; energy: ½ I_O ω² = m g Δz of its centre with I_O = I_yy + m a²), it
/// comes to rest on the stop's corners, and the hinge holds throughout.
#[test]
fn a_revolute_trapdoor_falls_about_its_hinge_and_comes_to_rest_on_a_stop() {
    let (a, b, c, m) = (0.5, 0.3, 0.02, 1.0);
    let spec = json!({
        "model": {
            "scene": "rigid_bodies",
            "contact": { "restitution": 0.0, "friction": 0.3, "margin": 1e-6 },
            "bodies": [
                { "name": "door", "shape": { "kind": "box", "half_extents": [a, b, c] },
                  "mass": m, "inertia": [m * (b * b + c * c) / 3.0, m * (a * a + c * c) / 3.0,
                                         m * (a * a + b * b) / 3.0],
                  "position": [a, 0.0, 1.0] },
                { "name": "stop", "shape": { "kind": "half_space", "normal": [0.0, 0.0, 1.0] },
                  "position": [0.0, 0.0, 0.5] }
            ],
            "joints": [{ "kind": "revolute", "bodies": ["world", "door"],
                         "anchor": [0.0, 0.0, 1.0], "axis": [0.0, 1.0, 0.0] }]
        },
        "integrator": { "scheme": "moreau_jean" },
        "time": { "h": 1e-3, "t_end": 2.0 }
    });
    let rec = record(spec);
    let i_o = m * (a * a + c * c) / 3.0 + m * a * a;
    let contacts = col(&rec, "contacts");
    let landing = contacts
        .iter()
        .position(|c| *c > 0.0)
        .expect("the door lands");
    let k = landing - 2;
    let (wx, wy, wz) = (
        col(&rec, "door_wx")[k],
        col(&rec, "door_wy")[k],
        col(&rec, "door_wz")[k],
    );
    assert!(wx.abs() <= 1e-12 && wz.abs() <= 1e-12, "({wx}, {wy}, {wz})");
    let drop = 1.0 - col(&rec, "door_z")[k];
    let expected = (2.0 * m * G * drop / i_o).sqrt();
    assert!(
        (wy - expected).abs() <= 1e-3 * expected,
        "ω = {wy}, energy says {expected}"
    );
    // At rest on the stop at the end, hinge intact, the far edge's corners on the floor.
    let last = rec.rows.len() - 1;
    for name in [
        "door_vx", "door_vy", "door_vz", "door_wx", "door_wy", "door_wz",
    ] {
        let v = col(&rec, name)[last];
        assert!(v.abs() <= 1e-9, "{name} = {v}");
    }
    assert!(contacts[last] >= 2.0, "{}", contacts[last]);
    let residual = col(&rec, "position_residual");
    assert!(residual.iter().all(|r| *r <= 1e-12), "{residual:?}");
    // The resting angle: the lower far corners, (2a, ±b, −c) in the hinge frame, at
    // z = 1 − 2a sin φ − c cos φ, on the stop up to the penetration of the landing step (the
    // index set takes a contact at predicted gap g + ½ h U_n ≤ margin, so a corner landing at
    // |U_n| ≈ 2.9 m/s can end up to h |U_n| inside, measured 2.4 mm), which `max_penetration`
    // reports exactly.
    let (qw, qy) = (col(&rec, "door_qw")[last], col(&rec, "door_qy")[last]);
    let phi = 2.0 * qy.atan2(qw);
    let corner = 1.0 - (2.0 * a * phi.sin() + c * phi.cos());
    assert!((corner - 0.5).abs() <= 3e-3, "corner at z = {corner}");
    let penetration = col(&rec, "max_penetration")[last];
    assert!(
        (penetration - (0.5 - corner)).abs() <= 1e-9,
        "max_penetration {penetration}, corner at z = {corner}"
    );
}
