//! Both friction solvers (Lemke on the LCP reformulation, the nonsmooth Gauss–Seidel) and the
//! `auto` dispatch over the fixture corpus `tests/fixtures/friction/*.json` (made by
//! `scripts/friction_corpus.py` backwards from known solutions, in the uniqueness regime): each
//! must return the known impulses P and local velocities U to 1e-9 relative, with its
//! natural-map error within tolerance and friction doing no positive work.

// Only the core library must stay pure (clippy.toml): a test may read fixtures and print.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use serde::Deserialize;
use signorini_core::friction::{FrictionProblem, solve_friction};
use signorini_core::lcp::{LcpOptions, LcpSolverKind};
use std::path::Path;

#[derive(Deserialize)]
struct Problem {
    note: String,
    mu: Vec<f64>,
    w: Vec<Vec<f64>>,
    q: Vec<f64>,
    p: Vec<f64>,
    u: Vec<f64>,
}

#[test]
fn both_solvers_solve_the_friction_corpus() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/friction");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .expect("the corpus directory")
        .flatten()
        .map(|e| e.path())
        .collect();
    files.sort();
    assert!(files.len() >= 19, "corpus missing: {}", dir.display());
    for path in &files {
        let text = std::fs::read_to_string(path).expect("reading a fixture");
        let p: Problem = serde_json::from_str(&text).expect("a fixture");
        let w: Vec<f64> = p.w.iter().flatten().copied().collect();
        let problem = FrictionProblem {
            w: &w,
            q: &p.q,
            mu: &p.mu,
        };
        for kind in [
            LcpSolverKind::Lemke,
            LcpSolverKind::Pgs,
            LcpSolverKind::Auto,
        ] {
            let options = LcpOptions {
                kind,
                tolerance: 1e-12,
                max_iterations: 100_000,
            };
            let what = format!("{}: {kind:?} ({})", path.display(), p.note);
            let s = solve_friction(problem, &options).unwrap_or_else(|e| panic!("{what}: {e}"));
            assert!(s.error <= 1e-12, "{what}: error {:e}", s.error);
            let u = problem.local_velocity(&s.p);
            let scale = p.p.iter().chain(&p.u).fold(1.0f64, |m, x| m.max(x.abs()));
            for (i, ((got, want), (ug, uw))) in
                s.p.iter().zip(&p.p).zip(u.iter().zip(&p.u)).enumerate()
            {
                assert!(
                    (got - want).abs() <= 1e-9 * scale,
                    "{what}: P[{i}] = {got} but the solution is {want}"
                );
                assert!(
                    (ug - uw).abs() <= 1e-9 * scale,
                    "{what}: U[{i}] = {ug} but the solution has {uw}"
                );
            }
            for c in 0..p.mu.len() {
                assert!(
                    s.p[2 * c + 1] * u[2 * c + 1] <= 1e-12 * scale * scale,
                    "{what}"
                );
            }
        }
    }
}
