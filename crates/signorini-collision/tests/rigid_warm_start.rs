//! The warm start of the rigid step's friction problem (issue 29, the 1 000-sphere benchmark's
//! solve): each step's FC3D solve starts from the last impulses of the same contacts. It changes
//! the solver's path, not the bound on its error: on a small pile of spheres poured into a box the
//! warm and cold runs both accept only solutions within the tolerance and close the ledger at
//! round-off, and the warm run needs fewer Gauss–Seidel sweeps; a box resting on a floor,
//! whose impulses do not change from step to step, is solved by one sweep per step.

use signorini_collision::ParryDetectors;
use signorini_core::friction::Fc3dOptions;
use signorini_core::observer::Recorder;
use signorini_core::rigid::{
    Body, BodyState, ContactLaw, DetectorFactory, RigidMoreauJean, RigidMoreauJeanParams,
    RigidScene, RigidScratch, RigidStepping, Shape,
};
use signorini_core::stepping::{TimeStepping, run};

fn state(position: [f64; 3]) -> BodyState {
    BodyState {
        position,
        orientation: [1.0, 0.0, 0.0, 0.0],
        velocity: [0.0; 3],
        angular_velocity: [0.0; 3],
    }
}

fn wall(normal: [f64; 3], position: [f64; 3]) -> (String, Body, BodyState) {
    (
        format!("wall{normal:?}"),
        Body {
            shape: Shape::HalfSpace { normal },
            mass: 0.0,
            inertia: [0.0; 3],
            fixed: true,
        },
        state(position),
    )
}

fn free(shape: Shape, position: [f64; 3]) -> (String, Body, BodyState) {
    let (mass, inertia) = shape.mass_properties(1000.0).unwrap();
    (
        format!("body{position:?}"),
        Body {
            shape,
            mass,
            inertia,
            fixed: false,
        },
        state(position),
    )
}

fn scene(parts: Vec<(String, Body, BodyState)>) -> RigidScene {
    RigidScene {
        names: parts.iter().map(|p| p.0.clone()).collect(),
        bodies: parts.iter().map(|p| p.1.clone()).collect(),
        initial: parts.iter().map(|p| p.2).collect(),
        gravity: [0.0, 0.0, -9.81],
        default_law: ContactLaw {
            restitution: 0.0,
            friction: 0.3,
        },
        pair_laws: Vec::new(),
        margin: 5e-3,
        joints: Vec::new(),
    }
}

/// 27 spheres (r = 5 cm) on a 3 × 3 × 3 lattice of pitch 11 cm, nudged sideways, released at
/// rest in a 0.4 m square box: the 1 000-sphere benchmark in small.
fn pile() -> RigidScene {
    let mut parts = vec![
        wall([0.0, 0.0, 1.0], [0.0; 3]),
        wall([1.0, 0.0, 0.0], [-0.2, 0.0, 0.0]),
        wall([-1.0, 0.0, 0.0], [0.2, 0.0, 0.0]),
        wall([0.0, 1.0, 0.0], [0.0, -0.2, 0.0]),
        wall([0.0, -1.0, 0.0], [0.0, 0.2, 0.0]),
    ];
    let mut k: f64 = 0.0;
    for iz in 0..3 {
        for iy in 0..3 {
            for ix in 0..3 {
                k += 1.0;
                let nudge = 0.004 * (1.7 * k).sin();
                parts.push(free(
                    Shape::Sphere { radius: 0.05 },
                    [
                        (ix as f64 - 1.0) * 0.11 + nudge,
                        (iy as f64 - 1.0) * 0.11 - nudge,
                        0.06 + 0.11 * iz as f64,
                    ],
                ));
            }
        }
    }
    scene(parts)
}

fn params(warm_start: bool) -> RigidMoreauJeanParams {
    RigidMoreauJeanParams {
        fc3d: Fc3dOptions {
            tolerance: 1e-8,
            ..Fc3dOptions::default()
        },
        warm_start,
        ..RigidMoreauJeanParams::default()
    }
}

