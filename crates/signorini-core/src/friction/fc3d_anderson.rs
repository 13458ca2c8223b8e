//! Nonsmooth Gauss–Seidel accelerated by Anderson's method for the FC3D problem.
//!
//! One Gauss–Seidel sweep over the contacts ([`super::fc3d_nsgs`]) is a map `r ↦ g(r)` whose
//! fixed points are the solutions; on a dense pile of rigid bodies it converges linearly with a
//! rate close to 1 (the load has to cross the pile contact after contact). Anderson's method
//! ([`crate::anderson`]) combines the last `d + 1` sweeps; for a linear map it is GMRES on
//! `r − g(r) = 0`, which is why it helps where the sweeps crawl. The error is measured on the
//! sweeps' outputs `g(r_k)`, which satisfy the cone contact by contact. The map is only semismooth (a contact
//! that changes between take-off, stick and slide changes it), so the history is dropped and the
//! next sweep starts from the sweep output of smallest error whenever a sweep's error exceeds
//! [`RESTART_GROWTH`] times the smallest error so far or [`STALL`] sweeps in a row have not
//! lowered it.
//!
//! **Fallback to plain sweeps.** Nothing guarantees that Anderson's method converges on such a
//! map (Walker & Ni 2011 relate it to GMRES for a linear map; no result covers a nonsmooth one),
//! and it can stagnate: on dense piles of spheres (docs/rigid_benchmark.md, Round 7) the
//! accelerated sweeps plateau at an error of 10⁻⁵–10⁻⁴ where plain Gauss–Seidel converges. A
//! restart from the same best output with an empty history is deterministic, so a restart that
//! found no new best replays the same sweeps until the budget is spent. A restart therefore
//! *makes progress* when the smallest error has fallen to at most [`PROGRESS`] times its value at
//! the previous restart; after [`FRUITLESS_RESTARTS`] restarts in a row without progress the
//! acceleration is dropped for good and plain sweeps run from `start` again for the rest of the
//! budget: they are then Gauss–Seidel's own iterates, so the solver converges wherever Gauss–Seidel
//! converges within the budget left, in the sweeps spent accelerated (≈ 100–200 on the measured
//! stalls) plus Gauss–Seidel's. Plain sweeps from the best output instead were measured to need up
//! to 3.2× Gauss–Seidel's sweeps from the start (its error is smaller, its slow components are
//! not), and blocks of plain sweeps alternating with the acceleration again were slower still
//! (Round 7). The smallest error is still tracked over both phases.
//!
//! **Stagnation.** With [`Fc3dOptions::stall`] the sweeps stop as plain Gauss–Seidel's
//! do ([`super::fc3d_nsgs`], *Stagnation*), the window counted over accelerated sweeps and
//! restarts alike, and started over when the plain sweeps start over from `start`.
//!
//! **Over-relaxed fallback.** The plain sweeps are over-relaxed by [`Fc3dOptions::relaxation`]
//! (ω; 1 by default, 1.5 in a rigid time step: module [`super::fc3d_nsgs`]); the accelerated
//! ones never are. On the piles of the 1 000-sphere benchmark (docs/rigid_benchmark.md, Round 11)
//! the fallback took 837–2 125 sweeps where it took 2 156–4 469 at ω = 1 (on the three dumped
//! steps where the acceleration stalls), while ω = 1.4 or 1.6 in the accelerated sweeps made them
//! stall on a problem they solved in 328 sweeps at ω = 1.
//! Deterministic; `iterations` counts sweeps, accelerated and plain.

use super::fc3d::{ErrorMeter, Fc3dError, Fc3dOptions, Fc3dProblem, Fc3dSolution, check_solve};
use super::fc3d_nsgs::{LOCAL_TOLERANCE, Stagnation, diagonal_blocks, local_tolerance, sweep};
use crate::anderson::Accelerator;

