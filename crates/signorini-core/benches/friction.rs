//! One-step planar friction problems against the frictionless LCP on the same chain: m masses
//! (2 dof each: normal, tangent) joined by springs in both directions, each pressed against a
//! rough wall; the Moreau–Jean Delassus operator `W = H (M + h²K)⁻¹ Hᵀ` (dense, every contact
//! coupled), free velocity pressing into the wall and dragging along it. Solves per second
//! (best of 5) of `lcp::solve` on `(W_nn, q_n)` and of `friction::solve_friction` with Lemke
//! (LCP reformulation) and with the nonsmooth Gauss–Seidel, and their ratios.
//!
//! `cargo bench -p signorini-core --bench friction` (plain main, harness = false). Figures in
//! docs/friction.md.

// Only the core library must stay pure (clippy.toml): a benchmark times itself and prints.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use nalgebra::DMatrix;
use signorini_core::friction::{FrictionProblem, solve_friction};
use signorini_core::lcp::{Lcp, LcpOptions, LcpSolverKind, solve};
use std::time::Instant;

/// `(W, q)` of the chain with m contacts.
fn chain(m: usize) -> (Vec<f64>, Vec<f64>) {
    let n = 2 * m;
    let (mass, k, h) = (1.0, 1e4, 1e-3);
    let mut a = DMatrix::<f64>::zeros(n, n);
    for i in 0..n {
        a[(i, i)] = mass;
    }
    // Springs between neighbours, in each direction.
    for c in 0..m.saturating_sub(1) {
        for d in 0..2 {
            let (i, j) = (2 * c + d, 2 * (c + 1) + d);
            a[(i, i)] += h * h * k;
            a[(j, j)] += h * h * k;
            a[(i, j)] -= h * h * k;
            a[(j, i)] -= h * h * k;
        }
    }
    let inv = a.try_inverse().unwrap_or_else(|| DMatrix::identity(n, n));
    let w: Vec<f64> = (0..n * n).map(|x| inv[(x / n, x % n)]).collect();
    // Pressed into the wall (more at one end) and dragged along it (more at the other).
    let q: Vec<f64> = (0..m)
        .flat_map(|c| {
            let s = c as f64 / m.max(2) as f64;
            [-(1.0 + s), 0.2 + 1.5 * (1.0 - s)]
        })
        .collect();
    (w, q)
}

fn rate(mut f: impl FnMut() -> usize) -> (f64, usize) {
    let mut best = 0.0f64;
    let mut iterations = 0;
    for _ in 0..5 {
        let start = Instant::now();
        let mut count = 0;
        while start.elapsed().as_secs_f64() < 0.2 {
            iterations = f();
            count += 1;
        }
        best = best.max(count as f64 / start.elapsed().as_secs_f64());
    }
    (best, iterations)
}

fn main() {
    println!(
        "contacts  μ     lcp solves/s  lemke solves/s (pivots)  nsgs solves/s (sweeps)  lemke/lcp  nsgs/lcp"
    );
    for m in [5, 20, 50] {
        for mu in [0.3, 0.8] {
            let (w, q) = chain(m);
            let wnn: Vec<f64> = (0..m * m)
                .map(|x| w[2 * (x / m) * 2 * m + 2 * (x % m)])
                .collect();
            let qn: Vec<f64> = (0..m).map(|c| q[2 * c]).collect();
            let mus = vec![mu; m];
            let problem = FrictionProblem {
                w: &w,
                q: &q,
                mu: &mus,
            };
            let opts = |kind| LcpOptions {
                kind,
                tolerance: 1e-10,
                max_iterations: 1_000_000,
            };
            let (lcp, _) = rate(|| {
                solve(Lcp { m: &wnn, q: &qn }, &opts(LcpSolverKind::Auto))
                    .expect("frictionless LCP")
                    .iterations
            });
            let (lemke, pivots) = rate(|| {
                solve_friction(problem, &opts(LcpSolverKind::Lemke))
                    .expect("lemke")
                    .iterations
            });
            let (nsgs, sweeps) = rate(|| {
                solve_friction(problem, &opts(LcpSolverKind::Pgs))
                    .expect("nsgs")
                    .iterations
            });
            println!(
                "{m:8}  {mu:.1}  {lcp:12.0}  {lemke:14.0} ({pivots:4})  {nsgs:13.0} ({sweeps:5})  {:9.3}  {:8.3}",
                lemke / lcp,
                nsgs / lcp
            );
        }
    }
}
