//! The `contacts` table of a rigid run (`output.contacts = true`): a box resting on a
//! floor touches it through four corners whose normal impulses carry its weight over each step,
//! Σ P_n = m g h, and the table's points, normals and world impulses say where and how.

use signorini_collision::ParryDetectors;
use signorini_core::job::{self, Job};
use signorini_core::observer::Recorder;
use signorini_core::rigid::CONTACT_COLUMNS;
use signorini_core::spec::JobSpec;

const H: f64 = 1e-3;
const G: f64 = 9.81;

/// A 0.2 m cube of density 500 (m = 4 kg) at rest on the floor, recorded every 5th step.
fn resting_box(output: serde_json::Value) -> JobSpec {
    serde_json::from_value(serde_json::json!({
        "model": {
            "scene": "rigid_bodies",
            "gravity": [0.0, 0.0, -G],
            "contact": { "friction": 0.5, "restitution": 0.0, "margin": 1e-6 },
            "bodies": [
                { "name": "floor", "shape": { "kind": "half_space", "normal": [0.0, 0.0, 1.0] } },
                { "name": "cube", "shape": { "kind": "box", "half_extents": [0.1, 0.1, 0.1] },
                  "density": 500.0, "position": [0.3, -0.2, 0.1] }
            ]
        },
        "integrator": { "scheme": "moreau_jean" },
        "time": { "h": H, "steps": 50 },
        "output": output
    }))
    .unwrap()
}

#[test]
fn a_resting_box_has_four_contacts_whose_normal_impulses_sum_to_m_g_h() {
    let job = Job::from_spec(&resting_box(
        serde_json::json!({ "every": 5, "contacts": true }),
    ))
    .unwrap();
    let mut rec = Recorder::default();
    let out = job::run_with_detectors(&job, 1, &mut rec, None, &ParryDetectors).unwrap();
    assert_eq!(out.tables.len(), 1);
    let table = &out.tables[0];
    assert_eq!(table.name, "contacts");
    assert_eq!(table.columns, CONTACT_COLUMNS.to_vec());
    let col = |name: &str| table.columns.iter().position(|c| c == name).unwrap();
    let m = 500.0 * 0.2 * 0.2 * 0.2;
    // Records at steps 5, 10, …, 50 (step 0 has no step behind it): four rows each.
    let recorded: Vec<u64> = rec.steps.iter().copied().filter(|&k| k > 0).collect();
    assert_eq!(recorded.len(), 10);
    assert_eq!(table.rows.len(), 4 * recorded.len());
    for (i, &k) in recorded.iter().enumerate() {
        let rows = &table.rows[4 * i..4 * i + 4];
        let sum: f64 = rows.iter().map(|r| r[col("p_n")]).sum();
        assert!(
            (sum - m * G * H).abs() <= 1e-12 * m * G * H,
            "step {k}: Σ P_n = {sum}, m g h = {}",
            m * G * H
        );
        for r in rows {
            assert_eq!(r[col("step")], k as f64);
            assert!((r[col("t")] - k as f64 * H).abs() < 1e-15);
            // From the floor (body 0) to the cube (body 1), normal +z, at a corner on z = 0.
            assert_eq!([r[col("body_0")], r[col("body_1")]], [0.0, 1.0]);
            assert_eq!([r[col("nx")], r[col("ny")], r[col("nz")]], [0.0, 0.0, 1.0]);
            assert!(r[col("z")].abs() < 1e-9 && r[col("gap")].abs() < 1e-9);
            assert!(((r[col("x")] - 0.3).abs() - 0.1).abs() < 1e-9);
            assert!(((r[col("y")] + 0.2).abs() - 0.1).abs() < 1e-9);
            // The world impulse is the frame's: its z part is P_n (the tangents are horizontal).
            assert!((r[col("pz")] - r[col("p_n")]).abs() < 1e-15);
        }
        // The four corners' friction impulses may push against each other (the Delassus
        // operator of four coplanar corners is singular) but the box stays at rest: they sum to
        // zero, and each lies in the cone.
        for axis in ["px", "py"] {
            let net: f64 = rows.iter().map(|r| r[col(axis)]).sum();
            assert!(net.abs() <= 1e-12 * m * G * H, "step {k}: Σ {axis} = {net}");
        }
        for r in rows {
            let tangential = r[col("p_t1")].hypot(r[col("p_t2")]);
            assert!(tangential <= 0.5 * r[col("p_n")] * (1.0 + 1e-9), "{r:?}");
        }
    }
    // The table does not change the run: steps.csv is the same without it.
    let plain = Job::from_spec(&resting_box(serde_json::json!({ "every": 5 }))).unwrap();
    let mut rec_plain = Recorder::default();
    let out_plain =
        job::run_with_detectors(&plain, 1, &mut rec_plain, None, &ParryDetectors).unwrap();
    assert!(out_plain.tables.is_empty());
    assert_eq!(rec.rows, rec_plain.rows);
}

#[test]
fn contacts_and_vtk_are_refused_outside_rigid_bodies_naming_the_field() {
    for field in ["contacts", "vtk"] {
        let spec: JobSpec = serde_json::from_value(serde_json::json!({
            "model": { "scene": "bouncing_ball" },
            "integrator": { "scheme": "moreau_jean" },
            "time": { "h": 1e-3, "steps": 10 },
            "output": { field: true }
        }))
        .unwrap();
        let err = Job::from_spec(&spec).expect_err("refused");
        assert_eq!(err.field, format!("output.{field}"));
    }
}
