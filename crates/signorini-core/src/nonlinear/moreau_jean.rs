//! The nonlinear Moreau–Jean time-stepping of Siconos' `MoreauJeanOSI` for a
//! [`LagrangianSystem`] with unilateral contacts (Acary & Brogliato 2008, ch. 10; Jean 1999,
//! "The non-smooth contact dynamics method"); for a linear system it is the scheme of Acary
//! 2016, (21)–(24), step for step.
//!
//! One step from (t_k, q_k, v_k) to t_{k+1} = t_k + h, with θ ∈ [0, 1]:
//!
//! ```text
//! q_{k+1} = q_k + h v_{k+θ},     v_{k+θ} = (1 − θ) v_k + θ v_{k+1}                         (21b)
//! R(v_{k+1}) = M(q_{k+1})(v_{k+1} − v_k) − h[(1 − θ) F(t_k, q_k, v_k)
//!              + θ F(t_{k+1}, q_{k+1}, v_{k+1})] − H(q_{k+1})ᵀ P_{k+1} = 0                 (21a)
//! U = H(q) v + ∂g/∂t,   0 ≤ U^α_{k+1} + e_α U^α_k ⊥ P^α_{k+1} ≥ 0 on the index set        (21c)–(21d)
//! ```
//!
//! with F = −∇V − c + f the smooth forces and H = ∂g/∂q the gap Jacobian. Newton's method on
//! v_{k+1} (iterates v^i, q^i = q_k + h((1 − θ) v_k + θ v^i), starting from v^0 = v_k) solves at
//! each iterate the linearised problem, as `MoreauJeanOSI` does:
//!
//! ```text
//! W^i = M(q^i) − hθ ∂F/∂v(t_{k+1}, q^i, v^i) − h²θ² ∂F/∂q(t_{k+1}, q^i, v^i)
//! v_free = v^i − (W^i)⁻¹ R_free(v^i),   R_free(v) = M(q^i)(v − v_k) − h[(1 − θ) F_k + θ F(t_{k+1}, q^i, v^i)]
//! W_c = H (W^i)⁻¹ Hᵀ  (Delassus operator, H = H(q^i), active contacts only)
//! 0 ≤ W_c P + H v_free + ∂g/∂t(t_{k+1}) + e ∘ U_k ⊥ P ≥ 0,   v^{i+1} = v_free + (W^i)⁻¹ Hᵀ P
//! ```
//!
//! The iteration matrix neglects, as Siconos does, the derivative of the mass matrix along the
//! step, hθ ∂M/∂q·(v^i − v_k), and the curvature of the gaps, hθ ∂(HᵀP)/∂q: W is exact for
//! constant M and affine gaps, and Newton converges linearly (not quadratically) otherwise. W is
//! factorised once per iterate by LU with partial pivoting (it is not symmetric when ∂F/∂v is
//! not). Newton stops when the residual at the new iterate, `R(v^{i+1})` with M, F and H all at
//! q^{i+1}, is below `tolerance` relative to the size of its terms (|M Δv| + h|F_θ| + |HᵀP|); for
//! a linear system that is after one iterate.
//!
//! The index set is decided at every iterate with the gaps linearised at the iterate q^i
//! (rule (24) of Acary 2016, or Siconos' predicted gap, [`IndexSetRule`]):
//!
//! ```text
//! (24):          g(q^i, t_{k+1}) + H(q^i)(q_k + h v_k − q^i) ≤ 0   and   U_k ≤ 0
//! predicted gap: g(q_k, t_k) + γ h U_k ≤ 0
//! ```
//!
//! with U_k = H(q^i) v_k + ∂g/∂t(q^i, t_k), the local velocity of the start of the step seen
//! through the same Jacobian as U_{k+1} (so that the contact work below has the sign of Lemma
//! 1); the sign test reads `U_k ≤` the round-off level of the previous step's LCP, as in
//! [`crate::contact::IndexSet`]. Within a step the index set only grows: a contact that entered
//! it at an iterate stays for the later ones. Without that, a lasting contact whose U_k is near
//! zero can enter and leave at alternate iterates and Newton cycles between two active sets
//! (seen on the rocking block); Siconos avoids it by fixing the index set before the Newton loop.
//!
//! Accuracy: for a constant M and θ = ½ the smooth part is the trapezoidal rule, second order
//! (the energy error over a fixed time shrinks as h²); with M(q) the term M(q_{k+1})(v_{k+1} − v_k)
//! is a first-order approximation of ∫ M(q) dv, and the scheme is first order, as Siconos'.
//!
//! Energy (Acary 2016, Lemma 1, extended to M(q) and V(q, t)): `kinetic` = ½ vᵀM(q)v,
//! `potential` = V(q, t), `energy` = kinetic + potential,
//! `work_ext` = h [(1 − θ) f_k + θ f_{k+1}] · v_{k+θ} (the applied forces f, trapezoidal in time,
//! against the velocity of (21b)), `work_contact` = P · H v_{k+θ} (= U_{k+θ}ᵀP on a fixed
//! obstacle, with the H of the last LCP: for θ = ½ and an impact,
//! ½(U_{k+1} + U_k)P = ½(1 − e)U_k P ≤ 0), and `energy_error` = ΔE − work_ext − work_contact.
//! For the linear scheme this is Lemma 1's balance with the numerical dissipation
//! (½ − θ)‖Δv‖²_M left in; for a nonlinear system it is the scheme's energy error, which for
//! θ = ½ shrinks as h² over a fixed time.
//!
//! Coulomb friction (planar: one tangent per contact; Moreau 1988; Jean 1999; Acary & Brogliato
//! 2008, ch. 12–13). A contact α with μ_α > 0 has a tangential relative position τ_α(q, t),
//! tangent row T_α = ∇_q τ_αᵀ and tangential local velocity U_t = T v + ∂τ/∂t. When some
//! contact of the index set has μ > 0, the iterate's one-step problem has the rows (H_α, T_α)
//! of every active contact, in the order (n_1, t_1, n_2, t_2, …): Delassus operator
//! `[H; T](W^i)⁻¹[H; T]ᵀ` (2k×2k), free local velocity `(U_free + e U_k, T v_free + ∂τ/∂t)`,
//! and [`crate::friction::solve_friction`] gives (P_n, P_t) with Signorini and Newton's law in
//! the normal rows and Coulomb's law on U_t,{k+1} in the tangent rows; the impulse adds
//! `(W^i)⁻¹(Hᵀ P_n + Tᵀ P_t)` to Δv and `Tᵀ P_t` joins `Hᵀ P` in Newton's residual. Without
//! friction on the index set the step is the frictionless one, operation for operation.
//!
//! `work_friction` = Σ_α P_t,α (θ U_t,{k+1} + (1 − θ) U_t,k): the friction impulse against the
//! tangential local velocity of the step as the scheme writes it, U_t,{k+1} = T(q^i) v_{k+1} +
//! ∂τ/∂t the velocity of the last solve (on which Coulomb's law holds) and U_t,k the one at the
//! end of the previous step. Derivation: multiplying (21a) by v_{k+θ} turns each impulse term
//! into its work; the normal term gives `work_contact` = P_n · H v_{k+θ}, and the tangent term,
//! new with friction, P_t · T v_{k+θ} = P_t (θ T v_{k+1} + (1 − θ) T v_k). For a constant T (a
//! linear system, a fixed obstacle) T v_k is U_t,k and this is the definition above, so that
//! `energy_error` = ΔE − work_ext − work_contact − work_friction closes (at round-off for a
//! linear system, with Lemma 1's numerical dissipation (½ − θ)‖Δv‖²_M left in). For a T(q) the
//! two differ by (1 − θ) P_t (T(q^i) − T(q_k)) v_k = O(h²) per step, which stays in
//! `energy_error` (the scheme's error): with T(q^i) v_k a sticking pivot that turns (the
//! rocking block) would show a spurious ±O(h²) friction work although nothing slides.
//! Sign: Coulomb's law on U_t,{k+1} makes P_t U_t,{k+1} = −μ P_n |U_t,{k+1}| ≤ 0 (0 when
//! sticking); the term (1 − θ) P_t U_t,k is ≤ 0 unless the friction impulse points along the
//! start velocity, which needs U_t to reverse within the step (at an impact, through the
//! normal impulse's coupling: Kane's double-pendulum paradox). On such a step `work_friction`
//! is θ P_t U_t,{k+1} and the rest of the tangential impulse's work is counted in
//! `work_contact` ([`crate::friction::split_tangential_work`]): work_friction ≤ 0 at every step,
//! unchanged on every step without a reversal, and the sum work_contact + work_friction, hence
//! `energy_error`, is the impulses' work of (21a) as before.
//!
//! Lasting contacts with friction: the sign test of (24) already reads U_k ≤ its round-off
//! level u_ro; with friction the gap test reads g(q_k + h v_k) ≤ t_{k+1} u_ro as well. A
//! sliding or sticking block whose U_n is zero only up to round-off drifts off the plane by up
//! to h u_ro per step, so by at most t u_ro since t = 0 (seen: a block sliding on a slope
//! drifts by 4e-18 in 80 steps, always upwards); without the tolerance the contact leaves the
//! index set for one step, and with it the friction (the block then gains g μ cos α h). A
//! contact that separates has U_k > u_ro and still leaves. A frictionless system keeps the
//! strict test (its results are unchanged).
//!
//! Bilateral joints g(q, t) = 0 ([`JointedSystem`], nb of them; Acary & Brogliato 2008, ch. 10,
//! with the joints as equality rows of the one-step problem, Siconos' `EqualityConditionNSL`
//! in a mixed LCP). The joints are held at the position level of the step, g(q_{k+1}, t_{k+1})
//! = 0 with q_{k+1} = q_k + h v_{k+θ}; (21a) gains the joint impulse G_midᵀ Λ_{k+1}, along the
//! joint Jacobian at the midpoint of the step, G_mid = G(½(q_k + q_{k+1}), t_{k+½}). At each
//! Newton iterate the joint condition is linearised in v_{k+1} at q^i (∂q_{k+1}/∂v_{k+1} = hθ
//! exactly): `G(q^i) Δv = G(q^i) Δv^i − g(q^i, t_{k+1})/(hθ)`, so that θ > 0 is required; with
//! the contact rows of the index set this is the mixed LCP
//!
//! ```text
//! [G(q^i); H](W^i)⁻¹[G_mid; H]ᵀ (Λ, P) + (G(q^i) Δv_free − target, U_free + e U_k):
//!     = 0 in the joint rows,   0 ≤ … ⊥ P ≥ 0 in the contact rows
//! ```
//!
//! solved by [`crate::lcp::solve_mixed`] (the joint rows eliminated by their Schur complement:
//! the joints must be independent). Newton's residual gains −G_midᵀΛ, and Newton stops only
//! when the joint violation max_j |g_j(q^{i+1})| is below the tolerance as well, relative to
//! the joints' scale max_j Σ_i |G_ji| (|q_i| + |Δq_i|): the joints hold to Newton's tolerance
//! at every step (`position_residual`). Why the midpoint: the joint impulse's work over the
//! step is Λ·G_mid v_{k+θ} = Λ·G_mid (q_{k+1} − q_k)/h, which for a joint quadratic in q (a
//! rod, a pin: g = ½(|x_i − x_j|² − L²)) is exactly Λ(g(q_{k+1}) − g(q_k))/h = 0: ideal joints
//! do no work, and `energy_error` keeps its meaning (for θ = ½, a constant M and a linear
//! potential it is at the Newton tolerance between impacts). For other joints this work,
//! O(h³)Λ/h per step, stays in `energy_error`.
//!
//! Joints and friction together: when some contact of the index set has μ > 0 the one-step
//! problem is a planar friction problem with equality rows, on the rows `[G(q^i); H_α; T_α]`.
//! The joint rows are condensed out exactly, as the rigid bodies' joints are
//! ([`crate::rigid`]): Λ = −A⁺(b_B + D_BI P) with A = G(q^i)(W^i)⁻¹G_midᵀ and A⁺ its inverse
//! (its minimum-norm least-squares solve for dependent joints), which leaves the contacts'
//! friction problem on the condensed Delassus operator W' = D_II − D_IB A⁺ D_BI and free
//! velocity q' = b_I − D_IB A⁺ b_B; its (P_n, P_t) give Λ back (`condensed_friction_problem`).
//! Newton's residual gains −G_midᵀΛ and −TᵀP_t, the works are those above (ideal joints do no
//! work, the friction impulse's work split by [`crate::friction::split_tangential_work`]).
//! Without friction on the index set the step is the mixed LCP's, operation for operation.

