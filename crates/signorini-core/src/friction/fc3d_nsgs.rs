//! Nonsmooth Gauss–Seidel over contacts for the FC3D problem (M. Jean, *The non-smooth contact
//! dynamics method*, Computer Methods in Applied Mechanics and Engineering 177:235–257, 1999,
//! doi:10.1016/S0045-7825(98)00383-1; Acary, Brémond & Huber 2018, doi:10.1007/978-3-319-75972-2_10,
//! §6.1).
//!
//! A sweep visits the contacts in order; at contact a, with the others frozen, the local problem
//! is the one-contact problem `u_a = W_aa r_a + b_a`, `b_a = q_a + Σ_{b≠a} W_ab r_b`, with only
//! the stored blocks of block row a of the sparse W in the sum. It is solved
//!
//! - exactly when it is a take-off (`b_n ≥ 0`: r_a = 0, then û_a = b_a + μ‖b_t‖e_n ∈ K_μ*) or a
//!   stick (`−W_aa⁻¹ b_a` inside K_μ), or when μ = 0 (`r_n = −b_n / W_nn`, r_t = 0);
//! - otherwise by the semismooth Newton method on the contact's Alart–Curnier function with a
//!   line search (the 3×3 case of [`super::fc3d_newton`]), and when that does not converge by
//!   De Saxcé's projection iterations `r ← P_K(r − ρ û)`, keeping whichever leaves the smaller
//!   local natural map.
//!
//! **Local tolerance.** The local Newton method stops at a residual relative to the size of r_a
//! and ρ b_a that follows the sweeps: [`local_tolerance`], 10⁻² of the last sweep's global error
//! between 10⁻¹⁴ and 10⁻⁶. Far from the solution a local problem solved to 10⁻¹⁴ is undone by the
//! next sweep; near it the local solves are as tight as ever, and the sweeps stop on the same
//! global error. On Siconos' Rover problems it cut the local Newton iterations from 3.4 to 2.5 a
//! local solve. Anderson's accelerated sweeps ([`super::fc3d_anderson`]) keep the tight bound:
//! their combination of sweeps needs one map from sweep to sweep, and with the loose bound the
//! 1 000-sphere pour's first 384 steps took 128 FC3D iterations a step instead of 69
//! (docs/friction_benchmark.md, Round 16).
//!
//! **Over-relaxation.** With ω = [`Fc3dOptions::relaxation`] ≠ 1 the contact's new impulse is
//! `P_K(r_a + ω (r̃_a − r_a))`, r̃_a the local solution above and P_K the projection on its cone:
//! the projected successive over-relaxation of C. W. Cryer, *The solution of a quadratic
//! programming problem using systematic overrelaxation*, SIAM J. Control 9(3):385–392, 1971,
//! doi:10.1137/0309028, contact by contact. A fixed point with r̃_a = r_a is a solution, and the
//! solver stops on the same global error as without it. On the 1 000-sphere pile it cut the
//! sweeps 1.9–3.1× at ω = 1.5, and stalled at 1.7–1.85 on some steps (docs/rigid_benchmark.md,
//! Round 11). Nothing guarantees convergence for ω ≠ 1 (nor for ω = 1) with friction.
//!
//! Sweeps stop when the global error is ≤ the tolerance. Deterministic: fixed contact order.
//! Convergence is not guaranteed (Coulomb friction is not monotone); a spent budget is
//! [`Fc3dError::NotConverged`] with the best iterate.
//!
//! **Stagnation.** Where the sweeps do not converge they may cycle for the whole budget: on the
//! formed pile of the 1 000-sphere benchmark (docs/rigid_benchmark.md, Round 18) a step's sweeps
//! stay at an error of 1.399·10⁻⁵ from sweep 1 000 to sweep 50 000, the residual concentrated on
//! four contacts whose local problems are each solved to 10⁻¹⁶ in turn (and Siconos' NSGS,
//! shuffled or not, its ADMM, extragradient and Alart–Curnier Newton do not reach 10⁻⁶ on that
//! problem either). With [`Fc3dOptions::stall`] = (N, ε) the sweeps stop once N sweeps in a row
//! have not brought the smallest error below [`STAGNATION_GAIN`] times its value when they began
//! and that error is at most ε ([`Stagnation`]); the error is then [`Fc3dError::NotConverged`]
//! with the sweeps done. A linear rate that slow (≥ 0.9 over N sweeps) would need more than
//! 130 N sweeps to gain six orders of magnitude. The bound ε is there for the time step that
//! accepts errors up to it: a step of the pile stalled at 1.03·10⁻⁴ for 1 000 sweeps, with an
//! acceptance bound of 10⁻⁴, where the sweeps that went on reached it.

