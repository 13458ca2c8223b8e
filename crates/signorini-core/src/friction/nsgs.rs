//! Nonsmooth Gauss–Seidel over contacts (Jean & Moreau 1987; Jean 1999, *The non-smooth contact
//! dynamics method*; Acary & Brogliato 2008, ch. 13).
//!
//! A sweep visits the contacts in order; at contact a, with the others frozen, the local
//! problem is the 2×2 friction problem `U_a = W_aa P_a + r_a`, `r_a = q_a + Σ_{b≠a} W_ab P_b`,
//! solved exactly by enumerating its four cases:
//!
//! ```text
//! take-off   r_n ≥ 0:  P_a = 0
//! sticking   U_a = 0:  P_a = −W_aa⁻¹ r_a,                           valid if |P_t| ≤ μ P_n
//! sliding s  U_n = 0, P_t = −s μ P_n:  P_n = −r_n / (W_nn − s μ W_nt), valid if P_n ≥ 0, s U_t ≥ 0
//! ```
//!
//! The candidate with the smallest local natural-map residual is kept (ties: the first in the
//! order above; μ = 0 keeps P_t = 0 exactly), which is an exact local solution whenever one of the cases holds. Sweeps stop
//! when the global natural-map error is ≤ the tolerance. Deterministic: fixed contact order,
//! no randomisation. Convergence is not guaranteed for Coulomb friction (the problem is not
//! monotone); a budget spent is [`FrictionError::NotConverged`].

use super::{FrictionError, FrictionProblem, FrictionSolution, contact_residual};
use crate::lcp::LcpOptions;

/// Solves the friction problem by nonsmooth Gauss–Seidel (module documentation). `iterations`
/// counts sweeps; `options.kind` is ignored. Needs each 2×2 diagonal block of W positive
/// definite ([`FrictionError::LocalBlockNotDefinite`]).
pub fn solve_friction_nsgs(
    problem: FrictionProblem<'_>,
    options: &LcpOptions,
) -> Result<FrictionSolution, FrictionError> {
    problem.validate()?;
    if let Some(s) = super::separation(problem) {
        return Ok(s);
    }
    let m = problem.contacts();
    let n = 2 * m;
    let blocks: Vec<[f64; 4]> = (0..m)
        .map(|a| {
            let (i, j) = (2 * a, 2 * a + 1);
            [
                problem.w[i * n + i],
                problem.w[i * n + j],
                problem.w[j * n + i],
                problem.w[j * n + j],
            ]
        })
        .collect();
    for (contact, b) in blocks.iter().enumerate() {
        let det = b[0] * b[3] - b[1] * b[2];
        if !(b[0] > 0.0 && b[3] > 0.0 && det > 0.0 && det.is_finite()) {
            return Err(FrictionError::LocalBlockNotDefinite { contact });
        }
    }
    let mut p = vec![0.0; n];
    let mut error = f64::INFINITY;
    for sweep in 1..=options.max_iterations {
        for (a, &b) in blocks.iter().enumerate() {
            let (i, j) = (2 * a, 2 * a + 1);
            // r_a = q_a + Σ_{b≠a} W_ab P_b = (W P + q)_a − W_aa P_a.
            let row = |k: usize| {
                problem.q[k]
                    + problem.w[k * n..(k + 1) * n]
                        .iter()
                        .zip(&p)
                        .map(|(x, y)| x * y)
                        .sum::<f64>()
            };
            let r = [
                row(i) - b[0] * p[i] - b[1] * p[j],
                row(j) - b[2] * p[i] - b[3] * p[j],
            ];
            let local = solve_local(problem.mu[a], b, r);
            p[i] = local[0];
            p[j] = local[1];
        }
        error = problem.error(&p);
        if error <= options.tolerance {
            return Ok(FrictionSolution {
                p,
                iterations: sweep,
                error,
            });
        }
    }
    Err(FrictionError::NotConverged {
        solver: "nsgs",
        iterations: options.max_iterations,
        error,
        tolerance: options.tolerance,
    })
}

/// Exact solution of the 2×2 problem `U = W P + r` (W = `[W_nn, W_nt, W_tn, W_tt]` positive
/// definite) by enumeration of its cases (module documentation).
fn solve_local(mu: f64, w: [f64; 4], r: [f64; 2]) -> [f64; 2] {
    if r[0] >= 0.0 {
        return [0.0, 0.0];
    }
    if mu == 0.0 {
        // The normal problem alone, P_t = 0 exactly.
        return [-r[0] / w[0], 0.0];
    }
    let velocity = |p: [f64; 2]| {
        [
            w[0] * p[0] + w[1] * p[1] + r[0],
            w[2] * p[0] + w[3] * p[1] + r[1],
        ]
    };
    let det = w[0] * w[3] - w[1] * w[2];
    let stick = [
        (-w[3] * r[0] + w[1] * r[1]) / det,
        (w[2] * r[0] - w[0] * r[1]) / det,
    ];
    let mut best = stick;
    let mut best_residual = contact_residual(mu, stick, velocity(stick));
    for s in [1.0, -1.0] {
        let d = w[0] - s * mu * w[1];
        if d <= 0.0 {
            continue;
        }
        let pn = -r[0] / d;
        let candidate = [pn, -s * mu * pn];
        let residual = contact_residual(mu, candidate, velocity(candidate));
        if residual < best_residual {
            best = candidate;
            best_residual = residual;
        }
    }
    best
}