use super::LagrangianSystem;
use super::joints::JointedSystem;
use crate::contact::{Activation, IndexSetRule, LcpStats};
use crate::dense::{amax, dot, lu_factor_with};
use crate::friction::{self, FrictionError, FrictionProblem};
use crate::lcp::{
    self, EqualityElimination, Lcp, LcpError, LcpOptions, MixedLcp, MixedLcpError, MixedSolution,
    solve_mixed,
};
use crate::observer::Columns;
use crate::soi2::banded::{BandLu, BandOrder};
use crate::stepping;
use crate::triplets::Triplets;
use nalgebra::{DMatrix, DVectorViewMut};
use thiserror::Error;

/// Names of the per-step energy columns of a nonlinear run, in output order.
pub const NONLINEAR_ENERGY_COLUMNS: [&str; 6] = [
    "kinetic",
    "potential",
    "energy",
    "work_ext",
    "work_contact",
    "energy_error",
];

/// Names of the columns that follow [`NONLINEAR_ENERGY_COLUMNS`]: the cumulative works and the
/// step's Newton iterations.
pub const NONLINEAR_RUN_COLUMNS: [&str; 3] =
    ["work_ext_total", "work_contact_total", "newton_iterations"];

/// The friction columns of a run whose model has friction (μ > 0 on some contact), after the
/// run columns: the step's friction work and its cumulative sum.
pub const FRICTION_COLUMNS: [&str; 2] = ["work_friction", "work_friction_total"];

/// Newton's settings. Defaults: tolerance 1e-10, 20 iterations.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NewtonOptions {
    /// Largest residual accepted, relative to the size of the residual's terms (> 0).
    pub tolerance: f64,
    /// Largest number of iterates (≥ 1); one LU factorisation and one LCP each.
    pub max_iterations: usize,
}

impl Default for NewtonOptions {
    fn default() -> Self {
        Self {
            tolerance: 1e-10,
            max_iterations: 20,
        }
    }
}

/// Parameters of the nonlinear Moreau–Jean scheme.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NonlinearMoreauJeanParams {
    /// θ ∈ [0, 1], default ½ (see [`crate::integrators::moreau_jean::MoreauJeanParams`]).
    pub theta: f64,
    /// Index-set rule, (24) by default.
    pub index_set: IndexSetRule,
    /// Newton's settings.
    pub newton: NewtonOptions,
}

impl Default for NonlinearMoreauJeanParams {
    /// θ = ½, rule (24), [`NewtonOptions::default`].
    fn default() -> Self {
        Self {
            theta: 0.5,
            index_set: IndexSetRule::default(),
            newton: NewtonOptions::default(),
        }
    }
}

/// A parameter of the scheme is out of range.
#[derive(Debug, Clone, PartialEq, Error)]
#[error("{field}: {reason}")]
pub struct ParamError {
    /// The parameter.
    pub field: &'static str,
    /// What is wrong with it.
    pub reason: String,
}

/// Why a step failed. `step` and `t` are those of the state the step was to reach.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum NonlinearStepError {
    /// Newton's method did not reach its tolerance.
    #[error(
        "step {step} (t = {t}): Newton did not converge in {iterations} iterations (relative residual {residual:e}, tolerance {tolerance:e})"
    )]
    NewtonNotConverged {
        /// Step number.
        step: u64,
        /// Time t_{k+1}.
        t: f64,
        /// Iterations done.
        iterations: usize,
        /// Relative residual of the last iterate.
        residual: f64,
        /// Tolerance asked.
        tolerance: f64,
    },
    /// The iteration matrix W = M − hθ ∂F/∂v − h²θ² ∂F/∂q is singular.
    #[error(
        "step {step} (t = {t}): the iteration matrix is singular (Newton iteration {iteration})"
    )]
    Singular {
        /// Step number.
        step: u64,
        /// Time t_{k+1}.
        t: f64,
        /// Newton iteration (from 1).
        iteration: usize,
    },
    /// A value of the system or of the state is NaN or infinite: which value, its first
    /// entry that is not finite, and the state it was evaluated at (so a user can find the
    /// expression and the configuration that broke it).
    #[error(
        "step {step} (t = {t}): {what} is not finite{}",
        where_not_finite(*.component, *.value, .q, .v)
    )]
    NotFinite {
        /// Step number.
        step: u64,
        /// Time the value was evaluated at.
        t: f64,
        /// Which value.
        what: &'static str,
        /// Its first entry that is not finite (row-major for a matrix), when it is a vector or
        /// matrix.
        component: Option<usize>,
        /// That entry (NaN or ±∞), or the scalar value.
        value: f64,
        /// The positions it was evaluated at (empty when the value does not depend on them).
        q: Vec<f64>,
        /// The velocities it was evaluated at (empty when the value does not depend on them).
        v: Vec<f64>,
    },
    /// The impulse LCP could not be solved to tolerance.
    #[error("step {step} (t = {t}): contact LCP failed: {source}")]
    Lcp {
        /// Step number.
        step: u64,
        /// Time t_{k+1}.
        t: f64,
        /// The solver's error.
        source: LcpError,
    },
    /// The friction problem of the step (some contact of the index set has μ > 0) could not
    /// be solved to tolerance.
    #[error("step {step} (t = {t}): contact friction problem failed: {source}")]
    Friction {
        /// Step number.
        step: u64,
        /// Time t_{k+1}.
        t: f64,
        /// The solver's error.
        source: FrictionError,
    },
}

/// State of a nonlinear system at t_k.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct NonlinearState {
    /// Step number k.
    pub step: u64,
    /// Time t_k.
    pub t: f64,
    /// Positions q_k.
    pub q: Vec<f64>,
    /// Velocities v_k.
    pub v: Vec<f64>,
}

impl NonlinearState {
    /// The system's initial state at t = 0.
    pub fn initial<S: LagrangianSystem + ?Sized>(system: &S) -> Self {
        let (q, v) = system.initial();
        Self {
            step: 0,
            t: 0.0,
            q,
            v,
        }
    }
}

/// What one step produced besides the new state.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct NonlinearStepReport {
    /// ½ vᵀM(q)v at t_{k+1}.
    pub kinetic: f64,
    /// V(q, t) at t_{k+1}.
    pub potential: f64,
    /// Discrete work of the applied forces over the step.
    pub work_ext: f64,
    /// Discrete work of the contact impulses over the step.
    pub work_contact: f64,
    /// Discrete work of the friction impulses over the step, `Σ P_t,α T_α(q) v_{k+θ}`.
    pub work_friction: f64,
    /// ΔE − work_ext − work_contact − work_friction.
    pub energy_error: f64,
    /// Gap g_α(q_{k+1}, t_{k+1}).
    pub gap: Vec<f64>,
    /// Local velocity U_{k+1} = H(q_{k+1}) v_{k+1} + ∂g/∂t.
    pub local_velocity: Vec<f64>,
    /// Impulse P_{k+1}.
    pub impulse: Vec<f64>,
    /// Tangential impulse P_t,{k+1} (zero for contacts without friction).
    pub tangent_impulse: Vec<f64>,
    /// Tangential local velocity U_t,{k+1} = T(q_{k+1}) v_{k+1} + ∂τ/∂t (zero when the system
    /// has no friction).
    pub tangent_velocity: Vec<f64>,
    /// The last LCP (or friction problem) of the step.
    pub lcp: LcpStats,
    /// Newton iterates of the step.
    pub newton_iterations: usize,
    /// Largest joint violation max_j |g_j(q_{k+1}, t_{k+1})| (0 for a system without joints).
    pub position_residual: f64,
}

impl NonlinearStepReport {
    /// Mechanical energy kinetic + potential.
    pub fn energy(&self) -> f64 {
        self.kinetic + self.potential
    }

    /// A report of the state `state` (no step taken: works zero).
    pub fn of_state<S: LagrangianSystem + ?Sized>(system: &S, state: &NonlinearState) -> Self {
        let (n, m) = (system.dofs(), system.contacts());
        let mut mass = Triplets::new(n, n);
        system.mass_entries(&state.q, &mut mass);
        let mut report = Self {
            kinetic: kinetic(&mass, &state.v, &mut vec![0.0; n]),
            potential: system.potential(state.t, &state.q),
            gap: vec![0.0; m],
            local_velocity: vec![0.0; m],
            impulse: vec![0.0; m],
            tangent_impulse: vec![0.0; m],
            tangent_velocity: vec![0.0; m],
            ..Default::default()
        };
        let mut jac = vec![0.0; m * n];
        system.gaps(state.t, &state.q, &mut report.gap);
        system.gap_jacobian(state.t, &state.q, &mut jac);
        system.gap_rates(state.t, &state.q, &mut report.local_velocity);
        for (a, u) in report.local_velocity.iter_mut().enumerate() {
            *u += dot(&jac[a * n..(a + 1) * n], &state.v);
        }
        if has_friction(system) {
            system.tangent_jacobian(state.t, &state.q, &mut jac);
            system.tangent_rates(state.t, &state.q, &mut report.tangent_velocity);
            for (a, u) in report.tangent_velocity.iter_mut().enumerate() {
                *u += dot(&jac[a * n..(a + 1) * n], &state.v);
            }
        }
        report
    }
}

