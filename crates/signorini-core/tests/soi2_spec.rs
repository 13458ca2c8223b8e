//! SOI2 jobs through the job spec: runs, summaries, and one test per bad input.

// Only the core library must stay pure (clippy.toml): a test may read fixtures and print.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use signorini_core::job::{Job, run};
use signorini_core::observer::Recorder;
use signorini_core::outcome::RunError;
use signorini_core::soi2::Soi2Error;
use signorini_core::spec::{JobSpec, SpecError};

fn spec(json: &str) -> JobSpec {
    serde_json::from_str(json).expect("spec parses")
}

fn build_err(json: &str) -> SpecError {
    Job::from_spec(&spec(json)).expect_err("must be rejected")
}

#[test]
fn jay_negrut_test_job_reports_global_errors() {
    let s = spec(
        r#"{"model": {"scene": "jay_negrut_test"},
            "integrator": {"scheme": "soi2_generalized_alpha", "rho_inf": 0.2},
            "time": {"h": 0.03125, "t_end": 1.0, "pattern": [0.3333333333333333, 0.6666666666666667], "adjust": true},
            "output": {"every": 4, "probes": [0, 1]}}"#,
    );
    let job = Job::from_spec(&s).expect("valid");
    assert_eq!(job.size().steps, 64);
    let mut rec = Recorder::default();
    let out = run(&job, 1, &mut rec).expect("runs");
    let summary = out.summary.to_map();
    let e = summary["errors"].as_object().expect("errors");
    // Fig. 1 at h = 2⁻⁵ (measured by tests/soi2_order.rs): all errors ~1e-4 or below.
    for k in ["y", "z", "a", "lambda", "psi"] {
        let v = e[k].as_f64().expect("number");
        assert!(v > 0.0 && v < 2e-3, "{k}: {v}");
    }
    assert_eq!(summary["scene"], "jay_negrut_test");
    assert_eq!(summary["scheme"], "soi2_generalized_alpha");
    assert!((summary["t_end"].as_f64().expect("t_end") - 1.0).abs() < 1e-14);
    for c in [
        "kinetic",
        "potential",
        "energy",
        "work_damping",
        "position_residual",
        "velocity_residual",
        "nonholonomic_residual",
        "newton_iterations",
        "lambda_0",
        "psi_0",
        "y_0",
        "z_1",
    ] {
        assert!(rec.columns.index(c).is_some(), "column {c}");
    }
    assert_eq!(rec.steps.len(), 64 / 4 + 1);
    let y0 = rec.column("y_0").expect("probe");
    assert!((y0[y0.len() - 1] - 1f64.exp()).abs() < 2e-3);
    let k = rec.column("nonholonomic_residual").expect("k");
    assert!(k.iter().all(|v| *v < 1e-9), "k residual {k:?}");
}

#[test]
fn pendulum_and_slider_crank_jobs_run() {
    for (scene, scheme) in [
        ("pendulum", "soi2_generalized_alpha"),
        ("pendulum", "soi2_hht"),
        ("slider_crank", "soi2_hht"),
        ("slider_crank", "hht_i3"),
    ] {
        let s = spec(&format!(
            r#"{{"model": {{"scene": "{scene}"}}, "integrator": {{"scheme": "{scheme}"}}, "time": {{"h": 0.001, "t_end": 0.1}}}}"#
        ));
        let job = Job::from_spec(&s).expect("valid");
        let out = run(&job, 1, &mut Recorder::default()).expect("runs");
        let summary = out.summary.to_map();
        assert_eq!(summary["steps"], 100, "{scene}/{scheme}");
        assert!(summary["max_position_residual"].as_f64().expect("res") < 1e-10);
        assert!(summary.get("errors").is_none());
    }
}

#[test]
fn bad_input_singular_constraint_jacobian() {
    // Rod as long as the crank, crank vertical: the slider sits on the pivot and (g_y) loses rank.
    let e = build_err(
        r#"{"model": {"scene": "slider_crank", "crank_length": 0.2, "rod_length": 0.2, "crank_angle": 1.5707963267948966, "crank_speed": 0.0},
            "integrator": {"scheme": "soi2_hht"}, "time": {"h": 0.001, "t_end": 0.1}}"#,
    );
    assert_eq!(e.field, "model");
    assert!(e.reason.contains("singular constraint Jacobian"), "{e}");
    assert!(e.reason.contains("rank 6 < 7"), "{e}");
}

