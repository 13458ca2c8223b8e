//! Semismooth Newton on Alart and Curnier's function for the FC3D problem, with a line search.
//!
//! P. Alart, A. Curnier, *A mixed formulation for frictional contact problems prone to Newton
//! like solution methods*, Computer Methods in Applied Mechanics and Engineering 92(3):353–375,
//! 1991, doi:10.1016/0045-7825(91)90022-X; in the notation of Acary, Brémond & Huber 2018
//! (doi:10.1007/978-3-319-75972-2_10, §3.3 and §5), per contact with `u = W r + q`, a weight
//! ρ > 0 and `x = r − ρ u`:
//!
//! ```text
//! Φ_n(r) = r_n − max(0, x_n)
//! Φ_t(r) = r_t − P_{B(0, μ max(0, x_n))}(x_t)
//! ```
//!
//! Φ(r) = 0 exactly at the solutions of Coulomb's law (the projection on the ball of radius
//! μ r_n reproduces stick and slide, the max Signorini). Φ is semismooth; writing `Φ = r − Π(x)`
//! and G ∈ ∂Π(x) (block diagonal, 3×3 per contact), an element of its generalized Jacobian is
//!
//! ```text
//! J = (I − G) + ρ G W
//! ```
//!
//! Each iteration solves `J d = −Φ` and takes the largest step `t ∈ {1, ½, ¼, …}` that decreases
//! the merit `ψ = ½‖Φ‖²` by Armijo's rule `ψ(r + t d) ≤ (1 − 2σt) ψ(r)` (σ = 10⁻⁴; Qi & Sun's
//! semismooth Newton with a line search). When no step does, one projection step
//! `r ← P_K(r − ρ û)` (De Saxcé's fixed point) is taken instead. Alart–Curnier's merit has
//! spurious stationary points where Φ ≠ 0, at which the line search keeps finding tiny steps
//! that change nothing: when the smallest error has not fallen by 1 % in [`STALL_ITERATIONS`]
//! iterations, as many projection steps follow before Newton resumes (a problem built from a
//! known solution, six contacts, stalled at error 6.5e-4 for 10 000 iterations without them). Nothing depends on the order of
//! the contacts. The linear systems ([`Fc3dOptions::newton_linear`]) are solved by a sparse LU
//! of J assembled from W's blocks — first the block LU of [`super::fc3d_block_lu`] (3×3 blocks,
//! its pattern ordered and filled once, no pivoting between blocks; its direction is taken when
//! its measured residual meets the forcing term below), else the LU with partial pivoting of
//! [`super::fc3d_sparse_lu`] —, densely (LU with partial pivoting), or by GMRES (Y. Saad,
//! M. H. Schultz, *GMRES: a generalized minimal residual algorithm for solving nonsymmetric
//! linear systems*, SIAM J. Sci. Stat. Comput. 7(3):856–869, 1986, doi:10.1137/0907058)
//! preconditioned by the inverse of J's diagonal blocks, with products by the sparse W only.
//! `Auto` takes the sparse LU unless a factorisation costs more than [`SPARSE_LU_MAX_PASSES`]
//! products by W (its factors fill in: the block LU knows it from its pattern before any
//! arithmetic, the pivoting LU after its first factorisation), and from then on, for the rest
//! of the solve, the dense LU up to [`Fc3dOptions::dense_newton_max`] unknowns and GMRES above.
//!
//! **Inexact Newton.** GMRES stops at the relative residual `‖J d + Φ_k‖ ≤ η_k ‖Φ_k‖` of a
//! forcing term that follows ‖Φ‖ (S. C. Eisenstat, H. F. Walker, *Choosing the forcing terms in
//! an inexact Newton method*, SIAM J. Sci. Comput. 17(1):16–32, 1996, doi:10.1137/0917003,
//! choice 2 with its safeguard):
//!
//! ```text
//! η_0 = η_max,   η_k = γ (‖Φ_k‖ / ‖Φ_{k−1}‖)^α,   η_k ← max(η_k, γ η_{k−1}^α) when γ η_{k−1}^α > 0.1
//! η_k ← min(η_max, max(η_k, ½ tolerance / e_k))
//! ```
//!
//! (γ = 0.9, α = 2; the last line is C. T. Kelley's safeguard against solving the last step
//! more precisely than the tolerance asks, *Iterative Methods for Linear and Nonlinear
//! Equations*, SIAM, 1995, doi:10.1137/1.9781611970944, §6.3, with e_k the natural-map error of
//! r_k), and the step is accepted by the sufficient decrease of an inexact direction,
//! `ψ(r + t d) ≤ (1 − 2σt(1 − η)) ψ(r)` with η the residual GMRES reached (S. C. Eisenstat,
//! H. F. Walker, *Globally convergent inexact Newton methods*, SIAM J. Optim. 4(2):393–422,
//! 1994, doi:10.1137/0804022: such a d descends on ψ with slope ≤ −2(1 − η)ψ; η = 0 for the
//! dense and sparse LU). η_max is 10⁻³, not Eisenstat and Walker's 0.9: measured on Siconos' Capsules and
//! KaplasTower problems (docs/friction_benchmark.md, Round 9), the proximal point method's Newton
//! took 1.7–22× more iterations with η_max = 0.9 or 0.1 than with GMRES solved to 10⁻¹⁰, while
//! 10⁻³ keeps those iteration counts (±4) and needs 1.06–4.4× fewer products by W's blocks.

