//! Bilateral holonomic joints g(q, t) = 0 of a nonlinear Lagrangian system: the interface both
//! nonlinear time-steppings read ([`super::moreau_jean`] as equality rows of its mixed LCP,
//! [`super::generalized_alpha`] in its smooth, velocity and position stages), and its
//! implementation by the user models of `scene = "lagrangian"`.

use super::LagrangianSystem;
use super::delassus::JointStructure;
use crate::lagrangian::{StoredMatrix, UserModel};
use crate::soi2::banded::BandOrder;
use crate::soi2::sparsity::Pattern;
use crate::soi2::{ConstrainedModel, Dual64, g_ddot};
use crate::triplets::Triplets;

/// A [`LagrangianSystem`] with bilateral holonomic joints g(q, t) = 0 (nb of them). The
/// defaults describe a system without joints.
pub trait JointedSystem: LagrangianSystem {
    /// Number of joints nb.
    fn joints(&self) -> usize {
        0
    }

    /// g(q, t), nb entries.
    fn joint_values(&self, t: f64, q: &[f64], out: &mut [f64]) {
        let _ = (t, q, out);
    }

    /// G = ∂g/∂q, nb×n row-major.
    fn joint_jacobian(&self, t: f64, q: &[f64], out: &mut [f64]) {
        let _ = (t, q, out);
    }

    /// G v + g_t, nb entries.
    fn joint_rates(&self, t: f64, q: &[f64], v: &[f64], out: &mut [f64]) {
        let _ = (t, q, v, out);
    }

    /// κ = d/dt(G v + g_t) with q̈ = 0, i.e. g_qq(v, v) + 2 g_qt v + g_tt, nb entries.
    fn joint_curvature(&self, t: f64, q: &[f64], v: &[f64], out: &mut [f64]) {
        let _ = (t, q, v, out);
    }

    /// G as its structural nonzeros, replacing the entries of `out` (nb×n). Default: every
    /// entry of [`Self::joint_jacobian`].
    fn joint_jacobian_entries(&self, t: f64, q: &[f64], out: &mut Triplets) {
        let g = out.rows() * q.len();
        let mut dense = vec![0.0; g];
        self.joint_jacobian(t, q, &mut dense);
        out.clear();
        out.extend_dense(&dense, true);
    }

    /// ∂(M(q) a)/∂q, n×n: how the inertia forces of the acceleration `a` change with the
    /// positions (a term of Newton's exact iteration matrix), replacing the entries of `out`.
    /// Default: none, exact for a constant mass matrix.
    fn mass_derivative(&self, q: &[f64], a: &[f64], out: &mut Triplets) {
        let _ = (q, a);
        out.clear();
    }

    /// ∂(G(q, t)ᵀ λ)/∂q = Σ_j λ_j ∇²g_j, n×n: how the joint forces change with the positions,
    /// replacing the entries of `out`. Default: none (no joints).
    fn joint_force_derivative(&self, t: f64, q: &[f64], lambda: &[f64], out: &mut Triplets) {
        let _ = (t, q, lambda);
        out.clear();
    }

    /// The derivatives of the joints' acceleration level g̈ = G(q, t) a + κ(t, q, v) at fixed
    /// a: ∂g̈/∂q into `dq` and ∂g̈/∂v = ∂κ/∂v into `dv`, nb×n each, replacing their entries.
    /// Default: none (no joints).
    fn joint_acceleration_derivatives(
        &self,
        t: f64,
        q: &[f64],
        v: &[f64],
        a: &[f64],
        dq: &mut Triplets,
        dv: &mut Triplets,
    ) {
        let _ = (t, q, v, a);
        dq.clear();
        dv.clear();
    }

    /// A band order of Newton's saddle-point matrix of the smooth stage (unknowns q̈ then λ),
    /// when the model knows its structure and a band LU pays ([`crate::soi2::banded`]).
    /// Default: none (dense LU).
    fn newton_band(&self) -> Option<&BandOrder> {
        None
    }

