//! The example specs of issue 5 parse, validate and (the WFEM run) finish with a closed energy
//! balance; a wrong scene and a wrong step are rejected with the field named.

// Only the core library must stay pure (clippy.toml): a test may read fixtures and print.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use signorini_core::job::{Job, run};
use signorini_core::observer::Recorder;
use signorini_core::spec::JobSpec;

fn load(name: &str) -> JobSpec {
    let path = format!("{}/../../examples/{name}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).expect("example file");
    toml::from_str(&text).expect("valid TOML spec")
}

#[test]
fn examples_validate_and_the_wfem_dep_bar_runs() {
    for name in ["nonsmooth_modes.toml", "forced_response.toml"] {
        Job::from_spec(&load(name)).expect(name);
    }
    let job = Job::from_spec(&load("wfem_dep_bar.toml")).expect("wfem_dep_bar");
    let mut rec = Recorder::default();
    let out = run(&job, 1, &mut rec).expect("run");
    let summary = out.summary.to_map();
    assert_eq!(summary["scheme"], "wfem");
    assert!(summary["closures"].as_u64().unwrap() >= 2);
    let e = summary["energy_final"].as_f64().unwrap().max(1.0);
    assert!(summary["max_abs_balance_residual"].as_f64().unwrap() < 1e-9 * e);
    assert!(
        rec.column("contact_force")
            .unwrap()
            .iter()
            .any(|r| *r < 0.0)
    );
}

#[test]
fn wfem_rejects_other_scenes_and_wrong_steps() {
    let mut spec = load("wfem_dep_bar.toml");
    spec.time.as_mut().unwrap().h = 1e-3;
    assert_eq!(Job::from_spec(&spec).unwrap_err().field, "time.h");
    let spec: JobSpec = toml::from_str("[model]\nscene = \"bouncing_ball\"\n[integrator]\nscheme = \"wfem\"\n[time]\nh = 0.01\nsteps = 10\n").unwrap();
    assert_eq!(Job::from_spec(&spec).unwrap_err().field, "model.scene");
}