/// The values at the end of one step kept for the next (they are the start of the next step),
/// with the state they belong to: a state changed between steps is evaluated afresh.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
struct EndOfStep {
    step: u64,
    t: f64,
    q: Vec<f64>,
    v: Vec<f64>,
    forces: Vec<f64>,
    applied: Vec<f64>,
    gaps: Vec<f64>,
    /// Tangential local velocities U_t,k (friction only; empty otherwise).
    tangent_velocity: Vec<f64>,
    energy: f64,
}

/// What the next step of the scheme reads besides the state (q_k, v_k): the end of the last
/// step (F_k, f_k, g(q_k), U_t,k, E_k) and the round-off levels of its local velocities, which
/// the sign test of the index set (24) reads. This, and nothing of [`Scratch`], is what a
/// checkpoint keeps of the scheme.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(crate) struct MoreauJeanMemory {
    last: Option<EndOfStep>,
    /// Step whose end state `roundoff` belongs to (`u64::MAX`: none yet).
    roundoff_step: u64,
    /// Round-off level of U^α at the end of that step (zero when inactive).
    roundoff: Vec<f64>,
}

/// Where a step is going (its number k + 1 and time t_{k+1}), for the errors of its phases.
#[derive(Debug, Clone, Copy)]
pub(crate) struct StepAt {
    pub(crate) step: u64,
    pub(crate) t: f64,
}

/// The part of a [`NonlinearStepError::NotFinite`] message after "is not finite": the entry
/// and the state, when known.
fn where_not_finite(component: Option<usize>, value: f64, q: &[f64], v: &[f64]) -> String {
    let mut text = match component {
        Some(i) => format!(" (entry {i} is {value})"),
        None => format!(" ({value})"),
    };
    if !q.is_empty() {
        text.push_str(&format!(" at q = {q:?}"));
    }
    if !v.is_empty() {
        text.push_str(&format!(", v = {v:?}"));
    }
    text
}

impl StepAt {
    /// Newton stopped after `iterations` with the relative `residual` still above `tolerance`.
    pub(crate) fn newton_not_converged(
        self,
        iterations: usize,
        residual: f64,
        tolerance: f64,
    ) -> NonlinearStepError {
        NonlinearStepError::NewtonNotConverged {
            step: self.step,
            t: self.t,
            iterations,
            residual,
            tolerance,
        }
    }

    /// A scalar value of the system or of the state (`value`) is not finite.
    pub(crate) fn not_finite(self, what: &'static str, value: f64) -> NonlinearStepError {
        NonlinearStepError::NotFinite {
            step: self.step,
            t: self.t,
            what,
            component: None,
            value,
            q: Vec::new(),
            v: Vec::new(),
        }
    }

    /// Refuses `x` unless every entry is finite (the error names the first entry that is not).
    pub(crate) fn check(self, x: &[f64], what: &'static str) -> Result<(), NonlinearStepError> {
        self.check_at(x, what, &[], &[])
    }

    /// Refuses `x`, evaluated at positions `q` and velocities `v` (either may be empty when
    /// `x` does not depend on it), unless every entry is finite; the error names the first
    /// entry that is not and the state.
    pub(crate) fn check_at(
        self,
        x: &[f64],
        what: &'static str,
        q: &[f64],
        v: &[f64],
    ) -> Result<(), NonlinearStepError> {
        match x.iter().position(|a| !a.is_finite()) {
            None => Ok(()),
            Some(i) => Err(NonlinearStepError::NotFinite {
                step: self.step,
                t: self.t,
                what,
                component: Some(i),
                value: x[i],
                q: q.to_vec(),
                v: v.to_vec(),
            }),
        }
    }

    /// [`StepAt::check_at`] for a sparse matrix: the error names the first entry that is not
    /// finite by its row-major index.
    pub(crate) fn check_entries_at(
        self,
        x: &Triplets,
        what: &'static str,
        q: &[f64],
        v: &[f64],
    ) -> Result<(), NonlinearStepError> {
        match x.first_non_finite() {
            None => Ok(()),
            Some((i, value)) => Err(NonlinearStepError::NotFinite {
                step: self.step,
                t: self.t,
                what,
                component: Some(i),
                value,
                q: q.to_vec(),
                v: v.to_vec(),
            }),
        }
    }

    /// The iteration matrix of Newton iteration `iteration` is singular.
    pub(crate) fn singular(self, iteration: usize) -> NonlinearStepError {
        NonlinearStepError::Singular {
            step: self.step,
            t: self.t,
            iteration,
        }
    }

    /// The impulse LCP failed.
    pub(crate) fn lcp(self, source: LcpError) -> NonlinearStepError {
        NonlinearStepError::Lcp {
            step: self.step,
            t: self.t,
            source,
        }
    }
}

/// What Newton's loop of a step hands to its end: its iterates and the impulses' works of the
/// last one.
struct NewtonOutcome {
    iterations: usize,
    work_contact: f64,
    work_friction: f64,
}

/// The nonlinear Moreau–Jean scheme for one system and one step size. Holds its parameters, its
/// memory of the last step and scratch buffers; the state comes in explicitly.
#[derive(Debug, Clone)]
pub struct NonlinearMoreauJean {
    params: NonlinearMoreauJeanParams,
    h: f64,
    lcp: LcpOptions,
    n: usize,
    m: usize,
    /// Joints nb (bilateral rows of the one-step problem).
    nb: usize,
    /// μ_α per contact.
    mu: Vec<f64>,
    /// Whether some contact has μ > 0 (the tangent rows are then formed where needed).
    friction: bool,
    memory: MoreauJeanMemory,
    /// The band order of W = M − hθ ∂F/∂v − h²θ² ∂F/∂q when its structure makes the band LU
    /// pay (a large model with sparse matrices, [`BandOrder::of_pattern`]); else W is
    /// factorised densely.
    band: Option<BandOrder>,
    s: Scratch,
}

/// The buffers one step works in; nothing here is read by the next step.
#[derive(Debug, Clone)]
struct Scratch {
    /// M(q) at the iterate, as its entries.
    mass: Triplets,
    /// ∂F/∂q and ∂F/∂v at the iterate, as their entries.
    dfdq: Triplets,
    dfdv: Triplets,
    /// M Δv (or M v for the kinetic energy).
    mass_times: Vec<f64>,
    /// The entries of W (band path).
    w_entries: Vec<(usize, usize, f64)>,
    forces: Vec<f64>,
    applied: Vec<f64>,
    jac: Vec<f64>,
    gaps: Vec<f64>,
    rates_next: Vec<f64>,
    rates_k: Vec<f64>,
    q: Vec<f64>,
    v: Vec<f64>,
    dv: Vec<f64>,
    residual: Vec<f64>,
    predicted: Vec<f64>,
    active: Vec<usize>,
    /// Contacts that entered the index set at an earlier iterate of the step.
    member: Vec<bool>,
    rhs: Vec<f64>,
    /// Tangent Jacobian, m×n (friction only).
    tjac: Vec<f64>,
    /// ∂τ/∂t at t_{k+1}, m entries (friction only).
    trates: Vec<f64>,
    /// Whether the current iterate solved a friction problem (rows H_α and T_α) rather than
    /// the frictionless LCP (rows H_α).
    friction_step: bool,
    /// Columns (W^i)⁻¹ H_αᵀ of the active contacts, n each; with friction (W^i)⁻¹ H_αᵀ,
    /// (W^i)⁻¹ T_αᵀ per contact, in the order (n_1, t_1, n_2, t_2, …).
    columns: Vec<f64>,
    /// The Delassus operator on the same rows, row-major.
    delassus: Vec<f64>,
    /// Free local velocity of the friction problem, μ of its contacts, and the impulses of
    /// the last solve (in the order of `columns`).
    friction_q: Vec<f64>,
    friction_mu: Vec<f64>,
    solution: Vec<f64>,
    /// Joint Jacobian G(q^i), nb×n: the rows of the joint condition of the iterate.
    joint_rows: Vec<f64>,
    /// Joint Jacobian at the midpoint, G(½(q_k + q^i)), nb×n: the direction of the joint
    /// impulses (module documentation).
    joint_directions: Vec<f64>,
    /// g(q, t_{k+1}) at the iterate, nb entries.
    joint_values: Vec<f64>,
    /// Right-hand side of the joint rows, G(q^i) Δv^i − g(q^i, t_{k+1})/(hθ).
    joint_target: Vec<f64>,
    /// Joint impulses Λ of the last solve.
    joint_impulse: Vec<f64>,
    /// Joint rows at the head of the last one-step problem (nb with joints, else 0).
    offset: usize,
    /// The midpoint ½(q_k + q) of the iterate.
    midpoint: Vec<f64>,
    /// The column maxima of W^i, for the singularity test of its LU factors.
    column_max: Vec<f64>,
}

