//! The FC3D solver chosen by [`Fc3dOptions::kind`], and `auto`'s chain of solvers.

use super::fc3d::{
    Fc3dError, Fc3dOptions, Fc3dProblem, Fc3dSolution, Fc3dSolverKind, check_problem, check_solve,
};
use super::fc3d_anderson::nsgs_anderson;
use super::fc3d_newton::{Work, newton};
use super::fc3d_nsgs::nsgs;
use super::fc3d_prox::{prox, prox_within};

/// Solves the problem with the solver of `options.kind`, from r = 0
/// ([`solve_fc3d_from`] with a zero start). `Auto` runs Gauss–Seidel with Anderson acceleration
/// ([`super::solve_fc3d_nsgs_anderson`], which falls back to plain sweeps where the acceleration
/// stalls) for `auto_sweeps` sweeps (Gauss–Seidel: Acary, Brémond & Huber 2018, the fastest on
/// rigid sets at loose tolerance; the acceleration cut the sweeps of the 1 000-sphere benchmark's
/// first 400 steps 4.1× and its time 1.6×, docs/rigid_benchmark.md Round 7), then the proximal
/// point method with its inner Newton solves (independent of the contact ordering, and the best
/// of their solvers at 1e-8 on rigid sets whose W is rank-deficient) twice: from the best
/// iterate so far with `auto_prox_work / 3` products by W's 3×3 blocks, then from `start` (the
/// caller's: r = 0 or the warm start) with `auto_prox_work`, each for at most
/// `auto_newton_iterations` Newton iterations; then Gauss–Seidel again from the best iterate of
/// all with the whole `max_iterations` budget, over-relaxed by `relaxation`, and when that
/// fails with ω ≠ 1, once more without over-relaxation (so that `auto` still converges wherever
/// plain Gauss–Seidel does within the budget).
///
/// The first stage that reaches the tolerance answers, and its name is in the solution. A stage
/// that fails for any reason only hands over to the next one; when none answers, the error holds
/// the iterate of smallest error over all stages and the iterations of all of them.
///
/// Why two starts (docs/friction_benchmark.md, Round 9, with GMRES as Newton's linear solve):
/// from Gauss–Seidel's best iterate (small error, hence a small first weight α = σ e, a weak
/// regularisation) the method is fast where that iterate is close (Capsules-i100-889: 1.7·10⁷
/// block products, where from r = 0 it needs 1.4·10⁸) and fails where it is not
/// (Capsules-i122-1617: not solved in 200 Newton iterations, solved from r = 0 in 104, 5.5·10⁷
/// block products). The budgets bound what the proximal stage costs where it does not converge:
/// on the 7 002-contact granular problem it reached 1e-4 only after 60 s (1.7·10⁹ block
/// products), where Gauss–Seidel needs 605 sweeps (1 s).
pub fn solve_fc3d(problem: &Fc3dProblem, options: &Fc3dOptions) -> Result<Fc3dSolution, Fc3dError> {
    check_problem(problem, options)?;
    solve_checked(problem, options, vec![0.0; problem.q.len()])
}

/// [`solve_fc3d`] from the impulses `start` (3m, `(r_n, r_t1, r_t2)` per contact) instead of
/// r = 0: a warm start, as Siconos' time stepping starts each step's solver from the last step's
/// impulses of the same interactions (`LinearOSNS::preCompute` with `keepLambdaAndYState`). The problem
/// and the tolerance are those of a cold start, so a warm-started solution meets the same error
/// bound; only the path (hence the iterations, and the last digits) changes. A start of the
/// wrong length or with an entry that is not a number is refused.
pub fn solve_fc3d_from(
    problem: &Fc3dProblem,
    options: &Fc3dOptions,
    start: &[f64],
) -> Result<Fc3dSolution, Fc3dError> {
    check_solve(problem, options, start)?;
    solve_checked(problem, options, start.to_vec())
}

