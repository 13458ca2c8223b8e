//! Moreau–Jean steps per second with Coulomb friction against the frictionless run of the same
//! chain: N unit masses pressed against a wall and dragged along it, the model of
//! `examples/chain_rough_wall.toml` (dofs (x_i, y_i), springs 1e3 along the wall and 1e2 across
//! it, 10 N pressing each mass, 20·N/4 N pulling the last one, μ = 0.3, h = 1e-3, θ = ½). The
//! frictionless run is the same model without `friction`/`t_matrix` (its contacts stay pressed,
//! so every step solves an LCP of size N; with friction a friction problem of size 2N). Best of
//! 3 runs of `steps` steps, energy bookkeeping on, no output recorded.
//!
//! ```text
//! cargo bench -p signorini-core --bench friction_steps
//! ```
//!
//! Prints one JSON line per (N, solver) with steps/s and the ratio friction/frictionless.
//! Figures in docs/friction.md.

// Only the core library must stay pure (clippy.toml): a benchmark times itself and prints.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use serde_json::json;
use signorini_core::integrators::moreau_jean::{MoreauJean, MoreauJeanParams};
use signorini_core::integrators::{LinearState, OutputOptions, run_linear};
use signorini_core::job::build_model;
use signorini_core::lcp::{LcpOptions, LcpSolverKind};
use signorini_core::model::LinearModel;
use signorini_core::observer::{Observer, StepRecord};
use signorini_core::spec::ModelSpec;
use std::ops::ControlFlow;
use std::time::Instant;

/// Counts records, keeps nothing.
struct Count(u64);

impl Observer for Count {
    fn observe(&mut self, _: &StepRecord<'_>) -> ControlFlow<()> {
        self.0 += 1;
        ControlFlow::Continue(())
    }
}

/// The chain on a rough wall with n masses, with or without friction.
fn chain(n: usize, friction: bool) -> LinearModel {
    let mut mass = Vec::new();
    let mut stiffness = Vec::new();
    for i in 0..n {
        mass.extend([
            json!([2 * i, 2 * i, 1.0]),
            json!([2 * i + 1, 2 * i + 1, 1.0]),
        ]);
    }
    for i in 1..n {
        for (d, k) in [(0, 1e3), (1, 1e2)] {
            let (a, b) = (2 * (i - 1) + d, 2 * i + d);
            stiffness.extend([json!([a, a, k]), json!([b, b, k]), json!([b, a, -k])]);
        }
    }
    let row = |j: usize| {
        (0..2 * n)
            .map(|i| f64::from(u8::from(i == j)))
            .collect::<Vec<_>>()
    };
    let mut force = vec![0.0; 2 * n];
    for i in 0..n {
        force[2 * i + 1] = -10.0;
    }
    force[2 * (n - 1)] = 5.0 * n as f64;
    let mut spec = json!({
        "scene": "linear",
        "mass_triplets": mass,
        "stiffness_triplets": stiffness,
        "force": force,
        "g_matrix": (0..n).map(|i| row(2 * i + 1)).collect::<Vec<_>>(),
        "restitution": vec![0.0; n],
    });
    if friction {
        spec["t_matrix"] = json!((0..n).map(|i| row(2 * i)).collect::<Vec<_>>());
        spec["friction"] = json!(vec![0.3; n]);
    }
    let spec: ModelSpec = serde_json::from_value(spec).expect("chain spec");
    build_model(&spec).expect("chain model")
}

/// Best steps/s of 3 runs.
fn steps_per_s(model: &LinearModel, kind: LcpSolverKind, steps: u64) -> f64 {
    let lcp = LcpOptions {
        kind,
        ..LcpOptions::default()
    };
    let mut best = f64::INFINITY;
    for _ in 0..3 {
        let mut scheme =
            MoreauJean::new(model, MoreauJeanParams::default(), 1e-3, lcp).expect("SPD");
        let mut state = LinearState::initial(model);
        let output = OutputOptions {
            every: u64::MAX,
            probes: vec![],
        };
        let t0 = Instant::now();
        run_linear(
            model,
            &mut scheme,
            &mut state,
            steps,
            &output,
            &mut Count(0),
        )
        .expect("run");
        best = best.min(t0.elapsed().as_secs_f64());
        std::hint::black_box(&state);
    }
    steps as f64 / best
}

fn main() {
    for n in [4usize, 20, 50] {
        let steps = (40_000 / n) as u64;
        let frictionless = chain(n, false);
        let with = chain(n, true);
        let base = steps_per_s(&frictionless, LcpSolverKind::Auto, steps);
        for (name, kind) in [
            ("auto", LcpSolverKind::Auto),
            ("lemke", LcpSolverKind::Lemke),
            ("nsgs", LcpSolverKind::Pgs),
        ] {
            let rate = steps_per_s(&with, kind, steps);
            println!(
                "{{\"bench\":\"friction_steps\",\"masses\":{n},\"steps\":{steps},\"solver\":\"{name}\",\"frictionless_steps_per_s\":{base:.0},\"friction_steps_per_s\":{rate:.0},\"ratio\":{:.3}}}",
                rate / base
            );
        }
    }
}