impl NonlinearMoreauJean {
    /// Prepares the scheme for `system` with step `h`.
    pub fn new<S: JointedSystem + ?Sized>(
        system: &S,
        params: NonlinearMoreauJeanParams,
        h: f64,
        lcp: LcpOptions,
    ) -> Result<Self, ParamError> {
        let bad = |field, reason: &str| {
            Err(ParamError {
                field,
                reason: reason.to_string(),
            })
        };
        if !(h > 0.0 && h.is_finite()) {
            return bad("h", "must be positive and finite");
        }
        if !(0.0..=1.0).contains(&params.theta) {
            return bad("theta", "must be in [0, 1]");
        }
        if params.index_set.activation == Activation::PredictedGap
            && !(params.index_set.gamma.is_finite() && params.index_set.gamma >= 0.0)
        {
            return bad("gamma", "must be finite and ≥ 0");
        }
        if !(params.newton.tolerance > 0.0 && params.newton.tolerance.is_finite()) {
            return bad("newton.tolerance", "must be positive and finite");
        }
        if params.newton.max_iterations == 0 {
            return bad("newton.max_iterations", "must be at least 1");
        }
        let (n, m, nb) = (system.dofs(), system.contacts(), system.joints());
        let z = |k| vec![0.0; k];
        let mu: Vec<f64> = (0..m).map(|a| system.friction(a)).collect();
        let friction = mu.iter().any(|&x| x > 0.0);
        if nb > 0 && params.theta == 0.0 {
            return bad(
                "theta",
                "must be > 0 for a system with joints: they are held at q_{k+1} = q_k + h v_{k+θ}, which does not depend on v_{k+1} when θ = 0",
            );
        }
        let fm = if friction { m } else { 0 };
        Ok(Self {
            params,
            h,
            lcp,
            n,
            m,
            nb,
            mu,
            friction,
            memory: MoreauJeanMemory {
                last: None,
                roundoff_step: u64::MAX,
                roundoff: z(m),
            },
            band: iteration_matrix_band(system),
            s: Scratch {
                mass: Triplets::new(n, n),
                dfdq: Triplets::new(n, n),
                dfdv: Triplets::new(n, n),
                mass_times: z(n),
                w_entries: Vec::new(),
                forces: z(n),
                applied: z(n),
                jac: z(m * n),
                gaps: z(m),
                rates_next: z(m),
                rates_k: z(m),
                q: z(n),
                v: z(n),
                dv: z(n),
                residual: z(n),
                predicted: z(n),
                active: Vec::with_capacity(m),
                member: vec![false; m],
                rhs: Vec::with_capacity(m),
                tjac: z(fm * n),
                trates: z(fm),
                friction_step: false,
                columns: Vec::with_capacity(m * n),
                delassus: Vec::with_capacity(m * m),
                friction_q: Vec::with_capacity(2 * fm),
                friction_mu: Vec::with_capacity(fm),
                solution: Vec::with_capacity(2 * m + nb),
                joint_rows: z(nb * n),
                joint_directions: z(nb * n),
                joint_values: z(nb),
                joint_target: z(nb),
                joint_impulse: z(nb),
                offset: 0,
                midpoint: z(if nb > 0 { n } else { 0 }),
                column_max: z(n),
            },
        })
    }

    /// Step size h.
    pub fn step_size(&self) -> f64 {
        self.h
    }

    /// What the next step reads besides the state (for a checkpoint).
    pub(crate) fn memory(&self) -> &MoreauJeanMemory {
        &self.memory
    }

    /// Restores the memory of a checkpoint; refused when it does not fit the system.
    pub(crate) fn restore(
        &mut self,
        memory: MoreauJeanMemory,
    ) -> Result<(), crate::checkpoint::CheckpointError> {
        if memory.roundoff.len() != self.m {
            return Err(crate::checkpoint::CheckpointError::Mismatch(format!(
                "a nonlinear Moreau–Jean memory of {} contacts, the system has {}",
                memory.roundoff.len(),
                self.m
            )));
        }
        self.memory = memory;
        Ok(())
    }

    /// Advances `state` by one step, writing the step's terms into `report` (sized by
    /// [`NonlinearStepReport::of_state`]). The phases, in Siconos' words: the start of the step
    /// (kept from the last one), the free state of iterate 0, Newton's loop (per iterate: the
    /// iteration matrix, the free velocity, the index set, the one-step nonsmooth problem, the
    /// works and the new iterate), the round-off levels of the index set, and the update of the
    /// state with the step's energy terms.
    pub fn step<S: JointedSystem + ?Sized>(
        &mut self,
        system: &S,
        state: &mut NonlinearState,
        report: &mut NonlinearStepReport,
    ) -> Result<(), NonlinearStepError> {
        let step = state.step + 1;
        let at = StepAt {
            step,
            t: (step as f64) * self.h,
        };
        let start = self.start_of_step(system, state, at)?;
        self.free_state(system, state, at)?;
        let newton = self.newton(system, state, &start, report, at)?;
        self.keep_roundoff(step);
        self.finish(system, state, start, newton, report, at)
    }

    /// The start of the step: F_k, f_k, g(q_k, t_k), U_t,k and E_k, kept from the last step
    /// when `state` is its end, evaluated afresh otherwise.
    fn start_of_step<S: JointedSystem + ?Sized>(
        &mut self,
        system: &S,
        state: &NonlinearState,
        at: StepAt,
    ) -> Result<EndOfStep, NonlinearStepError> {
        let (n, m, t_k) = (self.n, self.m, state.t);
        if let Some(e) = self.memory.last.take()
            && e.step == state.step
            && e.t == state.t
            && e.q == state.q
            && e.v == state.v
        {
            return Ok(e);
        }
        let mut e = EndOfStep {
            step: state.step,
            t: t_k,
            q: state.q.clone(),
            v: state.v.clone(),
            forces: vec![0.0; n],
            applied: vec![0.0; n],
            gaps: vec![0.0; m],
            tangent_velocity: Vec::new(),
            energy: 0.0,
        };
        system.forces(t_k, &state.q, &state.v, &mut e.forces);
        at.check_at(&e.forces, "F(t, q, v)", &state.q, &state.v)?;
        system.applied_forces(t_k, &state.q, &state.v, &mut e.applied);
        at.check_at(
            &e.applied,
            "the applied forces f(t, q, v)",
            &state.q,
            &state.v,
        )?;
        system.gaps(t_k, &state.q, &mut e.gaps);
        at.check_at(&e.gaps, "a gap g(q, t)", &state.q, &[])?;
        system.mass_entries(&state.q, &mut self.s.mass);
        e.energy = kinetic(&self.s.mass, &state.v, &mut self.s.mass_times)
            + system.potential(t_k, &state.q);
        if self.friction {
            e.tangent_velocity = vec![0.0; m];
            system.tangent_jacobian(t_k, &state.q, &mut self.s.tjac);
            at.check(&self.s.tjac, "the tangent Jacobian")?;
            system.tangent_rates(t_k, &state.q, &mut e.tangent_velocity);
            for (a, u) in e.tangent_velocity.iter_mut().enumerate() {
                *u += dot(&self.s.tjac[a * n..(a + 1) * n], &state.v);
            }
            at.check(&e.tangent_velocity, "a tangential velocity")?;
        }
        if !e.energy.is_finite() {
            return Err(at.not_finite("the energy", e.energy));
        }
        Ok(e)
    }

    /// The free state of iterate 0: v^0 = v_k, q^0 = q_k + h v_k, M(q^0), F(t_{k+1}, q^0, v^0),
    /// and q_k + h v_k, the point (24) predicts the gaps at.
    fn free_state<S: JointedSystem + ?Sized>(
        &mut self,
        system: &S,
        state: &NonlinearState,
        at: StepAt,
    ) -> Result<(), NonlinearStepError> {
        let (h, theta, s) = (self.h, self.params.theta, &mut self.s);
        s.dv.fill(0.0);
        position(&state.q, &state.v, &s.dv, h, theta, &mut s.q);
        s.v.copy_from_slice(&state.v);
        system.mass_entries(&s.q, &mut s.mass);
        at.check_entries_at(&s.mass, "M(q)", &s.q, &[])?;
        system.forces(at.t, &s.q, &s.v, &mut s.forces);
        at.check_at(&s.forces, "F(t, q, v)", &s.q, &s.v)?;
        for ((p, q), v) in s.predicted.iter_mut().zip(&state.q).zip(&state.v) {
            *p = q + h * v;
        }
        Ok(())
    }

    /// Newton's method on v_{k+1} (module documentation): per iterate the iteration matrix,
    /// the free velocity, the index set, the one-step nonsmooth problem, the works and the new
    /// iterate, until the residual is below the tolerance.
    fn newton<S: JointedSystem + ?Sized>(
        &mut self,
        system: &S,
        state: &NonlinearState,
        start: &EndOfStep,
        report: &mut NonlinearStepReport,
        at: StepAt,
    ) -> Result<NewtonOutcome, NonlinearStepError> {
        let newton = self.params.newton;
        self.s.member.fill(false);
        let mut outcome = NewtonOutcome {
            iterations: 0,
            work_contact: 0.0,
            work_friction: 0.0,
        };
        let mut residual = f64::INFINITY;
        report.impulse.fill(0.0);
        report.tangent_impulse.fill(0.0);
        report.lcp = LcpStats::default();
        while outcome.iterations < newton.max_iterations {
            outcome.iterations += 1;
            let lu = self.iteration_matrix(system, at, outcome.iterations)?;
            if self.nb > 0 {
                self.joint_condition(system, state, at)?;
            }
            self.free_velocity(&lu, start, at)?;
            self.update_index_set(system, state, start, report, at)?;
            if self.nb > 0 && self.s.active.iter().any(|&a| self.mu[a] > 0.0) {
                self.condensed_friction_problem(
                    system,
                    &lu,
                    state,
                    report,
                    at,
                    outcome.iterations,
                )?;
            } else if self.nb > 0 {
                self.mixed_problem(&lu, report, at, outcome.iterations)?;
            } else if !self.s.active.is_empty() {
                self.one_step_problem(system, &lu, state, report, at)?;
            }
            (outcome.work_contact, outcome.work_friction) = self.works(state, start, report);
            residual = self.next_iterate(system, state, start, report, at)?;
            if residual <= newton.tolerance {
                break;
            }
        }
        if residual > newton.tolerance {
            return Err(at.newton_not_converged(outcome.iterations, residual, newton.tolerance));
        }
        Ok(outcome)
    }

