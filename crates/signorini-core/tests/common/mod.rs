//! The reference scenes every linear scheme's energy identity is checked on, and a run helper:
//! one harness for Moreau–Jean, the nonsmooth α-family and the position-contact baselines.

use signorini_core::integrators::{
    LinearRunStats, LinearScheme, LinearState, OutputOptions, run_linear,
};
use signorini_core::model::LinearModel;
use signorini_core::observer::Recorder;
use signorini_core::scenes::{Bar, BouncingBall, Chain, HarmonicSpec, LeftEnd, MassMatrix};

/// A reference scene: its name, model, step size and number of steps (every scene impacts).
pub struct Scene {
    pub name: String,
    pub model: LinearModel,
    pub h: f64,
    pub steps: u64,
}

/// A ball (released just off a knife edge), four bars (both mass matrices, both left ends,
/// Rayleigh damping C ≠ 0, body force, harmonic load, moving wall) and a four-mass chain with
/// simultaneous contacts and constant forces, all with restitution `e`.
pub fn reference_scenes(e: f64) -> Vec<Scene> {
    let ball = BouncingBall {
        restitution: e,
        q0: 1.0 - 1e-7,
        ..Default::default()
    };
    let mut v = vec![Scene {
        name: "bouncing_ball".into(),
        model: ball.build().unwrap(),
        h: 1e-3,
        steps: 3000,
    }];
    for mass_matrix in [MassMatrix::Lumped, MassMatrix::Consistent] {
        for left in [LeftEnd::Fixed, LeftEnd::Free] {
            let bar = Bar {
                elements: 40,
                mass_matrix,
                left,
                gap: 0.02,
                restitution: e,
                initial_velocity: 0.5,
                body_force: 0.3,
                rayleigh_mass: 0.05,
                rayleigh_stiffness: 1e-3,
                harmonic_force: Some(HarmonicSpec {
                    amplitude: 0.8,
                    omega: 7.0,
                }),
                wall_motion: Some(HarmonicSpec {
                    amplitude: 0.005,
                    omega: 3.0,
                }),
                ..Default::default()
            };
            v.push(Scene {
                name: format!("bar {mass_matrix:?} {left:?}"),
                model: bar.build().unwrap(),
                h: 2e-3,
                steps: 2000,
            });
        }
    }
    let chain = Chain {
        masses: vec![1.0, 2.0, 0.5, 1.5],
        stiffness: 50.0,
        positions: vec![0.05, 0.1, 0.12, 0.2],
        velocities: vec![-1.0, -0.5, -2.0, -1.0],
        restitution: e,
        force: Some(vec![-1.0, 0.0, 0.5, -2.0]),
        ..Default::default()
    };
    v.push(Scene {
        name: "chain".into(),
        model: chain.build().unwrap(),
        h: 1e-3,
        steps: 2000,
    });
    v
}

/// Runs `steps` steps recording every one.
pub fn simulate(
    model: &LinearModel,
    scheme: &mut dyn LinearScheme,
    steps: u64,
) -> (Recorder, LinearRunStats) {
    let mut state = LinearState::initial(model);
    let mut rec = Recorder::default();
    let output = OutputOptions {
        every: 1,
        probes: vec![],
    };
    let stats =
        run_linear(model, scheme, &mut state, steps, &output, &mut rec).expect("run completes");
    (rec, stats)
}
