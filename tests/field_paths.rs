//! Issue 30, item 2: field paths right in every deserialisation error, audited section by
//! section. For every top-level section of a spec (`name`, `model` of each kind of scene,
//! `integrator`, `time`, `contact_solver`, `output`, `analysis`, `check`, `study` with its base,
//! schemes and reference) one value of the wrong type or one misspelt field, sent through the CLI
//! (`signorini run` of a TOML file: exit 1, `FIELD: reason` on stderr), HTTP (`POST /v1/jobs`:
//! 400, `error.field`) and gRPC (`SubmitJob` with the JSON spelling: INVALID_ARGUMENT,
//! `x-error-field`), is named by the same full path everywhere.

mod common;

use common::refusals::{edit, refusals};
use common::{Options, TestServer};
use serde_json::{Value, json};
use tonic::Code;

/// The bouncing ball with every optional section of a run.
fn ball() -> Value {
    json!({
        "name": "ball",
        "model": {"scene": "bouncing_ball", "mass": 1.0, "gravity": 9.81, "q0": 1.0, "v0": 0.0,
                  "restitution": 0.9},
        "integrator": {"scheme": "moreau_jean", "theta": 0.5},
        "time": {"h": 0.01, "t_end": 0.1},
        "contact_solver": {"kind": "lemke"},
        "output": {"every": 1, "probes": [0]},
        "check": {"max_balance_residual": 1e-12,
                  "reference": [{"column": "q_0", "t": 0.1, "value": 0.95, "tolerance": 0.1}]}
    })
}

/// A user model with a joint and a contact with friction.
fn lagrangian() -> Value {
    json!({
        "model": {"scene": "lagrangian", "coordinates": ["x", "y"], "parameters": {"m": 1.0},
                  "mass": [["m", 0], [0, "m"]], "potential": "9.81*m*y", "q0": [0.0, 1.0],
                  "contacts": [{"gap": "y", "restitution": 0.5, "friction": 0.2, "tangent": "x"}]},
        "integrator": {"scheme": "moreau_jean", "theta": 0.5},
        "time": {"h": 0.01, "t_end": 0.1}
    })
}

/// A ball on a floor, rigid bodies.
fn rigid() -> Value {
    json!({
        "model": {"scene": "rigid_bodies", "gravity": [0.0, 0.0, -9.81],
                  "contact": {"friction": 0.2, "restitution": 0.0},
                  "bodies": [{"name": "ball", "shape": {"kind": "sphere", "radius": 0.1},
                              "density": 1000.0, "position": [0.0, 0.0, 0.1]},
                             {"name": "floor",
                              "shape": {"kind": "half_space", "normal": [0.0, 0.0, 1.0]}}]},
        "integrator": {"scheme": "moreau_jean", "theta": 0.5},
        "time": {"h": 0.001, "t_end": 0.01}
    })
}

/// The nonsmooth modal analysis of a short bar.
fn analysis() -> Value {
    json!({"analysis": {"kind": "nonsmooth_modes", "cells": 10, "gaps": [1e-3],
                        "max_period_steps": 40, "phases": 1, "stability_periods": 1}})
}

/// A study of the ball over two step sizes, its base inline.
fn study() -> Value {
    let mut base = ball();
    base.as_object_mut().expect("a table").remove("check");
    json!({"study": {"base": base, "reference": {"scheme": "moreau_jean", "theta": 0.5, "h": 1e-3},
                     "error": "max_abs",
                     "schemes": [{"scheme": "moreau_jean", "theta": 0.5},
                                 {"scheme": "ns_generalized_alpha", "rho_inf": 0.8}],
                     "grid": {"time.h": [1e-2, 5e-3]}}})
}

