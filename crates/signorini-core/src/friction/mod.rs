//! The one-step planar friction problem in impulses and its solvers.
//!
//! Planar contacts (one tangent each), m of them, unknowns per contact the normal and tangential
//! impulses `(P_n, P_t)`. The local velocity is
//!
//! ```text
//! U = W P + q
//! ```
//!
//! with W the 2m×2m Delassus operator, rows and columns ordered `(n_1, t_1, n_2, t_2, …)`, and q
//! the free local velocity, whose normal rows already hold the Newton-law term `e U_n,k`
//! (Moreau 1988; Acary & Brogliato 2008, *Numerical Methods for Nonsmooth Dynamical Systems*,
//! ch. 12–13). Each contact obeys Signorini in the normal direction and Coulomb's law
//! in the tangent:
//!
//! ```text
//! 0 ≤ U_n ⊥ P_n ≥ 0,   |P_t| ≤ μ P_n,   U_t ≠ 0 ⇒ P_t = −μ P_n sign(U_t)   (U_t = 0: sticking)
//! ```
//!
//! Equivalently (De Saxcé & Feng 1991; Acary & Brogliato 2008, ch. 13) with the cone
//! `K_μ = {(p_n, p_t) : |p_t| ≤ μ p_n}` and the modified velocity `Û = (U_n + μ|U_t|, U_t)`:
//! `K_μ ∋ P ⊥ Û ∈ K_μ*`, i.e. `P = proj_{K_μ}(P − Û)`. Every solve reports its error as that
//! natural map, relative, as Siconos' `fc2d_compute_error` and `fc3d_compute_error` do:
//!
//! ```text
//! error = ‖P − proj_{K_μ}(P − Û)‖₂ / max(‖q‖₂, ‖P‖₂, ‖U‖₂)
//! ```
//!
//! over all contacts stacked (not divided when the scale is ≤ the machine epsilon), zero exactly
//! at a solution and small near one. Relative, so a problem of tiny q (‖q‖ = 3.5e-15 in Siconos'
//! FrictionContactProblem00394) is not declared solved by a residual that is small only in
//! absolute terms. A solve that cannot reach the tolerance is a [`FrictionError`], never a
//! silent approximation.
//!
//! The three-dimensional problem (two tangents, Coulomb's cone) is [`fc3d`], on a block-sparse
//! Delassus operator ([`block_csr`]).
//!
//! Two solvers: the exact LCP reformulation of the planar cone solved by Lemke
//! ([`solve_friction_lemke`]) and the nonsmooth Gauss–Seidel over contacts
//! ([`solve_friction_nsgs`]); [`solve_friction`] dispatches on [`LcpOptions::kind`].

mod block3;
pub mod block_csr;
pub mod fc3d;
mod fc3d_anderson;
mod fc3d_block_lu;
mod fc3d_newton;
mod fc3d_nsgs;
mod fc3d_prox;
mod fc3d_solve;
mod fc3d_sparse_lu;
mod lemke_reformulation;
mod nsgs;
mod work;

pub use block_csr::{BlockCsr, BlockCsrError};
pub use fc3d::{
    Fc3dError, Fc3dNewtonLinear, Fc3dOptions, Fc3dProblem, Fc3dSolution, Fc3dSolverKind, Fc3dStall,
    natural_map_error,
};
pub use fc3d_anderson::solve_fc3d_nsgs_anderson;
pub use fc3d_newton::solve_fc3d_newton;
pub use fc3d_nsgs::solve_fc3d_nsgs;
pub use fc3d_prox::solve_fc3d_prox;
pub use fc3d_solve::{solve_fc3d, solve_fc3d_from};
pub use lemke_reformulation::solve_friction_lemke;
pub use nsgs::solve_friction_nsgs;
pub use work::{TangentialWork, split_tangential_work};

use crate::lcp::{self, Lcp, LcpError, LcpOptions, LcpSolverKind};
use thiserror::Error;

/// A dense planar friction problem with m contacts.
#[derive(Debug, Clone, Copy)]
pub struct FrictionProblem<'a> {
    /// Row-major 2m×2m Delassus operator, ordered `(n_1, t_1, n_2, t_2, …)`.
    pub w: &'a [f64],
    /// Free local velocity (2m), same order; the normal rows include `e U_n,k`.
    pub q: &'a [f64],
    /// Friction coefficient per contact (m), finite and ≥ 0.
    pub mu: &'a [f64],
}