use super::block3::{self, Block};
use super::fc3d::{
    ErrorMeter, Fc3dError, Fc3dOptions, Fc3dProblem, Fc3dSolution, Fc3dStall, check_solve,
    contact_natural_map, project_cone,
};
use super::fc3d_newton::{alart_curnier, weight};
use std::cell::OnceCell;

/// Newton iterations of the local solver.
const LOCAL_NEWTON: usize = 30;
/// Projection iterations of the local fallback.
const LOCAL_PROJECTION: usize = 200;
/// Relative size of the local Alart–Curnier residual at which the local Newton stops, at its
/// tightest: the local solves of a sweep stop at [`local_tolerance`] of the last sweep's global
/// error, which reaches this bound as the sweeps converge.
pub(crate) const LOCAL_TOLERANCE: f64 = 1e-14;
/// The loosest local tolerance, for the first sweep (no global error known yet).
const LOCAL_TOLERANCE_FIRST: f64 = 1e-6;
/// The local tolerance as a fraction of the last sweep's global error.
const LOCAL_TOLERANCE_RATIO: f64 = 1e-2;
/// Relative size of the local residual below which the local Newton's answer is kept without
/// trying the projection fallback (far below any global tolerance asked in practice), unless
/// the local tolerance is looser.
const LOCAL_ACCEPTED: f64 = 1e-11;

/// The factor by which the smallest error must fall within [`Fc3dStall::sweeps`] sweeps for the
/// sweeps to go on (module documentation, *Stagnation*).
pub(crate) const STAGNATION_GAIN: f64 = 0.9;

/// The stagnation test of a sequence of sweeps (module documentation, *Stagnation*): the
/// smallest error when the current window began, the sweeps since, and the smallest error.
pub(crate) struct Stagnation {
    test: Option<Fc3dStall>,
    mark: f64,
    since: usize,
    smallest: f64,
}

impl Stagnation {
    /// The test `test` (`None`: never stalled).
    pub(crate) fn new(test: Option<Fc3dStall>) -> Self {
        Self {
            test,
            mark: f64::INFINITY,
            since: 0,
            smallest: f64::INFINITY,
        }
    }

    /// Takes a sweep's error; true when the sweeps have stalled: [`Fc3dStall::sweeps`] in a row
    /// without an error below [`STAGNATION_GAIN`] times the mark, the smallest error within
    /// [`Fc3dStall::below`]. An error below it becomes the mark.
    pub(crate) fn stalled(&mut self, error: f64) -> bool {
        let Some(test) = self.test else {
            return false;
        };
        self.smallest = self.smallest.min(error);
        if error < STAGNATION_GAIN * self.mark {
            self.mark = error;
            self.since = 0;
            false
        } else {
            self.since += 1;
            self.since >= test.sweeps && self.smallest <= test.below
        }
    }

    /// Forgets the mark: the sweeps start over from another iterate.
    pub(crate) fn restart(&mut self) {
        self.mark = f64::INFINITY;
        self.since = 0;
        self.smallest = f64::INFINITY;
    }
}

/// The tolerance of a sweep's local solves after a sweep of global error `error` (infinite
/// before the first): [`LOCAL_TOLERANCE_RATIO`] of it, between [`LOCAL_TOLERANCE`] and
/// [`LOCAL_TOLERANCE_FIRST`]. A local problem solved to 1e-14 when the sweeps are still far
/// from the solution costs Newton iterations that the next sweep undoes; near the solution the
/// local solves are as tight as ever (docs/friction_benchmark.md, Round 16).
pub(crate) fn local_tolerance(error: f64) -> f64 {
    (LOCAL_TOLERANCE_RATIO * error).clamp(LOCAL_TOLERANCE, LOCAL_TOLERANCE_FIRST)
}

