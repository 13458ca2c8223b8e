//! Nonlinear Lagrangian systems with unilateral contacts, and the time-stepping that runs them.
//!
//! The equations of motion are Lagrange's, with the contact impulses of Moreau's sweeping
//! process:
//!
//! ```text
//! M(q) dv = F(t, q, v) dt + Σ_α (∇g_α dP_α + ∇τ_α dP_t,α),   F = −∇V(q, t) − c(q, v) + f(t, q, v),
//! c(q, v) = Ṁ(q) v − ½ ∇_q(vᵀ M(q) v),               g_α(q, t) ≥ 0 with Newton's impact law,
//! ```
//!
//! with Coulomb's law on the tangential impulse P_t,α of a contact with friction μ_α (τ_α its
//! tangential relative position, [`LagrangianSystem::tangent_jacobian`]), where c is the Coriolis/centrifugal vector derived from M, V the potential (conservative
//! forces, part of the energy) and f the applied non-conservative forces (their work is
//! `work_ext`). [`LagrangianSystem`] is the interface an integrator needs: values and exact
//! Jacobians, no finite differences. The user models of `scene = "lagrangian"` implement it
//! from compiled expressions; a test can implement it by hand. [`moreau_jean`] runs it;
//! [`generalized_alpha`] (the nonsmooth generalized-α scheme) runs it with bilateral joints too
//! ([`joints::JointedSystem`]).

pub mod delassus;
pub mod generalized_alpha;
pub mod joints;
pub mod moreau_jean;
pub mod run;

use crate::triplets::Triplets;

/// A nonlinear mechanical system with unilateral contacts, as the nonlinear Moreau–Jean
/// time-stepping sees it. Matrices are row-major slices; sizes are [`Self::dofs`] = n and
/// [`Self::contacts`] = m. Every function is exact (closed form, symbolic or automatic
/// differentiation).
pub trait LagrangianSystem {
    /// Generalized coordinates n.
    fn dofs(&self) -> usize;

    /// Unilateral contacts m.
    fn contacts(&self) -> usize;

    /// Initial positions q₀ and velocities v₀.
    fn initial(&self) -> (Vec<f64>, Vec<f64>);

    /// Mass matrix M(q), n×n, symmetric positive definite.
    fn mass(&self, q: &[f64], out: &mut [f64]);

    /// Smooth generalized forces F(t, q, v) = −∇V − c(q, v) + f, n entries.
    fn forces(&self, t: f64, q: &[f64], v: &[f64], out: &mut [f64]);

    /// Jacobians ∂F/∂q and ∂F/∂v, n×n each (Newton's iteration matrix).
    fn force_jacobians(&self, t: f64, q: &[f64], v: &[f64], dq: &mut [f64], dv: &mut [f64]);

    /// M(q) as its structural nonzeros, replacing the entries of `out` (n×n): what an
    /// integrator reads when it multiplies with M or assembles a sparse Newton matrix from it.
    /// Default: every entry of [`Self::mass`].
    fn mass_entries(&self, q: &[f64], out: &mut Triplets) {
        let n = self.dofs();
        let mut m = vec![0.0; n * n];
        self.mass(q, &mut m);
        out.clear();
        out.extend_dense(&m, true);
    }

    /// ∂F/∂q and ∂F/∂v as their structural nonzeros, replacing the entries of `dq` and `dv`
    /// (n×n each). Default: every entry of [`Self::force_jacobians`].
    fn force_jacobian_entries(
        &self,
        t: f64,
        q: &[f64],
        v: &[f64],
        dq: &mut Triplets,
        dv: &mut Triplets,
    ) {
        let n = self.dofs();
        let (mut a, mut b) = (vec![0.0; n * n], vec![0.0; n * n]);
        self.force_jacobians(t, q, v, &mut a, &mut b);
        dq.clear();
        dq.extend_dense(&a, true);
        dv.clear();
        dv.extend_dense(&b, true);
    }

    /// The applied non-conservative forces f(t, q, v) alone, n entries (their work is
    /// `work_ext`).
    fn applied_forces(&self, t: f64, q: &[f64], v: &[f64], out: &mut [f64]);

    /// Potential energy V(q, t).
    fn potential(&self, t: f64, q: &[f64]) -> f64;

    /// Gaps g_α(q, t), m entries.
    fn gaps(&self, t: f64, q: &[f64], out: &mut [f64]);

    /// Gap Jacobian, m×n: row α is ∇_q g_α(q, t)ᵀ (the contact's normal direction in
    /// generalized coordinates, Gᵀ of the linear case).
    fn gap_jacobian(&self, t: f64, q: &[f64], out: &mut [f64]);

    /// ∂g_α/∂t (q, t), m entries: 0 for a fixed obstacle.
    fn gap_rates(&self, t: f64, q: &[f64], out: &mut [f64]);

    /// Newton restitution coefficient e_α ∈ [0, 1] of contact α.
    fn restitution(&self, alpha: usize) -> f64;

    /// Coulomb friction coefficient μ_α ≥ 0 of contact α. A system without friction keeps the
    /// default, 0 for every contact, and then needs no tangent.
    fn friction(&self, _alpha: usize) -> f64 {
        0.0
    }

    /// Tangent Jacobian, m×n: row α is ∇_q τ_α(q, t)ᵀ, the gradient of the tangential relative
    /// position τ_α (the tangent direction in generalized coordinates); the scheme reads the
    /// rows of the contacts with μ_α > 0 only. Default: zero rows (no contact has friction).
    fn tangent_jacobian(&self, _t: f64, _q: &[f64], out: &mut [f64]) {
        out.fill(0.0);
    }

    /// ∂τ_α/∂t (q, t), m entries: 0 for a fixed obstacle (the default).
    fn tangent_rates(&self, _t: f64, _q: &[f64], out: &mut [f64]) {
        out.fill(0.0);
    }
}
