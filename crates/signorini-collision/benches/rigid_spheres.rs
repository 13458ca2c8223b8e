//! The rigid-bodies speed benchmark of issue 29 (docs/rigid_benchmark.md): runs a
//! `rigid_bodies` spec (by default `examples/rigid/spheres_1000.toml`, 1 000 spheres poured into a
//! box) under `moreau_jean` with parry's detector and prints one JSON line: steps per second,
//! contacts per step, and the time split between contact detection, assembly of the one-step
//! problem, the FC3D solve and the update, measured by the phases the step reports
//! ([`StepPhases`]).
//!
//! `cargo bench -p signorini-collision --bench rigid_spheres -- [SPEC] [--steps N] [--cold]`
//!
//! `--cold` starts every friction solve from P = 0 instead of the last impulses of the same
//! contacts (`RigidMoreauJeanParams::warm_start`), to measure what the warm start saves;
//! `--solver auto|nsgs|prox` and `--auto-sweeps N` set the FC3D solver and `auto`'s Gauss–Seidel
//! budget before its proximal-point stage and `--relaxation W` the over-relaxation of its plain
//! sweeps (`Fc3dOptions`; `rigid::RELAXATION` by default, 1 for none) and `--stall-sweeps N` the
//! stagnation window of the sweeps within the spec's `accept_error` (`rigid::STALL_SWEEPS` by
//! default, 0 for none), to measure what the time stepping needs; `--trace` prints each step's contacts, FC3D iterations, error and milliseconds on
//! stderr. The line also gives how many steps took ≤ 10, ≤ 100, ≤ 1 000 and more FC3D
//! iterations. `--tolerance T` and `--accept-error E|none` replace the spec's
//! `contact_solver.tolerance` and `accept_error` (the benchmark's runs at several tolerances).
//! `--dump K FILE` (repeatable) writes step K's one-step friction problem (W, q, μ) as a Siconos
//! `.dat` file (sparse-block storage) that `signorini solve` and Siconos' `fc3d_driver` read, and
//! the start its solver was given (the warm start) to `FILE.start`, one number a line.

use signorini_collision::ParryDetectors;
use signorini_core::friction::Fc3dProblem;
use signorini_core::friction::Fc3dSolverKind;
use signorini_core::rigid::{
    DetectorFactory, RigidMoreauJean, RigidScratch, StepPhase, StepPhases,
};
use signorini_core::spec::{JobSpec, ModelSpec};
use std::fmt::Write as _;
use std::time::{Duration, Instant};

/// Time spent in each phase.
struct PhaseClock {
    current: Option<StepPhase>,
    since: Instant,
    spent: [Duration; 4],
    /// Write the problem of these steps to these files (`--dump`).
    dump: Vec<(u64, String)>,
    step: u64,
}

/// `problem` as Siconos writes it (`frictionContact_printInFile`): d, contacts, W as a
/// sparse-block matrix (`SBM_print_in_file`: sizes, block starts, block columns, then each block
/// column-major), q, μ; numbers in Rust's shortest round-trip form.
fn siconos_dat(problem: &Fc3dProblem) -> String {
    let m = problem.contacts();
    let blocks = problem.w.stored_blocks();
    let mut out = format!("3\n{m}\n1\n{0}\n{0}\n{blocks}\n{m}\n{m}\n", 3 * m);
    let ends: Vec<String> = (1..=m).map(|a| (3 * a).to_string()).collect();
    let _ = writeln!(
        out,
        "{}\n{}\n{}\n{blocks}",
        ends.join(" "),
        ends.join(" "),
        m + 1
    );
    let mut starts = vec!["0".to_string()];
    let mut columns = Vec::new();
    for a in 0..m {
        columns.extend(problem.w.row(a).map(|(b, _)| b.to_string()));
        starts.push(columns.len().to_string());
    }
    let _ = writeln!(out, "{}\n{}", starts.join(" "), columns.join(" "));
    let mut number = 0;
    for a in 0..m {
        for (_, block) in problem.w.row(a) {
            let _ = writeln!(out, "{number}");
            number += 1;
            for k in 0..9 {
                let _ = writeln!(out, "{:e}", block[(k % 3) * 3 + k / 3]);
            }
        }
    }
    for x in problem.q.iter().chain(&problem.mu) {
        let _ = writeln!(out, "{x:e}");
    }
    out
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

    fn problem(&mut self, problem: &Fc3dProblem, start: &[f64]) {
        if let Some((_, path)) = self.dump.iter().find(|(k, _)| *k == self.step) {
            std::fs::write(path, siconos_dat(problem)).expect("writing the problem");
            let start: String = start.iter().map(|x| format!("{x:e}\n")).collect();
            std::fs::write(format!("{path}.start"), start).expect("writing the start");
        }
    }
}

