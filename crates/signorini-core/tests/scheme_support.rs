//! The scheme × feature table (`spec::support::TABLE`) against the validation: for every row and
//! feature, a spec with that feature under that scheme is built and handed to
//! `Job::from_spec`. A refused feature must be refused naming the table's field, with the
//! table's reason after the scheme's name; a feature taken must be accepted (the linear,
//! `lagrangian` and built-in constrained families; rigid bodies for contacts, friction and 3D
//! tangents). `capabilities` lists the same rows, so what it says and what validation does
//! cannot drift apart.

// Only the core library must stay pure (clippy.toml): a test may read fixtures and print.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use serde_json::{Value, json};
use signorini_core::capabilities::capabilities;
use signorini_core::job::Job;
use signorini_core::spec::JobSpec;
use signorini_core::spec::support::{Feature, ModelFamily, Support, TABLE};
use std::path::Path;

fn example(name: &str) -> Value {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples")
        .join(format!("{name}.toml"));
    let text = std::fs::read_to_string(&path).expect("reading the example");
    let spec: JobSpec = toml::from_str(&text).expect("the example parses");
    serde_json::to_value(&spec).expect("json")
}

/// A point mass (x, y) under gravity: with a rod joint to the origin (`joints`), and with a floor
/// 0.5 below the origin as a contact (`contacts`), rough when `mu` > 0.
fn point_mass(joints: bool, contacts: bool, mu: f64) -> Value {
    let mut contact = json!({"gap": "y + 0.5", "restitution": 0.5});
    if mu > 0.0 {
        contact["friction"] = json!(mu);
        contact["tangent"] = json!("x");
    }
    let constraints = if joints {
        json!([{"expr": "(x^2 + y^2 - 1)/2"}])
    } else {
        json!([])
    };
    let contacts = if contacts {
        json!([contact])
    } else {
        json!([])
    };
    json!({
        "scene": "lagrangian",
        "coordinates": ["x", "y"],
        "parameters": {"m": 1.0, "g": 9.81},
        "mass": [["m", 0], [0, "m"]],
        "potential": "m*g*y",
        "q0": [1.0, 0.0],
        "v0": [0.0, 0.0],
        "constraints": constraints,
        "contacts": contacts
    })
}

/// A spec of `family` with `feature` and as little else as the family allows, under `scheme`
/// with its defaults (ns_hht: α = 0.1, hht_position_contact: α = 0.1, which have none);
/// `None` when the family cannot express the feature here.
fn spec_with(family: ModelFamily, scheme: &str, feature: Feature) -> Option<Value> {
    let mut doc = match family {
        ModelFamily::Linear if scheme == "wfem" => example("wfem_dep_bar"),
        ModelFamily::Linear => {
            let mut doc = example("chain_rough_wall");
            if feature != Feature::Friction {
                let model = doc["model"].as_object_mut()?;
                model.remove("friction");
                model.remove("t_matrix");
            }
            doc
        }
        ModelFamily::Lagrangian => {
            let model = match feature {
                Feature::Contacts => point_mass(false, true, 0.0),
                Feature::Friction => point_mass(false, true, 0.3),
                Feature::Joints | Feature::VariableStep => point_mass(true, false, 0.0),
                Feature::RedundantJoints => {
                    let mut m = point_mass(true, false, 0.0);
                    m["redundant_joints"] = json!(true);
                    m
                }
                _ => return None,
            };
            json!({"model": model, "time": {"h": 1e-3, "t_end": 0.01}})
        }
        ModelFamily::ConstrainedScene => {
            let scene = match feature {
                Feature::Nonholonomic => "jay_negrut_test",
                _ => "pendulum",
            };
            json!({"model": {"scene": scene}, "time": {"h": 0.01, "t_end": 0.1}})
        }
        ModelFamily::RigidBodies => match feature {
            Feature::Contacts | Feature::Friction | Feature::Tangents3d | Feature::VariableStep => {
                example("rigid/ball_slide_roll")
            }
            _ => return None,
        },
    };
    if scheme == "ns_hht" || scheme == "hht_position_contact" {
        // Their α has no default.
        doc["integrator"] = json!({"scheme": scheme, "alpha": 0.1});
    } else if scheme != "wfem" {
        doc["integrator"] = json!({"scheme": scheme});
    }
    if feature == Feature::VariableStep {
        doc["time"]["pattern"] = json!([1.0, 0.5]);
    }
    Some(doc)
}

#[test]
fn every_refusal_of_the_table_names_its_field_and_every_feature_taken_is_accepted() {
    let (mut refused, mut taken) = (0, 0);
    for row in &TABLE {
        for (feature, support) in row.features {
            if support == Support::NotInModel {
                continue;
            }
            let Some(doc) = spec_with(row.family, row.scheme, feature) else {
                continue;
            };
            let what = format!("{} on {:?} with {:?}", row.scheme, row.family, feature);
            let spec: JobSpec = serde_json::from_value(doc)
                .unwrap_or_else(|e| panic!("{what}: the spec does not parse: {e}"));
            match (support, Job::from_spec(&spec)) {
                (Support::Refused { field, reason }, Err(e)) => {
                    assert_eq!(e.field, field, "{what}: {e}");
                    assert!(
                        e.reason.starts_with(&format!("{} {reason}", row.scheme)),
                        "{what}: {e}"
                    );
                    refused += 1;
                }
                (Support::Refused { .. }, Ok(_)) => {
                    panic!("{what}: accepted, the table refuses it")
                }
                (Support::Takes, Ok(_)) => taken += 1,
                (Support::Takes, Err(e)) => panic!("{what}: refused, the table takes it: {e}"),
                (Support::NotInModel, _) => unreachable!(),
            }
        }
    }
    println!("{refused} refusals and {taken} features taken checked");
    // Every refusal the table holds for a family this test can build was walked.
    assert_eq!(
        (refused, taken),
        (23, 41),
        "refusals and features taken walked"
    );
}

/// `capabilities` carries the table, row for row.
#[test]
fn capabilities_list_the_table() {
    let caps = capabilities();
    assert_eq!(caps.support, TABLE.to_vec());
    let mj = caps
        .support
        .iter()
        .find(|r| r.scheme == "moreau_jean" && r.family == ModelFamily::Lagrangian)
        .expect("moreau_jean on lagrangian");
    for (feature, support) in mj.features {
        let expected = match feature {
            Feature::Contacts | Feature::Friction | Feature::Joints => Support::Takes,
            Feature::Tangents3d | Feature::Nonholonomic => Support::NotInModel,
            Feature::RedundantJoints | Feature::VariableStep => continue,
        };
        assert_eq!(support, expected, "{feature:?}");
    }
}