impl FrictionProblem<'_> {
    /// Number of contacts m.
    pub fn contacts(&self) -> usize {
        self.mu.len()
    }

    /// Checks the sizes and the friction coefficients.
    pub fn validate(&self) -> Result<(), FrictionError> {
        let m = self.contacts();
        if self.q.len() != 2 * m || self.w.len() != 4 * m * m {
            return Err(FrictionError::Dimensions {
                contacts: m,
                q_len: self.q.len(),
                w_len: self.w.len(),
            });
        }
        if let Some((contact, &mu)) = self
            .mu
            .iter()
            .enumerate()
            .find(|(_, mu)| !(mu.is_finite() && **mu >= 0.0))
        {
            return Err(FrictionError::InvalidFriction { contact, mu });
        }
        Ok(())
    }

    /// Local velocity U = W P + q.
    pub fn local_velocity(&self, p: &[f64]) -> Vec<f64> {
        let n = self.q.len();
        (0..n)
            .map(|i| {
                self.q[i]
                    + self.w[i * n..(i + 1) * n]
                        .iter()
                        .zip(p)
                        .map(|(a, b)| a * b)
                        .sum::<f64>()
            })
            .collect()
    }

    /// The relative natural-map error of `p` (module documentation).
    pub fn error(&self, p: &[f64]) -> f64 {
        let u = self.local_velocity(p);
        let squared: f64 = (0..self.contacts())
            .map(|c| {
                let d = contact_natural_map(
                    self.mu[c],
                    [p[2 * c], p[2 * c + 1]],
                    [u[2 * c], u[2 * c + 1]],
                );
                d[0] * d[0] + d[1] * d[1]
            })
            .sum();
        relative_error(squared, self.q, p, &u)
    }

    /// Work of the friction impulses on the local tangential velocities, `Σ P_t U_t` (≤ 0 at
    /// a solution: friction never does positive work).
    pub fn friction_work(&self, p: &[f64]) -> f64 {
        let u = self.local_velocity(p);
        (0..self.contacts())
            .map(|c| p[2 * c + 1] * u[2 * c + 1])
            .sum()
    }
}

/// Siconos' relative measure of a natural map whose squared 2-norm over all contacts is
/// `squared`: `‖P − proj(P − Û)‖₂ / max(‖q‖₂, ‖P‖₂, ‖U‖₂)` (`fc3d_compute_error`, the same for
/// the planar and the 3D cone; not divided when the scale is ≤ the machine epsilon).
pub(crate) fn relative_error(squared: f64, q: &[f64], p: &[f64], u: &[f64]) -> f64 {
    let squares = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>();
    relative_error_of_squares(squared, squares(q), squares(p), squares(u))
}

/// [`relative_error`] from the squared norms of q, P and U.
pub(crate) fn relative_error_of_squares(squared: f64, q: f64, p: f64, u: f64) -> f64 {
    let scale = q.sqrt().max(p.sqrt()).max(u.sqrt());
    if scale > f64::EPSILON {
        squared.sqrt() / scale
    } else {
        squared.sqrt()
    }
}

/// `P − proj_{K_μ}(P − Û)` for one contact.
fn contact_natural_map(mu: f64, p: [f64; 2], u: [f64; 2]) -> [f64; 2] {
    let x = [p[0] - (u[0] + mu * u[1].abs()), p[1] - u[1]];
    let y = project_cone(mu, x);
    [p[0] - y[0], p[1] - y[1]]
}

/// `‖P − proj_{K_μ}(P − Û)‖_∞` for one contact (unscaled).
pub(crate) fn contact_residual(mu: f64, p: [f64; 2], u: [f64; 2]) -> f64 {
    let d = contact_natural_map(mu, p, u);
    d[0].abs().max(d[1].abs())
}

/// Euclidean projection on the planar cone `K_μ = {(n, t) : |t| ≤ μ n}` (μ = 0: the half-line
/// t = 0, n ≥ 0).
pub(crate) fn project_cone(mu: f64, [n, t]: [f64; 2]) -> [f64; 2] {
    if t.abs() <= mu * n {
        [n, t]
    } else if mu * t.abs() <= -n {
        // In the polar cone −K_{1/μ}.
        [0.0, 0.0]
    } else {
        // On the boundary ray (1, μ sign t).
        let r = (n + mu * t.abs()) / (1.0 + mu * mu);
        [r, mu * r * t.signum()]
    }
}