#[test]
fn bad_input_inconsistent_initial_conditions() {
    let e = build_err(
        r#"{"model": {"scene": "jay_negrut_test", "y0": [1.0, 2.0]},
            "integrator": {"scheme": "soi2_generalized_alpha"}, "time": {"h": 0.01, "t_end": 1.0}}"#,
    );
    assert_eq!(e.field, "model");
    assert!(
        e.reason
            .contains("inconsistent initial conditions: position constraint residual 1e0"),
        "{e}"
    );
    // Velocity level: positions on the circle, velocity not tangent.
    let e = build_err(
        r#"{"model": {"scene": "pendulum", "z0": [0.0, 1.0, 10.0]},
            "integrator": {"scheme": "soi2_hht"}, "time": {"h": 0.01, "t_end": 1.0}}"#,
    );
    assert!(
        e.reason
            .contains("inconsistent initial conditions: velocity"),
        "{e}"
    );
    // Within the tolerance it is accepted.
    let ok = spec(
        r#"{"model": {"scene": "jay_negrut_test", "y0": [1.0, 1.000000000001]},
            "integrator": {"scheme": "soi2_generalized_alpha"}, "time": {"h": 0.01, "t_end": 0.1}}"#,
    );
    assert!(Job::from_spec(&ok).is_ok());
}

#[test]
fn bad_input_alpha_m_equal_one() {
    let e = build_err(
        r#"{"model": {"scene": "pendulum"},
            "integrator": {"scheme": "soi2_generalized_alpha", "alpha_m": 1.0, "alpha_f": 0.5},
            "time": {"h": 0.01, "t_end": 1.0}}"#,
    );
    assert_eq!(e.field, "integrator.alpha_m");
    assert!(e.reason.contains("α_m = 1"), "{e}");
}

#[test]
fn bad_input_newton_divergence() {
    // One iteration cannot meet the tolerance: the run fails at step 1 with the residual.
    let s = spec(
        r#"{"model": {"scene": "pendulum"},
            "integrator": {"scheme": "soi2_generalized_alpha", "newton_max_iterations": 1},
            "time": {"h": 0.01, "t_end": 1.0}}"#,
    );
    let job = Job::from_spec(&s).expect("valid");
    match run(&job, 1, &mut Recorder::default()) {
        Err(RunError::Soi2(Soi2Error::NewtonDiverged {
            step,
            t,
            iterations,
            residual,
            ..
        })) => {
            assert_eq!((step, iterations), (1, 1));
            assert!((t - 0.01).abs() < 1e-15);
            assert!(residual > 0.0);
        }
        other => panic!("expected Newton divergence, got {other:?}"),
    }
    // A step far too large for the test problem's exponential nonlinearity.
    let s = spec(
        r#"{"model": {"scene": "jay_negrut_test"},
            "integrator": {"scheme": "soi2_generalized_alpha"},
            "time": {"h": 8.0, "t_end": 64.0}}"#,
    );
    let job = Job::from_spec(&s).expect("valid");
    let err = run(&job, 1, &mut Recorder::default()).expect_err("diverges");
    let msg = err.to_string();
    assert!(
        msg.contains("Newton did not converge") || msg.contains("singular Newton matrix"),
        "{msg}"
    );
}