    /// W^i = M(q^i) − hθ ∂F/∂v − h²θ² ∂F/∂q at (t_{k+1}, q^i, v^i), assembled from the
    /// matrices' entries and factorised by LU with partial pivoting: in the band order of
    /// `self.band` when there is one (no n×n array), else densely.
    fn iteration_matrix<S: JointedSystem + ?Sized>(
        &mut self,
        system: &S,
        at: StepAt,
        iteration: usize,
    ) -> Result<IterationLu, NonlinearStepError> {
        let (h, theta, n, s) = (self.h, self.params.theta, self.n, &mut self.s);
        system.force_jacobian_entries(at.t, &s.q, &s.v, &mut s.dfdq, &mut s.dfdv);
        at.check_entries_at(&s.dfdq, "∂F/∂q", &s.q, &s.v)?;
        at.check_entries_at(&s.dfdv, "∂F/∂v", &s.q, &s.v)?;
        let (cv, cq) = (h * theta, h * h * theta * theta);
        // M, then −hθ ∂F/∂v, then −h²θ² ∂F/∂q, summed position by position in that order.
        let terms = [(&s.mass, None), (&s.dfdv, Some(cv)), (&s.dfdq, Some(cq))];
        let term = |c: Option<f64>, v: f64| c.map_or(v, |c| -(c * v));
        let Some(band) = &self.band else {
            let mut w = DMatrix::zeros(n, n);
            for (t, c) in terms {
                for &(i, j, v) in t.entries() {
                    w[(i, j)] += term(c, v);
                }
            }
            return lu_factor_with(w, &mut s.column_max)
                .map(IterationLu::Dense)
                .ok_or(at.singular(iteration));
        };
        // W's entries, each position summed once (a stable sort keeps the order above).
        let w = &mut s.w_entries;
        w.clear();
        for (t, c) in terms {
            w.extend(t.entries().iter().map(|&(i, j, v)| (i, j, term(c, v))));
        }
        w.sort_by_key(|&(i, j, _)| (j, i));
        w.dedup_by(|next, kept| {
            let same = (next.0, next.1) == (kept.0, kept.1);
            if same {
                kept.2 += next.2;
            }
            same
        });
        let lu = BandLu::factor_regular(band, w).ok_or(at.singular(iteration))?;
        Ok(IterationLu::Band(lu))
    }

    /// The free velocity Δv_free = Δv^i − (W^i)⁻¹ R_free(v^i).
    fn free_velocity(
        &mut self,
        lu: &IterationLu,
        start: &EndOfStep,
        at: StepAt,
    ) -> Result<(), NonlinearStepError> {
        let (h, theta, n, s) = (self.h, self.params.theta, self.n, &mut self.s);
        mass_times(&s.mass, &s.dv, &mut s.mass_times);
        for i in 0..n {
            let f_theta = (1.0 - theta) * start.forces[i] + theta * s.forces[i];
            s.residual[i] = s.mass_times[i] - h * f_theta;
        }
        solve_in_place(lu, &mut s.residual);
        for (d, r) in s.dv.iter_mut().zip(&s.residual) {
            *d -= r;
        }
        at.check(&s.dv, "the free velocity")
    }

    /// The index set of the iterate, with the gaps linearised at q^i (module documentation),
    /// and the right-hand side U_free + e U_k of its contacts' normal rows.
    fn update_index_set<S: JointedSystem + ?Sized>(
        &mut self,
        system: &S,
        state: &NonlinearState,
        start: &EndOfStep,
        report: &mut NonlinearStepReport,
        at: StepAt,
    ) -> Result<(), NonlinearStepError> {
        let (h, n, m) = (self.h, self.n, self.m);
        let (params, memory, s) = (&self.params, &self.memory, &mut self.s);
        report.impulse.fill(0.0);
        report.tangent_impulse.fill(0.0);
        report.lcp = LcpStats::default();
        s.friction_step = false;
        s.offset = 0;
        s.joint_impulse.fill(0.0);
        s.active.clear();
        s.rhs.clear();
        if m == 0 {
            return Ok(());
        }
        let t_k = state.t;
        system.gap_jacobian(at.t, &s.q, &mut s.jac);
        at.check(&s.jac, "the gap Jacobian")?;
        system.gaps(at.t, &s.q, &mut s.gaps);
        at.check(&s.gaps, "a gap g(q, t)")?;
        system.gap_rates(at.t, &s.q, &mut s.rates_next);
        system.gap_rates(t_k, &s.q, &mut s.rates_k);
        at.check(&s.rates_next, "∂g/∂t")?;
        at.check(&s.rates_k, "∂g/∂t")?;
        for a in 0..m {
            let row = &s.jac[a * n..(a + 1) * n];
            let u_k = dot(row, &state.v) + s.rates_k[a];
            let active = s.member[a]
                || match params.index_set.activation {
                    Activation::GapAndVelocity => {
                        let u_tol = if memory.roundoff_step == state.step {
                            memory.roundoff[a]
                        } else {
                            0.0
                        };
                        let shift: f64 = (0..n).map(|i| row[i] * (s.predicted[i] - s.q[i])).sum();
                        // With friction, a lasting contact keeps its place when its predicted
                        // gap is within t × the velocity round-off (the drift that round-off
                        // in U can have put into q): dropping it for one step would drop its
                        // friction too (module documentation).
                        let gap_tol = if self.friction { at.t * u_tol } else { 0.0 };
                        s.gaps[a] + shift <= gap_tol && u_k <= u_tol
                    }
                    Activation::PredictedGap => {
                        start.gaps[a] + params.index_set.gamma * h * u_k <= 0.0
                    }
                };
            if active {
                s.member[a] = true;
                s.active.push(a);
                let u_free = dot(row, &state.v) + dot(row, &s.dv) + s.rates_next[a];
                s.rhs.push(u_free + system.restitution(a) * u_k);
            }
        }
        Ok(())
    }

    /// The one-step nonsmooth problem on the index set: the Delassus operator
    /// [H; T](W^i)⁻¹[H; T]ᵀ, the LCP (or, with friction on an active contact, the planar
    /// friction problem), and the impulse's velocity (W^i)⁻¹(Hᵀ P_n + Tᵀ P_t) added to Δv.
    fn one_step_problem<S: JointedSystem + ?Sized>(
        &mut self,
        system: &S,
        lu: &IterationLu,
        state: &NonlinearState,
        report: &mut NonlinearStepReport,
        at: StepAt,
    ) -> Result<(), NonlinearStepError> {
        let n = self.n;
        let s = &mut self.s;
        let k = s.active.len();
        // With friction on some active contact, the rows of the one-step problem are
        // (H_α, T_α) per contact, in the order (n_1, t_1, n_2, t_2, …); otherwise H_α.
        let friction_step = self.friction && s.active.iter().any(|&a| self.mu[a] > 0.0);
        s.friction_step = friction_step;
        if friction_step {
            system.tangent_jacobian(at.t, &s.q, &mut s.tjac);
            at.check(&s.tjac, "the tangent Jacobian")?;
            system.tangent_rates(at.t, &s.q, &mut s.trates);
            at.check(&s.trates, "∂τ/∂t")?;
        }
        let rows = if friction_step { 2 } else { 1 };
        let kk = rows * k;
        s.columns.clear();
        for &a in &s.active {
            for r in 0..rows {
                let src = if r == 0 { &s.jac } else { &s.tjac };
                let start_col = s.columns.len();
                s.columns.extend_from_slice(&src[a * n..(a + 1) * n]);
                solve_in_place(lu, &mut s.columns[start_col..]);
            }
        }
        s.delassus.clear();
        for &a in &s.active {
            for r in 0..rows {
                let src = if r == 0 { &s.jac } else { &s.tjac };
                let row = &src[a * n..(a + 1) * n];
                for c in 0..kk {
                    s.delassus.push(dot(row, &s.columns[c * n..(c + 1) * n]));
                }
            }
        }
        at.check(&s.delassus, "the Delassus operator")?;
        s.solution.clear();
        let (iterations, error) = if friction_step {
            // Free local velocity: normal rows U_free + e U_k, tangent rows
            // T(q^i)(v_k + Δv_free) + ∂τ/∂t(t_{k+1}).
            s.friction_q.clear();
            s.friction_mu.clear();
            for (r, &a) in s.active.iter().enumerate() {
                let row = &s.tjac[a * n..(a + 1) * n];
                s.friction_q.push(s.rhs[r]);
                s.friction_q
                    .push(dot(row, &state.v) + dot(row, &s.dv) + s.trates[a]);
                s.friction_mu.push(self.mu[a]);
            }
            let sol = solve_friction_at(
                FrictionProblem {
                    w: &s.delassus,
                    q: &s.friction_q,
                    mu: &s.friction_mu,
                },
                &self.lcp,
                at,
            )?;
            s.solution.extend_from_slice(&sol.p);
            (sol.iterations, sol.error)
        } else {
            let sol = lcp::solve(
                Lcp {
                    m: &s.delassus,
                    q: &s.rhs,
                },
                &self.lcp,
            )
            .map_err(|source| at.lcp(source))?;
            s.solution.extend_from_slice(&sol.z);
            (sol.iterations, sol.error)
        };
        for (c, &p) in s.solution.iter().enumerate() {
            let a = s.active[c / rows];
            if c % rows == 0 {
                report.impulse[a] = p;
            } else {
                report.tangent_impulse[a] = p;
            }
            if p != 0.0 {
                for (d, col) in s.dv.iter_mut().zip(&s.columns[c * n..(c + 1) * n]) {
                    *d += p * col;
                }
            }
        }
        report.lcp = LcpStats {
            size: k,
            iterations,
            error,
        };
        Ok(())
    }

    /// The contact and friction works (work_contact, work_friction) of the iterate, with the
    /// H and T of its solve, against v_{k+θ} = v_k + θ Δv (module documentation).
    fn works(
        &self,
        state: &NonlinearState,
        start: &EndOfStep,
        report: &NonlinearStepReport,
    ) -> (f64, f64) {
        let (theta, n, s) = (self.params.theta, self.n, &self.s);
        let mut work_contact = 0.0;
        let mut work_friction = 0.0;
        for &a in &s.active {
            let p = report.impulse[a];
            if p != 0.0 {
                let row = &s.jac[a * n..(a + 1) * n];
                let u: f64 = (0..n)
                    .map(|i| row[i] * (state.v[i] + theta * s.dv[i]))
                    .sum();
                work_contact += p * u;
            }
            let pt = report.tangent_impulse[a];
            if s.friction_step && pt != 0.0 {
                // θ U_t,{k+1} (the velocity of this solve, on which Coulomb's law holds)
                // + (1 − θ) U_t,k (the end of the last step), split by friction::work.
                let row = &s.tjac[a * n..(a + 1) * n];
                let u_next = dot(row, &state.v) + dot(row, &s.dv) + s.trates[a];
                let u_start = start.tangent_velocity[a];
                let work = pt * (theta * u_next + (1.0 - theta) * u_start);
                let split = friction::split_tangential_work(work, theta, pt * u_start, pt * u_next);
                work_friction += split.friction;
                work_contact += split.contact;
            }
        }
        (work_contact, work_friction)
    }

