//! `scene = "rigid_bodies"` validated at the edge: every error names its field, every scheme but
//! moreau_jean is refused naming `integrator.scheme`, and a run without a contact detector is
//! refused with its own error.

use serde_json::{Value, json};
use signorini_core::job::{self, Job};
use signorini_core::observer::Recorder;
use signorini_core::outcome::RunError;
use signorini_core::spec::JobSpec;

fn base() -> Value {
    json!({
        "model": {
            "scene": "rigid_bodies",
            "contact": { "friction": 0.5, "margin": 1e-6,
                         "pairs": [{ "bodies": ["ball", "floor"], "restitution": 0.5 }] },
            "bodies": [
                { "name": "ball", "shape": { "kind": "sphere", "radius": 0.1 }, "density": 1000.0,
                  "position": [0.0, 0.0, 0.1] },
                { "name": "block", "shape": { "kind": "box", "half_extents": [0.1, 0.1, 0.1] },
                  "density": 500.0, "position": [1.0, 0.0, 0.1] },
                { "name": "floor", "shape": { "kind": "half_space", "normal": [0.0, 0.0, 1.0] } }
            ]
        },
        "integrator": { "scheme": "moreau_jean" },
        "time": { "h": 1e-3, "steps": 10 }
    })
}

fn field_of(spec: Value) -> String {
    let spec: JobSpec = serde_json::from_value(spec).expect("a spec serde accepts");
    Job::from_spec(&spec).expect_err("refused").field
}

#[test]
fn a_valid_scene_builds_and_runs_only_with_a_detector() {
    let spec: JobSpec = serde_json::from_value(base()).unwrap();
    let job = Job::from_spec(&spec).expect("valid");
    // Six degrees of freedom per body.
    assert_eq!(job.size().dofs, 18);
    let err = job::run(&job, 1, &mut Recorder::default()).unwrap_err();
    assert!(matches!(err, RunError::NoDetector), "{err:?}");
}

/// A change to the valid spec.
type Edit = Box<dyn Fn(&mut Value)>;