#[test]
fn bad_input_scene_and_scheme_mismatch() {
    let e = build_err(
        r#"{"model": {"scene": "bouncing_ball"}, "integrator": {"scheme": "soi2_hht"}, "time": {"h": 0.01, "t_end": 1.0}}"#,
    );
    assert_eq!(e.field, "integrator.scheme");
    assert!(e.reason.contains("bouncing_ball"), "{e}");
    let e = build_err(
        r#"{"model": {"scene": "pendulum"}, "integrator": {"scheme": "moreau_jean"}, "time": {"h": 0.01, "t_end": 1.0}}"#,
    );
    assert_eq!(e.field, "integrator.scheme");
    assert!(e.reason.contains("pendulum"), "{e}");
    // HHT-SOI2 (17) has no nonholonomic constraints and needs additive forces.
    let e = build_err(
        r#"{"model": {"scene": "jay_negrut_test"}, "integrator": {"scheme": "soi2_hht"}, "time": {"h": 0.01, "t_end": 1.0}}"#,
    );
    assert_eq!(e.field, "integrator.scheme");
    let e = build_err(
        r#"{"model": {"scene": "jay_negrut_test"}, "integrator": {"scheme": "soi2_generalized_alpha", "additive": true}, "time": {"h": 0.01, "t_end": 1.0}}"#,
    );
    assert_eq!(e.field, "integrator.additive");
    let e = build_err(
        r#"{"model": {"scene": "pendulum"}, "integrator": {"scheme": "soi2_hht", "alpha": -0.5}, "time": {"h": 0.01, "t_end": 1.0}}"#,
    );
    assert_eq!(e.field, "integrator.alpha");
    let e = build_err(
        r#"{"model": {"scene": "pendulum"}, "integrator": {"scheme": "soi2_hht"}, "time": {"h": 0.01, "t_end": 1.0, "pattern": [1.0, -1.0]}}"#,
    );
    assert_eq!(e.field, "time.pattern");
}

#[test]
fn example_specs_parse_validate_and_run() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
    for name in ["pendulum_soi2", "slider_crank_hht", "jay_negrut_test"] {
        let text =
            std::fs::read_to_string(dir.join(format!("{name}.toml"))).expect("example exists");
        let s: JobSpec = toml::from_str(&text).expect("example parses");
        let job = Job::from_spec(&s).expect("example is valid");
        let out = run(&job, 1, &mut Recorder::default()).expect("example runs");
        let summary = out.summary.to_map();
        assert!(
            summary["max_position_residual"].as_f64().expect("res") < 1e-9,
            "{name}"
        );
        if name == "jay_negrut_test" {
            assert!(summary["errors"]["y"].as_f64().expect("y") < 1e-3);
        }
    }
}

#[test]
fn newton_strategy_from_the_spec() {
    // The pendulum (16) at h = 2⁻⁹, t ∈ [0, 1], each SOI2 scheme with `newton` unset
    // (simplified) and "full". Full Newton builds one Jacobian per iteration; simplified Newton
    // far fewer. Both meet the same Newton tolerance (1e-10), so the final states agree to the
    // bounds tests/soi2_newton.rs asserts over whole trajectories: y, z ≤ 1e-8, λ ≤ 1e-8·(1 + |λ|).
    for scheme in ["soi2_generalized_alpha", "soi2_hht", "hht_i3"] {
        let go = |newton: &str| {
            let s = spec(&format!(
                r#"{{"model": {{"scene": "pendulum"}},
                    "integrator": {{"scheme": "{scheme}"{newton}}},
                    "time": {{"h": 0.001953125, "t_end": 1.0}}}}"#
            ));
            let job = Job::from_spec(&s).expect("valid");
            run(&job, 1, &mut Recorder::default())
                .expect("runs")
                .summary
                .to_map()
        };
        let full = go(r#", "newton": "full""#);
        let simplified = go("");
        let count = |m: &serde_json::Map<String, serde_json::Value>, k: &str| {
            m[k].as_u64()
                .unwrap_or_else(|| panic!("{scheme}: {k} in {m:?}"))
        };
        assert_eq!(full["newton"], "full", "{scheme}");
        assert_eq!(simplified["newton"], "simplified", "{scheme}");
        assert_eq!(full["steps"], 512, "{scheme}");
        let (it_f, jac_f) = (
            count(&full, "newton_iterations_total"),
            count(&full, "newton_jacobians_total"),
        );
        let (it_s, jac_s) = (
            count(&simplified, "newton_iterations_total"),
            count(&simplified, "newton_jacobians_total"),
        );
        println!("{scheme}: full {it_f} iterations, {jac_f} Jacobians; simplified {it_s}, {jac_s}");
        assert_eq!(
            jac_f, it_f,
            "{scheme}: full Newton, one Jacobian per iteration"
        );
        assert!(it_f >= 512, "{scheme}: at least one iteration per step");
        assert!(
            2 * jac_s < jac_f && jac_s < it_s,
            "{scheme}: simplified Newton reuses Jacobians ({jac_s} of {it_s} vs {jac_f})"
        );
        let v = |m: &serde_json::Map<String, serde_json::Value>, k: &str| -> Vec<f64> {
            m[k].as_array()
                .unwrap_or_else(|| panic!("{scheme}: {k}"))
                .iter()
                .map(|x| x.as_f64().expect("a number"))
                .collect()
        };
        let mut dyz = 0.0_f64;
        for k in ["y_final", "z_final"] {
            let (a, b) = (v(&full, k), v(&simplified, k));
            assert_eq!(a.len(), b.len(), "{scheme} {k}");
            for (a, b) in a.iter().zip(&b) {
                assert!((a - b).abs() <= 1e-8, "{scheme} {k}: {a} vs {b}");
                dyz = dyz.max((a - b).abs());
            }
        }
        let (lf, ls) = (v(&full, "lambda_final"), v(&simplified, "lambda_final"));
        assert_eq!(lf.len(), ls.len(), "{scheme} lambda_final");
        let lmax = lf.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
        let mut dl = 0.0_f64;
        for (a, b) in lf.iter().zip(&ls) {
            assert!(
                (a - b).abs() <= 1e-8 * (1.0 + lmax),
                "{scheme} lambda_final: {a} vs {b}"
            );
            dl = dl.max((a - b).abs() / (1.0 + lmax));
        }
        println!("{scheme}: final max |Δy|, |Δz| = {dyz:.1e}, max |Δλ|/(1 + |λ|) = {dl:.1e}");
    }
}