/// A solution with its diagnostics.
#[derive(Debug, Clone, PartialEq)]
pub struct FrictionSolution {
    /// Impulses `(P_n, P_t)` per contact, in the order of q.
    pub p: Vec<f64>,
    /// Pivots (Lemke on the reformulation) or sweeps (nonsmooth Gauss–Seidel).
    pub iterations: usize,
    /// Natural-map error (module documentation).
    pub error: f64,
}

/// Why a friction solve failed.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum FrictionError {
    /// The sizes of W, q and μ do not describe one problem.
    #[error("{contacts} contacts need q of length {} and W of length {}, got {q_len} and {w_len}", 2 * contacts, 4 * contacts * contacts)]
    Dimensions {
        /// Contacts (length of μ).
        contacts: usize,
        /// Length of q.
        q_len: usize,
        /// Length of W.
        w_len: usize,
    },
    /// A friction coefficient is negative or not finite.
    #[error("friction coefficient of contact {contact} is {mu}: it must be finite and ≥ 0")]
    InvalidFriction {
        /// Contact.
        contact: usize,
        /// The coefficient given.
        mu: f64,
    },
    /// The 2×2 diagonal block of W of a contact is not positive definite (the nonsmooth
    /// Gauss–Seidel needs it).
    #[error("the 2×2 block of W for contact {contact} is not positive definite")]
    LocalBlockNotDefinite {
        /// Contact.
        contact: usize,
    },
    /// The iteration budget ran out, or an exact method ended above tolerance.
    #[error(
        "{solver} did not reach tolerance {tolerance:e} in {iterations} iterations (error {error:e})"
    )]
    NotConverged {
        /// Solver name.
        solver: &'static str,
        /// Iterations done.
        iterations: usize,
        /// Natural-map error reached.
        error: f64,
        /// Tolerance asked.
        tolerance: f64,
    },
    /// The LCP solver failed (on the reformulation, or on the frictionless problem when μ = 0).
    #[error("LCP solver: {0}")]
    Lcp(#[from] LcpError),
    /// The solver kind has no friction counterpart.
    #[error("solver {kind:?} does not solve friction problems (use lemke, pgs or auto)")]
    UnsupportedSolver {
        /// The kind asked.
        kind: LcpSolverKind,
    },
}

/// Solves the friction problem with the solver chosen by `options.kind`:
///
/// - `Lemke`: the LCP reformulation ([`solve_friction_lemke`]);
/// - `Pgs`: the nonsmooth Gauss–Seidel ([`solve_friction_nsgs`]);
/// - `Auto`: Gauss–Seidel, falling back to Lemke when it does not converge (it can cycle at
///   large μ) or meets a singular 2×2 block. Measured on the step problems of the examples
///   (docs/friction.md): NSGS never failed and ran 3–16× faster than Lemke, which missed the
///   tolerance on the rocking block with both corners down (a singular W);
/// - `Enumeration`: refused ([`FrictionError::UnsupportedSolver`]); enumeration of the 4m-sized
///   reformulation would be 2^{4m} index sets and is not offered.
///
/// Trivial cases: when every `q_n ≥ 0`, P = 0 is a solution (no contact is approached) and is
/// returned with 0 iterations. When every μ is 0 the problem is the frictionless LCP on the
/// normal rows `(W_nn, q_n)`, solved by [`lcp::solve`] with the same options (so the impulses are
/// exactly those of the frictionless solver, and `P_t = 0`).
pub fn solve_friction(
    problem: FrictionProblem<'_>,
    options: &LcpOptions,
) -> Result<FrictionSolution, FrictionError> {
    problem.validate()?;
    if matches!(
        options.kind,
        LcpSolverKind::Enumeration | LcpSolverKind::BandedActiveSet
    ) {
        return Err(FrictionError::UnsupportedSolver { kind: options.kind });
    }
    if let Some(s) = separation(problem) {
        return Ok(s);
    }
    if problem.mu.iter().all(|&mu| mu == 0.0) {
        return solve_frictionless(problem, options);
    }
    match options.kind {
        LcpSolverKind::Lemke => solve_friction_lemke(problem, options),
        LcpSolverKind::Pgs => solve_friction_nsgs(problem, options),
        // NSGS first (3–16× faster on the step problems measured, and it solves the singular
        // W on which Lemke's tableau misses the tolerance); Lemke when NSGS cannot: it can
        // cycle at large μ (Coulomb friction is not monotone), and Lemke always ends on a
        // PSD W. If both fail, Lemke's error is reported.
        _ => solve_friction_nsgs(problem, options).or_else(|nsgs| match nsgs {
            FrictionError::NotConverged { .. } | FrictionError::LocalBlockNotDefinite { .. } => {
                solve_friction_lemke(problem, options)
            }
            other => Err(other),
        }),
    }
}

