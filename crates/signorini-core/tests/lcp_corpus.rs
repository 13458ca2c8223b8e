//! Every LCP solver over the fixture corpus `tests/fixtures/lcp/*.json` (made by
//! `scripts/lcp_corpus.py` backwards from known solutions): each applicable solver must return
//! the known z to 1e-9 relative, with its reported error within tolerance.

// Only the core library must stay pure (clippy.toml): a test may read fixtures and print.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use serde::Deserialize;
use signorini_core::lcp::{ENUMERATION_MAX, Lcp, LcpOptions, LcpSolverKind, solve};
use std::path::Path;

#[derive(Deserialize)]
struct Problem {
    note: String,
    m: Vec<Vec<f64>>,
    q: Vec<f64>,
    z: Vec<f64>,
    symmetric: bool,
}

#[test]
fn every_solver_solves_the_corpus() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/lcp");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .collect();
    files.sort();
    assert!(files.len() >= 12, "corpus missing: {}", dir.display());
    let mut solved = 0;
    for path in files {
        let p: Problem = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        let n = p.q.len();
        let m: Vec<f64> = p.m.iter().flatten().copied().collect();
        let lcp = Lcp { m: &m, q: &p.q };
        let mut kinds = vec![LcpSolverKind::Auto, LcpSolverKind::Lemke];
        if p.symmetric {
            kinds.push(LcpSolverKind::Pgs);
        }
        if n <= ENUMERATION_MAX {
            kinds.push(LcpSolverKind::Enumeration);
        }
        for kind in kinds {
            let opts = LcpOptions {
                kind,
                tolerance: 1e-10,
                max_iterations: 1_000_000,
            };
            let s = solve(lcp, &opts)
                .unwrap_or_else(|e| panic!("{}: {kind:?}: {e} ({})", path.display(), p.note));
            assert!(s.error <= 1e-10);
            let scale = p.z.iter().fold(1.0f64, |a, b| a.max(b.abs()));
            for i in 0..n {
                assert!(
                    (s.z[i] - p.z[i]).abs() <= 1e-9 * scale,
                    "{}: {kind:?}: z[{i}] = {} but the solution is {} ({})",
                    path.display(),
                    s.z[i],
                    p.z[i],
                    p.note
                );
            }
            solved += 1;
        }
    }
    assert!(solved >= 40);
}
