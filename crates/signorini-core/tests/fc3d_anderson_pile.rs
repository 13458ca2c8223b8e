//! Gauss–Seidel with Anderson acceleration (`nsgs_aa`) on a piece of a dense pile of spheres where
//! the accelerated sweeps alone stagnate (docs/rigid_benchmark.md, Round 7): the fallback to plain
//! sweeps must converge where plain Gauss–Seidel does, within a few restart cycles of its sweep
//! count, and to the same solution.

// Only the core library must stay pure (clippy.toml): a test may read fixtures.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use serde::Deserialize;
use signorini_core::friction::{
    BlockCsr, Fc3dError, Fc3dOptions, Fc3dProblem, Fc3dSolution, Fc3dSolverKind, solve_fc3d_from,
};
use std::path::Path;

#[derive(Deserialize)]
struct Fixture {
    mu: Vec<f64>,
    q: Vec<f64>,
    start: Vec<f64>,
    /// `(a, b, W_ab row-major)` for every stored 3×3 block.
    blocks: Vec<(usize, usize, [f64; 9])>,
}

/// `tests/fixtures/fc3d/pile_step298_66.json` (its `note` says where it was cut from) and its warm
/// start.
fn pile() -> (Fc3dProblem, Vec<f64>) {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/fc3d/pile_step298_66.json");
    let text = std::fs::read_to_string(&path).expect("the fixture");
    let f: Fixture = serde_json::from_str(&text).expect("a fixture");
    let entries = f
        .blocks
        .iter()
        .flat_map(|(a, b, w)| (0..9).map(move |k| (3 * a + k / 3, 3 * b + k % 3, w[k])));
    let w = BlockCsr::from_triplets(3, f.q.len(), entries).expect("blocks");
    (
        Fc3dProblem {
            w,
            q: f.q,
            mu: f.mu,
        },
        f.start,
    )
}

fn solve_relaxed(
    problem: &Fc3dProblem,
    kind: Fc3dSolverKind,
    start: &[f64],
    relaxation: f64,
) -> Fc3dSolution {
    let options = Fc3dOptions {
        kind,
        tolerance: 1e-6,
        max_iterations: 2000,
        relaxation,
        ..Fc3dOptions::default()
    };
    solve_fc3d_from(problem, &options, start).unwrap_or_else(|e| panic!("{}: {e}", kind.name()))
}

/// From the step's warm start and from r = 0, plain Gauss–Seidel reaches 1e-6 in 877 and 878
/// sweeps. The accelerated sweeps plateau near 6.8e-4 (without the fallback they spent any budget
/// there), drop the acceleration after three restarts without progress, and then run Gauss–Seidel
/// from the start again: they return Gauss–Seidel's impulses to the bit, after its sweeps plus
/// the ≈ 100 spent accelerated.
#[test]
fn accelerated_sweeps_fall_back_to_plain_sweeps_where_they_stall() {
    let (problem, warm) = pile();
    assert_eq!(problem.contacts(), 66);
    for (start, sweeps) in [(warm.clone(), 877), (vec![0.0; warm.len()], 878)] {
        assert_eq!(falls_back_to_plain_sweeps(&problem, &start, 1.0), sweeps);
    }
}

/// Plain sweeps (over-relaxed by `relaxation`) and the accelerated ones from `start`: the
/// accelerated ones return the plain ones' impulses to the bit, at the tolerance, after 40–150
/// sweeps of their own. Returns the plain sweeps.
fn falls_back_to_plain_sweeps(problem: &Fc3dProblem, start: &[f64], relaxation: f64) -> usize {
    let plain = solve_relaxed(problem, Fc3dSolverKind::Nsgs, start, relaxation);
    let fast = solve_relaxed(problem, Fc3dSolverKind::NsgsAnderson, start, relaxation);
    assert_eq!(fast.solver, "nsgs_aa");
    assert_eq!(fast.r, plain.r);
    assert!(plain.error <= 1e-6 && problem.error(&plain.r) == plain.error);
    assert!(fast.error <= 1e-6 && problem.error(&fast.r) == fast.error);
    let accelerated = fast.iterations - plain.iterations;
    assert!(
        (40..=150).contains(&accelerated),
        "{accelerated} sweeps accelerated"
    );
    plain.iterations
}

/// Over-relaxed plain sweeps (ω = 1.5, a rigid step's `rigid::RELAXATION`; Cryer's projected
/// SOR contact by contact) on the same pile: Gauss–Seidel needs 291 and 292 sweeps instead of 877
/// and 878 to the same tolerance, and the accelerated sweeps, which are never relaxed, fall back
/// to those over-relaxed sweeps and return their impulses to the bit. An over-relaxation outside
/// (0, 2) is refused.
#[test]
fn over_relaxed_plain_sweeps_converge_in_fewer_sweeps_on_the_pile() {
    let (problem, warm) = pile();
    for (start, sweeps) in [(warm.clone(), 291), (vec![0.0; warm.len()], 292)] {
        assert_eq!(falls_back_to_plain_sweeps(&problem, &start, 1.5), sweeps);
    }
    for relaxation in [0.0, 2.0, -1.0, f64::NAN] {
        let options = Fc3dOptions {
            relaxation,
            ..Fc3dOptions::default()
        };
        assert!(matches!(
            solve_fc3d_from(&problem, &options, &warm),
            Err(Fc3dError::InvalidRelaxation { .. })
        ));
    }
}
