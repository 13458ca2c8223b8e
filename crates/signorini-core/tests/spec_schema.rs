//! The JSON Schema generated from the spec types (`signorini schema`) accepts every example spec
//! and refuses what serde refuses: an unknown field, a wrong type, an unknown scene or scheme, a
//! value outside a checked range. Validated by an independent JSON-Schema validator (boon).

// Only the core library must stay pure (clippy.toml): a test may read fixtures and print.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use serde_json::{Value, json};
use signorini_core::spec::{JobSpec, json_schema};
use std::path::Path;

struct Validator {
    schemas: boon::Schemas,
    index: boon::SchemaIndex,
}

impl Validator {
    fn new() -> Self {
        let mut schemas = boon::Schemas::new();
        let mut compiler = boon::Compiler::new();
        let url = "urn:signorini:job-spec";
        compiler
            .add_resource(url, json_schema())
            .expect("the schema is a JSON document");
        let index = compiler
            .compile(url, &mut schemas)
            .unwrap_or_else(|e| panic!("the generated schema compiles: {e:#}"));
        Self { schemas, index }
    }

    fn check(&self, spec: &Value) -> Result<(), String> {
        self.schemas
            .validate(spec, self.index)
            .map_err(|e| format!("{e:#}"))
    }
}

#[test]
fn every_example_validates_against_the_schema() {
    let validator = Validator::new();
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .expect("examples/")
        .map(|e| e.expect("dir entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml" || e == "json"))
        .collect();
    files.sort();
    assert!(files.len() >= 10, "the example corpus: {files:?}");
    for path in &files {
        let text = std::fs::read_to_string(path).expect("reading an example");
        let spec: Value = if path.extension().is_some_and(|e| e == "json") {
            serde_json::from_str(&text).expect("JSON")
        } else {
            toml::from_str(&text).expect("TOML")
        };
        validator
            .check(&spec)
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        // serde agrees.
        serde_json::from_value::<JobSpec>(spec)
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    }
}

#[test]
fn specs_serde_refuses_are_refused_by_the_schema() {
    let validator = Validator::new();
    let ok = json!({
        "$schema": "./signorini.schema.json",
        "model": {"scene": "chain", "restitution": 0.5},
        "integrator": {"scheme": "ns_hht", "alpha": 0.1, "activation": "predicted_gap", "activation_gamma": 0.5},
        "time": {"h": 0.01, "steps": 10},
        "output": {"every": 2, "probes": [0, 1]}
    });
    validator.check(&ok).expect("a valid spec");
    serde_json::from_value::<JobSpec>(ok.clone()).expect("serde accepts it too");
    let bad = |pointer: &str, value: Value| {
        let mut spec = ok.clone();
        let (parent, key) = pointer.rsplit_once('/').expect("a pointer");
        spec.pointer_mut(parent)
            .and_then(Value::as_object_mut)
            .expect("parent object")
            .insert(key.to_string(), value);
        spec
    };
    for (what, spec) in [
        ("unknown top-level field", bad("/nmae", json!("x"))),
        ("unknown model field", bad("/model/mas", json!(1.0))),
        (
            "unknown integrator field",
            bad("/integrator/activaton", json!("predicted_gap")),
        ),
        (
            "a group field on a scheme without it",
            bad("/integrator/newton", json!("full")),
        ),
        ("unknown time field", bad("/time/stpes", json!(3))),
        ("wrong type", bad("/model/masses", json!("x"))),
        (
            "wrong type in a group",
            bad("/integrator/activation_gamma", json!("big")),
        ),
        ("unknown scene", bad("/model/scene", json!("trampoline"))),
        (
            "unknown scheme",
            bad("/integrator/scheme", json!("ns_hhht")),
        ),
        (
            "unknown enum value",
            bad("/integrator/activation", json!("sometimes")),
        ),
        ("missing required field", {
            let mut s = ok.clone();
            s["time"].as_object_mut().expect("time").remove("h");
            s
        }),
        ("restitution above 1", bad("/model/restitution", json!(1.5))),
        ("every = 0", bad("/output/every", json!(0))),
        ("h = 0", bad("/time/h", json!(0.0))),
    ] {
        assert!(validator.check(&spec).is_err(), "{what}: {spec}");
    }
    // The same unknown field and wrong type are refused by serde (the schema says no more).
    for spec in [
        bad("/model/mas", json!(1.0)),
        bad("/model/masses", json!("x")),
    ] {
        assert!(serde_json::from_value::<JobSpec>(spec).is_err());
    }
}

#[test]
fn fields_carry_their_doc_default_and_range() {
    let schema = json_schema();
    let defs = &schema["$defs"];
    let time = &defs["TimeSpec"]["properties"]["h"];
    assert_eq!(time["exclusiveMinimum"], 0.0, "{time}");
    assert!(
        time["description"]
            .as_str()
            .is_some_and(|d| d.contains("Step size"))
    );
    let every = &defs["OutputSpec"]["properties"]["every"];
    assert_eq!(every["default"], 1, "{every}");
    assert_eq!(every["minimum"], 1, "{every}");
    let solver = &defs["ContactSolverSpec"]["properties"]["tolerance"];
    assert_eq!(solver["default"], 1e-12, "{solver}");
}