use super::fc3d::{
    Fc3dError, Fc3dNewtonLinear, Fc3dOptions, Fc3dProblem, Fc3dSolution, check_solve,
    contact_natural_map, natural_map_error,
};
use super::fc3d_block_lu::{BlockLu, newton_product};
use super::fc3d_sparse_lu::SparseNewton;
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

/// The Armijo constant σ of the line search.
const ARMIJO: f64 = 1e-4;
/// Smallest step of the line search before the projection step is taken instead.
const SMALLEST_STEP: f64 = 1.0 / 1024.0;
/// Newton iterations without reducing the smallest error by the factor [`STALL_DECREASE`] after
/// which the iteration counts as stalled at a spurious stationary point of the merit, and as
/// many projection steps follow.
const STALL_ITERATIONS: usize = 20;
/// See [`STALL_ITERATIONS`]: a stall is an iteration that gains less than 1 % in 20 iterations
/// (a slow but real descent, as in the proximal point's inner solves on Siconos' Capsules
/// problems, is not interrupted).
const STALL_DECREASE: f64 = 0.99;
/// GMRES: restart length, budget of inner iterations.
const GMRES_RESTART: usize = 40;
const GMRES_MAX: usize = 400;
/// Eisenstat–Walker's choice 2 (module documentation): γ and the exponent α (their values in
/// Eisenstat & Walker 1996, §4), and the largest forcing term η_max, also the first (measured,
/// module documentation).
const EW_GAMMA: f64 = 0.9;
const EW_ALPHA: f64 = 2.0;
const EW_MAX: f64 = 1e-3;
/// The smallest forcing term: below it GMRES's own round-off (modified Gram–Schmidt) dominates.
const EW_MIN: f64 = 1e-10;

/// The forcing term η_k of Eisenstat and Walker's choice 2 with its safeguards (module
/// documentation): `phi_norm` is ‖Φ(r_k)‖, `previous` the norm and forcing term of the previous
/// iteration (None at the first), `error` the natural-map error of r_k and `tolerance` the one asked.
fn forcing_term(phi_norm: f64, previous: Option<(f64, f64)>, error: f64, tolerance: f64) -> f64 {
    let eta = match previous {
        None => EW_MAX,
        Some((previous_norm, previous_eta)) => {
            let eta = EW_GAMMA * (phi_norm / previous_norm).powf(EW_ALPHA);
            let floor = EW_GAMMA * previous_eta.powf(EW_ALPHA);
            if floor > 0.1 { eta.max(floor) } else { eta }
        }
    };
    // Kelley's safeguard against oversolving the last step.
    let eta = eta.max(0.5 * tolerance / error);
    if eta.is_finite() {
        eta.clamp(EW_MIN, EW_MAX)
    } else {
        EW_MAX
    }
}

/// The weight ρ of a contact: the inverse of the largest diagonal entry of its 3×3 block of W
/// (1 when that is not positive), so that `ρ u` has the unit and the size of an impulse.
pub(crate) fn weight(block: &[f64]) -> f64 {
    let d = block[0].max(block[4]).max(block[8]);
    if d > 0.0 { 1.0 / d } else { 1.0 }
}

