//! Determinism: the same spec gives bit-identical output run after run and with any thread
//! count granted (the analyses spread their scans over threads and gather them in a fixed
//! order; a time integration runs on the calling thread).

use signorini_core::job::{self, Job};
use signorini_core::observer::Recorder;
use signorini_core::outcome::RunOutput;
use signorini_core::spec::JobSpec;

/// Everything a run returns and records, as text that tells every f64 apart.
fn printed(spec: &JobSpec, threads: usize) -> String {
    let job = Job::from_spec(spec).unwrap();
    let mut rec = Recorder::default();
    let out: RunOutput = job::run(&job, threads, &mut rec).unwrap();
    let bits: Vec<Vec<u64>> = rec
        .rows
        .iter()
        .map(|r| r.iter().map(|x| x.to_bits()).collect())
        .collect();
    format!(
        "{}\n{:?}\n{:?}\n{:?}\n{:?}",
        serde_json::to_string(&out.summary).unwrap(),
        out.tables,
        out.charts,
        rec.steps,
        bits
    )
}

fn same_for_every_thread_count(spec: &str) {
    let spec: JobSpec = toml::from_str(spec).unwrap();
    let one = printed(&spec, 1);
    assert_eq!(one, printed(&spec, 1), "two runs on one thread differ");
    for threads in [2, 3, 4] {
        assert_eq!(
            one,
            printed(&spec, threads),
            "{threads} threads differ from 1"
        );
    }
}

#[test]
fn nonsmooth_modes_do_not_depend_on_the_thread_count() {
    same_for_every_thread_count(
        r#"
        [analysis]
        kind = "nonsmooth_modes"
        cells = 30
        gaps = [1e-3, 0.0, -1e-3]
        max_period_steps = 200
        phases = 1
        stability_periods = 50
        "#,
    );
}

#[test]
fn forced_response_does_not_depend_on_the_thread_count() {
    same_for_every_thread_count(
        r#"
        [analysis]
        kind = "forced_response"
        cells = 20
        gap = 1e-3
        excitation = "wall"
        amplitude = 2e-3
        omegas = [0.9, 1.1, 1.3, 1.5, 2.0]
        damping = [0.02, 0.1]
        transient_periods = 20
        average_periods = 5
        "#,
    );
}

#[test]
fn time_integrations_do_not_depend_on_the_thread_count() {
    same_for_every_thread_count(
        r#"
        [model]
        scene = "bar"
        elements = 50
        gap = 0.001
        initial_velocity = 1.0
        [integrator]
        scheme = "ns_generalized_alpha"
        [time]
        h = 0.001
        steps = 2000
        [output]
        every = 7
        "#,
    );
}
