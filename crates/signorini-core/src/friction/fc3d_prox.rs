//! The proximal point method for the FC3D problem, with the semismooth Newton method of
//! [`super::fc3d_newton`] as its inner solver (V. Acary, M. Brémond, O. Huber, *On solving
//! contact problems with Coulomb friction: formulations and numerical comparisons*, 2018,
//! doi:10.1007/978-3-319-75972-2_10: the best of their solvers at tight tolerance on rigid sets;
//! Siconos' `fc3d_proximal`, strategy PROX, whose parameters are taken here).
//!
//! Each outer iteration k solves, from `r_k`, the regularised problem
//!
//! ```text
//! u = (W + α_k I) r + (q − α_k r_k),   K_μ ∋ r ⊥ û ∈ K_μ*
//! ```
//!
//! (the proximal step of the problem's variational inequality) to the inner tolerance
//! `max(e_k / 10, tolerance / m)`, e_k the error of `r_k` on the original problem, and takes its
//! answer as `r_{k+1}`. W + α I is better conditioned than W, which is rank-deficient on rigid sets
//! with more contacts than degrees of freedom, so Newton converges on it where it stalls on W. The
//! weight follows the error: `α_{k+1} = σ e_{k+1}^ν` (σ = 5, ν = 1) after an inner success, and
//! `α_{k+1} = 10 α_k` after an inner failure (a stronger regularisation, an easier problem, a
//! shorter step). A fixed point `r_{k+1} = r_k` solves the original problem.

use super::fc3d::{Fc3dError, Fc3dOptions, Fc3dProblem, Fc3dSolution, Fc3dSolverKind, check_solve};
use super::fc3d_newton::{LinearCache, Work, newton_within};

/// σ of the weight `α = σ e^ν` (Siconos' default).
const SIGMA: f64 = 5.0;
/// ν of the weight `α = σ e^ν` (Siconos' default).
const NU: f64 = 1.0;
/// Ratio of the outer error to the inner tolerance (Siconos' `INTERNAL_ERROR_RATIO`).
const INNER_RATIO: f64 = 10.0;
/// Factor of α after an inner failure.
const FAILURE_GROWTH: f64 = 10.0;

/// Solves the problem by the proximal point method (module documentation) from `start`.
/// `iterations` counts the inner Newton iterations, summed (the cost: each is one linear solve);
/// the outer iterations are at most [`Fc3dOptions::prox_outer_iterations`], and the inner Newton
/// gets [`Fc3dOptions::prox_inner_iterations`] each. On failure the error holds the iterate of
/// smallest error.
pub fn solve_fc3d_prox(
    problem: &Fc3dProblem,
    options: &Fc3dOptions,
    start: &[f64],
) -> Result<Fc3dSolution, Fc3dError> {
    check_solve(problem, options, start)?;
    prox(problem, options, start)
}

/// [`solve_fc3d_prox`] on checked inputs ([`check_solve`]).
pub(crate) fn prox(
    problem: &Fc3dProblem,
    options: &Fc3dOptions,
    start: &[f64],
) -> Result<Fc3dSolution, Fc3dError> {
    prox_within(problem, options, start, &mut Work::unbounded())
}

/// [`prox`] counting its passes over W in `work` (the inner Newton solves' and one per error
/// evaluation) and stopping, not converged, once the budget is spent.
pub(crate) fn prox_within(
    problem: &Fc3dProblem,
    options: &Fc3dOptions,
    start: &[f64],
    work: &mut Work,
) -> Result<Fc3dSolution, Fc3dError> {
    let m = problem.contacts();
    let mut r = start.to_vec();
    let pass = problem.w.stored_blocks().max(1);
    let mut error = problem.error(&r);
    work.spent += pass;
    let mut best = (error, r.clone());
    let mut spent = 0;
    let mut alpha = SIGMA * error.powf(NU);
    let inner = Fc3dOptions {
        kind: Fc3dSolverKind::NewtonAlartCurnier,
        max_iterations: options.prox_inner_iterations,
        ..*options
    };
    let mut linear = LinearCache::default();
    for _ in 0..options.prox_outer_iterations {
        if error <= options.tolerance {
            break;
        }
        if spent >= options.max_iterations
            || work.spent >= work.budget
            || !(alpha.is_finite() && alpha > 0.0)
        {
            break;
        }
        let regularised = Fc3dProblem {
            w: problem.w.with_diagonal_shift(alpha)?,
            q: problem
                .q
                .iter()
                .zip(&r)
                .map(|(q, r)| q - alpha * r)
                .collect(),
            mu: problem.mu.clone(),
        };
        let inner = Fc3dOptions {
            tolerance: (error / INNER_RATIO).max(options.tolerance / m as f64),
            max_iterations: inner.max_iterations.min(options.max_iterations - spent),
            ..inner
        };
        let failed = match newton_within(&regularised, &inner, &r, work, &mut linear, false) {
            Ok(s) => {
                spent += s.iterations;
                r = s.r;
                false
            }
            Err(Fc3dError::NotConverged {
                iterations,
                best: inner_best,
                ..
            }) => {
                spent += iterations;
                r = inner_best;
                true
            }
            Err(other) => return Err(other),
        };
        error = problem.error(&r);
        work.spent += pass;
        if error < best.0 {
            best = (error, r.clone());
        }
        alpha = if failed {
            FAILURE_GROWTH * alpha
        } else {
            SIGMA * error.powf(NU)
        };
    }
    if best.0 <= options.tolerance {
        let r = best.1;
        return Ok(Fc3dSolution {
            u: problem.local_velocity(&r),
            r,
            iterations: spent,
            error: best.0,
            solver: "prox",
        });
    }
    Err(Fc3dError::NotConverged {
        solver: "prox",
        iterations: spent,
        error: best.0,
        tolerance: options.tolerance,
        best: best.1,
    })
}