    /// The structure of the joints' Delassus operator G M⁻¹ Gᵀ when M is block diagonal and
    /// the operator has a band that pays ([`super::delassus`]): the position and velocity
    /// stages then form and factorise it from its sparse pieces. Default: none (dense).
    fn joint_structure(&self) -> Option<&JointStructure> {
        None
    }
}

/// The joints of a user model from its symbolic tapes; κ is the derivative of the tape of
/// G v + g_t along (t, q, v) → (1, v, 0), by one forward-mode dual evaluation.
impl JointedSystem for UserModel {
    fn joints(&self) -> usize {
        UserModel::joints(self)
    }

    fn joint_values(&self, t: f64, q: &[f64], out: &mut [f64]) {
        ConstrainedModel::g(self, t, q, out);
    }

    /// The band order of the model's one-block Newton pattern (coordinates, then joints).
    fn newton_band(&self) -> Option<&BandOrder> {
        self.newton_pattern(1).and_then(Pattern::band)
    }

    /// From the nonzero entries of M and the coordinates of each joint, found when the model
    /// was compiled.
    fn joint_structure(&self) -> Option<&JointStructure> {
        UserModel::joint_structure(self)
    }

    fn joint_jacobian(&self, t: f64, q: &[f64], out: &mut [f64]) {
        ConstrainedModel::g_y(self, t, q, out);
    }

    fn joint_rates(&self, t: f64, q: &[f64], v: &[f64], out: &mut [f64]) {
        ConstrainedModel::g_dot(self, t, q, v, out);
    }

    fn joint_curvature(&self, t: f64, q: &[f64], v: &[f64], out: &mut [f64]) {
        let td = Dual64::new(t, 1.0);
        let qd: Vec<Dual64> = q.iter().zip(v).map(|(&x, &w)| Dual64::new(x, w)).collect();
        let vd: Vec<Dual64> = v.iter().map(|&w| Dual64::from(w)).collect();
        let mut rd = vec![Dual64::from(0.0); out.len()];
        ConstrainedModel::g_dot(self, td, &qd, &vd, &mut rd);
        for (o, r) in out.iter_mut().zip(&rd) {
            *o = r.eps;
        }
    }

    /// The entries the tape of G stores.
    fn joint_jacobian_entries(&self, t: f64, q: &[f64], out: &mut Triplets) {
        out.clear();
        self.stored_entries(StoredMatrix::JointJacobian, t, q, |r, i, x| {
            out.push(r, i, x)
        });
    }

    /// One forward-mode dual evaluation of M's stored entries (its nonzeros) per group of
    /// coordinates whose columns share no row (the model's Newton pattern,
    /// [`crate::soi2::sparsity`]): (∂M/∂q_G a)_i = Σ_k ∂M_ik/∂q_G a_k over the nonzeros of
    /// row i, where q_G seeds the group's coordinates together.
    fn mass_derivative(&self, q: &[f64], a: &[f64], out: &mut Triplets) {
        let m = StoredMatrix::Mass;
        self.stored_derivative(m, 0.0, q, out, |i, k, d| (i, d * a[k]));
    }

    /// One forward-mode dual evaluation of G's stored entries per group of coordinates:
    /// (∂(Gᵀλ)/∂q_G)_i = Σ_r λ_r ∂G_ri/∂q_G over the nonzeros of column i of G.
    fn joint_force_derivative(&self, t: f64, q: &[f64], lambda: &[f64], out: &mut Triplets) {
        let g = StoredMatrix::JointJacobian;
        self.stored_derivative(g, t, q, out, |r, i, d| (i, d * lambda[r]));
    }