/// 400 steps of h = 1 ms: the spheres fall, land and pile up (up to ~80 contacts).
#[test]
fn warm_started_pile_meets_the_tolerance_with_fewer_sweeps() {
    let s = pile();
    let mut runs = Vec::new();
    for warm in [false, true] {
        let scheme = RigidMoreauJean::new(params(warm), 1e-3);
        let detector = ParryDetectors.detector(&s.bodies).unwrap();
        let mut family = RigidStepping::new(&s, &scheme, detector, 400);
        let mut rec = Recorder::default();
        run(&mut family, 1, &mut rec, None).unwrap();
        let stats = family.stats().clone();
        // Only solutions within the tolerance are accepted, warm or cold.
        assert!(stats.friction_error_max <= 1e-8, "{stats:?}");
        assert!(stats.max_contacts >= 40, "{stats:?}");
        // The ledger closes at round-off of the energy in every step.
        let scale = stats.energy_initial.abs();
        assert!(stats.max_abs_energy_error <= 1e-10 * scale, "{stats:?}");
        runs.push((stats, rec));
    }
    let (cold, warm) = (&runs[0].0, &runs[1].0);
    eprintln!(
        "sweeps cold {} warm {}; energy cold {} warm {}",
        cold.friction_iterations_total,
        warm.friction_iterations_total,
        cold.energy_final,
        warm.energy_final
    );
    // Measured: 20 112 sweeps warm against 26 061 cold (−23 %) with plain Gauss–Seidel first in
    // `auto`, 6 707 against 8 076 (−17 %) with the accelerated sweeps first (Round 7): the
    // spheres land one layer after another, and each landing changes the impulses through the
    // pile.
    assert!(
        100 * warm.friction_iterations_total <= 85 * cold.friction_iterations_total,
        "warm {} cold {}",
        warm.friction_iterations_total,
        cold.friction_iterations_total
    );
    // Both runs dissipate the same energy to the tolerance's order (the paths differ by solver
    // round-off amplified by the pile's collisions, not by a different law).
    let dropped = cold.energy_initial - cold.energy_final;
    assert!(
        (warm.energy_final - cold.energy_final).abs() <= 1e-3 * dropped,
        "energy cold {} warm {}",
        cold.energy_final,
        warm.energy_final
    );
}

/// A 10 cm box at rest on a floor (four corner contacts): the impulses repeat from step to step,
/// so after the first steps every friction problem starts at its solution and one sweep confirms
/// it; the kept impulses sum to the weight over a step, m g h, to the solver's tolerance (1e-8).
#[test]
fn a_resting_box_is_solved_in_one_sweep_per_step() {
    let s = scene(vec![
        wall([0.0, 0.0, 1.0], [0.0; 3]),
        free(
            Shape::Box {
                half_extents: [0.05; 3],
            },
            [0.0, 0.0, 0.05],
        ),
    ]);
    let h = 1e-3;
    let scheme = RigidMoreauJean::new(params(true), h);
    let mut detector = ParryDetectors.detector(&s.bodies).unwrap();
    let mut state = s.initial.clone();
    let mut scratch = RigidScratch::default();
    for k in 1..=50u64 {
        let report = scheme
            .step(
                &s,
                &mut state,
                detector.as_mut(),
                &mut scratch,
                k,
                (k - 1) as f64 * h,
            )
            .unwrap();
        assert_eq!(report.contacts, 4);
        if k > 2 {
            assert_eq!(report.friction_iterations, 1, "step {k}: {report:?}");
        }
        let kept = scratch.previous_impulses();
        assert_eq!(kept.len(), 4);
        let weight = s.bodies[1].mass * 9.81 * h;
        let sum: f64 = kept.iter().map(|c| c.impulse[2]).sum();
        assert!(
            (sum - weight).abs() <= 1e-8 * weight,
            "step {k}: {sum} vs {weight}"
        );
    }
    // The features tell the four corners apart: four distinct keys.
    let mut keys: Vec<_> = scratch
        .previous_impulses()
        .iter()
        .map(|c| (c.bodies, c.features))
        .collect();
    keys.sort();
    keys.dedup();
    assert_eq!(keys.len(), 4);
}

/// The impulses of the last step are part of the state a checkpoint keeps (so a resumed run
/// starts its next solve where the uninterrupted one does): `memory()` holds one per contact.
#[test]
fn the_memory_keeps_the_last_impulses() {
    let s = pile();
    let scheme = RigidMoreauJean::new(params(true), 1e-3);
    let detector = ParryDetectors.detector(&s.bodies).unwrap();
    let mut family = RigidStepping::new(&s, &scheme, detector, 100);
    for k in 1..=100 {
        family.step(k).unwrap();
    }
    let memory = family.memory();
    assert_eq!(memory.impulses.len(), family.last_report().contacts);
    assert!(!memory.impulses.is_empty());
    assert!(
        memory
            .impulses
            .iter()
            .all(|c| c.impulse.iter().all(|x| x.is_finite()))
    );
}