    /// The new iterate q^{i+1}, v^{i+1} and its relative residual R(v^{i+1}), with M, F, H
    /// and T all at q^{i+1}.
    fn next_iterate<S: JointedSystem + ?Sized>(
        &mut self,
        system: &S,
        state: &NonlinearState,
        start: &EndOfStep,
        report: &NonlinearStepReport,
        at: StepAt,
    ) -> Result<f64, NonlinearStepError> {
        let (h, theta, n, m, s) = (self.h, self.params.theta, self.n, self.m, &mut self.s);
        position(&state.q, &state.v, &s.dv, h, theta, &mut s.q);
        for ((v, vk), d) in s.v.iter_mut().zip(&state.v).zip(&s.dv) {
            *v = vk + d;
        }
        system.mass_entries(&s.q, &mut s.mass);
        at.check_entries_at(&s.mass, "M(q)", &s.q, &[])?;
        system.forces(at.t, &s.q, &s.v, &mut s.forces);
        at.check_at(&s.forces, "F(t, q, v)", &s.q, &s.v)?;
        if m > 0 {
            system.gap_jacobian(at.t, &s.q, &mut s.jac);
            at.check(&s.jac, "the gap Jacobian")?;
        }
        if s.friction_step {
            system.tangent_jacobian(at.t, &s.q, &mut s.tjac);
            at.check(&s.tjac, "the tangent Jacobian")?;
        }
        let nb = self.nb;
        if nb > 0 {
            midpoint(&state.q, &s.q, &mut s.midpoint);
            system.joint_jacobian(at.t - 0.5 * h, &s.midpoint, &mut s.joint_directions);
            at.check(&s.joint_directions, "the joint Jacobian")?;
        }
        let (mut r_max, mut scale) = (0.0f64, 0.0f64);
        mass_times(&s.mass, &s.dv, &mut s.mass_times);
        for i in 0..n {
            let md = s.mass_times[i];
            let (fk, f1) = ((1.0 - theta) * start.forces[i], theta * s.forces[i]);
            let (mut hp, mut hp_abs) = (0.0, 0.0);
            for &a in &s.active {
                let t = s.jac[a * n + i] * report.impulse[a];
                hp += t;
                hp_abs += t.abs();
                if s.friction_step {
                    let t = s.tjac[a * n + i] * report.tangent_impulse[a];
                    hp += t;
                    hp_abs += t.abs();
                }
            }
            for (j, lambda) in s.joint_impulse.iter().enumerate() {
                let t = s.joint_directions[j * n + i] * lambda;
                hp += t;
                hp_abs += t.abs();
            }
            let r = md - h * (fk + f1) - hp;
            r_max = r_max.max(r.abs());
            scale = scale.max(md.abs() + h * (fk.abs() + f1.abs()) + hp_abs);
        }
        let mut residual = if r_max == 0.0 { 0.0 } else { r_max / scale };
        if nb > 0 {
            residual = residual.max(self.joint_violation(system, state, at)?);
        }
        if !residual.is_finite() {
            return Err(at.not_finite("the Newton residual", residual));
        }
        Ok(residual)
    }

    /// The joint violation of the iterate q^{i+1} relative to the joints' scale,
    /// max_j |g_j(q^{i+1}, t_{k+1})| / max_j Σ_i |G_ji| (|q_i| + ‖q − q_k‖∞), with g kept in
    /// `joint_values`. The step's motion enters through its largest coordinate, not each
    /// coordinate's own: q^{i+1} comes from Δv, whose every entry carries the round-off of
    /// the whole solve, so a joint on coordinates that stay at zero (x₀ = 0 on a falling bar)
    /// sees round-off of the size of the motion elsewhere. Measured against its own
    /// coordinates alone (10⁻²⁰ against 10⁻²⁰), it read 0.5 and Newton failed at step 4.
    fn joint_violation<S: JointedSystem + ?Sized>(
        &mut self,
        system: &S,
        state: &NonlinearState,
        at: StepAt,
    ) -> Result<f64, NonlinearStepError> {
        let (n, s) = (self.n, &mut self.s);
        system.joint_values(at.t, &s.q, &mut s.joint_values);
        at.check(&s.joint_values, "a joint g(q, t)")?;
        system.joint_jacobian(at.t, &s.q, &mut s.joint_rows);
        at.check(&s.joint_rows, "the joint Jacobian")?;
        let motion =
            s.q.iter()
                .zip(&state.q)
                .fold(0.0f64, |m, (q, qk)| m.max((q - qk).abs()));
        let scale = (0..self.nb)
            .map(|j| {
                (0..n)
                    .map(|i| s.joint_rows[j * n + i].abs() * (s.q[i].abs() + motion))
                    .sum::<f64>()
            })
            .fold(0.0f64, f64::max);
        let worst = amax(&s.joint_values);
        Ok(if scale > 0.0 { worst / scale } else { worst })
    }

    /// The joint condition of the iterate: g(q_{k+1}, t_{k+1}) = 0 with q_{k+1} = q_k +
    /// h(v_k + θ Δv), linearised in Δv at q^i (exactly: ∂q_{k+1}/∂Δv = hθ),
    /// `G(q^i) Δv = G(q^i) Δv^i − g(q^i, t_{k+1})/(hθ)`, kept in `joint_target` (`dv` still
    /// holds Δv^i here); and the joint impulses' directions G at the midpoint ½(q_k + q^i),
    /// t_{k+½} (module documentation).
    fn joint_condition<S: JointedSystem + ?Sized>(
        &mut self,
        system: &S,
        state: &NonlinearState,
        at: StepAt,
    ) -> Result<(), NonlinearStepError> {
        let (h, theta, n, s) = (self.h, self.params.theta, self.n, &mut self.s);
        system.joint_values(at.t, &s.q, &mut s.joint_values);
        at.check(&s.joint_values, "a joint g(q, t)")?;
        system.joint_jacobian(at.t, &s.q, &mut s.joint_rows);
        at.check(&s.joint_rows, "the joint Jacobian")?;
        midpoint(&state.q, &s.q, &mut s.midpoint);
        system.joint_jacobian(at.t - 0.5 * h, &s.midpoint, &mut s.joint_directions);
        at.check(&s.joint_directions, "the joint Jacobian")?;
        for (j, target) in s.joint_target.iter_mut().enumerate() {
            let row = &s.joint_rows[j * n..(j + 1) * n];
            *target = dot(row, &s.dv) - s.joint_values[j] / (h * theta);
        }
        Ok(())
    }

    /// The one-step problem of a system with joints: the mixed LCP (Siconos' MLCP) of the joint
    /// rows G(q^i) (equalities, [`Self::joint_condition`]) and the contact rows H_α of the index
    /// set, on the operator `[G(q^i); H](W^i)⁻¹[G_mid; H]ᵀ` (not symmetric: the joint impulses
    /// act along G_mid); free values `G(q^i) Δv_free − target` and `U_free + e U_k`. Its
    /// impulses (Λ, P) add (W^i)⁻¹(G_midᵀ Λ + Hᵀ P) to Δv.
    fn mixed_problem(
        &mut self,
        lu: &IterationLu,
        report: &mut NonlinearStepReport,
        at: StepAt,
        iteration: usize,
    ) -> Result<(), NonlinearStepError> {
        let (n, nb, s) = (self.n, self.nb, &mut self.s);
        let k = nb + s.active.len();
        s.columns.clear();
        for r in 0..k {
            let start_col = s.columns.len();
            if r < nb {
                s.columns
                    .extend_from_slice(&s.joint_directions[r * n..(r + 1) * n]);
            } else {
                let a = s.active[r - nb];
                s.columns.extend_from_slice(&s.jac[a * n..(a + 1) * n]);
            }
            solve_in_place(lu, &mut s.columns[start_col..]);
        }
        s.delassus.clear();
        let mut b = Vec::with_capacity(k);
        for r in 0..k {
            let row = if r < nb {
                &s.joint_rows[r * n..(r + 1) * n]
            } else {
                let a = s.active[r - nb];
                &s.jac[a * n..(a + 1) * n]
            };
            for c in 0..k {
                s.delassus.push(dot(row, &s.columns[c * n..(c + 1) * n]));
            }
            b.push(if r < nb {
                dot(row, &s.dv) - s.joint_target[r]
            } else {
                s.rhs[r - nb]
            });
        }
        at.check(&s.delassus, "the Delassus operator")?;
        let d = DMatrix::from_row_slice(k, k, &s.delassus);
        let sol = solve_mixed_at(&d, &b, nb, &self.lcp, at, iteration)?;
        s.solution.clear();
        s.solution.extend_from_slice(&sol.z);
        s.joint_impulse.copy_from_slice(&sol.z[..nb]);
        for (c, &p) in sol.z.iter().enumerate() {
            if c >= nb {
                report.impulse[s.active[c - nb]] = p;
            }
            if p != 0.0 {
                for (d, col) in s.dv.iter_mut().zip(&s.columns[c * n..(c + 1) * n]) {
                    *d += p * col;
                }
            }
        }
        s.offset = nb;
        report.lcp = LcpStats {
            size: sol.size,
            iterations: sol.iterations,
            error: sol.error,
        };
        Ok(())
    }

