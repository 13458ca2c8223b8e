//! The second-derivative terms of the nonsmooth generalized-α smooth stage's exact Newton
//! matrix ([`crate::nonlinear::generalized_alpha`]) as sparse tapes, derived symbolically from
//! the model's expressions and compiled once, at first use:
//!
//! ```text
//! ∂(M(q) w)/∂q              (n×n, w = q̈),
//! ∂(G(q, t)ᵀ w)/∂q = Σ_r w_r ∇²g_r   (n×n, w = λ),
//! ∂g̈/∂q, ∂g̈/∂q̇              (nb×n each, w = q̈), g̈ = d/dt(G q̇ + g_t) along (1, q̇, w),
//! ```
//!
//! and the joints' curvature term κ = g̈ at q̈ = 0 (g_qq(q̇, q̇) + 2 g_qt q̇ + g_tt) that the
//! stage's residual reads.
//!
//! Each tape reads the variables (q, q̇, t, w): the model's own, then the vector w the term is
//! linear in. Only the coordinates an entry depends on are differentiated, so the tapes hold
//! the structural nonzeros and a step evaluates each once, in f64. (Before, each term was one
//! forward-mode dual evaluation of M's, G's or g̈'s tape per group of columns that share no
//! row, and g̈ itself a dual evaluation of the tape of G q̇ + g_t: nested dual numbers.) Only
//! that scheme reads them, so a model run by another never builds them.

use super::UserModel;
use crate::expr::{Expr, Tape};
use crate::triplets::Triplets;

/// The expressions the terms are derived from: M's entries (row-major position, both
/// triangles), G's rows (coordinate, ∂g_r/∂q_i) and the joints' rates G q̇ + g_t.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct NewtonSources {
    pub(super) mass: Vec<(usize, Expr)>,
    pub(super) joint_jacobian: Vec<Vec<(usize, Expr)>>,
    pub(super) joint_rate: Vec<Expr>,
}

/// The three terms' tapes (module documentation).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct NewtonTerms {
    /// ∂(M w)/∂q, n×n.
    mass: Tape,
    /// ∂(Gᵀ w)/∂q, n×n.
    joint_force: Tape,
    /// ∂g̈/∂q then ∂g̈/∂q̇, row r of each at r·2n and r·2n + n.
    joint_acceleration: Tape,
    /// κ, one per joint.
    curvature: Tape,
}

impl NewtonTerms {
    /// Derives and compiles the terms of a model of `n` coordinates.
    pub(super) fn new(n: usize, sources: &NewtonSources) -> Self {
        let w = |k: usize| Expr::var(2 * n + 1 + k);
        let mut rows: Vec<Vec<Expr>> = vec![Vec::new(); n];
        for (at, entry) in &sources.mass {
            rows[at / n].push(entry.clone() * w(at % n));
        }
        let mass = gradients(n, rows.into_iter().map(|r| r.into_iter().sum()), n);
        let mut forces: Vec<Vec<Expr>> = vec![Vec::new(); n];
        for (r, row) in sources.joint_jacobian.iter().enumerate() {
            for (i, g) in row {
                forces[*i].push(g.clone() * w(r));
            }
        }
        let joint_force = gradients(n, forces.into_iter().map(|f| f.into_iter().sum()), n);
        let nb = sources.joint_rate.len();
        let (mut entries, mut curvature) = (Vec::new(), Vec::with_capacity(nb));
        for (r, rate) in sources.joint_rate.iter().enumerate() {
            let kappa: Expr = rate
                .variables_in(0..n)
                .map(|i| rate.derivative(i) * Expr::var(n + i))
                .sum::<Expr>()
                + rate.derivative(2 * n);
            let g_ddot = kappa.clone()
                + rate
                    .variables_in(n..2 * n)
                    .map(|i| rate.derivative(i) * w(i - n))
                    .sum();
            for (i, d) in g_ddot.sparse_gradient(0..2 * n) {
                entries.push((r * 2 * n + i, d));
            }
            curvature.push(kappa);
        }
        Self {
            mass: Tape::compile_sparse(n * n, &mass),
            joint_force: Tape::compile_sparse(n * n, &joint_force),
            joint_acceleration: Tape::compile_sparse(nb * 2 * n, &entries),
            curvature: Tape::compile(&curvature),
        }
    }

    /// κ of `model` at (t, q, v) into `out`.
    pub(crate) fn curvature(
        &self,
        model: &UserModel,
        (t, q, v): (f64, &[f64], &[f64]),
        out: &mut [f64],
    ) {
        model.for_each_stored(&self.curvature, (t, q, Some(v), &[]), |k, x| out[k] = x);
    }

    /// ∂(M(q) a)/∂q of `model` into `out`.
    pub(crate) fn mass(&self, model: &UserModel, q: &[f64], a: &[f64], out: &mut Triplets) {
        let n = model.n;
        out.clear();
        out.reserve(self.mass.stored());
        model.for_each_stored(&self.mass, (0.0, q, None, a), |k, x| {
            out.push(k / n, k % n, x)
        });
    }

    /// ∂(G(q, t)ᵀ λ)/∂q of `model` into `out`.
    pub(crate) fn joint_force(
        &self,
        model: &UserModel,
        (t, q, lambda): (f64, &[f64], &[f64]),
        out: &mut Triplets,
    ) {
        let n = model.n;
        out.clear();
        out.reserve(self.joint_force.stored());
        model.for_each_stored(&self.joint_force, (t, q, None, lambda), |k, x| {
            out.push(k / n, k % n, x)
        });
    }

    /// ∂g̈/∂q of `model` into `dq` and ∂g̈/∂q̇ into `dv` at (t, q, v) and q̈ = `a`.
    pub(crate) fn joint_acceleration(
        &self,
        model: &UserModel,
        (t, q, v, a): (f64, &[f64], &[f64], &[f64]),
        dq: &mut Triplets,
        dv: &mut Triplets,
    ) {
        let n = model.n;
        dq.clear();
        dv.clear();
        dq.reserve(self.joint_acceleration.stored());
        dv.reserve(self.joint_acceleration.stored());
        model.for_each_stored(&self.joint_acceleration, (t, q, Some(v), a), |k, x| {
            let (r, i) = (k / (2 * n), k % (2 * n));
            if i < n {
                dq.push(r, i, x);
            } else {
                dv.push(r, i - n, x);
            }
        });
    }
}

/// The sparse gradients along q (variables 0..n) of `exprs`, as (row-major position in a
/// rows×`width` matrix, expression) entries.
fn gradients(n: usize, exprs: impl Iterator<Item = Expr>, width: usize) -> Vec<(usize, Expr)> {
    exprs
        .enumerate()
        .flat_map(|(row, e)| {
            e.sparse_gradient(0..n)
                .into_iter()
                .map(move |(j, d)| (row * width + j, d))
        })
        .collect()
}