/// Alart–Curnier's function of one contact and an element G of the generalized Jacobian of its
/// projection part (module documentation), row-major.
pub(crate) fn alart_curnier(mu: f64, rho: f64, r: [f64; 3], u: [f64; 3]) -> ([f64; 3], [f64; 9]) {
    let x = [r[0] - rho * u[0], r[1] - rho * u[1], r[2] - rho * u[2]];
    let mut g = [0.0; 9];
    let mut phi = [0.0; 3];
    if x[0] > 0.0 {
        phi[0] = r[0] - x[0];
        g[0] = 1.0;
    } else {
        phi[0] = r[0];
    }
    let radius = mu * x[0].max(0.0);
    // (Not `hypot`: its care for overflow beyond 1e154 costs a tenth of a Gauss–Seidel sweep.)
    let s = (x[1] * x[1] + x[2] * x[2]).sqrt();
    if s <= radius {
        // Stick: Π_t(x) = x_t.
        phi[1] = r[1] - x[1];
        phi[2] = r[2] - x[2];
        g[4] = 1.0;
        g[8] = 1.0;
    } else if radius > 0.0 {
        // Slide: Π_t(x) = μ x_n x_t / ‖x_t‖.
        let (e1, e2) = (x[1] / s, x[2] / s);
        phi[1] = r[1] - radius * e1;
        phi[2] = r[2] - radius * e2;
        let k = radius / s;
        g[3] = mu * e1;
        g[6] = mu * e2;
        g[4] = k * (1.0 - e1 * e1);
        g[5] = -k * e1 * e2;
        g[7] = -k * e1 * e2;
        g[8] = k * (1.0 - e2 * e2);
    } else {
        phi[1] = r[1];
        phi[2] = r[2];
    }
    (phi, g)
}

/// Φ(r) of every contact and the G blocks.
fn residual(problem: &Fc3dProblem, rho: &[f64], r: &[f64], u: &[f64]) -> (Vec<f64>, Vec<[f64; 9]>) {
    let m = problem.contacts();
    let mut phi = vec![0.0; 3 * m];
    let mut gs = Vec::with_capacity(m);
    for (c, &rho_c) in rho.iter().enumerate() {
        let k = 3 * c;
        let (p, g) = alart_curnier(
            problem.mu[c],
            rho_c,
            [r[k], r[k + 1], r[k + 2]],
            [u[k], u[k + 1], u[k + 2]],
        );
        phi[k..k + 3].copy_from_slice(&p);
        gs.push(g);
    }
    (phi, gs)
}

fn half_squared(v: &[f64]) -> f64 {
    0.5 * v.iter().map(|x| x * x).sum::<f64>()
}

/// Solves the problem by the semismooth Newton method (module documentation) from `start`.
/// `iterations` counts Newton iterations. On failure the error holds the iterate of smallest
/// error.
pub fn solve_fc3d_newton(
    problem: &Fc3dProblem,
    options: &Fc3dOptions,
    start: &[f64],
) -> Result<Fc3dSolution, Fc3dError> {
    check_solve(problem, options, start)?;
    newton(problem, options, start)
}

/// [`solve_fc3d_newton`] on checked inputs ([`check_solve`]).
pub(crate) fn newton(
    problem: &Fc3dProblem,
    options: &Fc3dOptions,
    start: &[f64],
) -> Result<Fc3dSolution, Fc3dError> {
    let mut work = Work::unbounded();
    let mut linear = LinearCache::default();
    newton_within(problem, options, start, &mut work, &mut linear, true)
}

/// Largest work of a sparse LU factorisation, in passes over W (products by its stored blocks),
/// for which `Fc3dNewtonLinear::Auto` keeps the sparse LU; above it the factors fill in and
/// GMRES takes over for the rest of the solve. Measured (docs/friction_benchmark.md, Rounds 10
/// and 15): a factorisation costs 10–14 passes with the block LU (7–19 with the pivoting LU) on
/// Siconos' Capsules and BoxesStack1 problems, where GMRES spends up to 400 per Newton iteration
/// (one restart cycle is 41), and 134 (460) on KaplasTower, where GMRES needs about 80 per
/// Newton iteration.
const SPARSE_LU_MAX_PASSES: usize = 50;

