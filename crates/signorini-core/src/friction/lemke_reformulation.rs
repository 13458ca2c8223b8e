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
//! never an approximate one. A frictionless contact (μ = 0) keeps its normal unknown alone
//! (P_t = 0; its β⁺, β⁻, λ rows would only force β⁺ = β⁻ = 0 through `0 ≤ −β⁺ − β⁻ ⊥ λ`, and on
//! a problem whose every μ is 0 Lemke's method ended on a ray there: found by the property test
//! `both_solvers_solve_random_problems`, kept in its regression file).

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
    // The unknowns of contact a start at first[a]: P_n, then β⁺, β⁻, λ when μ_a > 0. A
    // frictionless contact has P_t = 0 and no tangential condition, so it keeps P_n alone
    // (with its three rows, μ = 0 would force β⁺ = β⁻ = 0 through a row `0 ≤ −β⁺ − β⁻ ⊥ λ`
    // that makes the matrix lose copositivity-plus, and Lemke's method can end on a ray there).
    let frictional: Vec<bool> = problem.mu.iter().map(|&mu| mu > 0.0).collect();
    let mut first = Vec::with_capacity(m);
    let mut size = 0usize;
    for &f in &frictional {
        first.push(size);
        size += if f { 4 } else { 1 };
    }
    // The size×size reformulated matrix and Lemke's size × (2 size + 2) tableau, both dense:
    // refused before either is allocated when together they exceed Lemke's limit.
    let bytes = size
        .saturating_mul(size)
        .saturating_mul(std::mem::size_of::<f64>())
        .saturating_add(tableau_bytes(size));
    if bytes > DEFAULT_TABLEAU_LIMIT {
        return Err(FrictionError::Lcp(LcpError::TooLargeForMemory {
            solver: "lemke",
            size,
            bytes,
            limit: DEFAULT_TABLEAU_LIMIT,
        }));
    }
    let w = |i: usize, j: usize| problem.w[i * n2 + j];
    let mut mat = vec![0.0; size * size];
    let mut q = vec![0.0; size];
    for a in 0..m {
        let (na, ta) = (2 * a, 2 * a + 1);
        let d = first[a];
        q[d] = problem.q[na];
        if frictional[a] {
            q[d + 1] = problem.q[ta];
            q[d + 2] = -problem.q[ta];
        }
        for b in 0..m {
            let (nb, tb) = (2 * b, 2 * b + 1);
            let rows = [
                [w(na, nb), w(na, tb), -w(na, tb)],
                [w(ta, nb), w(ta, tb), -w(ta, tb)],
                [-w(ta, nb), -w(ta, tb), w(ta, tb)],
            ];
            let own_rows = if frictional[a] { 3 } else { 1 };
            let columns = if frictional[b] { 3 } else { 1 };
            for (r, row) in rows.iter().enumerate().take(own_rows) {
                let at = (d + r) * size + first[b];
                mat[at..at + columns].copy_from_slice(&row[..columns]);
            }
        }
        if frictional[a] {
            mat[(d + 1) * size + d + 3] = 1.0;
            mat[(d + 2) * size + d + 3] = 1.0;
            mat[(d + 3) * size + d] = problem.mu[a];
            mat[(d + 3) * size + d + 1] = -1.0;
            mat[(d + 3) * size + d + 2] = -1.0;
        }
    }
    let s = solve_lemke(Lcp { m: &mat, q: &q }, options)?;
    let mut p = vec![0.0; n2];
    for a in 0..m {
        let d = first[a];
        let tangential = if frictional[a] {
            s.z[d + 1] - s.z[d + 2]
        } else {
            0.0
        };
        // β⁺ + β⁻ ≤ μ P_n holds up to the tableau's round-off; the projection on K_μ (identity
        // on an exact solution) makes the cone condition exact.
        let pa = super::project_cone(problem.mu[a], [s.z[d], tangential]);
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