/// (section, the spec with one bad field, the field the error must name, a piece of the reason)
fn cases() -> Vec<(&'static str, Value, &'static str, &'static str)> {
    vec![
        (
            "name",
            edit(ball(), "/name", json!(3)),
            "name",
            "invalid type",
        ),
        (
            "model (linear scene)",
            edit(ball(), "/model/restitution", json!("high")),
            "model.restitution",
            "invalid type",
        ),
        (
            "model (linear scene)",
            edit(ball(), "/model/mas", json!(1.0)),
            "model.mas",
            "unknown field",
        ),
        (
            "model (lagrangian)",
            edit(lagrangian(), "/model/contacts/0/friction", json!("rough")),
            "model.contacts[0].friction",
            "invalid type",
        ),
        (
            "model (lagrangian)",
            edit(lagrangian(), "/model/parameters/m", json!([1])),
            "model.parameters.m",
            "",
        ),
        (
            "model (rigid bodies)",
            edit(rigid(), "/model/bodies/0/shape/radius", json!("big")),
            "model.bodies[0].shape.radius",
            "invalid type",
        ),
        (
            "model (rigid bodies)",
            edit(rigid(), "/model/contact/frictoin", json!(0.1)),
            "model.contact.frictoin",
            "unknown field",
        ),
        (
            "model (rigid bodies)",
            edit(rigid(), "/model/bodies/1/position", json!([0.0, "x", 0.0])),
            "model.bodies[1].position[1]",
            "invalid type",
        ),
        (
            "integrator",
            edit(ball(), "/integrator/theta", json!("half")),
            "integrator.theta",
            "invalid type",
        ),
        (
            "integrator",
            edit(ball(), "/integrator/thetta", json!(0.5)),
            "integrator.thetta",
            "unknown field",
        ),
        (
            "time",
            edit(ball(), "/time/h", json!("0.01")),
            "time.h",
            "invalid type",
        ),
        (
            "time",
            edit(ball(), "/time/pattern", json!([1.0, "x"])),
            "time.pattern[1]",
            "invalid type",
        ),
        (
            "contact_solver",
            edit(ball(), "/contact_solver/kind", json!("lemk")),
            "contact_solver.kind",
            "unknown variant",
        ),
        (
            "contact_solver",
            edit(ball(), "/contact_solver/tolerance", json!(true)),
            "contact_solver.tolerance",
            "invalid type",
        ),
        (
            "output",
            edit(ball(), "/output/probes", json!([0, "q"])),
            "output.probes[1]",
            "invalid type",
        ),
        (
            "output",
            edit(ball(), "/output/evry", json!(2)),
            "output.evry",
            "unknown field",
        ),
        (
            "analysis",
            edit(analysis(), "/analysis/gaps", json!([1e-3, "x"])),
            "analysis.gaps[1]",
            "invalid type",
        ),
        (
            "analysis",
            edit(analysis(), "/analysis/cels", json!(10)),
            "analysis.cels",
            "unknown field",
        ),
        (
            "check",
            edit(ball(), "/check/max_balance_residual", json!("tiny")),
            "check.max_balance_residual",
            "invalid type",
        ),
        (
            "check",
            edit(ball(), "/check/reference/0/colum", json!("q_0")),
            "check.reference[0].colum",
            "unknown field",
        ),
        (
            "study",
            edit(study(), "/study/eror", json!("max_abs")),
            "study.eror",
            "unknown field",
        ),
        (
            "study (inline base)",
            edit(study(), "/study/base/time/h", json!("x")),
            "study.base.time.h",
            "invalid type",
        ),
        (
            "study (inline base)",
            edit(study(), "/study/base/model/restitutoin", json!(0.5)),
            "study.base.model.restitutoin",
            "unknown field",
        ),
        (
            "study (schemes)",
            edit(study(), "/study/schemes/1/rho_inf", json!("x")),
            "study.schemes[1].rho_inf",
            "invalid type",
        ),
        (
            "study (schemes)",
            edit(study(), "/study/schemes/0/thetta", json!(0.5)),
            "study.schemes[0].thetta",
            "unknown field",
        ),
        (
            "study (reference)",
            edit(study(), "/study/reference/h", json!("fine")),
            "study.reference.h",
            "invalid type",
        ),
        (
            "study (grid)",
            edit(study(), "/study/grid", json!({"time.h": 1e-3})),
            "study.grid.time.h",
            "invalid type",
        ),
    ]
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn one_bad_field_per_section_is_named_by_its_path_over_cli_http_and_grpc() {
    let dir = tempfile::tempdir().expect("tempdir");
    let server = TestServer::start(&dir.path().join("store.db"), &Options::default());
    let mut client = server.grpc().await;
    let mut wrong = Vec::new();
    for (section, spec, field, reason) in cases() {
        let said = refusals(&server, &mut client, dir.path(), &spec).await;
        let cli_ok = said.cli_code == Some(1)
            && said.cli_stderr.contains(&format!("bad.toml: {field}: "))
            && said.cli_stderr.contains(reason);
        if !cli_ok {
            wrong.push(format!("{section}, CLI: {field}: {}", said.cli_stderr));
        }
        let reason_said = said.http_body["error"]["reason"]
            .as_str()
            .unwrap_or_default();
        if said.http_code != 400
            || said.http_body["error"]["field"] != field
            || !reason_said.contains(reason)
        {
            wrong.push(format!(
                "{section}, HTTP: {field}: {} {}",
                said.http_code, said.http_body
            ));
        }
        if said.grpc_code != Code::InvalidArgument || said.grpc_field.as_deref() != Some(field) {
            wrong.push(format!(
                "{section}, gRPC: {field}: {:?} {:?} {}",
                said.grpc_code, said.grpc_field, said.grpc_message
            ));
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

/// The bases above are valid as they are, so each case's error is its one edit's.
#[test]
fn the_bases_are_valid() {
    for base in [ball(), lagrangian(), rigid(), analysis(), study()] {
        let text = toml::to_string(&base).expect("TOML");
        signorini::spec_file::parse(&text, signorini::spec_file::Format::Toml)
            .unwrap_or_else(|e| panic!("{e}: {base}"));
    }
}
