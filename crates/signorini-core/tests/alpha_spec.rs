//! The α-family and the baselines through the job spec: every scheme name runs, parameters are
//! validated with errors naming the field, stability conditions are enforced unless
//! `allow_unstable = true`.

use serde_json::{Value, json};
use signorini_core::job::{self, Job};
use signorini_core::observer::Recorder;
use signorini_core::spec::JobSpec;

fn spec(integrator: Value) -> JobSpec {
    serde_json::from_value(json!({
        "model": { "scene": "bar", "elements": 20, "gap": 0.01, "initial_velocity": 1.0,
                   "rayleigh_stiffness": 1e-3, "restitution": 0.5,
                   "harmonic_force": { "amplitude": 0.3, "omega": 2.0 } },
        "integrator": integrator,
        "time": { "h": 0.005, "t_end": 3.0 }
    }))
    .expect("spec parses")
}

fn error_of(integrator: Value) -> (String, String) {
    let e = Job::from_spec(&spec(integrator)).expect_err("spec must be rejected");
    (e.field, e.reason)
}

#[test]
fn every_scheme_name_runs_and_closes_its_balance() {
    for integrator in [
        json!({ "scheme": "ns_newmark" }),
        json!({ "scheme": "ns_newmark", "beta": 0.3, "gamma": 0.55 }),
        json!({ "scheme": "ns_hht", "alpha": 0.1 }),
        json!({ "scheme": "ns_hht", "alpha": 0.1, "beta": 0.4, "gamma": 0.7 }),
        json!({ "scheme": "ns_generalized_alpha", "rho_inf": 0.8 }),
        json!({ "scheme": "ns_generalized_alpha" }),
        json!({ "scheme": "ns_generalized_alpha", "alpha_m": 0.2, "alpha_f": 0.4 }),
        json!({ "scheme": "ns_kh_alpha", "rho_inf": 0.5, "activation": "predicted_gap", "activation_gamma": 0.5 }),
        json!({ "scheme": "newmark_position_contact" }),
        json!({ "scheme": "hht_position_contact", "alpha": 0.05 }),
    ] {
        let name = integrator["scheme"].as_str().unwrap().to_string();
        let job = Job::from_spec(&spec(integrator.clone()))
            .unwrap_or_else(|e| panic!("{integrator}: {e}"));
        let mut rec = Recorder::default();
        let out = job::run(&job, 1, &mut rec).expect("runs");
        let summary = out.summary.to_map();
        assert_eq!(summary["scheme"], json!(name));
        let residual = summary["max_abs_balance_residual"].as_f64().unwrap();
        let hmax = summary["algorithmic_energy_max"].as_f64().unwrap();
        assert!(
            residual <= 1e-10 * hmax.max(1.0),
            "{integrator}: residual {residual:e}"
        );
        assert!(
            summary["impacts"].as_u64().unwrap() > 0,
            "{integrator}: the bar must hit the wall"
        );
        assert_eq!(rec.rows.len(), 601);
    }
}

#[test]
fn bad_parameters_name_their_field() {
    let cases = [
        (
            json!({ "scheme": "ns_generalized_alpha", "rho_inf": 1.5 }),
            "integrator.rho_inf",
            "must be in [0, 1]",
        ),
        (
            json!({ "scheme": "ns_generalized_alpha", "rho_inf": 0.5, "beta": 0.3 }),
            "integrator.beta",
            "not both",
        ),
        (
            json!({ "scheme": "ns_generalized_alpha", "alpha_m": 1.0, "alpha_f": 0.5 }),
            "integrator.alpha_m",
            "< 1",
        ),
        (
            json!({ "scheme": "ns_generalized_alpha", "alpha_m": 0.3 }),
            "integrator.alpha_f",
            "missing",
        ),
        (
            json!({ "scheme": "ns_generalized_alpha", "alpha_m": 0.4, "alpha_f": 0.2 }),
            "integrator.alpha_f",
            "α_m ≤ α_f ≤ ½",
        ),
        (
            json!({ "scheme": "ns_generalized_alpha", "alpha_m": 0.5, "alpha_f": 0.3, "allow_unstable": true }),
            "integrator.alpha_f",
            "Remark 1",
        ),
        (
            json!({ "scheme": "ns_newmark", "beta": 0.2, "gamma": 0.5 }),
            "integrator.beta",
            "2β ≥ γ",
        ),
        (
            json!({ "scheme": "ns_newmark", "beta": 0.25, "gamma": 0.4 }),
            "integrator.gamma",
            "≥ ½",
        ),
        (
            json!({ "scheme": "ns_hht", "alpha": 0.6 }),
            "integrator.alpha",
            "(83)",
        ),
        (
            json!({ "scheme": "ns_kh_alpha", "alpha_m": 0.3, "alpha_f": 0.2, "gamma": 0.6 }),
            "integrator.alpha_f",
            "(76)",
        ),
        (
            json!({ "scheme": "ns_hht", "alpha": 0.1, "activation_gamma": 0.5 }),
            "integrator.activation_gamma",
            "predicted_gap",
        ),
        (
            json!({ "scheme": "newmark_position_contact", "alpha": 0.1 }),
            "integrator.alpha",
            "no α",
        ),
        (
            json!({ "scheme": "hht_position_contact" }),
            "integrator.alpha",
            "missing",
        ),
        (
            json!({ "scheme": "newmark_position_contact", "beta": 0.0, "gamma": 0.5 }),
            "integrator.beta",
            "> 0",
        ),
    ];
    for (integrator, field, reason) in cases {
        let (f, r) = error_of(integrator.clone());
        assert_eq!(f, field, "{integrator}: {r}");
        assert!(
            r.contains(reason),
            "{integrator}: reason {r:?} lacks {reason:?}"
        );
    }
    // Outside the conditions but explicitly allowed: runs.
    let unstable =
        json!({ "scheme": "ns_newmark", "beta": 0.2, "gamma": 0.5, "allow_unstable": true });
    assert!(Job::from_spec(&spec(unstable)).is_ok());
    // Unknown fields are rejected by the schema.
    let bad: Result<JobSpec, _> = serde_json::from_value(
        json!({ "integrator": { "scheme": "ns_hht", "alpha": 0.1, "theta": 0.5 } }),
    );
    assert!(bad.is_err());
}
