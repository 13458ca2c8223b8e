//! The planar friction problem as one LCP, solved by Lemke's method.
//!
//! The tangential impulse is split `P_t = β⁺ − β⁻` and the slack `λ = |U_t|` is added, per
//! contact (Stewart & Trinkle 1996, planar case; Glocker 2001; Acary & Brogliato 2008, ch. 13):
//!
//! ```text
//! 0 ≤ U_n          ⊥ P_n ≥ 0
//! 0 ≤ λ + U_t      ⊥ β⁺  ≥ 0
//! 0 ≤ λ − U_t      ⊥ β⁻  ≥ 0
//! 0 ≤ μ P_n − β⁺ − β⁻ ⊥ λ ≥ 0
//! ```
//!
//! with `U = W P + q`. The last three lines give λ ≥ |U_t|; λ > 0 forces `β⁺ + β⁻ = μ P_n` and
//! then U_t > 0 forces β⁺ = 0, λ = U_t (sliding, `P_t = −μ P_n`), and symmetrically; λ = 0 is
//! sticking (U_t = 0, `|P_t| ≤ μ P_n`). The unknowns `z = (P_n, β⁺, β⁻, λ)` per contact make a
//! 4m×4m LCP whose matrix
//!
//! ```text
//!          P_n_b      β⁺_b       β⁻_b      λ_b
//! U_n_a  [ W_nn      W_nt      −W_nt       0  ]
//! β⁺_a   [ W_tn      W_tt      −W_tt      δ_ab]      q_lcp = (q_n, q_t, −q_t, 0)
//! β⁻_a   [−W_tn     −W_tt       W_tt      δ_ab]
//! λ_a    [ μ δ_ab   −δ_ab      −δ_ab       0  ]
//! ```
//!
//! is neither symmetric nor positive semidefinite. For W positive semidefinite it is copositive
//! and Lemke's method processes it and finds a solution (Anitescu & Potra 1997, *Formulating
//! dynamic multi-rigid-body contact problems with friction as solvable LCPs*, Nonlinear
//! Dynamics 14); when W is not, Lemke may end on a secondary ray, which is returned as
//! [`FrictionError::Lcp`]`(`[`LcpError::RayTermination`](crate::lcp::LcpError)`)` — no answer,
//! never an approximate one.

use super::{FrictionError, FrictionProblem, FrictionSolution};
use crate::lcp::{DEFAULT_TABLEAU_LIMIT, Lcp, LcpError, LcpOptions, solve_lemke, tableau_bytes};

/// Solves the friction problem by Lemke's method on the LCP reformulation (module
/// documentation; refused with [`LcpError::TooLargeForMemory`] when the reformulated matrix and
/// the tableau together would exceed [`DEFAULT_TABLEAU_LIMIT`]), then maps `(P_n, β⁺ − β⁻)` back (projected on K_μ, which only removes round-off). `iterations` counts Lemke's pivots; the
/// reported error is the natural map of the friction problem, checked against
/// `options.tolerance` (`options.kind` is ignored).
pub fn solve_friction_lemke(
    problem: FrictionProblem<'_>,
    options: &LcpOptions,
) -> Result<FrictionSolution, FrictionError> {
    problem.validate()?;
    if let Some(s) = super::separation(problem) {
        return Ok(s);
    }
    let m = problem.contacts();
    let n2 = 2 * m;
    let n4 = 4 * m;
    // The 4m×4m reformulated matrix and Lemke's 4m × (8m + 2) tableau, both dense: refused
    // before either is allocated when together they exceed Lemke's limit.
    let bytes = n4
        .saturating_mul(n4)
        .saturating_mul(std::mem::size_of::<f64>())
        .saturating_add(tableau_bytes(n4));
    if bytes > DEFAULT_TABLEAU_LIMIT {
        return Err(FrictionError::Lcp(LcpError::TooLargeForMemory {
            solver: "lemke",
            size: n4,
            bytes,
            limit: DEFAULT_TABLEAU_LIMIT,
        }));
    }
    let w = |i: usize, j: usize| problem.w[i * n2 + j];
    let mut mat = vec![0.0; n4 * n4];
    let mut q = vec![0.0; n4];
    for a in 0..m {
        let (na, ta) = (2 * a, 2 * a + 1);
        q[4 * a] = problem.q[na];
        q[4 * a + 1] = problem.q[ta];
        q[4 * a + 2] = -problem.q[ta];
        for b in 0..m {
            let (nb, tb) = (2 * b, 2 * b + 1);
            let rows = [
                [w(na, nb), w(na, tb), -w(na, tb), 0.0],
                [w(ta, nb), w(ta, tb), -w(ta, tb), 0.0],
                [-w(ta, nb), -w(ta, tb), w(ta, tb), 0.0],
                [0.0; 4],
            ];
            for (r, row) in rows.iter().enumerate() {
                mat[(4 * a + r) * n4 + 4 * b..(4 * a + r) * n4 + 4 * b + 4].copy_from_slice(row);
            }
        }
        let d = 4 * a;
        mat[(d + 1) * n4 + d + 3] = 1.0;
        mat[(d + 2) * n4 + d + 3] = 1.0;
        mat[(d + 3) * n4 + d] = problem.mu[a];
        mat[(d + 3) * n4 + d + 1] = -1.0;
        mat[(d + 3) * n4 + d + 2] = -1.0;
    }
    let s = solve_lemke(Lcp { m: &mat, q: &q }, options)?;
    let mut p = vec![0.0; n2];
    for a in 0..m {
        // β⁺ + β⁻ ≤ μ P_n holds up to the tableau's round-off; the projection on K_μ (identity
        // on an exact solution) makes the cone condition exact, and gives P_t = 0 exactly when
        // μ = 0 or P_n = 0.
        let pa = super::project_cone(problem.mu[a], [s.z[4 * a], s.z[4 * a + 1] - s.z[4 * a + 2]]);
        p[2 * a] = pa[0];
        p[2 * a + 1] = pa[1];
    }
    let error = problem.error(&p);
    if error > options.tolerance {
        return Err(FrictionError::NotConverged {
            solver: "lemke",
            iterations: s.iterations,
            error,
            tolerance: options.tolerance,
        });
    }
    Ok(FrictionSolution {
        p,
        iterations: s.iterations,
        error,
    })
}