/// The solver of `options.kind` on checked inputs ([`check_solve`]), from `start`.
fn solve_checked(
    problem: &Fc3dProblem,
    options: &Fc3dOptions,
    start: Vec<f64>,
) -> Result<Fc3dSolution, Fc3dError> {
    match options.kind {
        Fc3dSolverKind::Nsgs => nsgs(problem, options, start),
        Fc3dSolverKind::NsgsAnderson => nsgs_anderson(problem, options, &start),
        Fc3dSolverKind::NewtonAlartCurnier => newton(problem, options, &start),
        Fc3dSolverKind::Prox => prox(problem, options, &start),
        Fc3dSolverKind::Auto => solve_auto(problem, options, start),
    }
}

/// What `auto`'s stages have left: the iterate of smallest error, its error, the iterations
/// spent and the last solver tried.
struct Chain {
    best: Vec<f64>,
    error: f64,
    spent: usize,
    solver: &'static str,
}

impl Chain {
    /// Takes one stage's outcome: a solution ends the chain (its iterations counted after the
    /// earlier stages'); a failure of any kind is absorbed, its best iterate kept when it is the
    /// best so far.
    fn stage(
        &mut self,
        solver: &'static str,
        budget: usize,
        outcome: Result<Fc3dSolution, Fc3dError>,
    ) -> Option<Fc3dSolution> {
        self.solver = solver;
        match outcome {
            Ok(mut s) => {
                s.iterations += self.spent;
                Some(s)
            }
            Err(Fc3dError::NotConverged {
                iterations,
                error,
                best,
                ..
            }) => {
                self.spent += iterations;
                if error < self.error {
                    self.error = error;
                    self.best = best;
                }
                None
            }
            Err(_) => {
                self.spent += budget;
                None
            }
        }
    }
}

/// `auto` (see [`solve_fc3d`]).
fn solve_auto(
    problem: &Fc3dProblem,
    options: &Fc3dOptions,
    start: Vec<f64>,
) -> Result<Fc3dSolution, Fc3dError> {
    // The start competes for the best iterate from the first failure on: a problem the first
    // stage solves never pays for the start's error.
    let mut chain = Chain {
        error: f64::INFINITY,
        best: start.clone(),
        spent: 0,
        solver: "nsgs_aa",
    };
    let sweeps = options.auto_sweeps.min(options.max_iterations);
    let short = Fc3dOptions {
        max_iterations: sweeps,
        ..*options
    };
    if let Some(s) = chain.stage("nsgs_aa", sweeps, nsgs_anderson(problem, &short, &start)) {
        return Ok(s);
    }
    let start_error = problem.error(&start);
    if start_error < chain.error {
        chain.error = start_error;
        chain.best = start.clone();
    }
    let newton_budget = options.auto_newton_iterations.min(options.max_iterations);
    let prox = Fc3dOptions {
        max_iterations: newton_budget,
        ..*options
    };
    let mut short_work = Work {
        spent: 0,
        budget: options.auto_prox_work / 3,
    };
    let from_best = chain.best.clone();
    if let Some(s) = chain.stage(
        "prox",
        newton_budget,
        prox_within(problem, &prox, &from_best, &mut short_work),
    ) {
        return Ok(s);
    }
    let mut work = Work {
        spent: 0,
        budget: options.auto_prox_work,
    };
    if let Some(s) = chain.stage(
        "prox",
        newton_budget,
        prox_within(problem, &prox, &start, &mut work),
    ) {
        return Ok(s);
    }
    let outcome = nsgs(problem, options, chain.best.clone());
    if let Some(s) = chain.stage("nsgs", options.max_iterations, outcome) {
        return Ok(s);
    }
    if options.relaxation != 1.0 {
        let plain = Fc3dOptions {
            relaxation: 1.0,
            ..*options
        };
        let outcome = nsgs(problem, &plain, chain.best.clone());
        if let Some(s) = chain.stage("nsgs", options.max_iterations, outcome) {
            return Ok(s);
        }
    }
    Err(Fc3dError::NotConverged {
        solver: chain.solver,
        iterations: chain.spent,
        error: chain.error,
        tolerance: options.tolerance,
        best: chain.best,
    })
}