    /// g̈ as the derivative of the tape of G v + g_t along (1, v, a) ([`g_ddot`]), its
    /// derivatives by one more dual evaluation per group of coordinates, of q and of v.
    fn joint_acceleration_derivatives(
        &self,
        t: f64,
        q: &[f64],
        v: &[f64],
        a: &[f64],
        dq: &mut Triplets,
        dv: &mut Triplets,
    ) {
        let n = q.len();
        let (mut qd, mut vd, ad) = (duals(q), duals(v), duals(a));
        let td = Dual64::from(t);
        let mut out = vec![Dual64::from(0.0); UserModel::joints(self)];
        dq.clear();
        dv.clear();
        let pattern = self.newton_pattern(1);
        for group in coordinate_groups(n, pattern) {
            seed(&mut qd, &group, 1.0);
            g_ddot(self, td, &qd, &vd, &ad, &mut out);
            seed(&mut qd, &group, 0.0);
            push_joint_rows(n, pattern, &group, &out, dq);
            seed(&mut vd, &group, 1.0);
            g_ddot(self, td, &qd, &vd, &ad, &mut out);
            seed(&mut vd, &group, 0.0);
            push_joint_rows(n, pattern, &group, &out, dv);
        }
    }
}

impl UserModel {
    /// The derivative along each group of coordinates of an n-vector linear in the stored
    /// entries X_ik of `which` (at `t` and `q`): one dual evaluation of the entries per group;
    /// `term(i, k, ∂X_ik/∂q_G)` gives the row of the vector that entry adds to and how much,
    /// and the rows are pushed into `out` at the group's columns (each row is touched by one
    /// column of a group).
    fn stored_derivative(
        &self,
        which: StoredMatrix,
        t: f64,
        q: &[f64],
        out: &mut Triplets,
        term: impl Fn(usize, usize, f64) -> (usize, f64),
    ) {
        let n = q.len();
        let mut qd = duals(q);
        let mut rows = vec![0.0; n];
        out.clear();
        let pattern = self.newton_pattern(1);
        for group in coordinate_groups(n, pattern) {
            seed(&mut qd, &group, 1.0);
            rows.fill(0.0);
            self.stored_entries(which, Dual64::from(t), &qd, |i, k, x| {
                let (row, value) = term(i, k, x.eps);
                rows[row] += value;
            });
            seed(&mut qd, &group, 0.0);
            for &j in &group {
                for i in motion_rows(n, pattern, j) {
                    out.push(i, j, rows[i]);
                }
            }
        }
    }
}

/// Groups of coordinates whose columns share no row of the derivatives above (the coordinate
/// columns of the model's one-block Newton pattern, [`crate::soi2::sparsity::Pattern`]), or
/// one group per coordinate for a model without a pattern.
fn coordinate_groups(n: usize, pattern: Option<&Pattern>) -> Vec<Vec<usize>> {
    match pattern {
        Some(p) => p
            .groups()
            .iter()
            .map(|g| g.iter().copied().filter(|&c| c < n).collect::<Vec<_>>())
            .filter(|g| !g.is_empty())
            .collect(),
        None => (0..n).map(|j| vec![j]).collect(),
    }
}

/// The equations of motion (rows 0..n of the one-block pattern) that column `j` touches; all n
/// without a pattern.
fn motion_rows(n: usize, pattern: Option<&Pattern>, j: usize) -> impl Iterator<Item = usize> + '_ {
    let (rows, all) = match pattern {
        Some(p) => (p.rows_of(j), 0),
        None => (&[][..], n),
    };
    rows.iter().copied().filter(move |&i| i < n).chain(0..all)
}

/// Sets the dual parts of the coordinates of `group` to `eps`.
fn seed(x: &mut [Dual64], group: &[usize], eps: f64) {
    for &j in group {
        x[j].eps = eps;
    }
}

/// Pushes the derivative of each joint row along the column of `group` that touches it into
/// `into` (joints×n).
fn push_joint_rows(
    n: usize,
    pattern: Option<&Pattern>,
    group: &[usize],
    out: &[Dual64],
    into: &mut Triplets,
) {
    for &j in group {
        match pattern {
            Some(p) => {
                for r in p.rows_of(j).iter().filter(|&&i| i >= n).map(|i| i - n) {
                    into.push(r, j, out[r].eps);
                }
            }
            None => {
                for (r, o) in out.iter().enumerate() {
                    into.push(r, j, o.eps);
                }
            }
        }
    }
}

/// Constant dual numbers of `x` (no derivative direction yet).
fn duals(x: &[f64]) -> Vec<Dual64> {
    x.iter().map(|&v| Dual64::from(v)).collect()
}