/// Depth d: sweeps combined (besides the last).
const DEPTH: usize = 5;
/// A sweep whose error exceeds this factor times the smallest error so far restarts from the best
/// sweep output.
const RESTART_GROWTH: f64 = 2.0;
/// So do this many sweeps in a row without a new smallest error.
const STALL: usize = 2 * DEPTH;
/// Restarts in a row without progress before the acceleration is dropped.
const FRUITLESS_RESTARTS: usize = 3;
/// A restart makes progress when the smallest error is at most this factor times the smallest
/// error at the previous restart.
const PROGRESS: f64 = 0.5;

/// Solves the problem by Gauss–Seidel sweeps with Anderson acceleration (module documentation)
/// from `start`, falling back to plain sweeps from `start` after [`FRUITLESS_RESTARTS`] restarts
/// in a row without progress (over-relaxed by [`Fc3dOptions::relaxation`]). `iterations` counts
/// sweeps, accelerated or plain. On failure the error
/// holds the sweep output of smallest error.
pub fn solve_fc3d_nsgs_anderson(
    problem: &Fc3dProblem,
    options: &Fc3dOptions,
    start: &[f64],
) -> Result<Fc3dSolution, Fc3dError> {
    check_solve(problem, options, start)?;
    nsgs_anderson(problem, options, start)
}

/// [`solve_fc3d_nsgs_anderson`] on checked inputs ([`check_solve`]).
pub(crate) fn nsgs_anderson(
    problem: &Fc3dProblem,
    options: &Fc3dOptions,
    start: &[f64],
) -> Result<Fc3dSolution, Fc3dError> {
    let diagonal = diagonal_blocks(problem);
    let mut meter = ErrorMeter::new(problem);
    let mut r = start.to_vec();
    // The sweep output of smallest error (none yet: the start, of infinite error).
    let mut best = (f64::INFINITY, None::<Vec<f64>>);
    let mut accelerator = Accelerator::new(DEPTH);
    let mut stalled = 0;
    // Restarts in a row without progress, and the smallest error at the last restart.
    let mut fruitless = 0;
    let mut best_at_restart = f64::INFINITY;
    let mut accelerated = true;
    let mut last_error = f64::INFINITY;
    let mut stagnation = Stagnation::new(options.stall);
    let mut iteration = 0;
    while iteration < options.max_iterations {
        iteration += 1;
        let mut g = r.clone();
        let omega = if accelerated { 1.0 } else { options.relaxation };
        // The accelerated sweeps solve their local problems tightly: Anderson's combination
        // needs the same map g from one sweep to the next.
        let local = if accelerated {
            LOCAL_TOLERANCE
        } else {
            local_tolerance(last_error)
        };
        sweep(problem, &diagonal, omega, local, &mut g);
        let error = meter.error(&g);
        last_error = error;
        if error <= options.tolerance {
            return Ok(Fc3dSolution {
                r: g,
                u: meter.into_velocity(),
                iterations: iteration,
                error,
                solver: "nsgs_aa",
            });
        }
        if !error.is_finite() {
            break;
        }
        if error < best.0 {
            best = (error, Some(g.clone()));
            stalled = 0;
        } else {
            stalled += 1;
        }
        if stagnation.stalled(error) {
            break;
        }
        if !accelerated {
            r = g;
            continue;
        }
        if error > RESTART_GROWTH * best.0 || stalled > STALL {
            if best.0 <= PROGRESS * best_at_restart {
                fruitless = 0;
            } else {
                fruitless += 1;
            }
            best_at_restart = best.0;
            accelerator.clear();
            stalled = 0;
            accelerated = fruitless < FRUITLESS_RESTARTS;
            if !accelerated {
                // Gauss–Seidel's own iterates from the start: their errors start over too.
                stagnation.restart();
            }
            r = match (&best.1, accelerated) {
                (Some(best), true) => best.clone(),
                _ => start.to_vec(),
            };
            continue;
        }
        r = accelerator.next(&r, g);
    }
    Err(Fc3dError::NotConverged {
        solver: "nsgs_aa",
        iterations: iteration,
        error: best.0,
        tolerance: options.tolerance,
        best: best.1.unwrap_or_else(|| start.to_vec()),
    })
}
