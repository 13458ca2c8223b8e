//! The rigid-bodies speed benchmark of issue 29 (docs/rigid_benchmark.md): runs a
//! `rigid_bodies` spec (by default `examples/rigid/spheres_1000.toml`, 1 000 spheres poured into a
//! box) under `moreau_jean` with parry's detector and prints one JSON line: steps per second,
//! contacts per step, and the time split between contact detection, assembly of the one-step
//! problem, the FC3D solve and the update, measured by the phases the step reports
//! ([`StepPhases`]).
//!
//! `cargo bench -p signorini-collision --bench rigid_spheres -- [SPEC] [--steps N]`

use signorini_collision::ParryDetectors;
use signorini_core::friction::Fc3dOptions;
use signorini_core::rigid::{
    DetectorFactory, RigidMoreauJean, RigidMoreauJeanParams, RigidScratch, StepPhase, StepPhases,
};
use signorini_core::spec::{JobSpec, ModelSpec};
use std::time::{Duration, Instant};

/// Time spent in each phase.
struct PhaseClock {
    current: Option<StepPhase>,
    since: Instant,
    spent: [Duration; 4],
}

impl PhaseClock {
    fn index(phase: StepPhase) -> usize {
        match phase {
            StepPhase::Detection => 0,
            StepPhase::Assembly => 1,
            StepPhase::Solve => 2,
            StepPhase::Update => 3,
        }
    }

    fn stop(&mut self) {
        let now = Instant::now();
        if let Some(p) = self.current.take() {
            self.spent[Self::index(p)] += now - self.since;
        }
        self.since = now;
    }
}

impl StepPhases for PhaseClock {
    fn enter(&mut self, phase: StepPhase) {
        self.stop();
        self.current = Some(phase);
    }
}

fn main() {
    let mut args = std::env::args().skip(1).filter(|a| a != "--bench");
    let mut path = format!(
        "{}/../../examples/rigid/spheres_1000.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    let mut steps_arg: Option<u64> = None;
    while let Some(a) = args.next() {
        if a == "--steps" {
            steps_arg = args.next().and_then(|s| s.parse().ok());
        } else {
            path = a;
        }
    }
    let text = std::fs::read_to_string(&path).expect("reading the spec");
    let spec: JobSpec = toml::from_str(&text).expect("a job spec");
    let Some(ModelSpec::RigidBodies(model)) = &spec.model else {
        panic!("{path}: not a rigid_bodies spec");
    };
    let scene = model.validate().expect("a valid scene");
    let time = spec.time_section().expect("a time section");
    let steps = time.steps(false).expect("steps");
    let h = steps.h;
    let count = steps_arg.unwrap_or(steps.count());
    let scheme = RigidMoreauJean::new(
        RigidMoreauJeanParams {
            fc3d: Fc3dOptions {
                tolerance: spec.contact_solver.tolerance,
                max_iterations: spec.contact_solver.max_iterations,
                ..Fc3dOptions::default()
            },
            ..RigidMoreauJeanParams::default()
        },
        h,
    );
    let mut detector = ParryDetectors.detector(&scene.bodies).expect("shapes");
    let mut state = scene.initial.clone();
    let mut scratch = RigidScratch::default();
    let mut clock = PhaseClock {
        current: None,
        since: Instant::now(),
        spent: [Duration::ZERO; 4],
    };
    let mut contacts = 0u64;
    let mut max_contacts = 0usize;
    let mut friction_iterations = 0u64;
    let (k0, v0) = RigidMoreauJean::energies(&scene, &state);
    let start = Instant::now();
    for k in 1..=count {
        let t = (k - 1) as f64 * h;
        let report = scheme
            .step_in_phases(
                &scene,
                &mut state,
                detector.as_mut(),
                &mut scratch,
                (k, t),
                &mut clock,
            )
            .unwrap_or_else(|e| panic!("{e}"));
        clock.stop();
        contacts += report.contacts as u64;
        max_contacts = max_contacts.max(report.contacts);
        friction_iterations += report.friction_iterations as u64;
    }
    let seconds = start.elapsed().as_secs_f64();
    let (k1, v1) = RigidMoreauJean::energies(&scene, &state);
    let split = clock.spent.map(|d| d.as_secs_f64());
    println!(
        "{{\"code\": \"signorini\", \"bodies\": {}, \"h\": {h}, \"steps\": {count}, \"seconds\": {seconds:.4}, \"steps_per_second\": {:.2}, \"ms_per_step\": {:.4}, \"contacts_per_step\": {:.1}, \"max_contacts\": {max_contacts}, \"friction_iterations_per_step\": {:.2}, \"split_seconds\": {{\"detection\": {:.4}, \"assembly\": {:.4}, \"solve\": {:.4}, \"update\": {:.4}}}, \"energy_start\": {:.6}, \"energy_end\": {:.6}}}",
        scene.bodies.len(),
        count as f64 / seconds,
        1e3 * seconds / count as f64,
        contacts as f64 / count as f64,
        friction_iterations as f64 / count as f64,
        split[0],
        split[1],
        split[2],
        split[3],
        k0 + v0,
        k1 + v1,
    );
}