/// What Newton's linear solve keeps from one iteration to the next, and from one of the
/// proximal point method's inner solves to the next (their W + α I share W's pattern): the
/// sparse LU's pattern and ordering, and whether its factors filled in beyond
/// [`SPARSE_LU_MAX_PASSES`].
#[derive(Default)]
pub(crate) struct LinearCache {
    block: Option<BlockLu>,
    sparse: Option<SparseNewton>,
    sparse_fills_in: bool,
}

/// Work of a solve in products by a 3×3 block of W (18 flops each): a product by W (a local
/// velocity, a line-search trial, a GMRES iteration; a Gauss–Seidel sweep costs the same) is one
/// per stored block, a dense LU factorisation of n unknowns its 2n³/3 flops over 18, a sparse LU
/// its assembly, the flops of its elimination counted from its factors, and its triangular
/// solves ([`super::fc3d_sparse_lu`]). `spent` accumulates; a solve stops (not converged) once it
/// reaches `budget`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Work {
    pub(crate) spent: usize,
    pub(crate) budget: usize,
}

impl Work {
    pub(crate) fn unbounded() -> Self {
        Self {
            spent: 0,
            budget: usize::MAX,
        }
    }

    fn exhausted(&self) -> bool {
        self.spent >= self.budget
    }
}

/// [`solve_fc3d_newton`] counting its passes over W in `work` and stopping, not converged, at
/// the first iteration that starts with the budget spent. `unstall` takes the projection steps
/// of a stall ([`STALL_ITERATIONS`]); the proximal point method's inner solves go without them
/// (its outer iteration answers an inner solve that fails by a larger regularisation, and on
/// Siconos' Capsules-i122 the projection steps cost it 264 Newton iterations instead of 76).
pub(crate) fn newton_within(
    problem: &Fc3dProblem,
    options: &Fc3dOptions,
    start: &[f64],
    work: &mut Work,
    cache: &mut LinearCache,
    unstall: bool,
) -> Result<Fc3dSolution, Fc3dError> {
    let m = problem.contacts();
    let diagonal: Vec<[f64; 9]> = (0..m)
        .map(|a| super::block3::diagonal(&problem.w, a))
        .collect();
    let rho: Vec<f64> = diagonal.iter().map(|b| weight(b)).collect();
    let mut r = start.to_vec();
    let pass = problem.w.stored_blocks().max(1);
    let mut u = problem.local_velocity(&r);
    work.spent += pass;
    let mut best = (f64::INFINITY, r.clone());
    let mut previous = None;
    let mut done = options.max_iterations;
    // The iteration and the smallest error at the last decrease of the smallest error by
    // STALL_DECREASE, and the projection steps left to take after a stall.
    let mut progress = (0, f64::INFINITY);
    let mut projections = 0;
    for iteration in 0..=options.max_iterations {
        let error = natural_map_error(&problem.mu, &problem.q, &r, &u);
        if error < best.0 {
            best = (error, r.clone());
        }
        if best.0 <= STALL_DECREASE * progress.1 {
            progress = (iteration, best.0);
        } else if unstall && projections == 0 && iteration >= progress.0 + STALL_ITERATIONS {
            projections = STALL_ITERATIONS;
            progress = (iteration + STALL_ITERATIONS, best.0);
        }
        if error <= options.tolerance {
            return Ok(Fc3dSolution {
                r,
                u,
                iterations: iteration,
                error,
                solver: "nsn_ac",
            });
        }
        if iteration == options.max_iterations || !error.is_finite() || work.exhausted() {
            done = iteration;
            break;
        }
        if projections > 0 {
            projections -= 1;
            projection_step(problem, &rho, &mut r, &mut u);
            work.spent += pass;
            continue;
        }
        let (phi, gs) = residual(problem, &rho, &r, &u);
        let psi = half_squared(&phi);
        let phi_norm = (2.0 * psi).sqrt();
        let eta = forcing_term(phi_norm, previous, error, options.tolerance);
        previous = Some((phi_norm, eta));
        let linear = Linearisation {
            rho: &rho,
            gs: &gs,
            diagonal: &diagonal,
        };
        let direction = newton_direction(problem, &linear, &phi, options, eta, cache, work);
        let mut step = 1.0;
        let mut accepted = false;
        // A direction with ‖J d + Φ‖ ≤ η‖Φ‖ (η < 1) descends on ψ with slope ≤ −2(1 − η)ψ.
        if let Some((d, achieved)) = direction.filter(|(_, achieved)| *achieved < 1.0) {
            while step >= SMALLEST_STEP {
                let trial: Vec<f64> = r.iter().zip(&d).map(|(a, b)| a + step * b).collect();
                let trial_u = problem.local_velocity(&trial);
                work.spent += pass;
                let (trial_phi, _) = residual(problem, &rho, &trial, &trial_u);
                let decrease = 1.0 - 2.0 * ARMIJO * step * (1.0 - achieved);
                if half_squared(&trial_phi) <= decrease * psi {
                    r = trial;
                    u = trial_u;
                    accepted = true;
                    break;
                }
                step *= 0.5;
            }
        }
        if !accepted {
            projection_step(problem, &rho, &mut r, &mut u);
            work.spent += pass;
        }
    }
    Err(Fc3dError::NotConverged {
        solver: "nsn_ac",
        iterations: done,
        error: best.0,
        tolerance: options.tolerance,
        best: best.1,
    })
}

