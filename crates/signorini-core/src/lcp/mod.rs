//! Linear complementarity problems `0 ≤ w = M z + q ⊥ z ≥ 0` and their solvers.
//!
//! As in Siconos' numerics layer, an LCP here is just `(M, q)`: the solvers know nothing about
//! models or contacts. Every solve reports its iterations and its complementarity error
//!
//! ```text
//! error = ‖min(z, M z + q)‖_∞ / max(1, ‖q‖_∞)
//! ```
//!
//! (the natural residual, zero exactly at a solution), and a solve that cannot reach the
//! tolerance is an [`LcpError`], never a silent approximation.

pub mod active_set;
mod enumeration;
mod lemke;
pub mod mixed;
mod pgs;

pub use enumeration::{ENUMERATION_MAX, solve_enumeration};
pub use lemke::{DEFAULT_TABLEAU_LIMIT, solve_lemke, solve_lemke_within, tableau_bytes};
pub use mixed::{EqualityElimination, MixedLcp, MixedLcpError, MixedSolution, solve_mixed};
pub use pgs::solve_pgs;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// A dense LCP `0 ≤ M z + q ⊥ z ≥ 0` of size n; `m` is row-major n×n.
#[derive(Debug, Clone, Copy)]
pub struct Lcp<'a> {
    /// Row-major n×n matrix.
    pub m: &'a [f64],
    /// Vector of size n.
    pub q: &'a [f64],
}

impl Lcp<'_> {
    /// Size n.
    pub fn size(&self) -> usize {
        self.q.len()
    }

    /// w = M z + q.
    pub fn w(&self, z: &[f64]) -> Vec<f64> {
        let n = self.size();
        (0..n)
            .map(|i| self.q[i] + (0..n).map(|j| self.m[i * n + j] * z[j]).sum::<f64>())
            .collect()
    }

    /// The natural-residual error of `z` (see the module documentation).
    pub fn error(&self, z: &[f64]) -> f64 {
        let n = self.size();
        let scale = self.q.iter().fold(1.0f64, |s, a| s.max(a.abs()));
        // w_i = (M z + q)_i as `w` sums it, one row at a time: no vector allocated per call
        // (the nonlinear schemes measure an LCP's error at every Newton iterate).
        (0..n).fold(0.0f64, |e, i| {
            let wi = self.q[i] + (0..n).map(|j| self.m[i * n + j] * z[j]).sum::<f64>();
            e.max(z[i].min(wi).abs())
        }) / scale
    }
}

/// A solution with its diagnostics.
#[derive(Debug, Clone, PartialEq)]
pub struct LcpSolution {
    /// z ≥ 0.
    pub z: Vec<f64>,
    /// Pivots (Lemke), sweeps (PGS) or index sets tried (enumeration).
    pub iterations: usize,
    /// Complementarity error (module documentation).
    pub error: f64,
}

/// Why an LCP solve failed.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum LcpError {
    /// Lemke's method ended on a secondary ray: the LCP has no solution the method can reach.
    #[error("Lemke's method ended on a ray after {pivots} pivots (no solution reachable)")]
    RayTermination {
        /// Pivots done.
        pivots: usize,
    },
    /// The iteration budget ran out before the tolerance was met.
    #[error(
        "{solver} did not reach tolerance {tolerance:e} in {iterations} iterations (error {error:e})"
    )]
    NotConverged {
        /// Solver name.
        solver: &'static str,
        /// Iterations done.
        iterations: usize,
        /// Error reached.
        error: f64,
        /// Tolerance asked.
        tolerance: f64,
    },
    /// Enumeration found no index set giving a solution.
    #[error("enumeration found no solution among {sets} index sets")]
    NoSolution {
        /// Index sets tried.
        sets: usize,
    },
    /// A diagonal entry of M is not positive (PGS needs M_ii > 0).
    #[error("M[{index}][{index}] = {value:e} is not positive")]
    NonPositiveDiagonal {
        /// Row.
        index: usize,
        /// Diagonal entry.
        value: f64,
    },
    /// The banded active-set method met an exchanged system with no pivot in column `dof`:
    /// the Delassus operator is singular on that active set (not a P-matrix).
    #[error("the banded system of the active set is singular (column {dof})")]
    SingularActiveSet {
        /// Column of the banded system (a dof).
        dof: usize,
    },
    /// The solver asked for solves another kind of problem.
    #[error("{solver} solves {solves}, not this problem")]
    WrongSolver {
        /// Solver name.
        solver: &'static str,
        /// What it solves.
        solves: &'static str,
    },
    /// A dense or tableau method would need more memory than its limit: refused before
    /// anything is allocated.
    #[error("{solver} on {size} unknowns needs {bytes} bytes, more than its limit of {limit}")]
    TooLargeForMemory {
        /// Solver name.
        solver: &'static str,
        /// Unknowns of the problem it would solve.
        size: usize,
        /// Bytes it would allocate.
        bytes: usize,
        /// Largest allocation allowed.
        limit: usize,
    },
    /// The problem is too large for enumeration.
    #[error("enumeration is limited to {max} unknowns, got {size}")]
    TooLarge {
        /// Size of the problem.
        size: usize,
        /// Largest size allowed.
        max: usize,
    },
}