/// Solves the problem by nonsmooth Gauss–Seidel (module documentation) from `start`.
/// `iterations` counts sweeps.
pub fn solve_fc3d_nsgs(
    problem: &Fc3dProblem,
    options: &Fc3dOptions,
    start: &[f64],
) -> Result<Fc3dSolution, Fc3dError> {
    check_solve(problem, options, start)?;
    nsgs(problem, options, start.to_vec())
}

/// [`solve_fc3d_nsgs`] on checked inputs ([`check_solve`]), from `r`.
pub(crate) fn nsgs(
    problem: &Fc3dProblem,
    options: &Fc3dOptions,
    mut r: Vec<f64>,
) -> Result<Fc3dSolution, Fc3dError> {
    let diagonal = diagonal_blocks(problem);
    let mut meter = ErrorMeter::new(problem);
    // The sweep output of smallest error, copied only when a sweep fails to converge.
    let mut best: Option<(f64, Vec<f64>)> = None;
    let mut error = f64::INFINITY;
    let mut stagnation = Stagnation::new(options.stall);
    let mut sweeps = 0;
    while sweeps < options.max_iterations {
        sweeps += 1;
        let local = local_tolerance(error);
        self::sweep(problem, &diagonal, options.relaxation, local, &mut r);
        error = meter.error(&r);
        if error <= options.tolerance {
            return Ok(Fc3dSolution {
                r,
                u: meter.into_velocity(),
                iterations: sweeps,
                error,
                solver: "nsgs",
            });
        }
        if !error.is_finite() {
            break;
        }
        if best.as_ref().is_none_or(|(smallest, _)| error < *smallest) {
            best = Some((error, r.clone()));
        }
        if stagnation.stalled(error) {
            break;
        }
    }
    // No sweep of finite error: the last iterate, of infinite error.
    let (error, best) = best.unwrap_or((f64::INFINITY, r));
    Err(Fc3dError::NotConverged {
        solver: "nsgs",
        iterations: sweeps,
        error,
        tolerance: options.tolerance,
        best,
    })
}

/// What a contact's local problem needs from W, computed once per solve: its diagonal block
/// W_aa (row-major), the weight ρ of its Alart–Curnier function and, at the first stick test
/// the contact meets (a contact that only takes off never needs it), that block's inverse (None
/// when singular: the stick test is then left to the local Newton method).
pub(crate) struct LocalBlock {
    w: Block,
    inverse: OnceCell<Option<Block>>,
    rho: f64,
}

/// The [`LocalBlock`] of every contact.
pub(crate) fn diagonal_blocks(problem: &Fc3dProblem) -> Vec<LocalBlock> {
    (0..problem.contacts())
        .map(|a| {
            let w = block3::diagonal(&problem.w, a);
            LocalBlock {
                inverse: OnceCell::new(),
                rho: weight(&w),
                w,
            }
        })
        .collect()
}

/// One Gauss–Seidel sweep over the contacts in order (module documentation), in place; `diagonal`
/// holds the contacts' [`LocalBlock`]s ([`diagonal_blocks`]), `omega` is the over-relaxation
/// (1: none), `tolerance` the local solves' ([`local_tolerance`]).
pub(crate) fn sweep(
    problem: &Fc3dProblem,
    diagonal: &[LocalBlock],
    omega: f64,
    tolerance: f64,
    r: &mut [f64],
) {
    for (a, block) in diagonal.iter().enumerate() {
        let k = 3 * a;
        let w = &block.w;
        let mut b = [problem.q[k], problem.q[k + 1], problem.q[k + 2]];
        problem.w.add_row_product(a, r, &mut b);
        let ra = [r[k], r[k + 1], r[k + 2]];
        for (i, bi) in b.iter_mut().enumerate() {
            *bi -= w[3 * i] * ra[0] + w[3 * i + 1] * ra[1] + w[3 * i + 2] * ra[2];
        }
        let local = solve_local(problem.mu[a], block, b, ra, tolerance);
        let local = if omega == 1.0 {
            local
        } else {
            project_cone(
                problem.mu[a],
                [0, 1, 2].map(|i| ra[i] + omega * (local[i] - ra[i])),
            )
        };
        r[k..k + 3].copy_from_slice(&local);
    }
}