    /// The one-step problem of a system with joints when some contact of the index set has
    /// μ > 0: a planar friction problem with equality rows. The rows are stacked as
    /// `[G(q^i); H_1; T_1; H_2; T_2; …]` with the impulse directions `[G_mid; H_1; T_1; …]`,
    /// the operator D = rows (W^i)⁻¹ directionsᵀ and the free values b as in
    /// [`Self::mixed_problem`] and [`Self::one_step_problem`]. The joint rows are condensed out
    /// exactly as the rigid bodies' joints are ([`crate::lcp::EqualityElimination`]):
    ///
    /// ```text
    /// Λ = −A⁺ (b_B + D_BI P),   A = D_BB = G(q^i)(W^i)⁻¹G_midᵀ
    /// W' = D_II − D_IB A⁺ D_BI,   q' = b_I − D_IB A⁺ b_B
    /// ```
    ///
    /// (A⁺ = A⁻¹ for independent joints, the minimum-norm least-squares solve when they are
    /// dependent), then the contacts' planar friction problem (W', q', μ) is solved by
    /// [`friction::solve_friction`] and Λ recovered from its P: Coulomb's law and Newton's
    /// impact law hold on the local velocities U = D_IB Λ + D_II P + b_I of the whole problem,
    /// with the joint rows satisfied exactly. The impulses add (W^i)⁻¹(G_midᵀ Λ + Hᵀ P_n +
    /// Tᵀ P_t) to Δv.
    fn condensed_friction_problem<S: JointedSystem + ?Sized>(
        &mut self,
        system: &S,
        lu: &IterationLu,
        state: &NonlinearState,
        report: &mut NonlinearStepReport,
        at: StepAt,
        iteration: usize,
    ) -> Result<(), NonlinearStepError> {
        let (n, nb, s) = (self.n, self.nb, &mut self.s);
        s.friction_step = true;
        system.tangent_jacobian(at.t, &s.q, &mut s.tjac);
        at.check(&s.tjac, "the tangent Jacobian")?;
        system.tangent_rates(at.t, &s.q, &mut s.trates);
        at.check(&s.trates, "∂τ/∂t")?;
        let k = s.active.len();
        let size = nb + 2 * k;
        s.columns.clear();
        for r in 0..size {
            let start_col = s.columns.len();
            let row = stacked_row(&s.joint_directions, &s.jac, &s.tjac, &s.active, (n, nb), r);
            s.columns.extend_from_slice(row);
            solve_in_place(lu, &mut s.columns[start_col..]);
        }
        s.delassus.clear();
        s.friction_q.clear();
        s.friction_mu.clear();
        let mut b = Vec::with_capacity(size);
        for r in 0..size {
            let row = stacked_row(&s.joint_rows, &s.jac, &s.tjac, &s.active, (n, nb), r);
            for c in 0..size {
                s.delassus.push(dot(row, &s.columns[c * n..(c + 1) * n]));
            }
            let value = match r.checked_sub(nb) {
                None => dot(row, &s.dv) - s.joint_target[r],
                Some(c) if c % 2 == 0 => s.rhs[c / 2],
                Some(c) => dot(row, &state.v) + dot(row, &s.dv) + s.trates[s.active[c / 2]],
            };
            if r >= nb {
                s.friction_q.push(value);
            }
            b.push(value);
        }
        s.friction_mu.extend(s.active.iter().map(|&a| self.mu[a]));
        at.check(&s.delassus, "the Delassus operator")?;
        let d = DMatrix::from_row_slice(size, size, &s.delassus);
        let sol = solve_joint_friction_at(&d, &b, nb, &s.friction_mu, &self.lcp, at, iteration)?;
        s.solution.clear();
        s.solution.extend_from_slice(&sol.z);
        s.joint_impulse.copy_from_slice(&s.solution[..nb]);
        for (c, &p) in s.solution.iter().enumerate() {
            if let Some(i) = c.checked_sub(nb) {
                let a = s.active[i / 2];
                if i % 2 == 0 {
                    report.impulse[a] = p;
                } else {
                    report.tangent_impulse[a] = p;
                }
            }
            if p != 0.0 {
                for (d, col) in s.dv.iter_mut().zip(&s.columns[c * n..(c + 1) * n]) {
                    *d += p * col;
                }
            }
        }
        s.offset = nb;
        report.lcp = LcpStats {
            size: k,
            iterations: sol.iterations,
            error: sol.error,
        };
        Ok(())
    }

    /// Round-off level of the last solve's local velocities (normal rows), for the sign test of
    /// the next step. With friction the solver couples each normal row to its tangent row (the
    /// Lemke tableau of the reformulation pivots on both), so the level counts both rows.
    fn keep_roundoff(&mut self, step: u64) {
        let (s, memory) = (&self.s, &mut self.memory);
        memory.roundoff.fill(0.0);
        let rows = if s.friction_step { 2 } else { 1 };
        // With joints the contact rows follow the `offset` joint rows.
        let off = s.offset;
        let kk = off + rows * s.active.len();
        for (r, &a) in s.active.iter().enumerate() {
            let mut level = 0.0;
            for row in rows * r..rows * (r + 1) {
                let wp: f64 = (0..kk)
                    .map(|c| (s.delassus[(off + row) * kk + c] * s.solution[c]).abs())
                    .sum();
                let b = if rows == 1 {
                    s.rhs[r]
                } else {
                    s.friction_q[row]
                };
                level += b.abs() + wp;
            }
            memory.roundoff[a] = 64.0 * f64::EPSILON * level;
        }
        memory.roundoff_step = step;
    }

    /// The end of the step: the applied forces and the works, the energy, the gaps and local
    /// velocities of the report; the end kept as the next step's start, and the state updated.
    fn finish<S: JointedSystem + ?Sized>(
        &mut self,
        system: &S,
        state: &mut NonlinearState,
        start: EndOfStep,
        newton: NewtonOutcome,
        report: &mut NonlinearStepReport,
        at: StepAt,
    ) -> Result<(), NonlinearStepError> {
        let (h, theta, n, s) = (self.h, self.params.theta, self.n, &mut self.s);
        system.applied_forces(at.t, &s.q, &s.v, &mut s.applied);
        at.check(&s.applied, "the applied forces f(t, q, v)")?;
        let mut work_ext = 0.0;
        for i in 0..n {
            let f_theta = (1.0 - theta) * start.applied[i] + theta * s.applied[i];
            work_ext += f_theta * (state.v[i] + theta * s.dv[i]);
        }
        work_ext *= h;
        report.kinetic = kinetic(&s.mass, &s.v, &mut s.mass_times);
        report.potential = system.potential(at.t, &s.q);
        let energy = report.energy();
        if !energy.is_finite() {
            return Err(at.not_finite("the energy", energy));
        }
        let NewtonOutcome {
            iterations,
            work_contact,
            work_friction,
        } = newton;
        report.work_ext = work_ext;
        report.work_contact = work_contact;
        report.work_friction = work_friction;
        report.energy_error = (energy - start.energy) - work_ext - work_contact - work_friction;
        report.newton_iterations = iterations;
        // joint_values holds g(q_{k+1}, t_{k+1}) of the last residual.
        report.position_residual = amax(&s.joint_values);
        system.gaps(at.t, &s.q, &mut report.gap);
        at.check(&report.gap, "a gap g(q, t)")?;
        system.gap_rates(at.t, &s.q, &mut report.local_velocity);
        for (a, u) in report.local_velocity.iter_mut().enumerate() {
            *u += dot(&s.jac[a * n..(a + 1) * n], &s.v);
        }
        if self.friction {
            system.tangent_jacobian(at.t, &s.q, &mut s.tjac);
            at.check(&s.tjac, "the tangent Jacobian")?;
            system.tangent_rates(at.t, &s.q, &mut report.tangent_velocity);
            for (a, u) in report.tangent_velocity.iter_mut().enumerate() {
                *u += dot(&s.tjac[a * n..(a + 1) * n], &s.v);
            }
        }

        let mut end = start;
        end.step = at.step;
        end.t = at.t;
        end.q.copy_from_slice(&s.q);
        end.v.copy_from_slice(&s.v);
        end.forces.copy_from_slice(&s.forces);
        end.applied.copy_from_slice(&s.applied);
        end.gaps.copy_from_slice(&report.gap);
        if self.friction {
            end.tangent_velocity
                .copy_from_slice(&report.tangent_velocity);
        }
        end.energy = energy;
        self.memory.last = Some(end);
        state.q.copy_from_slice(&s.q);
        state.v.copy_from_slice(&s.v);
        state.t = at.t;
        state.step = at.step;
        Ok(())
    }
}

/// LU factors of an iteration matrix W: dense, or in a band order.
#[derive(Debug)]
enum IterationLu {
    Dense(nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn>),
    Band(BandLu),
}

/// b ← W⁻¹ b with the LU factors of W (b holds W's n rows at its head).
fn solve_in_place(lu: &IterationLu, b: &mut [f64]) {
    match lu {
        IterationLu::Dense(lu) => {
            let n = b.len();
            lu.solve_mut(&mut DVectorViewMut::from_slice(b, n));
        }
        IterationLu::Band(lu) => {
            // Its pivots were checked when it was made.
            lu.solve_mut(b);
        }
    }
}

/// The band order of a system's iteration matrix W = M − hθ ∂F/∂v − h²θ² ∂F/∂q, from the
/// structural entries of M, ∂F/∂q and ∂F/∂v (evaluated once at q = v = 0, t = 0: only
/// their positions are read), when the band LU pays ([`BandOrder::of_pattern`]: at least 48
/// unknowns and a band well inside the matrix).
fn iteration_matrix_band<S: LagrangianSystem + ?Sized>(system: &S) -> Option<BandOrder> {
    let n = system.dofs();
    if n < 48 {
        return None;
    }
    let (zeros, mut mass, mut dq, mut dv) = (
        vec![0.0; n],
        Triplets::new(n, n),
        Triplets::new(n, n),
        Triplets::new(n, n),
    );
    system.mass_entries(&zeros, &mut mass);
    system.force_jacobian_entries(0.0, &zeros, &zeros, &mut dq, &mut dv);
    let entries = [&mass, &dq, &dv].into_iter().flat_map(Triplets::entries);
    BandOrder::of_entries(n, entries.map(|&(i, j, _)| (i, j)))
}

/// `out` ← M x, M as its entries (each row summed in the order of its entries: for the
/// row-major entries of a model, the order of a dense row's dot product).
fn mass_times(mass: &Triplets, x: &[f64], out: &mut [f64]) {
    out.fill(0.0);
    mass.mul_add(x, out);
}

/// The kinetic energy ½ vᵀ M v, M as its entries; `buffer` takes M v.
fn kinetic(mass: &Triplets, v: &[f64], buffer: &mut Vec<f64>) -> f64 {
    buffer.resize(v.len(), 0.0);
    mass_times(mass, v, buffer);
    0.5 * v.iter().zip(buffer.iter()).map(|(a, b)| a * b).sum::<f64>()
}

/// Row r of the stacked rows `[J; H_{a_1}; T_{a_1}; H_{a_2}; T_{a_2}; …]` of a friction
/// problem with joints: J the first nb rows of `joints` (n columns each), then the normal
/// (`jac`) and tangent (`tjac`) rows of the active contacts `active`.
pub(crate) fn stacked_row<'a>(
    joints: &'a [f64],
    jac: &'a [f64],
    tjac: &'a [f64],
    active: &[usize],
    (n, nb): (usize, usize),
    r: usize,
) -> &'a [f64] {
    match r.checked_sub(nb) {
        None => &joints[r * n..(r + 1) * n],
        Some(c) => {
            let a = active[c / 2];
            let src = if c % 2 == 0 { jac } else { tjac };
            &src[a * n..(a + 1) * n]
        }
    }
}

/// The midpoint ½(q_k + q).
fn midpoint(q_k: &[f64], q: &[f64], out: &mut [f64]) {
    for ((o, a), b) in out.iter_mut().zip(q_k).zip(q) {
        *o = 0.5 * (a + b);
    }
}

/// q = q_k + h (v_k + θ Δv), in the same floating-point order as the linear scheme.
fn position(q_k: &[f64], v_k: &[f64], dv: &[f64], h: f64, theta: f64, out: &mut [f64]) {
    for (((o, q), v), d) in out.iter_mut().zip(q_k).zip(v_k).zip(dv) {
        *o = q + h * (v + theta * d);
    }
}