/// De Saxcé's projection step r ← P_K(r − ρ û) on every contact, then u = W r + q.
fn projection_step(problem: &Fc3dProblem, rho: &[f64], r: &mut [f64], u: &mut Vec<f64>) {
    for (c, &rho_c) in rho.iter().enumerate() {
        let k = 3 * c;
        let d = contact_natural_map(
            problem.mu[c],
            [r[k], r[k + 1], r[k + 2]],
            [rho_c * u[k], rho_c * u[k + 1], rho_c * u[k + 2]],
        );
        for (ri, di) in r[k..k + 3].iter_mut().zip(d) {
            *ri -= di;
        }
    }
    *u = problem.local_velocity(r);
}

/// What J is made of at r_k: the weights ρ per contact, the blocks G of ∂Π, the diagonal blocks
/// of W.
struct Linearisation<'a> {
    rho: &'a [f64],
    gs: &'a [[f64; 9]],
    diagonal: &'a [[f64; 9]],
}

/// The Newton direction d of `J d = −Φ` and the relative residual `‖J d + Φ‖ / ‖Φ‖` reached (0
/// for the dense LU; GMRES stops at the forcing term `eta`); `None` when the linear solve fails.
fn newton_direction(
    problem: &Fc3dProblem,
    linear: &Linearisation,
    phi: &[f64],
    options: &Fc3dOptions,
    eta: f64,
    cache: &mut LinearCache,
    work: &mut Work,
) -> Option<(Vec<f64>, f64)> {
    let Linearisation { rho, gs, diagonal } = *linear;
    let m = problem.contacts();
    let n = 3 * m;
    let rhs: Vec<f64> = phi.iter().map(|x| -x).collect();
    let method = match options.newton_linear {
        Fc3dNewtonLinear::Auto if !cache.sparse_fills_in => Fc3dNewtonLinear::SparseLu,
        Fc3dNewtonLinear::Auto if n <= options.dense_newton_max => Fc3dNewtonLinear::DenseLu,
        Fc3dNewtonLinear::Auto => Fc3dNewtonLinear::Gmres,
        other => other,
    };
    if method == Fc3dNewtonLinear::SparseLu {
        if !cache.block.as_ref().is_some_and(|b| b.fits(&problem.w)) {
            cache.block = BlockLu::new(&problem.w);
        }
        if let Some(block) = cache.block.as_ref() {
            if options.newton_linear == Fc3dNewtonLinear::Auto
                && block.work() > SPARSE_LU_MAX_PASSES * problem.w.stored_blocks().max(1)
            {
                // The factors fill in: the rest of the solve goes without a sparse LU.
                cache.sparse_fills_in = true;
                return newton_direction(problem, linear, phi, options, eta, cache, work);
            }
            work.spent += block.work();
            // An inexact direction is taken when it meets the forcing term GMRES is held to;
            // otherwise the LU with partial pivoting solves again.
            if let Ok((d, residual)) = block.solve(&problem.w, gs, rho, &rhs)
                && residual <= eta
            {
                return Some((d, residual));
            }
        }
        if !cache.sparse.as_ref().is_some_and(|s| s.fits(&problem.w)) {
            cache.sparse = SparseNewton::new(&problem.w).ok();
        }
        let factors = cache.sparse.as_ref()?;
        let (d, factorisation) = factors
            .solve(&problem.w, gs, rho, &rhs, &mut work.spent)
            .ok()?;
        if factorisation > SPARSE_LU_MAX_PASSES * problem.w.stored_blocks().max(1) {
            cache.sparse_fills_in = true;
        }
        return Some((d, 0.0));
    }
    if method == Fc3dNewtonLinear::DenseLu {
        let mut j = DMatrix::<f64>::zeros(n, n);
        for a in 0..m {
            let g = &gs[a];
            for i in 0..3 {
                for k in 0..3 {
                    j[(3 * a + i, 3 * a + k)] += f64::from(i == k) - g[3 * i + k];
                }
            }
            for (b, block) in problem.w.row(a) {
                for i in 0..3 {
                    for k in 0..3 {
                        let gw: f64 = (0..3).map(|l| g[3 * i + l] * block[3 * l + k]).sum();
                        j[(3 * a + i, 3 * b + k)] += rho[a] * gw;
                    }
                }
            }
        }
        let flops = 2.0 * (n as f64).powi(3) / 3.0;
        work.spent += (flops / 18.0).ceil() as usize;
        let d = j.lu().solve(&DVector::from_column_slice(&rhs))?;
        return d
            .iter()
            .all(|x| x.is_finite())
            .then(|| (d.as_slice().to_vec(), 0.0));
    }
    let apply = |v: &[f64]| newton_product(&problem.w, gs, rho, v);
    // Block-Jacobi preconditioner: the inverse of J's diagonal blocks (identity where singular).
    let inverses: Vec<Matrix3<f64>> = (0..m)
        .map(|a| {
            let g = Matrix3::from_row_slice(&gs[a]);
            let w = Matrix3::from_row_slice(&diagonal[a]);
            let jaa = Matrix3::identity() - g + g * w * rho[a];
            jaa.try_inverse().unwrap_or_else(Matrix3::identity)
        })
        .collect();
    let precondition = |v: &[f64]| {
        let mut out = vec![0.0; n];
        for (a, inverse) in inverses.iter().enumerate() {
            let k = 3 * a;
            let y = inverse * Vector3::new(v[k], v[k + 1], v[k + 2]);
            out[k..k + 3].copy_from_slice(y.as_slice());
        }
        out
    };
    let (d, achieved, products) = gmres(apply, precondition, &rhs, eta);
    work.spent += products * problem.w.stored_blocks().max(1);
    d.iter().all(|x| x.is_finite()).then_some((d, achieved))
}