#[test]
fn every_error_names_its_field() {
    let cases: Vec<(&str, Edit)> = vec![
        (
            "model.bodies[0].shape.radius",
            Box::new(|s| s["model"]["bodies"][0]["shape"]["radius"] = json!(-1.0)),
        ),
        (
            "model.bodies[1].shape.half_extents[2]",
            Box::new(|s| s["model"]["bodies"][1]["shape"]["half_extents"][2] = json!(0.0)),
        ),
        (
            "model.bodies[2].shape.normal",
            Box::new(|s| s["model"]["bodies"][2]["shape"]["normal"] = json!([0.0, 0.0, 2.0])),
        ),
        (
            "model.bodies[0].orientation",
            Box::new(|s| s["model"]["bodies"][0]["orientation"] = json!([1.0, 0.1, 0.0, 0.0])),
        ),
        (
            "model.bodies[1].name",
            Box::new(|s| s["model"]["bodies"][1]["name"] = json!("ball")),
        ),
        (
            "model.bodies[0].density",
            Box::new(|s| {
                s["model"]["bodies"][0]
                    .as_object_mut()
                    .unwrap()
                    .remove("density");
            }),
        ),
        (
            "model.bodies[0].inertia",
            Box::new(|s| {
                s["model"]["bodies"][0]["density"] = json!(null);
                s["model"]["bodies"][0]["mass"] = json!(1.0);
            }),
        ),
        (
            "model.bodies[0].mass",
            Box::new(|s| s["model"]["bodies"][0]["mass"] = json!(0.0)),
        ),
        (
            "model.bodies[2].velocity",
            Box::new(|s| s["model"]["bodies"][2]["velocity"] = json!([1.0, 0.0, 0.0])),
        ),
        (
            "model.contact.pairs[0].bodies[1]",
            Box::new(|s| s["model"]["contact"]["pairs"][0]["bodies"][1] = json!("flor")),
        ),
        (
            "model.contact.pairs[0].restitution",
            Box::new(|s| s["model"]["contact"]["pairs"][0]["restitution"] = json!(1.5)),
        ),
        (
            "model.contact.friction",
            Box::new(|s| s["model"]["contact"]["friction"] = json!(-0.1)),
        ),
        (
            "model.contact.margin",
            Box::new(|s| s["model"]["contact"]["margin"] = json!(-1.0)),
        ),
        (
            "model.joints[0].bodies[0]",
            Box::new(|s| {
                s["model"]["joints"] = json!([{ "kind": "revolute", "bodies": ["arm", "world"] }])
            }),
        ),
        // Joints are implemented since this case was written: the same joint is now refused
        // for the anchor it lacks.
        (
            "model.joints[0].anchor",
            Box::new(|s| {
                s["model"]["joints"] = json!([{ "kind": "revolute", "bodies": ["ball", "world"] }])
            }),
        ),
        (
            "model.joints[0].axis",
            Box::new(|s| {
                s["model"]["joints"] = json!([{ "kind": "revolute", "bodies": ["ball", "world"],
                                                "anchor": [0.0, 0.0, 1.0], "axis": [0.0, 2.0, 0.0] }])
            }),
        ),
        (
            "model.joints[0].axis",
            Box::new(|s| {
                s["model"]["joints"] = json!([{ "kind": "revolute", "bodies": ["ball", "block"],
                                                "anchor": [0.0, 0.0, 1.0] }])
            }),
        ),
        (
            "model.joints[0].axis",
            Box::new(|s| {
                s["model"]["joints"] = json!([{ "kind": "spherical", "bodies": ["ball", "block"],
                                                "anchor": [0.0, 0.0, 1.0], "axis": [0.0, 1.0, 0.0] }])
            }),
        ),
        (
            "model.joints[0].bodies",
            Box::new(|s| {
                s["model"]["joints"] = json!([{ "kind": "spherical", "bodies": ["ball", "ball"],
                                                "anchor": [0.0, 0.0, 1.0] }])
            }),
        ),
        (
            "model.joints[0].bodies",
            Box::new(|s| {
                s["model"]["joints"] = json!([{ "kind": "spherical", "bodies": ["floor", "world"],
                                                "anchor": [0.0, 0.0, 1.0] }])
            }),
        ),
        (
            "model.joints[1].bodies[1]",
            Box::new(|s| {
                s["model"]["joints"] = json!([
                    { "kind": "spherical", "bodies": ["ball", "world"], "anchor": [0.0, 0.0, 1.0] },
                    { "kind": "spherical", "bodies": ["ball", "blok"], "anchor": [0.0, 0.0, 1.0] }])
            }),
        ),
        (
            "model.joints[0].kind",
            Box::new(|s| {
                s["model"]["joints"] = json!([{ "kind": "prismatic", "bodies": ["ball", "world"],
                                                "anchor": [0.0, 0.0, 1.0], "axis": [0.0, 1.0, 0.0] }])
            }),
        ),
        (
            "model.joints[0].kind",
            Box::new(|s| {
                s["model"]["joints"] = json!([{ "kind": "hinge", "bodies": ["ball", "world"],
                                                "anchor": [0.0, 0.0, 1.0] }])
            }),
        ),
        (
            "model.bodies[0].shape.points",
            Box::new(|s| {
                s["model"]["bodies"][0]["shape"] =
                    json!({ "kind": "convex", "points": [[0.0, 0.0, 0.0]] })
            }),
        ),
        (
            "model.bodies[0].density",
            Box::new(
                |s| s["model"]["bodies"][0]["shape"] = json!({ "kind": "convex", "points": [[0.0,0.0,0.0],[1.0,0.0,0.0],[0.0,1.0,0.0],[0.0,0.0,1.0]] }),
            ),
        ),
        (
            "integrator.scheme",
            Box::new(|s| s["integrator"] = json!({ "scheme": "ns_generalized_alpha" })),
        ),
        (
            "integrator.scheme",
            Box::new(|s| s["integrator"] = json!({ "scheme": "soi2_generalized_alpha" })),
        ),
        (
            "integrator.scheme",
            Box::new(|s| s["integrator"] = json!({ "scheme": "wfem" })),
        ),
        (
            "integrator.theta",
            Box::new(|s| s["integrator"]["theta"] = json!(1.5)),
        ),
        (
            "contact_solver.kind",
            Box::new(|s| s["contact_solver"] = json!({ "kind": "lemke" })),
        ),
        (
            "contact_solver.accept_error",
            Box::new(|s| s["contact_solver"] = json!({ "tolerance": 1e-6, "accept_error": 1e-7 })),
        ),
        (
            "output.probes",
            Box::new(|s| s["output"] = json!({ "probes": [0] })),
        ),
    ];
    for (field, edit) in cases {
        let mut spec = base();
        edit(&mut spec);
        assert_eq!(field_of(spec), field);
    }
}

/// `contact_solver.accept_error` is a rigid scene's alone: a model whose steps solve their contact
/// problem to the tolerance or fail refuses it, naming the field.
#[test]
fn accept_error_is_refused_outside_rigid_scenes() {
    let ball = json!({
        "model": { "scene": "bouncing_ball" },
        "integrator": { "scheme": "moreau_jean" },
        "time": { "h": 1e-3, "steps": 10 },
        "contact_solver": { "accept_error": 1e-4 }
    });
    assert_eq!(field_of(ball), "contact_solver.accept_error");
    let mut rigid = base();
    rigid["contact_solver"] = json!({ "tolerance": 1e-6, "accept_error": 1e-4 });
    let spec: JobSpec = serde_json::from_value(rigid).unwrap();
    Job::from_spec(&spec).expect("a rigid scene takes it");
}
