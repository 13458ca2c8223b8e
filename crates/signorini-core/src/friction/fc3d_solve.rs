//! The FC3D solver chosen by [`Fc3dOptions::kind`], and `auto`'s chain of solvers.

use super::fc3d::{Fc3dError, Fc3dOptions, Fc3dProblem, Fc3dSolution, Fc3dSolverKind};
use super::fc3d_newton::solve_fc3d_newton;
use super::fc3d_nsgs::solve_fc3d_nsgs;

/// Solves the problem with the solver of `options.kind`, from r = 0. `Auto` runs Gauss–Seidel
/// for `auto_sweeps` sweeps (Acary, Brémond & Huber 2018: the fastest on rigid sets at loose
/// tolerance), then Newton from its last iterate (quadratic near a solution, independent of the
/// contact ordering), then Gauss–Seidel again from Newton's best iterate with the whole budget;
/// the first that reaches the tolerance answers, and its name is in the solution.
pub fn solve_fc3d(problem: &Fc3dProblem, options: &Fc3dOptions) -> Result<Fc3dSolution, Fc3dError> {
    problem.validate()?;
    if options.tolerance.is_nan() || options.tolerance <= 0.0 {
        return Err(Fc3dError::InvalidTolerance {
            tolerance: options.tolerance,
        });
    }
    let start = vec![0.0; problem.q.len()];
    match options.kind {
        Fc3dSolverKind::Nsgs => solve_fc3d_nsgs(problem, options, &start),
        Fc3dSolverKind::NewtonAlartCurnier => solve_fc3d_newton(problem, options, &start),
        Fc3dSolverKind::Auto => {
            let short = Fc3dOptions {
                max_iterations: options.auto_sweeps.min(options.max_iterations),
                ..*options
            };
            let mut spent = 0;
            let retry = |e: Fc3dError, spent: &mut usize| match e {
                Fc3dError::NotConverged {
                    iterations, best, ..
                } => {
                    *spent += iterations;
                    Ok(best)
                }
                other => Err(other),
            };
            let from_nsgs = match solve_fc3d_nsgs(problem, &short, &start) {
                Ok(s) => return Ok(s),
                Err(e) => retry(e, &mut spent)?,
            };
            let from_newton = match solve_fc3d_newton(problem, options, &from_nsgs) {
                Ok(s) => return Ok(with_spent(s, spent)),
                Err(e) => retry(e, &mut spent)?,
            };
            solve_fc3d_nsgs(problem, options, &from_newton)
                .map(|s| with_spent(s, spent))
                .map_err(|e| match e {
                    Fc3dError::NotConverged {
                        solver,
                        iterations,
                        error,
                        tolerance,
                        best,
                    } => Fc3dError::NotConverged {
                        solver,
                        iterations: iterations + spent,
                        error,
                        tolerance,
                        best,
                    },
                    other => other,
                })
        }
    }
}

fn with_spent(mut s: Fc3dSolution, spent: usize) -> Fc3dSolution {
    s.iterations += spent;
    s
}