/// Whether some contact of `system` has μ > 0.
pub fn has_friction<S: LagrangianSystem + ?Sized>(system: &S) -> bool {
    (0..system.contacts()).any(|a| system.friction(a) > 0.0)
}

/// What a nonlinear run measured over all its steps (recorded or not); its fields are those of
/// `summary.json`.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct NonlinearRunStats {
    /// Steps done.
    pub steps: u64,
    /// Final time.
    pub t_end: f64,
    /// Mechanical energy at t₀.
    pub energy_initial: f64,
    /// Mechanical energy at the end.
    pub energy_final: f64,
    /// Largest mechanical energy seen.
    pub energy_max: f64,
    /// max_k |energy_error|.
    pub max_abs_energy_error: f64,
    /// Impacts: (step, contact) pairs whose impulse became positive after a step without.
    pub impacts: u64,
    /// Largest LCP complementarity error.
    pub lcp_max_error: f64,
    /// Steps that solved a non-empty LCP.
    pub lcp_solves: u64,
    /// Largest LCP (active contacts).
    pub lcp_max_size: usize,
    /// Largest number of Newton iterates in a step.
    pub newton_iterations_max: usize,
    /// Newton iterates per step, on average.
    pub newton_iterations_mean: f64,
    /// Cumulative work of the applied forces at the end.
    pub work_ext_total: f64,
    /// Cumulative work of the contact impulses at the end.
    pub work_contact_total: f64,
    /// Cumulative work of the friction impulses at the end (only for a system with friction).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub work_friction_total: Option<f64>,
    /// Largest friction work of one step, max_k work_friction (≤ 0 when friction never does
    /// positive work; only for a system with friction).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub work_friction_max: Option<f64>,
    /// Largest joint violation max_k position_residual (only for a system with joints).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_position_residual: Option<f64>,
}

impl NonlinearRunStats {
    /// Adds step `k` (ending at time `t`) with its `report`: the works' totals, the energy and
    /// LCP extremes, the Newton mean over `newton_total` iterates (updated here) and the impacts
    /// against the impulses of the previous step (updated here). The friction work is the
    /// family's own.
    pub(crate) fn add_step(
        &mut self,
        k: u64,
        t: f64,
        report: &NonlinearStepReport,
        newton_total: &mut u64,
        previous_impulse: &mut [f64],
    ) {
        self.steps = k;
        self.t_end = t;
        self.work_ext_total += report.work_ext;
        self.work_contact_total += report.work_contact;
        self.max_abs_energy_error = self.max_abs_energy_error.max(report.energy_error.abs());
        self.energy_final = report.energy();
        self.energy_max = self.energy_max.max(report.energy());
        self.lcp_max_error = self.lcp_max_error.max(report.lcp.error);
        self.lcp_solves += u64::from(report.lcp.size > 0);
        self.lcp_max_size = self.lcp_max_size.max(report.lcp.size);
        self.newton_iterations_max = self.newton_iterations_max.max(report.newton_iterations);
        *newton_total += report.newton_iterations as u64;
        self.newton_iterations_mean = *newton_total as f64 / k as f64;
        self.impacts += stepping::count_impacts(previous_impulse, &report.impulse);
    }

    /// The statistics of a run starting at `t` with energy `energy`; `friction`: the run sums
    /// the friction work (its system has friction).
    pub(crate) fn starting(t: f64, energy: f64, friction: bool) -> Self {
        Self {
            t_end: t,
            energy_initial: energy,
            energy_final: energy,
            energy_max: energy,
            work_friction_total: friction.then_some(0.0),
            ..Default::default()
        }
    }

    /// Adds a step's friction work `work_friction` to `work_friction_total` and
    /// `work_friction_max`, for a run of a system with friction (`work_friction_total` is
    /// `Some`); nothing otherwise.
    pub(crate) fn add_friction(&mut self, work_friction: f64) {
        if let Some(total) = self.work_friction_total.as_mut() {
            *total += work_friction;
            self.work_friction_max = Some(
                self.work_friction_max
                    .map_or(work_friction, |w| w.max(work_friction)),
            );
        }
    }
}

/// Why a nonlinear run ended early.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum NonlinearRunStop {
    /// A step failed.
    #[error(transparent)]
    Step(#[from] NonlinearStepError),
    /// The observer asked to stop (cancellation) after `step` steps.
    #[error("stopped by the observer after {step} steps")]
    Stopped {
        /// Steps done.
        step: u64,
    },
    /// A probe names a coordinate the system does not have.
    #[error("output.probes: coordinate {probe} does not exist (the system has {dofs})")]
    Probe {
        /// The probe.
        probe: usize,
        /// Coordinates of the system.
        dofs: usize,
    },
    /// The checkpoint to resume from does not fit the run.
    #[error(transparent)]
    Checkpoint(#[from] crate::checkpoint::CheckpointError),
}

/// Column names of a nonlinear run: [`NONLINEAR_ENERGY_COLUMNS`], [`NONLINEAR_RUN_COLUMNS`],
/// with friction [`FRICTION_COLUMNS`], then `gap_α, u_α, p_α` per contact (with friction also
/// `pt_α, ut_α`: tangential impulse and velocity), then `q_j, v_j` per probe. A system without
/// friction has exactly the frictionless columns.
pub fn nonlinear_columns(
    contacts: usize,
    friction: bool,
    joints: bool,
    probes: &[usize],
) -> Columns {
    let mut names: Vec<String> = NONLINEAR_ENERGY_COLUMNS
        .iter()
        .chain(&NONLINEAR_RUN_COLUMNS)
        .map(|s| s.to_string())
        .collect();
    if friction {
        names.extend(FRICTION_COLUMNS.iter().map(|s| s.to_string()));
    }
    contact_columns(contacts, friction, &mut names);
    if joints {
        names.push("position_residual".into());
    }
    probe_columns(probes, &mut names);
    Columns::new(names)
}

/// The values of each contact's columns (`gap_α`, `u_α`, `p_α`, with friction `pt_α`, `ut_α`)
/// from a step's report.
pub(crate) fn contact_values(report: &NonlinearStepReport, friction: bool, row: &mut Vec<f64>) {
    for a in 0..report.gap.len() {
        row.extend([report.gap[a], report.local_velocity[a], report.impulse[a]]);
        if friction {
            row.extend([report.tangent_impulse[a], report.tangent_velocity[a]]);
        }
    }
}

/// The names of each contact's columns, as [`contact_values`] writes them.
pub(crate) fn contact_columns(contacts: usize, friction: bool, names: &mut Vec<String>) {
    for a in 0..contacts {
        names.extend([format!("gap_{a}"), format!("u_{a}"), format!("p_{a}")]);
        if friction {
            names.extend([format!("pt_{a}"), format!("ut_{a}")]);
        }
    }
}

/// The names of the probes' columns (`q_j`, `v_j`), last in every row.
pub(crate) fn probe_columns(probes: &[usize], names: &mut Vec<String>) {
    for j in probes {
        names.extend([format!("q_{j}"), format!("v_{j}")]);
    }
}

/// The planar friction problem of step `at`, its failure named for the step.
fn solve_friction_at(
    problem: FrictionProblem<'_>,
    options: &LcpOptions,
    at: StepAt,
) -> Result<friction::FrictionSolution, NonlinearStepError> {
    friction::solve_friction(problem, options).map_err(|source| NonlinearStepError::Friction {
        step: at.step,
        t: at.t,
        source,
    })
}

/// The impulses of a planar friction problem with joint rows and its solve's diagnostics.
pub(crate) struct JointFrictionSolution {
    /// The joint impulses Λ, then (P_n, P_t) per contact.
    pub(crate) z: Vec<f64>,
    /// Iterations of the friction solver.
    pub(crate) iterations: usize,
    /// Its natural-map error.
    pub(crate) error: f64,
}

/// The planar friction problem with `nb` joint rows at its head: `d` (nb + 2k square) and `b`
/// on the rows `[G; H_1; T_1; …; H_k; T_k]`, `mu` per contact. The joint rows are condensed
/// out by [`EqualityElimination`] (Λ = −A⁺(b_B + D_BI P), the friction problem on the Schur
/// complement W' = D_II − D_IB A⁺ D_BI and q' = b_I − D_IB A⁺ b_B, module documentation), the
/// contacts' problem is solved by [`friction::solve_friction`] and Λ recovered from its P;
/// without joints the problem is solved as it stands. Its failure is named for Newton
/// iteration `iteration` of step `at`.
pub(crate) fn solve_joint_friction_at(
    d: &DMatrix<f64>,
    b: &[f64],
    nb: usize,
    mu: &[f64],
    options: &LcpOptions,
    at: StepAt,
    iteration: usize,
) -> Result<JointFrictionSolution, NonlinearStepError> {
    let k2 = b.len() - nb;
    if nb == 0 {
        let w: Vec<f64> = (0..k2 * k2).map(|r| d[(r / k2, r % k2)]).collect();
        let sol = solve_friction_at(FrictionProblem { w: &w, q: b, mu }, options, at)?;
        return Ok(JointFrictionSolution {
            z: sol.p,
            iterations: sol.iterations,
            error: sol.error,
        });
    }
    let condensed = EqualityElimination::new(MixedLcp {
        d,
        b,
        equalities: nb,
    })
    .map_err(|_| at.singular(iteration))?;
    let w: Vec<f64> = (0..k2 * k2)
        .map(|r| condensed.schur[(r / k2, r % k2)])
        .collect();
    let sol = solve_friction_at(
        FrictionProblem {
            w: &w,
            q: condensed.free.as_slice(),
            mu,
        },
        options,
        at,
    )?;
    let mut z = condensed.equality_part(&sol.p);
    z.extend_from_slice(&sol.p);
    Ok(JointFrictionSolution {
        z,
        iterations: sol.iterations,
        error: sol.error,
    })
}

/// The mixed LCP of the joint rows (equalities) and the contact rows, its failure named for
/// Newton iteration `iteration` of step `at`.
pub(crate) fn solve_mixed_at(
    d: &DMatrix<f64>,
    b: &[f64],
    nb: usize,
    options: &LcpOptions,
    at: StepAt,
    iteration: usize,
) -> Result<MixedSolution, NonlinearStepError> {
    solve_mixed(
        MixedLcp {
            d,
            b,
            equalities: nb,
        },
        options,
    )
    .map_err(|e| match e {
        MixedLcpError::Singular { .. } => at.singular(iteration),
        MixedLcpError::Lcp(source) => at.lcp(source),
    })
}