fn main() {
    let mut args = std::env::args().skip(1).filter(|a| a != "--bench");
    let mut path = format!(
        "{}/../../examples/rigid/spheres_1000.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    let mut steps_arg: Option<u64> = None;
    let mut dump = Vec::new();
    let mut warm_start = true;
    let mut trace = false;
    let mut kind = Fc3dSolverKind::Auto;
    let mut auto_sweeps = signorini_core::rigid::AUTO_SWEEPS;
    let mut relaxation = signorini_core::rigid::RELAXATION;
    let mut stall_sweeps = Some(signorini_core::rigid::STALL_SWEEPS);
    let mut tolerance: Option<f64> = None;
    // `Some(None)`: no acceptance above the tolerance.
    let mut accept_error: Option<Option<f64>> = None;
    while let Some(a) = args.next() {
        if a == "--cold" {
            warm_start = false;
        } else if a == "--trace" {
            trace = true;
        } else if a == "--solver" {
            let name = args.next().unwrap_or_default();
            kind =
                Fc3dSolverKind::from_name(&name).expect("--solver auto|nsgs|nsgs_aa|nsn_ac|prox");
        } else if a == "--auto-sweeps" {
            auto_sweeps = args
                .next()
                .and_then(|s| s.parse().ok())
                .expect("--auto-sweeps N");
        } else if a == "--relaxation" {
            relaxation = args
                .next()
                .and_then(|s| s.parse().ok())
                .expect("--relaxation W");
        } else if a == "--stall-sweeps" {
            // 0: no stagnation test.
            let n: usize = args
                .next()
                .and_then(|s| s.parse().ok())
                .expect("--stall-sweeps N");
            stall_sweeps = (n > 0).then_some(n);
        } else if a == "--tolerance" {
            tolerance = Some(
                args.next()
                    .and_then(|s| s.parse().ok())
                    .expect("--tolerance T"),
            );
        } else if a == "--accept-error" {
            let e = args.next().expect("--accept-error E|none");
            accept_error = Some((e != "none").then(|| e.parse().expect("--accept-error E|none")));
        } else if a == "--dump" {
            let step = args
                .next()
                .and_then(|s| s.parse().ok())
                .expect("--dump K FILE");
            dump.push((step, args.next().expect("--dump K FILE")));
        } else if a == "--steps" {
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
    let steps = time.steps(None).expect("steps");
    let h = steps.h;
    let count = steps_arg.unwrap_or(steps.count());
    // The spec's parameters as a job takes them, then the benchmark's own settings.
    let mut params = signorini_core::job::rigid_params(&spec).unwrap_or_else(|e| panic!("{e}"));
    params.fc3d.kind = kind;
    params.fc3d.auto_sweeps = auto_sweeps;
    params.fc3d.relaxation = relaxation;
    if let Some(t) = tolerance {
        params.fc3d.tolerance = t;
    }
    if let Some(e) = accept_error {
        params.accept_error = e;
    }
    params.warm_start = warm_start;
    params.stall_sweeps = stall_sweeps;
    let scheme = RigidMoreauJean::new(params, h);
    let mut detector = ParryDetectors.detector(&scene.bodies).expect("shapes");
    let mut state = scene.initial.clone();
    let mut scratch = RigidScratch::default();
    let mut clock = PhaseClock {
        current: None,
        since: Instant::now(),
        spent: [Duration::ZERO; 4],
        dump,
        step: 0,
    };
    let mut contacts = 0u64;
    let mut max_contacts = 0usize;
    let mut friction_iterations = 0u64;
    let mut friction_error_max: f64 = 0.0;
    // Steps that went on with a friction solve above the tolerance (`contact_solver.accept_error`).
    let mut accepted = 0u64;
    // The largest penetration at the start of a step (the stepper's `max_penetration` column).
    let mut max_penetration: f64 = 0.0;
    let mut histogram = [0u64; 4];
    let (k0, v0) = RigidMoreauJean::energies(&scene, &state);
    let start = Instant::now();
    for k in 1..=count {
        let t = (k - 1) as f64 * h;
        clock.step = k;
        let step_start = Instant::now();
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
        max_penetration = max_penetration.max(scratch.max_penetration());
        contacts += report.contacts as u64;
        max_contacts = max_contacts.max(report.contacts);
        friction_iterations += report.friction_iterations as u64;
        friction_error_max = friction_error_max.max(report.friction_error);
        accepted += u64::from(report.friction_accepted);
        if trace {
            eprintln!(
                "{k} {} {} {:e} {:.1}",
                report.contacts,
                report.friction_iterations,
                report.friction_error,
                1e3 * step_start.elapsed().as_secs_f64()
            );
        }
        histogram[match report.friction_iterations {
            0..=10 => 0,
            11..=100 => 1,
            101..=1000 => 2,
            _ => 3,
        }] += 1;
    }
    let seconds = start.elapsed().as_secs_f64();
    let (k1, v1) = RigidMoreauJean::energies(&scene, &state);
    // The gaps at which the last step's loaded contacts (P_n > 0) stand: the index set takes
    // a contact from the predicted gap `margin` on, so a pile at rest stands on gaps in
    // [0, margin] instead of touching.
    let loaded: Vec<f64> = scratch
        .active_impulses()
        .filter(|(_, p)| p[0] > 0.0)
        .map(|(c, _)| c.gap)
        .collect();
    let gap_mean = loaded.iter().sum::<f64>() / loaded.len().max(1) as f64;
    let gap_max = loaded.iter().copied().fold(0.0, f64::max);
    let solver = kind.name();
    let split = clock.spent.map(|d| d.as_secs_f64());
    println!(
        "{{\"code\": \"signorini\", \"bodies\": {}, \"h\": {h}, \"steps\": {count}, \"seconds\": {seconds:.4}, \"steps_per_second\": {:.2}, \"ms_per_step\": {:.4}, \"contacts_per_step\": {:.1}, \"max_contacts\": {max_contacts}, \"warm_start\": {warm_start}, \"solver\": \"{solver}\", \"tolerance\": {:e}, \"accept_error\": {}, \"auto_sweeps\": {auto_sweeps}, \"relaxation\": {relaxation}, \"stall_sweeps\": {}, \"steps_by_iterations\": {{\"le10\": {}, \"le100\": {}, \"le1000\": {}, \"more\": {}}}, \"friction_iterations_per_step\": {:.2}, \"friction_error_max\": {friction_error_max:e}, \"friction_steps_accepted\": {accepted}, \"max_penetration\": {max_penetration:e}, \"loaded_contacts_end\": {}, \"loaded_gap_mean_end\": {gap_mean:e}, \"loaded_gap_max_end\": {gap_max:e}, \"split_seconds\": {{\"detection\": {:.4}, \"assembly\": {:.4}, \"solve\": {:.4}, \"update\": {:.4}}}, \"energy_start\": {:.6}, \"energy_end\": {:.6}}}",
        scene.bodies.len(),
        count as f64 / seconds,
        1e3 * seconds / count as f64,
        contacts as f64 / count as f64,
        scheme.params().fc3d.tolerance,
        scheme
            .params()
            .accept_error
            .map_or("null".to_string(), |e| format!("{e:e}")),
        stall_sweeps.unwrap_or(0),
        histogram[0],
        histogram[1],
        histogram[2],
        histogram[3],
        friction_iterations as f64 / count as f64,
        loaded.len(),
        split[0],
        split[1],
        split[2],
        split[3],
        k0 + v0,
        k1 + v1,
    );
}
