//! Bilateral holonomic joints g(q, t) = 0 of a nonlinear Lagrangian system: the interface both
//! nonlinear time-steppings read ([`super::moreau_jean`] as equality rows of its mixed LCP,
//! [`super::generalized_alpha`] in its smooth, velocity and position stages), and its
//! implementation by the user models of `scene = "lagrangian"`.

use super::LagrangianSystem;
use super::delassus::JointStructure;
use crate::lagrangian::{StoredMatrix, UserModel};
use crate::soi2::ConstrainedModel;
use crate::soi2::banded::BandOrder;
use crate::soi2::sparsity::Pattern;
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

/// The joints of a user model from its symbolic tapes; κ and the derivatives of Newton's
/// matrix from those derived for the nonsmooth generalized-α ([`crate::lagrangian::newton_terms`]).
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

    /// From its symbolic tape ([`crate::lagrangian::UserModel::newton_terms`]).
    fn joint_curvature(&self, t: f64, q: &[f64], v: &[f64], out: &mut [f64]) {
        self.newton_terms().curvature(self, (t, q, v), out);
    }

    /// The entries the tape of G stores.
    fn joint_jacobian_entries(&self, t: f64, q: &[f64], out: &mut Triplets) {
        out.clear();
        out.reserve(self.stored_tape(StoredMatrix::JointJacobian).stored());
        self.stored_entries(StoredMatrix::JointJacobian, t, q, |r, i, x| {
            out.push(r, i, x)
        });
    }

    /// From its symbolic tape ([`crate::lagrangian::UserModel::newton_terms`]).
    fn mass_derivative(&self, q: &[f64], a: &[f64], out: &mut Triplets) {
        self.newton_terms().mass(self, q, a, out);
    }

    /// From its symbolic tape: Σ_r λ_r ∇²g_r over the nonzeros.
    fn joint_force_derivative(&self, t: f64, q: &[f64], lambda: &[f64], out: &mut Triplets) {
        self.newton_terms().joint_force(self, (t, q, lambda), out);
    }

    /// From the symbolic tape of the gradients of g̈ = d/dt(G v + g_t) along (1, v, a).
    fn joint_acceleration_derivatives(
        &self,
        t: f64,
        q: &[f64],
        v: &[f64],
        a: &[f64],
        dq: &mut Triplets,
        dv: &mut Triplets,
    ) {
        self.newton_terms()
            .joint_acceleration(self, (t, q, v, a), dq, dv);
    }
}