/// Restarted GMRES with right preconditioning, from x = 0, to a relative residual
/// `‖b − A x‖ ≤ tolerance ‖b‖` or [`GMRES_MAX`] inner iterations (Saad & Schultz 1986; modified
/// Gram–Schmidt and Givens rotations). Returns x and the relative residual of its last
/// restart cycle's recurrence (the true residual of x up to round-off: with right preconditioning
/// GMRES minimises the unpreconditioned residual).
fn gmres(
    apply: impl Fn(&[f64]) -> Vec<f64>,
    precondition: impl Fn(&[f64]) -> Vec<f64>,
    b: &[f64],
    tolerance: f64,
) -> (Vec<f64>, f64, usize) {
    let n = b.len();
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let b_norm = norm(b);
    let mut x = vec![0.0; n];
    if b_norm == 0.0 {
        return (x, 0.0, 0);
    }
    let mut done = 0;
    let mut products = 0;
    let mut achieved = 1.0;
    while done < GMRES_MAX {
        let ax = apply(&precondition(&x));
        products += 1;
        let residual: Vec<f64> = b.iter().zip(&ax).map(|(b, a)| b - a).collect();
        let beta = norm(&residual);
        achieved = beta / b_norm;
        if beta <= tolerance * b_norm {
            break;
        }
        let mut basis = vec![residual.iter().map(|v| v / beta).collect::<Vec<f64>>()];
        let mut h: Vec<Vec<f64>> = Vec::new();
        let (mut cs, mut sn): (Vec<f64>, Vec<f64>) = (Vec::new(), Vec::new());
        let mut g = vec![beta];
        for j in 0..GMRES_RESTART {
            done += 1;
            products += 1;
            let mut w = apply(&precondition(&basis[j]));
            let mut column = vec![0.0; j + 2];
            for (i, v) in basis.iter().enumerate() {
                column[i] = dot(&w, v);
                for (wk, vk) in w.iter_mut().zip(v) {
                    *wk -= column[i] * vk;
                }
            }
            column[j + 1] = norm(&w);
            for i in 0..j {
                let t = cs[i] * column[i] + sn[i] * column[i + 1];
                column[i + 1] = -sn[i] * column[i] + cs[i] * column[i + 1];
                column[i] = t;
            }
            let denominator = column[j].hypot(column[j + 1]);
            let (c, s) = if denominator == 0.0 {
                (1.0, 0.0)
            } else {
                (column[j] / denominator, column[j + 1] / denominator)
            };
            let next_norm = column[j + 1];
            column[j] = denominator;
            column[j + 1] = 0.0;
            cs.push(c);
            sn.push(s);
            g.push(-s * g[j]);
            g[j] *= c;
            h.push(column);
            let converged = g[j + 1].abs() <= tolerance * b_norm;
            if converged || next_norm == 0.0 || done >= GMRES_MAX || j + 1 == GMRES_RESTART {
                break;
            }
            basis.push(w.iter().map(|v| v / next_norm).collect());
        }
        // Back substitution of the triangular system H y = g, then x += V y.
        let k = h.len();
        let mut y = vec![0.0; k];
        for i in (0..k).rev() {
            let s: f64 = (i + 1..k).map(|l| h[l][i] * y[l]).sum();
            y[i] = if h[i][i] != 0.0 {
                (g[i] - s) / h[i][i]
            } else {
                0.0
            };
        }
        for (yi, v) in y.iter().zip(&basis) {
            for (xk, vk) in x.iter_mut().zip(v) {
                *xk += yi * vk;
            }
        }
        achieved = g[k].abs() / b_norm;
        if g[k].abs() <= tolerance * b_norm {
            break;
        }
    }
    (precondition(&x), achieved, products)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Eisenstat–Walker's choice 2 with its safeguards, capped at η_max.
    #[test]
    fn forcing_term_follows_the_residual() {
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-15 * b.abs();
        // The first iteration: η_max.
        assert_eq!(forcing_term(1.0, None, 1e-2, 1e-8), EW_MAX);
        // ‖Φ‖ fell 100×: η = 0.9 · 10⁻⁴ (the previous η's floor 0.9 · 10⁻⁶ is below 0.1).
        assert!(close(
            forcing_term(1e-2, Some((1.0, 1e-3)), 1e-4, 1e-12),
            9e-5
        ));
        // ‖Φ‖ did not fall: γ · 1 = 0.9, capped at η_max.
        assert_eq!(forcing_term(1.0, Some((1.0, 1e-3)), 1e-4, 1e-12), EW_MAX);
        // A fall of 10⁶ asks 0.9 · 10⁻¹², floored at EW_MIN …
        assert_eq!(forcing_term(1e-6, Some((1.0, 1e-3)), 1e-6, 1e-30), EW_MIN);
        // … unless the error is near the tolerance: Kelley's ½ · tolerance / e = ½ · 10⁻⁸ / 10⁻⁵.
        assert!(close(
            forcing_term(1e-6, Some((1.0, 1e-3)), 1e-5, 1e-8),
            5e-4
        ));
    }

    /// GMRES on a small nonsymmetric system reproduces the direct solution.
    #[test]
    fn gmres_solves_a_nonsymmetric_system() {
        let a = [4.0, 1.0, 0.0, -1.0, 3.0, 2.0, 0.5, 0.0, 5.0];
        let apply = |v: &[f64]| crate::friction::block3::apply(&a, v).to_vec();
        let (x, achieved, _) = gmres(apply, |v: &[f64]| v.to_vec(), &[1.0, 2.0, 3.0], 1e-10);
        assert!(achieved <= 1e-10, "{achieved}");
        let back = crate::friction::block3::apply(&a, &x);
        for (b, e) in back.iter().zip([1.0, 2.0, 3.0]) {
            assert!((b - e).abs() <= 1e-9, "{back:?}");
        }
    }
}