/// When every `q_n ≥ 0`, P = 0 (with 0 iterations): no contact is approached, and P = 0 with
/// U = q satisfies every contact's conditions whatever q_t.
pub(crate) fn separation(problem: FrictionProblem<'_>) -> Option<FrictionSolution> {
    let m = problem.contacts();
    (0..m)
        .all(|c| problem.q[2 * c] >= 0.0)
        .then(|| FrictionSolution {
            p: vec![0.0; 2 * m],
            iterations: 0,
            error: 0.0,
        })
}

/// μ = 0 everywhere: the LCP `0 ≤ W_nn P_n + q_n ⊥ P_n ≥ 0`, with `P_t = 0`.
fn solve_frictionless(
    problem: FrictionProblem<'_>,
    options: &LcpOptions,
) -> Result<FrictionSolution, FrictionError> {
    let m = problem.contacts();
    let n = 2 * m;
    let mut wnn = Vec::with_capacity(m * m);
    for a in 0..m {
        for b in 0..m {
            wnn.push(problem.w[2 * a * n + 2 * b]);
        }
    }
    let qn: Vec<f64> = (0..m).map(|a| problem.q[2 * a]).collect();
    let s = lcp::solve(Lcp { m: &wnn, q: &qn }, options)?;
    let mut p = vec![0.0; n];
    for (a, z) in s.z.iter().enumerate() {
        p[2 * a] = *z;
    }
    let error = problem.error(&p);
    Ok(FrictionSolution {
        p,
        iterations: s.iterations,
        error,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// proj_{K_μ} is the Euclidean projection: the image is in K_μ, the projection is
        /// idempotent, and x − proj(x) is orthogonal to proj(x) and in the polar cone
        /// (Moreau's decomposition).
        #[test]
        fn cone_projection_is_moreau_decomposition(
            mu in 0.0f64..3.0,
            n in -5.0f64..5.0,
            t in -5.0f64..5.0,
        ) {
            let y = project_cone(mu, [n, t]);
            prop_assert!(y[1].abs() <= mu * y[0] + 1e-12 && y[0] >= 0.0);
            let yy = project_cone(mu, y);
            prop_assert!((yy[0] - y[0]).abs() <= 1e-12 && (yy[1] - y[1]).abs() <= 1e-12);
            let d = [n - y[0], t - y[1]];
            prop_assert!((d[0] * y[0] + d[1] * y[1]).abs() <= 1e-10);
            // Polar of K_μ: μ|d_t| ≤ −d_n.
            prop_assert!(mu * d[1].abs() <= -d[0] + 1e-10);
        }
    }

    #[test]
    fn contact_residual_vanishes_exactly_on_the_law() {
        // Sliding: P on the edge, U_n = 0, U_t > 0 opposite to P_t.
        assert_eq!(contact_residual(0.5, [2.0, -1.0], [0.0, 3.0]), 0.0);
        // Sticking inside the cone, U = 0.
        assert_eq!(contact_residual(0.5, [2.0, 0.3], [0.0, 0.0]), 0.0);
        // Separation: P = 0, U_n > 0, any U_t.
        assert_eq!(contact_residual(0.5, [0.0, 0.0], [1.0, -4.0]), 0.0);
        // Friction pushing along the sliding velocity is not a solution.
        assert!(contact_residual(0.5, [2.0, 1.0], [0.0, 3.0]) > 0.1);
        // Penetrating velocity with an impulse is not a solution.
        assert!(contact_residual(0.5, [2.0, 0.0], [-1.0, 0.0]) > 0.1);
    }
}
