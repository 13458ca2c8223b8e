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
//! lowered it. Deterministic; `iterations` counts sweeps.

use super::fc3d::{Fc3dError, Fc3dOptions, Fc3dProblem, Fc3dSolution, natural_map_error};
use super::fc3d_nsgs::{diagonal_blocks, sweep};
use nalgebra::{DMatrix, DVector};
use std::collections::VecDeque;

/// Depth d: sweeps combined (besides the last).
const DEPTH: usize = 5;
/// A sweep whose error exceeds this factor times the smallest error so far restarts from the best
/// sweep output.
const RESTART_GROWTH: f64 = 2.0;
/// So do this many sweeps in a row without a new smallest error.
const STALL: usize = 2 * DEPTH;
/// Singular values of ΔFᵀΔF below this fraction of the largest are dropped (those of ΔF below
/// 10⁻⁷ of its largest: below that the Gram matrix holds round-off only).
const GRAM_CUT: f64 = 1e-14;

/// Solves the problem by Gauss–Seidel sweeps with Anderson acceleration (module documentation)
/// from `start`. On failure the error holds the sweep output of smallest error.
pub fn solve_fc3d_nsgs_anderson(
    problem: &Fc3dProblem,
    options: &Fc3dOptions,
    start: &[f64],
) -> Result<Fc3dSolution, Fc3dError> {
    problem.validate()?;
    let diagonal = diagonal_blocks(problem);
    let mut r = start.to_vec();
    let mut best = (f64::INFINITY, r.clone());
    let mut last: Option<(Vec<f64>, Vec<f64>)> = None;
    let mut history: VecDeque<(Vec<f64>, Vec<f64>)> = VecDeque::with_capacity(DEPTH);
    let mut stalled = 0;
    for iteration in 1..=options.max_iterations {
        let mut g = r.clone();
        sweep(problem, &diagonal, &mut g);
        let u = problem.local_velocity(&g);
        let error = natural_map_error(&problem.mu, &problem.q, &g, &u);
        if error <= options.tolerance {
            return Ok(Fc3dSolution {
                r: g,
                u,
                iterations: iteration,
                error,
                solver: "nsgs_aa",
            });
        }
        if !error.is_finite() {
            break;
        }
        if error < best.0 {
            best = (error, g.clone());
            stalled = 0;
        } else {
            stalled += 1;
        }
        if error > RESTART_GROWTH * best.0 || stalled > STALL {
            history.clear();
            last = None;
            stalled = 0;
            r = best.1.clone();
            continue;
        }
        let f: Vec<f64> = g.iter().zip(&r).map(|(g, r)| g - r).collect();
        if let Some((f_last, g_last)) = last.take() {
            if history.len() == DEPTH {
                history.pop_front();
            }
            history.push_back((difference(&f, &f_last), difference(&g, &g_last)));
        }
        r = extrapolate(&history, &f, &g);
        last = Some((f, g));
    }
    Err(Fc3dError::NotConverged {
        solver: "nsgs_aa",
        iterations: options.max_iterations,
        error: best.0,
        tolerance: options.tolerance,
        best: best.1,
    })
}

fn difference(a: &[f64], b: &[f64]) -> Vec<f64> {
    a.iter().zip(b).map(|(a, b)| a - b).collect()
}

/// `g − ΔG γ` with `γ = argmin ‖f − ΔF γ‖₂` (module documentation), γ from the normal equations
/// `ΔFᵀΔF γ = ΔFᵀ f` (d × d) by the singular value decomposition, singular values below
/// [`GRAM_CUT`] of the largest dropped; `g` itself without history or when that solve fails.
fn extrapolate(history: &VecDeque<(Vec<f64>, Vec<f64>)>, f: &[f64], g: &[f64]) -> Vec<f64> {
    if history.is_empty() {
        return g.to_vec();
    }
    let d = history.len();
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let gram = DMatrix::from_fn(d, d, |i, j| dot(&history[i].0, &history[j].0));
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