#[test]
fn bad_input_unknown_newton_strategy() {
    // The core spec type refuses it (the field name is added where text is parsed:
    // `spec_file::parse` names `integrator.newton`, tested in the root package).
    let e = serde_json::from_str::<JobSpec>(
        r#"{"model": {"scene": "pendulum"},
            "integrator": {"scheme": "soi2_hht", "newton": "sometimes"},
            "time": {"h": 0.01, "t_end": 1.0}}"#,
    )
    .expect_err("must be refused");
    let msg = e.to_string();
    assert!(
        msg.contains("unknown variant `sometimes`") && msg.contains("`simplified` or `full`"),
        "{msg}"
    );
}

/// A schedule is generated step by step and counted without being stored: a job of 10¹² steps
/// is sized at once (it used to build the list of every step size, and aborted out of memory),
/// and more than 2⁵³ steps are refused naming the field.
#[test]
fn long_schedules_are_counted_without_being_stored() {
    use signorini_core::soi2::run::{End, Schedule, StepSizes};
    // Exact count below 10⁷ steps, for patterns that end on a partial period and a sliver.
    for (pattern, t_end) in [
        (vec![1.0], 1.0),
        (vec![1.0 / 3.0, 2.0 / 3.0], 1.0),
        (vec![1.0 / 3.0, 2.0 / 3.0], 0.7 + 1e-13),
        (vec![0.25, 0.5, 1.0], 3.3),
    ] {
        let s = Schedule {
            h: 2f64.powi(-7),
            pattern,
            end: End::Time(t_end),
        };
        let sizes = s.sizes();
        assert_eq!(s.count(), sizes.len() as u64, "{s:?}");
        assert_eq!(s.iter().collect::<Vec<_>>(), sizes);
        assert_eq!(sizes.iter().sum::<f64>(), t_end, "lands on t_end: {s:?}");
        assert!((s.estimated_steps() - sizes.len() as f64).abs() <= s.pattern.len() as f64);
    }
    let steps = Schedule {
        h: 0.1,
        pattern: vec![1.0, 2.0],
        end: End::Steps(5),
    };
    assert_eq!(steps.sizes(), [0.1, 0.2, 0.1, 0.2, 0.1]);
    assert_eq!(steps.count(), 5);

    let job = |t_end: &str| {
        format!(
            r#"{{"model": {{"scene": "pendulum"}}, "integrator": {{"scheme": "soi2_hht"}}, "time": {{"h": 1e-9, "t_end": {t_end}, "pattern": [0.5, 1.5]}}}}"#
        )
    };
    let big = Job::from_spec(&spec(&job("1e3"))).expect("valid");
    let n = big.size().steps;
    assert!((n as f64 - 1e12).abs() <= 2.0, "{n}");
    let e = build_err(&job("1e300"));
    assert_eq!(e.field, "time.t_end");
    assert!(e.reason.contains("more than 2⁵³"), "{e}");
}