/// Which solver to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum LcpSolverKind {
    /// Enumeration up to 3 unknowns, Lemke up to 200, projected Gauss–Seidel above.
    #[default]
    Auto,
    /// Lemke's complementary pivoting (exact up to round-off; any P-matrix or copositive-plus M).
    Lemke,
    /// Projected Gauss–Seidel (symmetric positive semidefinite M, large sets).
    Pgs,
    /// Enumeration of index sets (tiny problems, reference).
    #[serde(rename = "enum")]
    Enumeration,
    /// Block principal pivoting (primal–dual active set) on the banded iteration matrix, never
    /// forming the Delassus operator: memory and time per iteration linear in the dofs
    /// ([`active_set`]). For linear models whose every contact is one dof, no two on the same
    /// dof, without friction (the α-family also needs a lumped mass); `auto` picks it for such
    /// models above 200 contacts.
    BandedActiveSet,
}

/// Solver settings. Defaults: `Auto`, tolerance 1e-12, 100 000 iterations.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LcpOptions {
    /// Which solver.
    pub kind: LcpSolverKind,
    /// Largest complementarity error accepted.
    pub tolerance: f64,
    /// Budget of pivots or sweeps.
    pub max_iterations: usize,
}

impl Default for LcpOptions {
    fn default() -> Self {
        Self {
            kind: LcpSolverKind::Auto,
            tolerance: 1e-12,
            max_iterations: 100_000,
        }
    }
}

/// Largest size `Auto` hands to enumeration.
pub const AUTO_ENUMERATION_MAX: usize = 3;
/// Largest size `Auto` hands to Lemke.
pub const AUTO_LEMKE_MAX: usize = 200;

/// Solves the LCP with the solver chosen by `options` (trivially z = 0 when q ≥ 0).
pub fn solve(lcp: Lcp<'_>, options: &LcpOptions) -> Result<LcpSolution, LcpError> {
    let n = lcp.size();
    if lcp.q.iter().all(|&qi| qi >= 0.0) {
        return Ok(LcpSolution {
            z: vec![0.0; n],
            iterations: 0,
            error: 0.0,
        });
    }
    let kind = match options.kind {
        LcpSolverKind::Auto if n <= AUTO_ENUMERATION_MAX => LcpSolverKind::Enumeration,
        LcpSolverKind::Auto if n <= AUTO_LEMKE_MAX => LcpSolverKind::Lemke,
        LcpSolverKind::Auto => LcpSolverKind::Pgs,
        k => k,
    };
    match kind {
        LcpSolverKind::BandedActiveSet => Err(LcpError::WrongSolver {
            solver: "banded_active_set",
            solves: "the banded contact problem of a step (active_set), not a dense LCP",
        }),
        LcpSolverKind::Enumeration => solve_enumeration(lcp, options),
        LcpSolverKind::Lemke => solve_lemke(lcp, options),
        LcpSolverKind::Pgs | LcpSolverKind::Auto => solve_pgs(lcp, options),
    }
}

#[cfg(test)]
mod tests;
