//! The shared field groups of `[integrator]` (index set, SOI2 Newton settings) are one struct each,
//! flattened into the scheme's table: their fields keep their spellings, defaults and checks, and a
//! field no group and no scheme knows is still refused by name.

use signorini_core::job::Job;
use signorini_core::spec::{IntegratorSpec, JobSpec};

fn parse(json: &str) -> Result<JobSpec, String> {
    serde_json::from_str::<JobSpec>(json).map_err(|e| e.to_string())
}

#[test]
fn unknown_fields_are_refused_by_name_next_to_a_group() {
    for integrator in [
        r#"{"scheme": "moreau_jean", "activaton": "predicted_gap"}"#,
        r#"{"scheme": "ns_hht", "alpha": 0.1, "activaton": "predicted_gap"}"#,
        r#"{"scheme": "ns_newmark", "activaton": "predicted_gap"}"#,
        r#"{"scheme": "ns_generalized_alpha", "activaton": "predicted_gap"}"#,
        r#"{"scheme": "soi2_hht", "activaton": "predicted_gap"}"#,
        r#"{"scheme": "soi2_generalized_alpha", "activaton": "predicted_gap"}"#,
    ] {
        let text = format!(
            r#"{{"model": {{"scene": "chain"}}, "integrator": {integrator}, "time": {{"h": 0.01, "steps": 1}}}}"#
        );
        let e = parse(&text).expect_err(&text);
        assert!(e.contains("unknown field `activaton`"), "{text}: {e}");
    }
    // A group's field on a scheme without that group is unknown there.
    let e = parse(r#"{"integrator": {"scheme": "soi2_hht", "activation": "predicted_gap"}}"#)
        .expect_err("soi2_hht has no index set");
    assert!(e.contains("unknown field `activation`"), "{e}");
    let e = parse(r#"{"integrator": {"scheme": "moreau_jean", "newton": "full"}}"#)
        .expect_err("moreau_jean has no Newton");
    assert!(e.contains("unknown field `newton`"), "{e}");
}

#[test]
fn group_fields_keep_their_spellings_defaults_and_types() {
    let spec = parse(
        r#"{"integrator": {"scheme": "ns_kh_alpha", "rho_inf": 0.5, "activation": "predicted_gap", "activation_gamma": 2}}"#,
    )
    .expect("integer γ is a number");
    match &spec.integrator {
        IntegratorSpec::NsKhAlpha(p) => assert_eq!(p.index_set.activation_gamma, Some(2.0)),
        other => panic!("{other:?}"),
    }
    let json = serde_json::to_value(&spec).expect("serialises");
    assert_eq!(json["integrator"]["activation"], "predicted_gap");
    assert_eq!(json["integrator"]["activation_gamma"], 2.0);
    let spec = parse(r#"{"integrator": {"scheme": "hht_i3", "newton_max_iterations": 7}}"#)
        .expect("parses");
    match &spec.integrator {
        IntegratorSpec::HhtI3(p) => {
            assert_eq!(p.solve.newton_max_iterations, 7);
            assert_eq!(p.solve.newton_tolerance, 1e-10);
            assert_eq!(p.solve.consistency_tolerance, 1e-8);
        }
        other => panic!("{other:?}"),
    }
    let e = parse(r#"{"integrator": {"scheme": "soi2_hht", "newton_tolerance": "x"}}"#)
        .expect_err("a string is not a tolerance");
    assert!(e.contains("invalid type"), "{e}");
    // TOML too (integers for floats, the whole path through the flattened group).
    let spec: JobSpec = toml::from_str(
        "[model]\nscene = \"pendulum\"\n[integrator]\nscheme = \"soi2_generalized_alpha\"\nnewton = \"full\"\nconsistency_tolerance = 1\n[time]\nh = 0.01\nsteps = 1\n",
    )
    .expect("TOML parses");
    match &spec.integrator {
        IntegratorSpec::Soi2GeneralizedAlpha(p) => {
            assert_eq!(p.solve.consistency_tolerance, 1.0);
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn each_group_is_checked_by_one_function_for_every_scheme() {
    for scheme in ["moreau_jean", "ns_newmark", "ns_generalized_alpha"] {
        let spec = parse(&format!(
            r#"{{"model": {{"scene": "bouncing_ball"}}, "integrator": {{"scheme": "{scheme}", "activation_gamma": 0.5}}, "time": {{"h": 0.01, "steps": 1}}}}"#
        ))
        .expect("parses");
        let e = Job::from_spec(&spec).expect_err("γ without predicted_gap");
        assert_eq!(e.field, "integrator.activation_gamma", "{scheme}: {e}");
    }
    for scheme in ["soi2_generalized_alpha", "soi2_hht", "hht_i3"] {
        let spec = parse(&format!(
            r#"{{"model": {{"scene": "pendulum"}}, "integrator": {{"scheme": "{scheme}", "newton_max_iterations": 0}}, "time": {{"h": 0.01, "steps": 1}}}}"#
        ))
        .expect("parses");
        let e = Job::from_spec(&spec).expect_err("no iteration");
        assert_eq!(e.field, "integrator.newton_max_iterations", "{scheme}: {e}");
    }
}
