//! Nonsmooth Gauss–Seidel accelerated by Anderson's method for the FC3D problem.
//!
//! One Gauss–Seidel sweep over the contacts ([`super::fc3d_nsgs`]) is a map `r ↦ g(r)` whose
//! fixed points are the solutions; on a dense pile of rigid bodies it converges linearly with a
//! rate close to 1 (the load has to cross the pile contact after contact). Anderson's method
//! (D. G. Anderson, *Iterative procedures for nonlinear integral equations*, J. ACM
//! 12(4):547–560, 1965, doi:10.1145/321296.321305; in the form of H. F. Walker, P. Ni, *Anderson
//! acceleration for fixed-point iterations*, SIAM J. Numer. Anal. 49(4):1715–1735, 2011,
//! doi:10.1137/10078356X, Algorithm AA) combines the last `d + 1` sweeps: with the residual
//! `f_k = g(r_k) − r_k` and the differences of the last d residuals and sweeps,
//!
//! ```text
//! ΔF_k = [f_{k−d+1} − f_{k−d}, …, f_k − f_{k−1}],   ΔG_k = [g(r_{k−d+1}) − g(r_{k−d}), …]
//! γ_k = argmin_γ ‖f_k − ΔF_k γ‖₂
//! r_{k+1} = g(r_k) − ΔG_k γ_k
//! ```
//!
//! (for a linear map this is GMRES on `r − g(r) = 0`, which is why it helps where the sweeps crawl).
//! The least-squares problem is solved through its d × d normal equations (singular values of
//! ΔF_kᵀΔF_k below 10⁻¹⁴ of the largest dropped). The error is measured on the sweeps' outputs
//! `g(r_k)`, which satisfy the cone contact by contact. The map is only semismooth (a contact
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
use nalgebra::{DMatrix, DVector};
use std::collections::VecDeque;

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
/// Singular values of ΔFᵀΔF below this fraction of the largest are dropped (those of ΔF below
/// 10⁻⁷ of its largest: below that the Gram matrix holds round-off only).
const GRAM_CUT: f64 = 1e-14;

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
    let mut last: Option<(Vec<f64>, Vec<f64>)> = None;
    let mut history = History::default();
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
            history.clear();
            last = None;
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
        let f: Vec<f64> = g.iter().zip(&r).map(|(g, r)| g - r).collect();
        if let Some((f_last, g_last)) = last.take() {
            history.push(difference(&f, &f_last), difference(&g, &g_last));
        }
        r = history.extrapolate(&f, &g);
        last = Some((f, g));
    }
    Err(Fc3dError::NotConverged {
        solver: "nsgs_aa",
        iterations: iteration,
        error: best.0,
        tolerance: options.tolerance,
        best: best.1.unwrap_or_else(|| start.to_vec()),
    })
}

fn difference(a: &[f64], b: &[f64]) -> Vec<f64> {
    a.iter().zip(b).map(|(a, b)| a - b).collect()
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The last d differences `(Δf, Δg)` (oldest first) and the Gram matrix `ΔFᵀΔF` of the Δf,
/// kept up to date as they come and go: a new difference costs d dot products, not d².
#[derive(Default)]
struct History {
    differences: VecDeque<(Vec<f64>, Vec<f64>)>,
    /// `gram[i][j] = Δf_i · Δf_j` for the stored differences.
    gram: VecDeque<VecDeque<f64>>,
}

impl History {
    fn clear(&mut self) {
        self.differences.clear();
        self.gram.clear();
    }

    /// Appends a difference, dropping the oldest beyond [`DEPTH`].
    fn push(&mut self, df: Vec<f64>, dg: Vec<f64>) {
        if self.differences.len() == DEPTH {
            self.differences.pop_front();
            self.gram.pop_front();
            for row in &mut self.gram {
                row.pop_front();
            }
        }
        let column: Vec<f64> = self.differences.iter().map(|(f, _)| dot(f, &df)).collect();
        for (row, &x) in self.gram.iter_mut().zip(&column) {
            row.push_back(x);
        }
        let mut row: VecDeque<f64> = column.into();
        row.push_back(dot(&df, &df));
        self.gram.push_back(row);
        self.differences.push_back((df, dg));
    }

    /// `g − ΔG γ` with `γ = argmin ‖f − ΔF γ‖₂` (module documentation), γ from the normal
    /// equations `ΔFᵀΔF γ = ΔFᵀ f` (d × d) by the singular value decomposition, singular values
    /// below [`GRAM_CUT`] of the largest dropped; `g` itself without history or when that solve
    /// fails.
    fn extrapolate(&self, f: &[f64], g: &[f64]) -> Vec<f64> {
        let history = &self.differences;
        if history.is_empty() {
            return g.to_vec();
        }
        let d = history.len();
        let gram = DMatrix::from_fn(d, d, |i, j| self.gram[i][j]);
        let rhs = DVector::from_fn(d, |i, _| dot(&history[i].0, f));
        let svd = gram.svd(true, true);
        let cut = GRAM_CUT * svd.singular_values.max();
        let Ok(gamma) = svd.solve(&rhs, cut) else {
            return g.to_vec();
        };
        let mut next = g.to_vec();
        for (j, (_, dg)) in history.iter().enumerate() {
            for (x, d) in next.iter_mut().zip(dg) {
                *x -= gamma[j] * d;
            }
        }
        if next.iter().all(|x| x.is_finite()) {
            next
        } else {
            g.to_vec()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Gram matrix kept up to date as differences come and go past the depth is, bit for
    /// bit, the one computed afresh from the differences held.
    #[test]
    fn the_kept_gram_matrix_is_the_fresh_one() {
        let mut history = History::default();
        for k in 0..2 * DEPTH + 3 {
            let df: Vec<f64> = (0..7).map(|i| ((k * 7 + i) as f64 * 0.37).sin()).collect();
            let dg: Vec<f64> = df.iter().map(|x| 2.0 * x).collect();
            history.push(df, dg);
            let d = history.differences.len();
            assert_eq!(d, (k + 1).min(DEPTH));
            for i in 0..d {
                for j in 0..d {
                    let fresh = dot(&history.differences[i].0, &history.differences[j].0);
                    assert_eq!(
                        history.gram[i][j].to_bits(),
                        fresh.to_bits(),
                        "{k}: ({i}, {j})"
                    );
                }
            }
        }
        history.clear();
        assert!(history.differences.is_empty() && history.gram.is_empty());
    }
}
