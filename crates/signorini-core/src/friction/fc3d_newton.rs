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
//! `r ← P_K(r − ρ û)` (De Saxcé's fixed point) is taken instead. Nothing depends on the order of
//! the contacts. The linear systems are solved densely (LU with partial pivoting) up to
//! [`Fc3dOptions::dense_newton_max`] unknowns, and above it by GMRES (Y. Saad, M. H. Schultz,
//! *GMRES: a generalized minimal residual algorithm for solving nonsymmetric linear systems*,
//! SIAM J. Sci. Stat. Comput. 7(3):856–869, 1986, doi:10.1137/0907058) preconditioned by the
//! inverse of J's diagonal blocks, with products by the sparse W only.

use super::fc3d::contact_natural_map;
use super::fc3d::{Fc3dError, Fc3dOptions, Fc3dProblem, Fc3dSolution, natural_map_error};
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

/// The Armijo constant σ of the line search.
const ARMIJO: f64 = 1e-4;
/// Smallest step of the line search before the projection step is taken instead.
const SMALLEST_STEP: f64 = 1.0 / 1024.0;
/// GMRES: restart length, budget of inner iterations, relative residual asked.
const GMRES_RESTART: usize = 40;
const GMRES_MAX: usize = 400;
const GMRES_TOLERANCE: f64 = 1e-10;

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
    let s = x[1].hypot(x[2]);
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
    problem.validate()?;
    let m = problem.contacts();
    let diagonal: Vec<Vec<f64>> = (0..m).map(|a| problem.w.diagonal_block(a)).collect();
    let rho: Vec<f64> = diagonal.iter().map(|b| weight(b)).collect();
    let mut r = start.to_vec();
    let mut u = problem.local_velocity(&r);
    let mut best = (f64::INFINITY, r.clone());
    for iteration in 0..=options.max_iterations {
        let error = natural_map_error(&problem.mu, &problem.q, &r, &u);
        if error < best.0 {
            best = (error, r.clone());
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
        if iteration == options.max_iterations || !error.is_finite() {
            break;
        }
        let (phi, gs) = residual(problem, &rho, &r, &u);
        let psi = half_squared(&phi);
        let direction = newton_direction(problem, &rho, &gs, &diagonal, &phi, options);
        let mut step = 1.0;
        let mut accepted = false;
        if let Some(d) = direction {
            while step >= SMALLEST_STEP {
                let trial: Vec<f64> = r.iter().zip(&d).map(|(a, b)| a + step * b).collect();
                let trial_u = problem.local_velocity(&trial);
                let (trial_phi, _) = residual(problem, &rho, &trial, &trial_u);
                if half_squared(&trial_phi) <= (1.0 - 2.0 * ARMIJO * step) * psi {
                    r = trial;
                    u = trial_u;
                    accepted = true;
                    break;
                }
                step *= 0.5;
            }
        }
        if !accepted {
            // De Saxcé's projection step r ← P_K(r − ρ û).
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
            u = problem.local_velocity(&r);
        }
    }
    Err(Fc3dError::NotConverged {
        solver: "nsn_ac",
        iterations: options.max_iterations,
        error: best.0,
        tolerance: options.tolerance,
        best: best.1,
    })
}

/// `G_a · x_a` for a 3-vector block.
fn block_times(g: &[f64; 9], x: &[f64]) -> [f64; 3] {
    [
        g[0] * x[0] + g[1] * x[1] + g[2] * x[2],
        g[3] * x[0] + g[4] * x[1] + g[5] * x[2],
        g[6] * x[0] + g[7] * x[1] + g[8] * x[2],
    ]
}

/// The Newton direction d of `J d = −Φ`; `None` when the linear solve fails.
fn newton_direction(
    problem: &Fc3dProblem,
    rho: &[f64],
    gs: &[[f64; 9]],
    diagonal: &[Vec<f64>],
    phi: &[f64],
    options: &Fc3dOptions,
) -> Option<Vec<f64>> {
    let m = problem.contacts();
    let n = 3 * m;
    let rhs: Vec<f64> = phi.iter().map(|x| -x).collect();
    if n <= options.dense_newton_max {
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
        let d = j.lu().solve(&DVector::from_column_slice(&rhs))?;
        return d
            .iter()
            .all(|x| x.is_finite())
            .then(|| d.as_slice().to_vec());
    }
    // J v = v − G v + ρ G (W v), blockwise.
    let apply = |v: &[f64]| {
        let wv = problem.w.affine(v, &vec![0.0; n]);
        let mut out = vec![0.0; n];
        for a in 0..m {
            let k = 3 * a;
            let gv = block_times(&gs[a], &v[k..k + 3]);
            let gwv = block_times(&gs[a], &wv[k..k + 3]);
            for i in 0..3 {
                out[k + i] = v[k + i] - gv[i] + rho[a] * gwv[i];
            }
        }
        out
    };
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
    let d = gmres(apply, precondition, &rhs);
    d.iter().all(|x| x.is_finite()).then_some(d)
}

/// Restarted GMRES with right preconditioning, from x = 0, to a relative residual of
/// [`GMRES_TOLERANCE`] or [`GMRES_MAX`] inner iterations (Saad & Schultz 1986; modified
/// Gram–Schmidt and Givens rotations).
fn gmres(
    apply: impl Fn(&[f64]) -> Vec<f64>,
    precondition: impl Fn(&[f64]) -> Vec<f64>,
    b: &[f64],
) -> Vec<f64> {
    let n = b.len();
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let b_norm = norm(b);
    let mut x = vec![0.0; n];
    if b_norm == 0.0 {
        return x;
    }
    let mut done = 0;
    while done < GMRES_MAX {
        let ax = apply(&precondition(&x));
        let residual: Vec<f64> = b.iter().zip(&ax).map(|(b, a)| b - a).collect();
        let beta = norm(&residual);
        if beta <= GMRES_TOLERANCE * b_norm {
            break;
        }
        let mut basis = vec![residual.iter().map(|v| v / beta).collect::<Vec<f64>>()];
        let mut h: Vec<Vec<f64>> = Vec::new();
        let (mut cs, mut sn): (Vec<f64>, Vec<f64>) = (Vec::new(), Vec::new());
        let mut g = vec![beta];
        for j in 0..GMRES_RESTART {
            done += 1;
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
            let converged = g[j + 1].abs() <= GMRES_TOLERANCE * b_norm;
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
        if g[k].abs() <= GMRES_TOLERANCE * b_norm {
            break;
        }
    }
    precondition(&x)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// GMRES on a small nonsymmetric system reproduces the direct solution.
    #[test]
    fn gmres_solves_a_nonsymmetric_system() {
        let a = [4.0, 1.0, 0.0, -1.0, 3.0, 2.0, 0.5, 0.0, 5.0];
        let apply = |v: &[f64]| block_times(&a, v).to_vec();
        let x = gmres(apply, |v: &[f64]| v.to_vec(), &[1.0, 2.0, 3.0]);
        let back = block_times(&a, &x);
        for (b, e) in back.iter().zip([1.0, 2.0, 3.0]) {
            assert!((b - e).abs() <= 1e-9, "{back:?}");
        }
    }
}