fn velocity(w: &[f64; 9], r: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        w[0] * r[0] + w[1] * r[1] + w[2] * r[2] + b[0],
        w[3] * r[0] + w[4] * r[1] + w[5] * r[2] + b[1],
        w[6] * r[0] + w[7] * r[1] + w[8] * r[2] + b[2],
    ]
}

fn squared3(v: [f64; 3]) -> f64 {
    v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
}

fn norm3(v: [f64; 3]) -> f64 {
    squared3(v).sqrt()
}

/// The local natural map's norm at r.
fn local_residual(mu: f64, w: &[f64; 9], b: [f64; 3], r: [f64; 3]) -> f64 {
    norm3(contact_natural_map(mu, r, velocity(w, r, b)))
}

/// Solves the one-contact problem `u = W r + b` (module documentation), from `r0`, its
/// Alart–Curnier residual to `tolerance` relative to the size of r0 and ρ b.
pub(crate) fn solve_local(
    mu: f64,
    block: &LocalBlock,
    b: [f64; 3],
    r0: [f64; 3],
    tolerance: f64,
) -> [f64; 3] {
    let w = &block.w;
    if b[0] >= 0.0 {
        return [0.0; 3];
    }
    if mu == 0.0 && w[0] > 0.0 {
        return [-b[0] / w[0], 0.0, 0.0];
    }
    if let Some(inverse) = block.inverse.get_or_init(|| block3::inverse(w)) {
        let s = velocity(inverse, b, [0.0; 3]).map(|x| -x);
        if s[0] >= 0.0 && (s[1] * s[1] + s[2] * s[2]).sqrt() <= mu * s[0] {
            return s;
        }
    }
    let rho = block.rho;
    // Sizes squared: the size of r0 and ρ b, the residual to reach, the residual accepted.
    let scale = squared3(r0).max(rho * rho * squared3(b));
    let target = tolerance * tolerance * scale;
    let accepted = tolerance.max(LOCAL_ACCEPTED).powi(2) * scale;
    let (newton, converged) = local_newton(mu, rho, w, b, r0, target, accepted);
    if converged {
        return newton;
    }
    let newton_residual = local_residual(mu, w, b, newton);
    let mut r = newton;
    for _ in 0..LOCAL_PROJECTION {
        let d = contact_natural_map(mu, r, velocity(w, r, b).map(|x| rho * x));
        r = [r[0] - d[0], r[1] - d[1], r[2] - d[2]];
    }
    if local_residual(mu, w, b, r) < newton_residual {
        r
    } else {
        newton
    }
}

/// Semismooth Newton on the contact's Alart–Curnier function with Armijo's line search, to
/// ‖Φ‖² ≤ `target`; the flag says whether ‖Φ‖² reached `accepted`.
fn local_newton(
    mu: f64,
    rho: f64,
    w: &[f64; 9],
    b: [f64; 3],
    r0: [f64; 3],
    target: f64,
    accepted: f64,
) -> ([f64; 3], bool) {
    let mut r = r0;
    let (mut phi, mut g) = alart_curnier(mu, rho, r, velocity(w, r, b));
    for _ in 0..LOCAL_NEWTON {
        // Squared sizes throughout: no square root on the local Newton's path.
        let size = squared3(phi);
        if size <= target {
            return (r, true);
        }
        // J = (I − G) + ρ G W.
        let mut j = block3::product(&g, w).map(|x| rho * x);
        for i in 0..3 {
            for c in 0..3 {
                j[3 * i + c] += f64::from(i == c) - g[3 * i + c];
            }
        }
        let Some(d) = block3::solve(&j, phi.map(|x| -x)) else {
            break;
        };
        let mut step = 1.0;
        let mut moved = false;
        while step >= 1.0 / 1024.0 {
            let trial = [r[0] + step * d[0], r[1] + step * d[1], r[2] + step * d[2]];
            let (trial_phi, trial_g) = alart_curnier(mu, rho, trial, velocity(w, trial, b));
            if squared3(trial_phi) <= (1.0 - 2e-4 * step) * size {
                r = trial;
                phi = trial_phi;
                g = trial_g;
                moved = true;
                break;
            }
            step *= 0.5;
        }
        if !moved {
            break;
        }
    }
    (r, squared3(phi) <= accepted)
}
